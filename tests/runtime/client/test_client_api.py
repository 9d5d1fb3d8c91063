"""The generated sync client against the generated simulator over Modbus TCP on 127.0.0.1."""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

import pytest

from drivemap.runtime.client.transport import bus as bus_module
from drivemap.runtime.errors import (
    BroadcastRead,
    DeviceException,
    DriveError,
    InexactValue,
    InvalidValue,
    ReadOnlyRegister,
    UnknownRegister,
    ValueOutOfRange,
    WriteOnlyRegister,
    WrongPage,
)
from tests.helpers_client import TIMEOUT, package, tcp_server

ev = package("ev")
v2 = package("v2")
edx = package("edx")
vfd = package("vfd1000")


@pytest.fixture
def ev_drive() -> Any:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, unit=1, timeout=TIMEOUT) as drive:
            yield sim, drive


def test_issue_example(ev_drive: Any) -> None:
    sim, drive = ev_drive
    # the monitors first: once X0 (start/stop by default) is on, the simulated motor ramps and its
    # next tick rewrites motor_speed
    sim.set("motor_state", int(ev.MotorState.RUN))
    sim.set("motor_speed", 1234)
    snap = drive.read(drive.motor_state, drive.motor_speed)
    assert snap.motor_state is ev.MotorState.RUN
    assert snap.motor_speed == 1234
    assert snap[drive.motor_speed] == 1234
    assert snap.digital_speed is None  # not read
    drive.digital_speed_ram[0].write(1000)
    assert sim.get("digital_speed_ram[0]") == 1000
    drive.net_in.write(ev.NetIn.X0)
    assert sim.get_raw("net_in") == 1
    assert drive.read_by_name("digital_speed_ram[0]") == 1000
    drive.write_by_name("digital_speed_ram[1]", 1500)
    assert drive.digital_speed_ram[1].read() == 1500
    assert isinstance(drive.net_in.read(), ev.NetIn)


def test_read_returns_engineering_types(ev_drive: Any) -> None:
    sim, drive = ev_drive
    settings = drive.rs485_comm_settings.read()
    assert dataclasses.is_dataclass(settings)
    assert isinstance(settings.parity, ev.Parity)
    new = dataclasses.replace(settings, parity=ev.Parity(2), stop_bits=True)
    drive.rs485_comm_settings.write(new)
    assert sim.get_raw("rs485_comm_settings") == 2 | (1 << 2)
    assert drive.rs485_comm_settings.read() == new
    assert drive.rs485_comm_settings.read_raw() == 6
    with pytest.raises(dataclasses.FrozenInstanceError):
        new.parity = ev.Parity(0)  # type: ignore[misc]


def test_checks_before_sending(ev_drive: Any) -> None:
    _sim, drive = ev_drive
    before = drive.stats.bytes_sent
    spec = ev.SPEC.register("digital_speed_ram")
    with pytest.raises(ValueOutOfRange):
        drive.digital_speed_ram[0].write(spec.max + 1)
    with pytest.raises(ValueOutOfRange):
        drive.digital_speed_ram[0].write(spec.min - 1)
    with pytest.raises(InvalidValue):
        drive.digital_speed_ram[0].write("1000")
    with pytest.raises(InvalidValue):
        drive.sc_cc_mode.write(1)  # an int where the enum is required
    with pytest.raises(ReadOnlyRegister):
        drive.write_by_name("motor_state", 2)
    with pytest.raises(AttributeError):
        drive.motor_state.write(ev.MotorState.RUN)  # read-only accessors have no write
    with pytest.raises(UnknownRegister):
        drive.read_by_name("no_such_register")
    with pytest.raises(UnknownRegister):
        drive.read_by_name("digital_speed[99]")
    with pytest.raises(ValueOutOfRange):
        drive.digital_speed_ram[0].write_raw(0x10000)
    assert issubclass(ValueOutOfRange, DriveError) and issubclass(WrongPage, DriveError)
    assert drive.stats.bytes_sent == before


def test_write_only_register_and_scaling() -> None:
    with tcp_server("vfd1000") as (sim, host, port):
        with vfd.Client.tcp(host, port, unit=1, timeout=TIMEOUT) as drive:
            with pytest.raises(WriteOnlyRegister):
                drive.read_by_name("control_command")
            assert not hasattr(drive.control_command, "read")
            # s16, scale 0.01: a value between two steps is refused (never rounded); negative values
            with pytest.raises(InexactValue):
                drive.communication_setting.write(-12.345)
            drive.communication_setting.write(-12.35)
            assert sim.get_raw("communication_setting") in (-1235, 0x10000 - 1235)
            assert drive.communication_setting.read() == pytest.approx(-12.35)
            with pytest.raises(InexactValue):
                drive.pid_setting.write(12.34)
            drive.pid_setting.write(12.3)
            assert drive.pid_setting.read_raw() == 123


def test_write_many_is_one_10h_request(ev_drive: Any) -> None:
    sim, drive = ev_drive
    drive.stats.by_function.clear()
    drive.digital_speed_ram.write([100, 200, 300, 400, 500, 600, 700, 800])
    assert drive.stats.by_function == {0x10: 1}
    assert [sim.get(f"digital_speed_ram[{i}]") for i in range(8)] == [100, 200, 300, 400, 500, 600, 700, 800]
    drive.stats.by_function.clear()
    drive.write_many([(drive.digital_accel_time_ram[0], 1.0), (drive.digital_speed_ram[0], 1000)])
    assert sum(drive.stats.by_function.values()) <= 2


def test_eeprom_write_waits_before_next_request(monkeypatch: pytest.MonkeyPatch, ev_drive: Any) -> None:
    _sim, drive = ev_drive
    waits: list[float] = []

    class Clock:
        monotonic = staticmethod(bus_module.time.monotonic)

        @staticmethod
        def sleep(seconds: float) -> None:
            waits.append(seconds)

    monkeypatch.setattr(bus_module, "time", Clock)
    eeprom = ev.SPEC.register("digital_speed")
    assert eeprom.storage == "eeprom" and eeprom.write_delay_ms
    drive.digital_speed_ram[0].write(1000)  # RAM: no hold
    drive.motor_speed.read()
    assert not waits
    drive.digital_speed[0].write(1000)
    drive.motor_speed.read()  # must wait out the EEPROM write delay first
    assert waits and max(waits) > (eeprom.write_delay_ms / 1000.0) * 0.5


def test_configuration_reflect(ev_drive: Any) -> None:
    sim, drive = ev_drive
    assert ev.SPEC.protocol.configuration is not None
    drive.net_x_input_function[0].write(ev.NetInputFunction(0))
    assert drive.pending_configuration == ("net_x_input_function[0]",)
    drive.apply_configuration()
    assert drive.pending_configuration == ()
    assert sim.get("net_x_input_function[0]") == 0


def test_power_cycle_reflect_is_recorded_and_logged(caplog: pytest.LogCaptureFixture) -> None:
    spec = dataclasses.replace(ev.SPEC, registers=tuple(
        dataclasses.replace(r, reflect="power_cycle") if r.name == "rs485_timeout" else r for r in ev.SPEC.registers),
        )

    class PowerCycleClient(ev.Client):
        SPEC = spec

    with tcp_server("ev") as (_sim, host, port):
        with PowerCycleClient.tcp(host, port, timeout=TIMEOUT) as drive:
            with caplog.at_level(logging.WARNING, logger="drivemap"):
                drive.rs485_timeout.write(100)
            assert drive.pending_power_cycle == ("rs485_timeout",)
            assert "powered off and on" in caplog.text


def test_pages_raise_or_switch(ev_drive: Any) -> None:
    sim, drive = ev_drive
    paged = [r for r in ev.SPEC.registers if r.page is not None]
    page1 = next(r for r in paged if r.page.value == 1)
    page0 = next(r for r in paged if r.page.value == 0)
    sim.set(page0.page.selector, 0)
    drive.read_by_name(page0.name)  # current page: fine
    with pytest.raises(WrongPage):
        drive.read_by_name(page1.name)
    with tcp_server("ev", sim=sim) as (_s, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT, page_policy="switch") as switching:
            switching.stats.by_function.clear()
            switching.read_by_name(page1.name)
            assert switching.stats.by_function == {0x06: 1, 0x03: 1}
            assert sim.get(page1.page.selector) == 1
            switching.read_by_name(page1.name)  # page known now: no second switch
            assert switching.stats.by_function == {0x06: 1, 0x03: 2}


@pytest.mark.parametrize("model,code", [("v2", 0x52), ("v2", 0x55), ("edx", 0x53), ("vfd1000", 0x06)])
def test_device_exceptions_are_typed(model: str, code: int) -> None:
    pkg = package(model)
    reg = next(r for r in pkg.SPEC.registers if "r" in r.access)
    with tcp_server(model) as (sim, host, port):
        with pkg.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            sim.inject_exception(code)
            with pytest.raises(DeviceException) as info:
                drive.read_by_name(reg.element_name(0))
    err = info.value
    expected = pkg.EXCEPTIONS[code]
    assert type(err) is expected and isinstance(err, DriveError)
    assert err.code == code and err.name == pkg.SPEC.protocol.exception(code).name
    assert err.meaning == pkg.SPEC.protocol.exception(code).meaning
    assert f"0x{code:02X}" in str(err)


def test_loopback() -> None:
    with tcp_server("v2") as (_sim, host, port):
        with v2.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            assert drive.loopback(0x1234) == 0x1234
    with tcp_server("ev") as (_sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            with pytest.raises(DriveError):
                drive.loopback(1)  # the ev map lists no 08h


def test_read_modify_write_flags(ev_drive: Any) -> None:
    sim, drive = ev_drive
    drive.net_in.write(ev.NetIn.X0)
    result = drive.read_modify_write(drive.net_in, lambda v: v | ev.NetIn.X2)
    assert result == ev.NetIn.X0 | ev.NetIn.X2
    assert sim.get_raw("net_in") == 0b101
    drive.net_in.modify(lambda v: v & ~ev.NetIn.X0)
    assert sim.get_raw("net_in") == 0b100


def test_broadcast_client_refuses_reads_before_sending() -> None:
    with tcp_server("ev") as (_sim, host, port):
        bus = ev.Bus.tcp(host, port, timeout=TIMEOUT)
        with bus:
            bc = ev.Client.broadcast(bus)
            assert bc.unit == ev.SPEC.protocol.broadcast_address
            with pytest.raises(BroadcastRead):
                bc.read_all()
            assert not hasattr(bc, "motor_state")  # read-only registers are not exposed
            assert bus.stats.bytes_sent == 0


def test_stats_and_frame_logging(ev_drive: Any, caplog: pytest.LogCaptureFixture) -> None:
    _sim, drive = ev_drive
    with caplog.at_level(logging.DEBUG, logger="drivemap"):
        drive.motor_speed.read()
    tx = [r.getMessage() for r in caplog.records if " TX " in r.getMessage()]
    rx = [r.getMessage() for r in caplog.records if " RX " in r.getMessage()]
    assert tx and rx
    assert tx[0].endswith("01 03 00 02 00 01")  # MBAP + unit 1, 03h, address 2, 1 register
    assert drive.stats.transactions >= 1 and drive.stats.retries == 0
    assert drive.stats.bytes_sent == 12 * drive.stats.transactions
    assert drive.stats.bytes_received > 0
