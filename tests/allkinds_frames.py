"""The example frames of ``tests/maps/allkinds.yaml``, built with pymodbus (not by hand).

Each example is a request PDU and a response PDU made from pymodbus's own message classes, with
register contents from pymodbus's ``convert_to_registers`` (word order "big"/"little"; a
low_first byte order swaps the two bytes of every word, which pymodbus has no option for). The
frames are pymodbus's RTU framer output. ``tests/project/test_map_allkinds.py`` checks that the map prints
exactly these frames; ``python -m tests.allkinds_frames`` prints them as YAML for the map.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pymodbus.client.mixin import ModbusClientMixin
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ModbusPDU
from pymodbus.pdu.bit_message import (
    ReadCoilsRequest,
    ReadCoilsResponse,
    ReadDiscreteInputsRequest,
    ReadDiscreteInputsResponse,
    WriteMultipleCoilsRequest,
    WriteMultipleCoilsResponse,
    WriteSingleCoilRequest,
    WriteSingleCoilResponse,
)
from pymodbus.pdu.register_message import (
    ReadHoldingRegistersRequest,
    ReadHoldingRegistersResponse,
    ReadInputRegistersRequest,
    ReadInputRegistersResponse,
    WriteMultipleRegistersRequest,
    WriteMultipleRegistersResponse,
    WriteSingleRegisterRequest,
    WriteSingleRegisterResponse,
)

M = ModbusClientMixin
DT = ModbusClientMixin.DATATYPE
UNIT = 1


def regs(value: Any, datatype: Any, word_order: str = "big", swap: bool = False, pad: int = 0,
         encoding: str = "utf-8") -> list[int]:
    """pymodbus's registers for ``value``; ``swap``: bytes of each word swapped (byte_order low_first)."""
    words = M.convert_to_registers(value, datatype, word_order=word_order, string_encoding=encoding)  # type: ignore[arg-type]
    words = words + [0] * (pad - len(words))
    return [((w & 0xFF) << 8) | (w >> 8) for w in words] if swap else words


@dataclass
class Case:
    name: str
    title: str
    request: ModbusPDU
    response: ModbusPDU
    operation: str
    address: int
    quantity: int
    values: dict[str, Any]
    preset: dict[str, Any] = field(default_factory=dict)

    def frames(self) -> tuple[str, str]:
        framer = FramerRTU(DecodePDU(False))
        self.request.dev_id = self.response.dev_id = UNIT
        return (framer.buildFrame(self.request).hex(" ").upper(), framer.buildFrame(self.response).hex(" ").upper())


def _read_input(address: int, words: list[int]) -> tuple[ModbusPDU, ModbusPDU]:
    return ReadInputRegistersRequest(address=address, count=len(words)), ReadInputRegistersResponse(registers=words)


def _read_holding(address: int, words: list[int]) -> tuple[ModbusPDU, ModbusPDU]:
    return (ReadHoldingRegistersRequest(address=address, count=len(words)),
            ReadHoldingRegistersResponse(registers=words))


def _write_holding(address: int, words: list[int]) -> tuple[ModbusPDU, ModbusPDU]:
    return (WriteMultipleRegistersRequest(address=address, registers=words),
            WriteMultipleRegistersResponse(address=address, count=len(words)))


def _case(name: str, title: str, pdus: tuple[ModbusPDU, ModbusPDU], operation: str, address: int, quantity: int,
          values: dict[str, Any], preset: dict[str, Any] | None = None) -> Case:
    return Case(name, title, pdus[0], pdus[1], operation, address, quantity, values,
                dict(values) if preset is None and operation == "read" else (preset or {}))


def cases() -> list[Case]:
    """Every example of the map, in the map's order: register reads, bit reads and writes, register writes."""
    return _register_reads() + _bit_cases() + _register_writes()


def _register_reads() -> list[Case]:
    voltages = (regs(230.5, DT.FLOAT32) + regs(231.25, DT.FLOAT32, "little")
                + regs(229.75, DT.FLOAT32, "little", swap=True) + regs(50.0, DT.FLOAT32, swap=True))
    energy = (regs(123456.789, DT.FLOAT64) + regs(2**40 + 12345, DT.UINT64)
              + regs(-987654321012, DT.INT64, "little"))
    identity = regs("SN-2024-000042", DT.STRING, pad=8, encoding="ascii") + regs("v1.2.3", DT.STRING, pad=4, swap=True)
    currents = [w for v in (10.5, 11.25, 12.0) for w in regs(v, DT.FLOAT64, "little", swap=True)]
    return [
        _case("read_voltages", "Four f32 in the four word/byte orders (input registers, 04h)",
              _read_input(0x0000, voltages), "read", 0x0000, 8,
              {"phase_1_voltage": 230.5, "phase_2_voltage": 231.25, "phase_3_voltage": 229.75, "frequency": 50.0}),
        _case("read_energy", "An f64, a u64 and an s64 (low word first) in one read",
              _read_input(0x0008, energy), "read", 0x0008, 12,
              {"total_energy": 123456.789, "energy_counter": 2**40 + 12345, "net_energy": -987654321012}),
        _case("read_identity", "Two strings: ASCII, and UTF-8 with swapped bytes",
              _read_input(0x0020, identity), "read", 0x0020, 12,
              {"serial_number": "SN-2024-000042", "firmware": "v1.2.3"}),
        _case("read_not_available", "A temperature that reads 0x8000 (not available) and an enum",
              _read_input(0x0016, [0x8000, 1]), "read", 0x0016, 2, {"temperature": None, "grid_state": 1}),
        _case("read_operating_seconds", "A u32 with swapped bytes",
              _read_input(0x002C, regs(3600000, DT.UINT32, swap=True)), "read", 0x002C, 2,
              {"operating_seconds": 3600000}),
        _case("read_phase_currents", "An f64 array, low word first and swapped bytes, stride 4",
              _read_input(0x0032, currents), "read", 0x0032, 12,
              {"phase_currents[0]": 10.5, "phase_currents[1]": 11.25, "phase_currents[2]": 12.0}),
        _case("read_active_power", "SunSpec: a value and its scale factor in the same request",
              _read_holding(40083, regs(1234, DT.INT16) + regs(-1, DT.INT16)), "read", 40083, 2,
              {"active_power": 123.4}, {"active_power_sf": -1, "active_power": 123.4}),
        _case("read_lifetime_energy", "SunSpec: a u64 counter with its scale factor four registers on",
              _read_holding(40109, regs(1234567890, DT.UINT64) + regs(1, DT.INT16)), "read", 40109, 5,
              {"lifetime_energy": 12345678900}, {"energy_sf": 1, "lifetime_energy": 12345678900}),
        _case("read_ac_current_not_available", "A current that reads 0xFFFF (not available)",
              _read_holding(40071, [0xFFFF]), "read", 40071, 1, {"ac_current": None}),
        _case("read_clock_month", "A register in a min_read block: the whole block is read",
              _read_holding(0x0200, [2024, 7, 15]), "read", 0x0200, 3, {"clock_month": 7},
              {"clock_year": 2024, "clock_month": 7, "clock_day": 15}),
        _case("read_first_holding", "A register the map gives by its Modicon number 400001",
              _read_holding(0x0000, [42]), "read", 0x0000, 1, {"first_holding": 42}),
    ]


def _bit_cases() -> list[Case]:
    return [
        _case("read_run", "Read a coil (01h)",
              (ReadCoilsRequest(address=0x0000, count=1), ReadCoilsResponse(bits=[True] + [False] * 7)),
              "read", 0x0000, 1, {"run": True}),
        _case("read_alarms", "Read three discrete inputs given by a Modicon number (02h)",
              (ReadDiscreteInputsRequest(address=0x0001, count=3),
               ReadDiscreteInputsResponse(bits=[True, False, True] + [False] * 5)),
              "read", 0x0001, 3, {"alarms[0]": True, "alarms[1]": False, "alarms[2]": True}),
        _case("write_run", "Write a coil (05h)",
              (WriteSingleCoilRequest(address=0x0000, bits=[True]), WriteSingleCoilResponse(address=0x0000, bits=[True])),
              "write", 0x0000, 1, {"run": True}),
        _case("write_relays", "Write four coils in one request (0Fh)",
              (WriteMultipleCoilsRequest(address=0x0010, bits=[True, False, True, True]),
               WriteMultipleCoilsResponse(address=0x0010, count=4)),
              "write_multiple", 0x0010, 4, {"relays[0]": True, "relays[1]": False, "relays[2]": True, "relays[3]": True}),
    ]


def _register_writes() -> list[Case]:
    return [
        _case("write_setpoint", "Write an f32 (10h)", _write_holding(0x0100, regs(-12.5, DT.FLOAT32)),
              "write_multiple", 0x0100, 2, {"setpoint": -12.5}),
        _case("write_ramp_limit", "Write an f64, low word first and swapped bytes",
              _write_holding(0x0102, regs(0.125, DT.FLOAT64, "little", swap=True)), "write_multiple", 0x0102, 4,
              {"ramp_limit": 0.125}),
        _case("write_device_name", "Write a string: NUL-padded to its six registers",
              _write_holding(0x0110, regs("PUMP-7", DT.STRING, pad=6, encoding="ascii")), "write_multiple", 0x0110, 6,
              {"device_name": "PUMP-7"}),
        _case("write_counter_preset", "Write a u64 with the top bit set",
              _write_holding(0x0120, regs(2**63 + 5, DT.UINT64)), "write_multiple", 0x0120, 4,
              {"counter_preset": 2**63 + 5}),
        _case("write_balance", "Write an s64, low word first and swapped bytes",
              _write_holding(0x0124, regs(-5000, DT.INT64, "little", swap=True)), "write_multiple", 0x0124, 4,
              {"balance": -5000}),
        _case("write_limit_32", "Write a scaled s32 with swapped bytes",
              _write_holding(0x0128, regs(12345, DT.INT32, swap=True)), "write_multiple", 0x0128, 2,
              {"limit_32": 123.45}),
        _case("write_enable", "Write a bool kept in a holding register (06h)",
              (WriteSingleRegisterRequest(address=0x0130, registers=[1]),
               WriteSingleRegisterResponse(address=0x0130, registers=[1])),
              "write", 0x0130, 1, {"enable": True}),
    ]


def _yaml_value(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def _yaml_map(values: dict[str, Any]) -> str:
    return "{" + ", ".join(f'"{k}": {_yaml_value(v)}' if "[" in k else f"{k}: {_yaml_value(v)}"
                           for k, v in values.items()) + "}"


def as_yaml() -> str:
    lines = []
    for case in cases():
        request, response = case.frames()
        lines += [
            f"  - name: {case.name}",
            f"    title: \"{case.title}\"",
            '    source: "synthetic §7"',
            "    mode: rtu",
            f'    request: "{request}"',
            f'    response: "{response}"',
            "    meaning:",
            f"      unit: {UNIT}",
            f"      operation: {case.operation}",
            f"      address: 0x{case.address:04X}",
            f"      quantity: {case.quantity}",
            f"      values: {_yaml_map(case.values)}",
        ]
        if case.preset:
            lines.append(f"    preset: {_yaml_map(case.preset)}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(as_yaml(), end="")
