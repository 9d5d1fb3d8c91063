"""The constructs of tests/maps/allkinds.yaml beyond the client: a register list using every table and
type compiles, the generated simulator serves every table and refuses what the map says (broadcasts
included), the JSON export and the docs show the new constructs, the scaffold's examples are served as
printed, and Modicon numbers convert both ways.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest
from rendered import load_package

from drivemap.compiler import compile_map
from tests.allkinds_server import DT, MODEL, PKG, M

ISSUE_REGISTERS = """
registers:
  - name: phase_1_voltage
    table: input            # holding (default) | input | coil | discrete
    address: 0x0000         # protocol address, 0-based, as today
    type: f32               # u16 s16 u32 s32 u64 s64 f32 f64 string bool
    word_order: high_first  # every multi-word type (today 32-bit only)
    byte_order: high_first  # bytes inside each word: high_first (Modbus standard) | low_first
    access: r
    unit: V
  - {name: model_name, address: 30000, type: string, length: 15, access: r}   # length in registers
  - {name: run, table: coil, address: 0x0000, access: rw}                       # bool by default
  - {name: active_power, address: 40083, type: s16, scale_register: active_power_sf, unit: W}
  - {name: active_power_sf, address: 40084, type: s16, access: r}              # value v -> x 10^v
  - {name: ac_current, address: 40071, type: u16, not_available: [0xFFFF], scale: 0.1, unit: A}
"""


def test_the_every_type_register_list_validates(tmp_path: Path) -> None:
    """A register list using every table and type as a map author writes it (plus the group and
    source every register needs) compiles, and means what it says."""
    import yaml

    from drivemap.backends.render import scaffold

    text = scaffold("everytype").replace(
        "  - {name: parameters, title: Parameters, source: \"manual §4\"}\n",
        "  - {name: parameters, title: Parameters, source: \"manual §4\"}\n  - {name: issue, title: Issue, source: \"x\"}\n")
    registers = yaml.safe_load(ISSUE_REGISTERS)["registers"]
    data = yaml.safe_load(text)
    for reg in registers:
        reg.update(group="issue", source="every-type list")
    data["registers"] = [r for r in data["registers"] if r["name"] not in {x["name"] for x in registers}
                         and r.get("table") not in ("coil",) and r["name"] != "line_voltage"] + registers
    data["examples"] = [e for e in data["examples"] if e["name"] == "read_frequency_command"]
    path = tmp_path / "everytype.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")
    model = compile_map(path)
    regs = {r.name: r for r in model.registers}
    assert (regs["phase_1_voltage"].table, regs["phase_1_voltage"].type) == ("input", "f32")
    assert (regs["model_name"].table, regs["model_name"].words, regs["model_name"].encoding) == ("holding", 15, "ascii")
    assert (regs["run"].type, regs["run"].access) == ("bool", "rw")
    assert regs["active_power"].scale_register == "active_power_sf" and regs["active_power"].access == "r"
    assert regs["ac_current"].not_available == (0xFFFF,) and regs["ac_current"].optional
    package = load_package(model)
    assert package.Client.plan([("active_power", 0), ("active_power_sf", 0)])[0].count == 2


# ---------------------------------------------------------------- the generated simulator


def _pdu(code: int, *fields: int) -> bytes:
    return bytes([code]) + b"".join(f.to_bytes(2, "big") for f in fields)


def test_simulator_serves_every_table_and_refuses_what_the_map_says() -> None:
    sim = importlib.import_module(f"{PKG.__name__}.simulator").Simulator([1])
    sim.set("run", True)
    sim.set("alarms[1]", True)
    sim.set("temperature", None)
    sim.set("phase_1_voltage", 230.5)
    assert sim.handle(1, _pdu(0x01, 0x0000, 1)) == bytes([0x01, 1, 0b1])
    assert sim.handle(1, _pdu(0x01, 0x0000, 2)) == bytes([0x81, 0x02])  # coil 1 (fault_reset) is write-only
    assert sim.handle(1, _pdu(0x02, 0x0000, 4)) == bytes([0x02, 1, 0b0100])
    assert sim.handle(1, _pdu(0x04, 0x0016, 1)) == bytes([0x04, 2, 0x80, 0x00])  # None: the not-available raw
    assert sim.handle(1, _pdu(0x04, 0x0000, 2)) == bytes([0x04, 4]) + bytes.fromhex("43668000")
    assert sim.handle(1, _pdu(0x03, 0x0000, 2)) == bytes([0x83, 0x02])  # holding 0x0001 is not in the map
    assert sim.handle(1, _pdu(0x03, 0x0106, 1)) == bytes([0x83, 0x02])  # reserved, not readable
    assert sim.handle(1, _pdu(0x04, 0x0030, 2)) == bytes([0x04, 4, 0, 0, 0, 0])  # reserved, readable
    assert sim.handle(1, _pdu(0x04, 0x0014, 2)) == bytes([0x04, 4, 0, 0, 0, 0])  # max_gap words read as 0
    assert sim.handle(1, _pdu(0x04, 0x0018, 1)) == bytes([0x84, 0x02])  # outside max_gap use: unknown
    assert sim.handle(1, _pdu(0x03, 0x0201, 1)) == bytes([0x83, 0x02])  # part of a min_read block
    assert sim.handle(1, _pdu(0x03, 0x0200, 3))[:2] == bytes([0x03, 6])  # the whole block
    assert sim.handle(1, _pdu(0x05, 0x0000, 0x1234)) == bytes([0x85, 0x03])  # not FF00/0000
    assert sim.handle(1, _pdu(0x05, 0x0000, 0x0000)) == _pdu(0x05, 0x0000, 0x0000) and sim.get("run") is False
    assert sim.handle(1, _pdu(0x05, 0x0010, 0xFF00)) == _pdu(0x05, 0x0010, 0xFF00) and sim.get("relays[0]") is True
    assert sim.handle(1, _pdu(0x0F, 0x0010, 4) + bytes([1, 0b1010])) == _pdu(0x0F, 0x0010, 4)
    assert [sim.get(f"relays[{i}]") for i in range(4)] == [False, True, False, True]
    assert sim.handle(1, _pdu(0x0F, 0x0010, 4) + bytes([2, 0, 0])) == bytes([0x8F, 0x03])  # byte count
    assert sim.handle(1, _pdu(0x06, 0x0101, 0)) == bytes([0x86, 0x02])  # half of an f32
    f32 = M.convert_to_registers(150.0, DT.FLOAT32)
    assert sim.handle(1, _pdu(0x10, 0x0100, 2) + bytes([4]) + b"".join(w.to_bytes(2, "big") for w in f32)) \
        == bytes([0x90, 0x03])  # above max 100
    assert sim.handle(1, _pdu(0x06, 0x0000, 1)) == bytes([0x86, 0x02])  # input registers are not writable by 06h
    assert sim.handle(1, _pdu(0x04, 0x0100, 1)) == bytes([0x84, 0x02])  # holding addresses are not input ones


def test_export_json_of_the_new_constructs() -> None:
    from drivemap.backends.export import export

    regs = {r["name"]: r for r in export(MODEL)["registers"]}
    assert regs["phase_3_voltage"]["table"] == "input" and regs["phase_3_voltage"]["byte_order"] == "low_first"
    assert regs["phase_3_voltage"]["word_order"] == "low_first" and regs["phase_3_voltage"]["length"] == 2
    assert regs["serial_number"]["length"] == 8 and regs["serial_number"]["encoding"] == "ascii"
    assert regs["active_power"]["scale_register"] == "active_power_sf"
    assert regs["temperature"]["not_available"] == [-32768] and regs["ac_current"]["not_available"] == [0xFFFF]
    assert regs["relays[3]"]["table"] == "coil" and regs["relays[3]"]["address"] == 0x13
    assert regs["device_name"]["default"] == "PUMP" and regs["enable"]["default"] is False


def test_docs_show_tables_modicon_numbers_layouts_and_not_available_values() -> None:
    from drivemap.backends.exporters.base import Options
    from drivemap.backends.exporters.docs import DocsExporter

    page = DocsExporter().render(MODEL, Options())["allkinds.md"]
    for text in ("**Input registers** (read 04h, read-only)", "**Coils** (read 01h, written 05h/0Fh",
                 "**Discrete inputs** (read 02h", "| 0x0016 | 22 | 30023 |", "440110-440113",
                 "the manual gives Modicon 30023", "bytes on the wire DC BA", "bytes on the wire CD AB",
                 "bytes on the wire BA DC", "bytes on the wire AB CD", "IEEE-754 binary64",
                 "not available: raw 0xFFFF (the client reads None)", "1 × 10^active\\_power\\_sf",
                 "string[8]", "16 bytes, ascii", "every read of it reads the block",
                 "| Example | Mode | Status | Source |", "phase\\_1\\_voltage word 2 of 2 → 230.5 V", '"SN-2024-000042"'):
        assert text in page, text


def test_scaffold_examples_are_served_as_printed(tmp_path: Path) -> None:
    """`drivemap new` writes examples of the new constructs (an f32 input register, a coil): the
    generated simulator answers their requests with the printed replies, the client decodes them."""
    from drivemap.backends.render import scaffold
    from drivemap.frontend import frames

    path = tmp_path / "scaffolded.yaml"
    path.write_text(scaffold("scaffolded"), encoding="utf-8")
    model = compile_map(path)
    package = load_package(model)
    sim = importlib.import_module(f"{package.__name__}.simulator").Simulator([1])
    for ex in model.examples:
        for name, value in ex.meaning.values:
            sim.set(name, value)
        request = frames.parse(ex.request, ex.mode).body
        response = frames.parse(ex.response, ex.mode).body
        assert sim.handle(request[0], request[1:]) == response[1:], ex.name


@pytest.mark.parametrize(("number", "where"), [
    (30001, ("input", 0)), (40001, ("holding", 0)), (49999, ("holding", 9998)), (400001, ("holding", 0)),
    (465536, ("holding", 65535)), (10001, ("discrete", 0)), (1, ("coil", 0)), (9999, ("coil", 9998)),
    ("00017", ("coil", 16)), ("012345", ("coil", 12344)), ("300001", ("input", 0)), (365536, ("input", 65535)),
])
def test_modicon_numbers(number: int | str, where: tuple[str, int]) -> None:
    from drivemap.model import modicon

    assert modicon.parse(number) == where
    table, address = where
    assert modicon.parse(modicon.number(table, address)) == where


@pytest.mark.parametrize("number", [40000, 20001, 50001, 465537, 300000, "4001", "4000001", "40000"])
def test_modicon_numbers_refused(number: int | str) -> None:
    from drivemap.model import modicon

    with pytest.raises(modicon.ModiconError):
        modicon.parse(number)


def test_simulator_applies_broadcast_coil_writes_to_every_unit() -> None:
    sim = importlib.import_module(f"{PKG.__name__}.simulator").Simulator([1, 2])
    assert sim.handle(0, _pdu(0x05, 0x0000, 0xFF00)) is None
    assert sim.get("run", unit=1) is True and sim.get("run", unit=2) is True
    assert sim.handle(0, _pdu(0x0F, 0x0010, 2) + bytes([1, 0b11])) is None
    assert [sim.get(f"relays[{i}]", unit=2) for i in range(2)] == [True, True]
    broadcast = PKG.BroadcastClient(PKG.Bus.tcp("127.0.0.1", 9))  # never connected
    assert "run" in broadcast.registers and "relays" in broadcast.registers
    assert "power_limit" not in broadcast.registers  # scaled: its factor must be read first
