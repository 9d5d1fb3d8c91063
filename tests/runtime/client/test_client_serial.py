"""Generated clients on a virtual serial line (RTU and ASCII) against the generated simulator."""

from __future__ import annotations

from typing import Any

import pytest

from drivemap.runtime.client.transport import bus as bus_module
from drivemap.runtime.errors import AccessError, BroadcastRead, DriveTimeout, NotBroadcastable, ValueOutOfRange
from tests.helpers_client import MODELS, TIMEOUT, package, serial_server

BAUD = 38400
CASES = [(m, mode) for m in MODELS for mode in ("rtu", "ascii") if mode in package(m).SPEC.protocol.modes]


def _client(pkg: Any, line: Any, mode: str, unit: int = 1, **kw: Any) -> Any:
    return pkg.Client.serial(line.master_port, unit=unit, mode=mode, baudrate=BAUD, parity="none", stopbits=1,
                             timeout=TIMEOUT, **kw)


def _rw_register(spec: Any) -> Any:
    return next(r for r in spec.registers if r.access == "rw" and not r.enum and not r.bits and r.page is None
                and r.reflect != "configuration" and not r.command_value)


@pytest.mark.parametrize("model,mode", CASES)
def test_read_write_round_trip(model: str, mode: str) -> None:
    pkg = package(model)
    reg = _rw_register(pkg.SPEC)
    value = reg.max if reg.max is not None else 12 * reg.scale
    with serial_server(model, mode) as (sim, line):
        with _client(pkg, line, mode) as drive:
            drive.write_by_name(reg.element_name(0), value)
            assert sim.get(reg.element_name(0)) == pytest.approx(value)
            assert drive.read_by_name(reg.element_name(0)) == pytest.approx(value)
            snap = drive.read_all() if not any(r.page for r in pkg.SPEC.registers) else None
            if snap is not None:
                assert getattr(snap, reg.name) is not None
            frames = line.captured("to_device")
            if mode == "ascii":
                assert frames.startswith(b":") and frames.endswith(b"\r\n")
            assert drive.stats.bytes_sent == len(frames)
            assert drive.stats.bytes_received == len(line.captured("to_master"))


@pytest.mark.parametrize("model,mode", CASES)
def test_range_error_sends_no_byte(model: str, mode: str) -> None:
    pkg = package(model)
    reg = next((r for r in pkg.SPEC.registers if r.writable and r.max is not None and not r.enum and not r.bits),
               _rw_register(pkg.SPEC))
    too_big = reg.max + reg.scale * 10 if reg.max is not None else 1e12
    with serial_server(model, mode) as (_sim, line):
        with _client(pkg, line, mode) as drive:
            with pytest.raises(ValueOutOfRange):
                drive.write_by_name(reg.element_name(0), too_big)
            line.wait_idle(1.0)
            assert line.captured("to_device") == b""
            assert drive.stats.transactions == 0


@pytest.mark.parametrize("model,mode", [("ev", "rtu"), ("edx", "ascii"), ("v2", "rtu")])
def test_retry_after_dropped_reply(model: str, mode: str) -> None:
    pkg = package(model)
    reg = _rw_register(pkg.SPEC)
    with serial_server(model, mode) as (sim, line):
        sim.set(reg.element_name(0), reg.scale * 7)
        with _client(pkg, line, mode, retries=2) as drive:
            line.faults.drop("to_master")
            assert drive.read_by_name(reg.element_name(0)) == pytest.approx(reg.scale * 7)
            assert drive.stats.retries == 1
            assert drive.stats.timeouts == 1
            assert drive.stats.transactions == 2
            assert len(line.frames("to_device")) == 2


def test_corrupt_reply_is_retried() -> None:
    pkg = package("ev")
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        with _client(pkg, line, "rtu", retries=1) as drive:
            line.faults.corrupt("to_master", byte_index=3)
            assert drive.motor_speed.read() == 321
            assert drive.stats.retries == 1


def test_timeout_after_last_retry() -> None:
    pkg = package("ev")
    with serial_server("ev", "rtu") as (_sim, line):
        with _client(pkg, line, "rtu", retries=2) as drive:
            line.faults.drop("to_master", frames=3)
            with pytest.raises(DriveTimeout):
                drive.motor_speed.read()
            assert drive.stats.transactions == 3 and drive.stats.retries == 2
            # the line recovers: the next request gets its answer
            assert drive.motor_speed.read() == 0 or True


@pytest.mark.parametrize("mode", ["rtu", "ascii"])
def test_broadcast_two_units_one_line(monkeypatch: pytest.MonkeyPatch, mode: str) -> None:
    pkg = package("ev")
    waits: list[float] = []

    class Clock:
        monotonic = staticmethod(bus_module.time.monotonic)

        @staticmethod
        def sleep(seconds: float) -> None:
            waits.append(seconds)
            bus_module_time.sleep(seconds)

    import time as bus_module_time

    monkeypatch.setattr(bus_module, "time", Clock)
    with serial_server("ev", mode, units=(1, 2)) as (sim, line):
        bus = pkg.Bus.serial(line.master_port, pkg.SPEC.protocol.serial, mode=mode, baudrate=BAUD, parity="none",
                             timeout=TIMEOUT)
        with bus:
            one, two = pkg.Client(bus, unit=1), pkg.Client(bus, unit=2)
            bc = pkg.Client.broadcast(bus)
            bc.digital_speed_ram[0].write(1234)
            line.wait_idle(1.0)
            assert line.captured("to_master") == b""  # nobody answers a broadcast
            assert bus.stats.broadcasts == 1
            waits.clear()
            assert one.digital_speed_ram[0].read() == 1234  # the next request keeps the broadcast gap
            assert waits and max(waits) > 0
            assert two.digital_speed_ram[0].read() == 1234
            assert sim.get("digital_speed_ram[0]", unit=1) == sim.get("digital_speed_ram[0]", unit=2) == 1234
            sent = len(line.captured("to_device"))
            with pytest.raises(BroadcastRead):
                bc.read_by_name("digital_speed_ram[0]")
            with pytest.raises(AccessError):
                bc._drivemap.write_raw_items([(("motor_state", 0), 1)])
            assert len(line.captured("to_device")) == sent


def test_not_broadcastable_is_refused_before_connecting() -> None:
    vfd = package("vfd1000")  # 06h broadcast support is not stated (null): nothing may be broadcast
    bus = vfd.Bus.tcp("127.0.0.1", 9, timeout=TIMEOUT)  # never connected: the check comes first
    with pytest.raises(NotBroadcastable, match="06h by broadcast: not stated in the manual"):
        vfd.Client.broadcast(bus)
    assert bus.stats.transactions == 0


def test_shared_bus_serialises_units() -> None:
    pkg = package("v2")
    with serial_server("v2", "rtu", units=(1, 2)) as (sim, line):
        bus = pkg.Bus.serial(line.master_port, pkg.SPEC.protocol.serial, baudrate=BAUD, parity="none", timeout=TIMEOUT)
        with bus:
            a, b = pkg.Client(bus, unit=1), pkg.Client(bus, unit=2)
            a.frequency_command.write(10.0)
            b.frequency_command.write(20.0)
            assert (a.frequency_command.read(), b.frequency_command.read()) == (10.0, 20.0)
            assert sim.get("frequency_command", unit=2) == 20.0
            assert a.stats is b.stats and a.stats.transactions == 4
