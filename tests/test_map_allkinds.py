"""Every construct of the map language against independent peers (tests/maps/allkinds.yaml).

* The map's example frames are exactly the frames pymodbus builds for the same PDUs and values
  (tests/allkinds_frames.py); tests/test_roundtrip.py runs them through client and simulator.
* The typed client reads every type from a *plain pymodbus server* (pymodbus's own datastore, not
  drivemap's simulator) holding values that pymodbus's ``convert_to_registers`` laid out, in every
  word and byte order, and gets them exactly (NaN and infinities included).
* Its writes put on the server exactly the registers ``convert_to_registers`` gives for the same
  values; bad values are refused before anything is sent.
* A server that refuses some addresses (02h) inside a merged read is read completely by splitting,
  the refused words become ``client.holes`` and are never spanned again, and ``client.stats`` counts
  the extra requests.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import math
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.client.mixin import ModbusClientMixin
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice
from rendered import load_package

from drivemap.compiler import compile_map
from drivemap.model.nodes import Model, Register
from drivemap.runtime.client.planner import plan_reads
from drivemap.runtime.errors import DeviceException, InvalidValue, ScaleUnavailable, ValueOutOfRange
from tests.allkinds_frames import cases

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


def _same(got: Any, want: Any) -> bool:
    if isinstance(want, tuple):
        return isinstance(got, tuple) and len(got) == len(want) and all(_same(g, w) for g, w in zip(got, want, strict=True))
    if isinstance(want, float) and math.isnan(want):
        return isinstance(got, float) and math.isnan(got)
    if isinstance(want, float):
        return isinstance(got, float) and got == want and math.copysign(1, got) == math.copysign(1, want)
    return bool(got == want) and (want is None or type(got) is type(want) or isinstance(want, int))


def expected(name: str) -> Any:
    return EXPECTED.get(name, VALUES.get(name))


# ---------------------------------------------------------------- the examples are pymodbus's frames


def test_example_frames_are_the_frames_pymodbus_builds() -> None:
    built = {case.name: case for case in cases()}
    assert {ex.name for ex in MODEL.examples} == set(built)
    for ex in MODEL.examples:
        case = built[ex.name]
        assert (ex.request, ex.response) == case.frames(), ex.name
        assert dict(ex.meaning.values) == case.values and ex.meaning.address == case.address
        assert ex.meaning.quantity == case.quantity and ex.status == "verified"


def test_map_uses_every_construct() -> None:
    regs = MODEL.registers
    assert {r.table for r in regs} == {"holding", "input", "coil", "discrete"}
    assert {r.type for r in regs} == {"u16", "s16", "u32", "s32", "u64", "s64", "f32", "f64", "string", "bool"}
    assert {(r.word_order, r.byte_order) for r in regs if r.type in ("f32", "f64")} >= {
        ("high_first", "high_first"), ("low_first", "high_first"), ("low_first", "low_first"), ("high_first", "low_first")}
    assert any(r.scale_register for r in regs) and any(r.not_available for r in regs) and any(r.min_read for r in regs)
    assert any(r.modicon_given for r in regs) and MODEL.protocol.max_gap > 0
    assert any(r.encoding == "utf-8" for r in regs if r.type == "string")


def test_modicon_numbers_convert() -> None:
    assert (MODEL.register("temperature").table, MODEL.register("temperature").address) == ("input", 22)
    assert (MODEL.register("first_holding").table, MODEL.register("first_holding").address) == ("holding", 0)
    assert (MODEL.register("lifetime_energy").address, MODEL.register("energy_sf").address) == (40109, 40113)
    assert (MODEL.register("fault_reset").table, MODEL.register("fault_reset").address) == ("coil", 1)
    assert (MODEL.register("alarms").table, MODEL.register("alarms").address) == ("discrete", 1)
    assert MODEL.register("modbus_unit").modicon == "40769" and MODEL.register("energy_sf").modicon == "440114"


# ---------------------------------------------------------------- reads from a plain pymodbus server


def test_typed_client_reads_every_type_from_a_plain_pymodbus_server() -> None:
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        for reg in MODEL.registers:
            if not reg.readable:
                continue
            got = drive.registers[reg.name].read()
            assert _same(got, expected(reg.name)), f"{reg.name}: {got!r} != {expected(reg.name)!r}"
        snap = drive.read_all()
        for reg in MODEL.registers:
            if reg.readable:
                assert _same(getattr(snap, reg.name), expected(reg.name)), reg.name
        assert drive.stats.exceptions == 0 and drive.stats.split_reads == 0 and drive.holes == frozenset()
        assert isinstance(drive.grid_state.read(), PKG.GridState)


def test_scaled_value_is_read_with_its_factor_every_time() -> None:
    tables = server_tables()
    with plain_server(tables) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        before = drive.stats.transactions
        assert drive.active_power.read() == -2.5
        assert drive.stats.transactions == before + 1  # value and factor in the same request
        assert drive.active_power.read_raw() == -250
        with ModbusTcpClient("127.0.0.1", port=port) as raw:  # the factor changes on the device
            raw.write_register(40084, 1, device_id=1)
        assert drive.active_power.read() == -2500.0  # never the remembered factor
        with ModbusTcpClient("127.0.0.1", port=port) as raw:
            raw.write_register(40084, 0x8000, device_id=1)  # -32768: not a plausible factor
        with pytest.raises(ScaleUnavailable):
            drive.active_power.read()


def test_not_available_factor_and_value() -> None:
    tables = server_tables()
    tables["holding"][40101] = 0x8000  # power_limit_sf: not available
    tables["holding"][40100] = 50
    with plain_server(tables) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        with pytest.raises(ScaleUnavailable, match="not available"):
            drive.power_limit.read()
        assert drive.power_limit_sf.read() is None


# ---------------------------------------------------------------- writes: pymodbus's own registers


def _holding(port: int, address: int, count: int) -> list[int]:
    with ModbusTcpClient("127.0.0.1", port=port) as raw:
        reply = raw.read_holding_registers(address, count=count, device_id=1)
        assert not reply.isError(), reply
        return list(reply.registers)


WRITES: list[tuple[str, Any]] = [
    ("setpoint", 12.25), ("setpoint", -100.0), ("ramp_limit", float("inf")), ("ramp_limit", 2.5e-5),
    ("device_name", "PUMP-7"), ("device_name", "ABCDEFGHIJKL"), ("counter_preset", 2**64 - 1),
    ("counter_preset", 0), ("balance", -(2**63)), ("balance", 123456789), ("limit_32", -1234.56),
    ("limit_32", 0.01), ("enable", True), ("enable", False), ("modbus_unit", 247),
]


@pytest.mark.parametrize(("name", "value"), WRITES, ids=[f"{n}={v!r}" for n, v in WRITES])
def test_writes_put_pymodbus_registers_on_the_server(name: str, value: Any) -> None:
    reg = MODEL.register(name)
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        drive.registers[name].write(value)
        assert _holding(port, reg.address, reg.words) == pymodbus_words(reg, value)
        assert _same(drive.registers[name].read(), value)


def test_scaled_and_optional_writes() -> None:
    reg = MODEL.register("power_limit")
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        with ModbusTcpClient("127.0.0.1", port=port) as raw:
            raw.write_register(40101, 0xFFFF, device_id=1)  # factor -1
        before = drive.stats.transactions
        drive.power_limit.write(55.5)
        assert drive.stats.transactions == before + 2  # the factor is read first, then the value written
        assert _holding(port, reg.address, 1) == pymodbus_words(reg, 555, raw=True)
        drive.power_limit.write(None)  # None writes the not-available value
        assert _holding(port, reg.address, 1) == [0xFFFF]
        assert drive.power_limit.read() is None
        before = drive.stats.transactions
        with pytest.raises(ValueOutOfRange):
            drive.power_limit.write(100.5)  # above max: refused before anything is sent
        assert drive.stats.transactions == before
        with ModbusTcpClient("127.0.0.1", port=port) as raw:
            raw.write_register(40101, 0xFFFD, device_id=1)  # factor -3
        before = drive.stats.transactions
        with pytest.raises(ValueOutOfRange, match="not available"):
            drive.power_limit.write(65.535)  # raw 65535 would read as not available: refused before the write
        assert drive.stats.transactions == before + 1 and drive.stats.by_function.get(0x06) == 2


def test_coil_writes() -> None:
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        drive.run.write(False)
        drive.relays.write((False, True, True, False))
        drive.fault_reset.write(True)
        with ModbusTcpClient("127.0.0.1", port=port) as raw:
            assert raw.read_coils(0, count=2, device_id=1).bits[:2] == [False, True]
            assert raw.read_coils(0x10, count=4, device_id=1).bits[:4] == [False, True, True, False]
        assert drive.stats.by_function.get(0x05) == 2 and drive.stats.by_function.get(0x0F) == 1
        assert drive.relays.read() == (False, True, True, False)


BAD_WRITES: list[tuple[str, Any, type[Exception]]] = [
    ("device_name", "ABCDEFGHIJKLM", ValueOutOfRange),  # 13 bytes, the field holds 12
    ("device_name", "Zürich", InvalidValue),  # not ASCII
    ("device_name", 5, InvalidValue),
    ("setpoint", NAN, ValueOutOfRange),  # the map gives a range: NaN is not in it
    ("setpoint", 100.5, ValueOutOfRange),
    ("setpoint", float("inf"), ValueOutOfRange),
    ("ramp_limit", "1.0", InvalidValue),
    ("counter_preset", 2**64, ValueOutOfRange),
    ("counter_preset", -1, ValueOutOfRange),
    ("balance", 2**63, ValueOutOfRange),
    ("enable", 1, InvalidValue),
    ("run", "yes", InvalidValue),
]


@pytest.mark.parametrize(("name", "value", "error"), BAD_WRITES, ids=[f"{n}={v!r}" for n, v, _ in BAD_WRITES])
def test_bad_writes_are_refused_before_the_wire(name: str, value: Any, error: type[Exception]) -> None:
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        drive.connect()
        with pytest.raises(error):
            drive.registers[name].write(value)
        assert drive.stats.transactions == 0 and drive.stats.bytes_sent == 0


def test_ramp_limit_nan_is_written_without_a_range() -> None:
    reg = MODEL.register("ramp_limit")
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        drive.ramp_limit.write(NAN)
        assert _holding(port, reg.address, 4) == pymodbus_words(reg, NAN)
        assert math.isnan(drive.ramp_limit.read())


# ---------------------------------------------------------------- adaptive reads


REFUSED = {("input", 0x14), ("input", 0x30), ("input", 0x31)}


def test_refused_words_are_found_by_splitting_and_never_spanned_again() -> None:
    """0x30-0x31 are reserved words the map calls readable and 0x14 an undocumented word inside
    max_gap; this device refuses them, so read_all's merged input reads get 02h."""
    plan = PKG.Client.plan()
    spanning = [r for r in plan if r.table == "input" and any(r.address <= a < r.address + r.count for _, a in REFUSED)]
    assert len(spanning) == 2, "the plan reads across the refused words"
    with plain_server(server_tables(REFUSED)) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        snap = drive.read_all()
        for reg in MODEL.registers:
            if reg.readable:
                assert _same(getattr(snap, reg.name), expected(reg.name)), reg.name
        stats = drive.stats
        assert stats.split_reads == 2
        assert stats.extra_requests == 16  # 6 to split 0x0000-0x0017, 10 for 0x0020-0x003D (bisection)
        assert stats.transactions == len(plan) + stats.extra_requests
        assert stats.exceptions == 3 + 7  # each refused part: 3 while splitting 0x0000-0x0017, 7 for 0x0020-0x003D
        assert drive.holes == frozenset({("input", 0x14), ("input", 0x15), ("input", 0x30), ("input", 0x31)})
        before = stats.transactions
        snap = drive.read_all()  # the holes are known: no refusal, no split
        assert stats.split_reads == 2 and stats.extra_requests == 16
        assert stats.transactions - before == len(drive._core.plan_with_holes(drive._core.tables.all_keys))
        assert stats.exceptions == 10
        assert _same(snap.net_energy, VALUES["net_energy"]) and _same(snap.phase_currents, VALUES["phase_currents"])
        # a single register next to a hole is read alone, not merged across it
        assert drive.temperature.read() == -12.3 and stats.exceptions == 10


def test_a_refused_register_the_caller_asked_for_raises() -> None:
    refuse = {("input", 0x16)}  # temperature itself
    with plain_server(server_tables(refuse)) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        with pytest.raises(DeviceException) as info:
            drive.read(drive.net_energy, drive.temperature, drive.grid_state)
        assert info.value.code == 0x02
        assert ("input", 0x16) in drive.holes
        snap = drive.read(drive.net_energy, drive.grid_state)  # the others still read, around the hole
        assert _same(snap.net_energy, VALUES["net_energy"]) and snap.grid_state == 2


def test_planner_never_spans_holes_and_reads_min_read_blocks_whole() -> None:
    spec = PKG.SPEC
    keys = [("net_energy", 0), ("temperature", 0)]
    assert [(r.address, r.count) for r in plan_reads(spec, keys)] == [(0x10, 7)]  # across the 2-word gap
    holes = {("input", 0x15)}
    assert [(r.address, r.count) for r in plan_reads(spec, keys, holes)] == [(0x10, 4), (0x16, 1)]
    assert [(r.address, r.count) for r in plan_reads(spec, [("clock_day", 0)])] == [(0x200, 3)]
    assert [(r.table, r.code) for r in plan_reads(spec, [("run", 0), ("door_open", 0), ("temperature", 0),
                                                        ("first_holding", 0)])] == [
        ("holding", 3), ("input", 4), ("coil", 1), ("discrete", 2)]


async def test_async_client_reads_writes_and_splits() -> None:
    with plain_server(server_tables(REFUSED)) as port:
        async with PKG.AsyncClient.tcp("127.0.0.1", port, timeout=2.0) as drive:
            snap = await drive.read_all()
            assert _same(snap.total_energy, -0.0) and snap.serial_number == "ABCDEFGHIJKLMNOP" and snap.temperature == -12.3
            assert snap.active_power == -2.5 and snap.power_limit is None and snap.alarms == (False, True, True)
            assert drive.stats.split_reads == 2 and len(drive.holes) == 4
            await drive.relays.write((True, True, False, False))
            assert await drive.relays.read() == (True, True, False, False)
            await drive.balance.write(-42)
            assert _holding(port, 0x124, 4) == pymodbus_words(MODEL.register("balance"), -42)
            assert await drive.power_limit.modify(lambda v: 12.0 if v is None else v + 1) == 12.0
            assert await drive.power_limit.read() == 12.0


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
