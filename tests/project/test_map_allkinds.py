"""Every construct of the map language against independent peers (tests/maps/allkinds.yaml).

* The map's example frames are exactly the frames pymodbus builds for the same PDUs and values
  (tests/allkinds_frames.py); tests/project/test_roundtrip.py runs them through client and simulator.
* The typed client reads every type from a *plain pymodbus server* (pymodbus's own datastore, not
  drivemap's simulator) holding values that pymodbus's ``convert_to_registers`` laid out, in every
  word and byte order, and gets them exactly (NaN and infinities included).
* Its writes put on the server exactly the registers ``convert_to_registers`` gives for the same
  values; bad values are refused before anything is sent.
* A server that refuses some addresses (02h) inside a merged read is read completely by splitting,
  the refused words become ``client.holes`` and are never spanned again, and ``client.stats`` counts
  the extra requests.

The peers and known values are in tests/allkinds_server.py; the compiler, the generated simulator,
the exports and the docs of the same map are checked in tests/project/test_map_allkinds_outputs.py.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymodbus.client import ModbusTcpClient

from drivemap.runtime.client.protocol.planner import plan_reads
from drivemap.runtime.errors import DeviceException, InvalidValue, ScaleUnavailable, ValueOutOfRange
from tests.allkinds_frames import cases
from tests.allkinds_server import (
    MODEL,
    NAN,
    PKG,
    REFUSED,
    VALUES,
    expected,
    holding_words,
    plain_server,
    pymodbus_words,
    same,
    server_tables,
)

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
            assert same(got, expected(reg.name)), f"{reg.name}: {got!r} != {expected(reg.name)!r}"
        snap = drive.read_all()
        for reg in MODEL.registers:
            if reg.readable:
                assert same(getattr(snap, reg.name), expected(reg.name)), reg.name
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
        assert holding_words(port, reg.address, reg.words) == pymodbus_words(reg, value)
        assert same(drive.registers[name].read(), value)


def test_scaled_and_optional_writes() -> None:
    reg = MODEL.register("power_limit")
    with plain_server(server_tables()) as port, PKG.Client.tcp("127.0.0.1", port, timeout=2.0) as drive:
        with ModbusTcpClient("127.0.0.1", port=port) as raw:
            raw.write_register(40101, 0xFFFF, device_id=1)  # factor -1
        before = drive.stats.transactions
        drive.power_limit.write(55.5)
        assert drive.stats.transactions == before + 2  # the factor is read first, then the value written
        assert holding_words(port, reg.address, 1) == pymodbus_words(reg, 555, raw=True)
        drive.power_limit.write(None)  # None writes the not-available value
        assert holding_words(port, reg.address, 1) == [0xFFFF]
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
        assert holding_words(port, reg.address, 4) == pymodbus_words(reg, NAN)
        assert math.isnan(drive.ramp_limit.read())


# ---------------------------------------------------------------- adaptive reads



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
                assert same(getattr(snap, reg.name), expected(reg.name)), reg.name
        stats = drive.stats
        assert stats.split_reads == 2
        assert stats.extra_requests == 16  # 6 to split 0x0000-0x0017, 10 for 0x0020-0x003D (bisection)
        assert stats.transactions == len(plan) + stats.extra_requests
        assert stats.exceptions == 3 + 7  # each refused part: 3 while splitting 0x0000-0x0017, 7 for 0x0020-0x003D
        assert drive.holes == frozenset({("input", 0x14), ("input", 0x15), ("input", 0x30), ("input", 0x31)})
        before = stats.transactions
        snap = drive.read_all()  # the holes are known: no refusal, no split
        assert stats.split_reads == 2 and stats.extra_requests == 16
        assert stats.transactions - before == len(drive._drivemap.core.plan_with_holes(drive._drivemap.core.tables.all_keys))
        assert stats.exceptions == 10
        assert same(snap.net_energy, VALUES["net_energy"]) and same(snap.phase_currents, VALUES["phase_currents"])
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
        assert same(snap.net_energy, VALUES["net_energy"]) and snap.grid_state == 2


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
            assert same(snap.total_energy, -0.0) and snap.serial_number == "ABCDEFGHIJKLMNOP" and snap.temperature == -12.3
            assert snap.active_power == -2.5 and snap.power_limit is None and snap.alarms == (False, True, True)
            assert drive.stats.split_reads == 2 and len(drive.holes) == 4
            await drive.relays.write((True, True, False, False))
            assert await drive.relays.read() == (True, True, False, False)
            await drive.balance.write(-42)
            assert holding_words(port, 0x124, 4) == pymodbus_words(MODEL.register("balance"), -42)
            assert await drive.power_limit.modify(lambda v: 12.0 if v is None else v + 1) == 12.0
            assert await drive.power_limit.read() == 12.0
