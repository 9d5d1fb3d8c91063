"""Read and write programs (clean reads must cost little more than the wire): the fault-free path is compiled, everything else
is the general path, and the two give the same results.

Each case runs twice against real servers: once with the generated client as it is (programs on)
and once with a subclass that never gets a program (``general_only``), each on its own fresh
server with the same faults; values, snapshots (their fields and their ``__dict__``), errors,
bus counters and the bytes on the line must be the same. Spies on the module functions the client
calls show which way a call went: a clean reply never enters the core's operation
(``Core.read_raw`` / ``Core.write_raw``), a reply that is not a plain success hands the replies so
far to it (``run_replay``), a client that knows holes runs it from the start.
"""

from __future__ import annotations

import asyncio
import dataclasses
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import drivemap.runtime.client.api.async_client as aclient_mod
import drivemap.runtime.client.api.sync_client as client_mod
from drivemap.runtime.client.api.machinery import without_programs
from drivemap.runtime.client.protocol.sansio import Core
from drivemap.runtime.errors import DeviceException, DriveError
from drivemap.testing.vserial import FrameFault
from tests.allkinds_server import MODEL, PKG, REFUSED, plain_server, server_tables
from tests.helpers_client import package, serial_server, tcp_server
from tests.runtime.client.test_client_faults import rtu

ev = package("ev")
vfd = package("vfd1000")


def general_only(cls: Any) -> Any:
    """``cls`` without read or write programs: every call takes the general path."""
    return without_programs(cls)


@pytest.fixture
def paths(monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, int]]:
    """Counts of the general path's entries: the core's operations, replays, runs from the start."""
    counts = {"read_raw": 0, "write_raw": 0, "replay": 0, "run": 0}

    def counting(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            counts[name] += 1
            return fn(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(Core, "read_raw", counting("read_raw", Core.read_raw))
    monkeypatch.setattr(Core, "write_raw", counting("write_raw", Core.write_raw))
    monkeypatch.setattr(client_mod, "run_replay", counting("replay", client_mod.run_replay))
    monkeypatch.setattr(client_mod, "_run", counting("run", client_mod._run))
    monkeypatch.setattr(aclient_mod, "arun_replay", counting("replay", aclient_mod.arun_replay))
    monkeypatch.setattr(aclient_mod, "arun", counting("run", aclient_mod.arun))
    yield counts


def outcome(fn: Callable[[], Any]) -> Any:
    """What a call gives: its value (a snapshot with its whole state), or its error's type and text."""
    try:
        value = fn()
    except DriveError as exc:
        return type(exc).__name__, str(exc), getattr(exc, "code", None)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return value, list(vars(value).items())
    return value


def test_clean_reads_and_writes_take_the_program(paths: dict[str, int]) -> None:
    with tcp_server("ev") as (sim, host, port), ev.Client.tcp(host, port, timeout=2.0) as drive:
        sim.set("motor_speed", 1234)
        sim.set("alarm_no", 7)
        assert drive.motor_speed.read() == 1234
        snap = drive.read(drive.motor_speed, drive.alarm_no, drive.motor_state)
        assert (snap.motor_speed, snap.alarm_no, snap.bus_voltage) == (1234, 7, None)
        assert snap[drive.motor_state] == drive.motor_state.read()
        drive.rs485_timeout.write(250)
        assert sim.get("rs485_timeout") == 250 and drive.rs485_timeout.read() == 250
        drive.comm_error_action.write(drive.comm_error_action.read())
        assert drive.digital_speed_ram.read() == tuple(sim.get(f"digital_speed_ram[{i}]") for i in range(8))
        assert paths == {"read_raw": 0, "write_raw": 0, "replay": 0, "run": 0}
        program = drive._drivemap.programs[(drive.motor_speed, drive.alarm_no, drive.motor_state)]
        assert program.__code__.co_filename == "<drivemap read program snapshot>"
        assert drive.motor_speed._program.__code__.co_filename == "<drivemap read program value>"
        assert drive.digital_speed_ram._program.__code__.co_filename == "<drivemap read program tuple>"
    with tcp_server("vfd1000") as (sim, host, port), vfd.Client.tcp(host, port, timeout=2.0) as drive:
        drive.read_all()
        assert drive._drivemap.all_program.__code__.co_filename == "<drivemap read program snapshot>"
        assert paths == {"read_raw": 0, "write_raw": 0, "replay": 0, "run": 0}


def _both(model: str, body: Callable[[Any, Any], Any]) -> tuple[Any, Any]:
    """``body(sim, drive)`` on a fresh TCP server with the generated client, then with general_only."""
    pkg = package(model)
    results = []
    for cls in (pkg.Client, general_only(pkg.Client)):
        with tcp_server(model) as (sim, host, port), cls.tcp(host, port, timeout=2.0) as drive:
            results.append((body(sim, drive), dataclasses.asdict(drive.stats)))
    return results[0], results[1]


@pytest.mark.parametrize("model", ["ev", "vfd1000", "v2", "edx"])
def test_every_seed_register_reads_as_on_the_general_path(model: str) -> None:
    def body(sim: Any, drive: Any) -> Any:
        out = []
        for name in sorted(drive.registers):
            acc = drive.registers[name]
            if acc.spec.readable:
                out.append((name, outcome(acc.read)))
        readable = [a for _, a in sorted(drive.registers.items()) if a.spec.readable and a.spec.page is None]
        out.append(outcome(lambda: drive.read(*readable[:12])))
        out.append(outcome(lambda: drive.read(*readable[-5:], *readable[:3])))
        out.append(outcome(drive.read_all))
        return out

    fast, general = _both(model, body)
    assert fast == general


def test_every_type_and_word_order_decodes_as_on_the_general_path(paths: dict[str, int]) -> None:
    """allkinds: floats, strings, 64-bit, scale factors, not-available values, byte orders, arrays."""
    tables = server_tables()
    results = []
    for cls in (PKG.Client, general_only(PKG.Client)):
        with plain_server(tables) as port, cls.tcp("127.0.0.1", port, timeout=2.0) as drive:
            values = {}
            for reg in MODEL.registers:
                if reg.readable:
                    values[reg.name] = outcome(drive.accessor(reg.name).read)
            registers = [drive.accessor(r.name) for r in MODEL.registers if r.readable and not r.bit_table]
            snap = outcome(lambda drive=drive, registers=registers: drive.read(*registers))
            results.append((values, snap, dataclasses.asdict(drive.stats)))
    assert repr(results[0]) == repr(results[1])  # -0.0 and NaN compare by their text


@pytest.mark.parametrize("refuse", [REFUSED, {("input", 0x16)}], ids=["gaps refused", "asked register refused"])
def test_adaptive_split_goes_the_general_way_with_the_same_results(paths: dict[str, int], refuse: set[Any]) -> None:
    tables = server_tables(refuse)
    results = []
    counts = []
    for cls in (PKG.Client, general_only(PKG.Client)):
        with plain_server(tables) as port, cls.tcp("127.0.0.1", port, timeout=2.0) as drive:
            before = dict(paths)
            first = outcome(lambda: drive.read(drive.net_energy, drive.temperature, drive.grid_state))
            second = outcome(lambda: drive.read(drive.net_energy, drive.temperature, drive.grid_state))
            third = outcome(drive.temperature.read)
            results.append((first, second, third, sorted(drive.holes), dataclasses.asdict(drive.stats)))
            counts.append({k: paths[k] - before[k] for k in paths})
    assert repr(results[0]) == repr(results[1])
    assert results[0][3], "the device refused words: the client knows holes"
    assert counts[0]["replay"] == 1  # the 02h reply went to the general operation, with the reply received
    assert counts[0]["run"] == 2  # with holes known, the later reads run the general operation from the start
    assert counts[1]["replay"] == 0 and counts[1]["run"] == 3


FAULTS = {
    "exception reply": (FrameFault(drop=True, prefix=rtu("01 83 04")), 1),
    "short reply": (FrameFault(drop=True, prefix=rtu("01 03 02 00 07")), 1),
    "other unit": (FrameFault(drop=True, prefix=rtu("02 03 04 00 07 00 08")), 1),
    "other function": (FrameFault(drop=True, prefix=rtu("01 04 04 00 07 00 08")), 1),
    "lost reply, retried": (FrameFault(drop=True), 1),
    "lost replies, timeout": (FrameFault(drop=True), 3),
}


def _serial_run(cls: Any, fault: FrameFault, frames: int, call: Callable[[Any], Any]) -> Any:
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        sim.set("alarm_no", 3)
        with cls.serial(line.master_port, unit=1, baudrate=38400, parity="none", stopbits=1, timeout=0.2,
                        retries=2) as drive:
            line.faults.add("to_master", fault, frames=frames)
            result = outcome(lambda: call(drive))
            after = outcome(lambda: call(drive))  # and the next call, clean again
            return result, after, dataclasses.asdict(drive.stats), line.delivered("to_device")


@pytest.mark.slow  # a virtual serial line (ptys) per fault, twice
@pytest.mark.parametrize("fault", sorted(FAULTS))
@pytest.mark.parametrize("what", ["element", "two registers"])
def test_faults_on_a_serial_line_give_the_same_results(paths: dict[str, int], fault: str, what: str) -> None:
    frame_fault, frames = FAULTS[fault]

    def call(drive: Any) -> Any:
        if what == "element":
            return drive.motor_speed.read()
        return drive.read(drive.motor_speed, drive.alarm_no)

    before = dict(paths)
    fast = _serial_run(ev.Client, frame_fault, frames, call)
    replays = paths["replay"] - before["replay"]
    general = _serial_run(general_only(ev.Client), frame_fault, frames, call)
    assert fast == general
    assert replays == (1 if fault == "exception reply" else 0)  # the bus itself retries and rejects
    if fault == "exception reply":
        assert fast[0][2] == 4  # the device's exception, typed


def test_paged_reads_are_never_programs(paths: dict[str, int]) -> None:
    def body(sim: Any, drive: Any) -> Any:
        return [outcome(drive.bus_voltage.read), outcome(lambda: drive.read(drive.bus_voltage, drive.output_current)),
                outcome(drive.read_all)]

    for policy in ("raise", "switch"):
        results = []
        for cls in (ev.Client, general_only(ev.Client)):
            with tcp_server("ev") as (sim, host, port), cls.tcp(host, port, timeout=2.0,
                                                                   page_policy=policy) as drive:
                results.append((body(sim, drive), dataclasses.asdict(drive.stats)))
                assert drive.bus_voltage._program.__code__.co_filename != "<drivemap read program value>"
        assert results[0] == results[1]


WRITE_FAULTS = {
    "exception reply": FrameFault(drop=True, prefix=rtu("01 86 03")),
    "echo of another value": FrameFault(drop=True, prefix=rtu("01 06 09 0B 00 01")),
    "lost reply": FrameFault(drop=True),
}


@pytest.mark.slow  # a virtual serial line (ptys) per fault, twice
@pytest.mark.parametrize("fault", sorted(WRITE_FAULTS))
def test_write_faults_give_the_same_results(paths: dict[str, int], fault: str) -> None:
    results = []
    for cls in (ev.Client, general_only(ev.Client)):
        results.append(_serial_run(cls, WRITE_FAULTS[fault], 1, lambda drive: drive.rs485_timeout.write(500)))
    assert results[0] == results[1]
    assert paths["write_raw"] == 2  # the general client's two writes; the program never enters the core


@pytest.mark.parametrize("value", [0, 1000, 1001, -1, 1.0, 2.5, True, "7", None])
def test_write_checks_and_errors_are_the_same(value: Any) -> None:
    def body(sim: Any, drive: Any) -> Any:
        return [outcome(lambda: drive.rs485_timeout.write(value)), sim.get("rs485_timeout"),
                outcome(lambda: drive.comm_error_action.write(value)),
                outcome(lambda: drive.comm_error_action.write(type(drive.comm_error_action.read())(1)))]

    fast, general = _both("ev", body)
    assert fast == general


async def _async_run(cls: Any, fault: FrameFault | None) -> Any:
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        async with cls.serial(line.master_port, unit=1, baudrate=38400, parity="none", stopbits=1, timeout=0.2,
                              retries=2) as drive:
            if fault is not None:
                line.faults.add("to_master", fault)
            out = []
            for call in (drive.motor_speed.read, lambda: drive.read(drive.motor_speed, drive.alarm_no),
                         lambda: drive.rs485_timeout.write(40)):
                try:
                    out.append(await call())
                except DriveError as exc:
                    out.append((type(exc).__name__, str(exc), getattr(exc, "code", None)))
            return out, dataclasses.asdict(drive.stats), line.delivered("to_device")


@pytest.mark.parametrize("fault", [None, "exception reply", "lost reply, retried"])
def test_async_programs_give_the_same_results(paths: dict[str, int], fault: str | None) -> None:
    frame_fault = FAULTS[fault][0] if fault is not None else None
    fast = asyncio.run(_async_run(ev.AsyncClient, frame_fault))
    counts = dict(paths)
    general = asyncio.run(_async_run(general_only(ev.AsyncClient), frame_fault))
    assert fast == general
    assert counts["replay"] == (1 if fault == "exception reply" else 0)
    assert counts["read_raw"] == counts["replay"] and counts["write_raw"] == 0
    if fault == "exception reply":
        assert isinstance(fast[0][0], tuple) and fast[0][0][2] == 4


def test_device_exception_from_a_program_is_typed() -> None:
    with serial_server("ev", "rtu") as (sim, line):
        with ev.Client.serial(line.master_port, unit=1, baudrate=38400, parity="none", stopbits=1,
                              timeout=0.2) as drive:
            line.faults.add("to_master", FrameFault(drop=True, prefix=rtu("01 83 04")))
            with pytest.raises(DeviceException) as err:
                drive.read(drive.motor_speed, drive.alarm_no)
            assert err.value.code == 4 and drive.stats.exceptions == 1 and drive.stats.retries == 0
            line.faults.add("to_master", FrameFault(drop=True, prefix=rtu("01 83 02")))
            sim.set("motor_speed", 99)
            assert drive.read(drive.motor_speed, drive.alarm_no).motor_speed == 99  # 02h: split, then read
            assert drive.stats.split_reads == 1 and drive.stats.exceptions == 2


def test_bus_settings_changed_after_a_transaction_apply_to_the_next() -> None:
    """The bus caches each transaction shape's timeout, attempts and quiet time; a setting changed
    later (timeout, retries, serial-line rules, baud rate) applies to the very next transaction."""
    with tcp_server("ev") as (_sim, host, port), ev.Client.tcp(host, port, timeout=2.0) as drive:
        bus = drive.bus
        drive.motor_speed.read()
        assert bus.client.comm_params.timeout_connect == 2.0 and bus.last_quiet_s == 0.0
        bus.timeout_override = 0.7
        drive.motor_speed.read()
        assert bus.client.comm_params.timeout_connect == 0.7
        bus.serial_line, bus.baudrate = True, 9600  # as on a serial line: the silent interval applies
        drive.motor_speed.read()
        assert bus.last_quiet_s == pytest.approx(bus.quiet_after(_first_exchange(drive)))
        assert bus.last_quiet_s > 0.003  # 3.5 characters of 11 bits at 9600 Bd, at least
        bus.serial_line = False
        drive.motor_speed.read()
        assert bus.last_quiet_s == 0.0


def _first_exchange(drive: Any) -> Any:
    """The prepared exchange of ``drive.motor_speed``'s read program."""
    for cell in drive.motor_speed._program.__closure__:
        if isinstance(cell.cell_contents, tuple) and cell.cell_contents:
            return cell.cell_contents[0]
    raise AssertionError("no prepared exchange")
