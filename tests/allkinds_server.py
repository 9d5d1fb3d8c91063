"""The peers of tests/project/test_map_allkinds.py: tests/maps/allkinds.yaml compiled and loaded, known values of
every register, and a *plain pymodbus server* (pymodbus's own datastore, not drivemap's simulator) holding
them as pymodbus's ``convert_to_registers`` lays them out."""

from __future__ import annotations

import asyncio
import contextlib
import math
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from pymodbus.client import ModbusTcpClient
from pymodbus.client.mixin import ModbusClientMixin
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice
from rendered import load_package

from drivemap.compiler import compile_map
from drivemap.model.nodes import Model, Register

HERE = Path(__file__).resolve().parent
MODEL: Model = compile_map(HERE / "maps" / "allkinds.yaml")
PKG = load_package(MODEL)
DT = ModbusClientMixin.DATATYPE
M = ModbusClientMixin
NAN = float("nan")

#: Known values of every readable register (engineering values; for scaled registers the raw value
#: and its factor are set below).
VALUES: dict[str, Any] = {
    "phase_1_voltage": 230.5,
    "phase_2_voltage": float("inf"),
    "phase_3_voltage": float("-inf"),
    "frequency": NAN,
    "total_energy": -0.0,
    "energy_counter": 2**64 - 1,
    "net_energy": -(2**63),
    "temperature": -12.3,
    "grid_state": 2,
    "serial_number": "ABCDEFGHIJKLMNOP",
    "firmware": "ü1.0",
    "operating_seconds": 0xDEADBEEF,
    "phase_currents": (1.5, -2.25, 1e-300),
    "ac_current": 12.5,
    "active_power_sf": -2,
    "power_limit_sf": 0,
    "energy_sf": 3,
    "first_holding": 42,
    "setpoint": -99.5,
    "ramp_limit": 3.141592653589793,
    "device_name": "PUMP",
    "counter_preset": 2**63 + 5,
    "balance": -1,
    "limit_32": -1234.56,
    "enable": 7,  # a bool register holding 7: true
    "clock_year": 2024,
    "clock_month": 7,
    "clock_day": 15,
    "modbus_unit": 17,
    "run": True,
    "fault_reset": False,
    "relays": (True, False, False, True),
    "door_open": True,
    "alarms": (False, True, True),
}
#: Raw values of the registers whose engineering value depends on a scale factor or is "not available".
RAW: dict[str, int] = {"active_power": -250, "power_limit": 0xFFFF, "lifetime_energy": 2**50}
#: What the client must read for those.
EXPECTED: dict[str, Any] = {"active_power": -2.5, "power_limit": None, "lifetime_energy": float(2**50 * 1000),
                            "enable": True, "grid_state": 2}

_DATATYPES = {"u16": DT.UINT16, "s16": DT.INT16, "u32": DT.UINT32, "s32": DT.INT32, "u64": DT.UINT64,
              "s64": DT.INT64, "f32": DT.FLOAT32, "f64": DT.FLOAT64}


def pymodbus_words(reg: Register, value: Any, *, raw: bool = False) -> list[int]:
    """The register contents for ``value`` as pymodbus lays them out (``raw``: value is the raw number).

    word_order low_first is pymodbus's word_order "little"; byte_order low_first swaps the bytes of
    each word afterwards (pymodbus has no byte order option).
    """
    order = "little" if reg.word_order == "low_first" else "big"
    if reg.type == "string":
        words = M.convert_to_registers(value, DT.STRING, word_order=order, string_encoding=reg.encoding)
        words += [0] * (reg.length - len(words))
    elif reg.type == "bool":
        words = [int(value)]
    else:
        plain = raw or reg.type in ("f32", "f64") or (reg.scale == 1 and reg.offset == 0)
        number = value if plain else round((value - reg.offset) / reg.scale)
        words = M.convert_to_registers(number, _DATATYPES[reg.type], word_order=order)
    if reg.byte_order == "low_first":
        words = [((w & 0xFF) << 8) | (w >> 8) for w in words]
    return words


def server_tables(refuse: frozenset[tuple[str, int]] | set[tuple[str, int]] = frozenset()) -> dict[str, dict[int, int]]:
    """table -> address -> word (bit) of every register, from :data:`VALUES` and :data:`RAW`;
    reserved words the map calls readable hold 0 unless ``refuse`` names them."""
    tables: dict[str, dict[int, int]] = {"holding": {}, "input": {}, "coil": {}, "discrete": {}}
    for reg in MODEL.registers:
        raw = reg.name in RAW
        value = RAW[reg.name] if raw else VALUES[reg.name]
        for i in range(reg.count):
            element = value[i] if reg.is_array else value
            if reg.bit_table:
                tables[reg.table][reg.element_address(i)] = int(element)
                continue
            for k, word in enumerate(pymodbus_words(reg, element, raw=raw)):
                tables[reg.table][reg.element_address(i) + k] = word
    for res in MODEL.reserved:
        if res.readable:
            for a in range(res.start, res.end + 1):
                tables[res.table][a] = 0
    for address in (0x14, 0x15, 0x2E, 0x2F):  # undocumented words inside max_gap: the device reads them as 0
        tables["input"][address] = 0
    for table, address in refuse:
        tables[table].pop(address, None)
    return tables


def _blocks(words: dict[int, int], bits: bool) -> list[SimData]:
    blocks: list[SimData] = []
    run: list[int] = []
    start = -1
    for address in sorted(words):
        if run and address != start + len(run):
            blocks.append(_block(start, run, bits))
            run = []
        if not run:
            start = address
        run.append(words[address])
    if run:
        blocks.append(_block(start, run, bits))
    return blocks


def _block(start: int, run: list[int], bits: bool) -> SimData:
    if bits:
        return SimData(address=start, values=[bool(v) for v in run], datatype=DataType.BITS)
    return SimData(address=start, values=run, datatype=DataType.REGISTERS)


@contextlib.contextmanager
def plain_server(tables: dict[str, dict[int, int]]) -> Iterator[int]:
    """A plain pymodbus TCP server (its own datastore, four distinct tables) on 127.0.0.1: the port.

    Addresses it holds no value for are invalid: pymodbus answers 02h (illegal data address).
    """
    device = SimDevice(id=1, simdata=(
        _blocks(tables["coil"], True), _blocks(tables["discrete"], True),
        _blocks(tables["holding"], False), _blocks(tables["input"], False),
    ))
    ready = threading.Event()
    state: dict[str, Any] = {}

    async def serve() -> None:
        server = ModbusTcpServer([device], framer=FramerType.SOCKET, address=("127.0.0.1", 0))
        await server.serve_forever(background=True)
        state["port"] = server.transport.sockets[0].getsockname()[1]
        state["stop"] = asyncio.Event()
        state["loop"] = asyncio.get_running_loop()
        ready.set()
        await state["stop"].wait()
        await server.shutdown()

    thread = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    thread.start()
    assert ready.wait(10)
    try:
        yield state["port"]
    finally:
        state["loop"].call_soon_threadsafe(state["stop"].set)
        thread.join(10)


def same(got: Any, want: Any) -> bool:
    if isinstance(want, tuple):
        return isinstance(got, tuple) and len(got) == len(want) and all(same(g, w) for g, w in zip(got, want, strict=True))
    if isinstance(want, float) and math.isnan(want):
        return isinstance(got, float) and math.isnan(got)
    if isinstance(want, float):
        return isinstance(got, float) and got == want and math.copysign(1, got) == math.copysign(1, want)
    return bool(got == want) and (want is None or type(got) is type(want) or isinstance(want, int))


def expected(name: str) -> Any:
    return EXPECTED.get(name, VALUES.get(name))


def holding_words(port: int, address: int, count: int) -> list[int]:
    with ModbusTcpClient("127.0.0.1", port=port) as raw:
        reply = raw.read_holding_registers(address, count=count, device_id=1)
        assert not reply.isError(), reply
        return list(reply.registers)

#: Words a device of tests/project/test_map_allkinds.py refuses (02h): two reserved words the map calls readable
#: and an undocumented word inside max_gap.
REFUSED = {("input", 0x14), ("input", 0x30), ("input", 0x31)}

