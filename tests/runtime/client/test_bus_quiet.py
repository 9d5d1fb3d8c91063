"""The quiet time after a transaction: serial-line rules on serial lines and RTU over TCP, not on Modbus TCP.

v2's map gives ``inter_frame_gap_ms: 10`` (a rule its manual states for the RS-485 port). On a
serial line and on RTU over TCP (a transparent gateway puts the frames on a serial line) the bus
keeps that gap plus the silent interval after every transaction; on Modbus TCP (MBAP framing)
it keeps neither. Broadcast gaps and EEPROM write delays hold on every transport. Evidence is
the quiet time the bus records (:attr:`Bus.last_quiet_s`) and whether it ever sleeps — never
wall-clock time.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from pymodbus.pdu.register_message import ReadHoldingRegistersRequest, WriteSingleRegisterRequest

from drivemap.runtime.client.transport.bus import DEFAULT_BROADCAST_GAP_MS, AsyncBus, Bus, Exchange
from drivemap.runtime.spec import TimingSpec
from tests.helpers_client import TIMEOUT, package, serial_server, tcp_server
from tests.runtime.client.test_client_tcp import rtu_over_tcp_server

v2 = package("v2")
GAP_S = v2.SPEC.protocol.timing.inter_frame_gap_ms / 1000.0


def _read(timing: TimingSpec = v2.SPEC.protocol.timing, **kw: Any) -> Exchange:
    return Exchange(1, ReadHoldingRegistersRequest(address=0, count=1), timing, **kw)


def test_v2_has_an_inter_frame_gap() -> None:
    assert GAP_S > 0  # the tests below mean something only with a gap


@pytest.mark.parametrize("factory", [Bus, AsyncBus])
async def test_quiet_after_by_transport(factory: Any) -> None:  # async: AsyncBus needs a loop
    tcp = factory.tcp("127.0.0.1", 1)
    gateway = factory.rtu_over_tcp("127.0.0.1", 1)
    line = factory.serial("/dev/null-not-opened", v2.SPEC.protocol.serial, baudrate=38400, parity="none", stopbits=1)
    t35 = 3.5 * 10 / 38400  # 8N1: 10 bits per character

    assert tcp.quiet_after(_read()) == 0.0
    assert gateway.quiet_after(_read()) == pytest.approx(GAP_S)  # baud rate unknown: no floor in v2's map
    assert line.quiet_after(_read()) == pytest.approx(GAP_S + t35)

    # broadcast gap and EEPROM hold: on every transport
    bgap = DEFAULT_BROADCAST_GAP_MS / 1000.0
    assert tcp.quiet_after(_read(expect_reply=False)) == pytest.approx(bgap)
    assert gateway.quiet_after(_read(expect_reply=False)) == pytest.approx(max(GAP_S, bgap))
    assert line.quiet_after(_read(expect_reply=False)) == pytest.approx(max(GAP_S, bgap) + t35)
    write = Exchange(1, WriteSingleRegisterRequest(address=0, registers=[1]), v2.SPEC.protocol.timing, hold_ms=250.0)
    for bus in (tcp, gateway, line):
        assert bus.quiet_after(write) == pytest.approx(0.25)

    # a map with a silent-interval floor: the floor applies on RTU over TCP, never on Modbus TCP
    floored = TimingSpec(silent_interval_floor_ms=1.75, inter_frame_gap_ms=5)
    assert tcp.quiet_after(_read(floored)) == 0.0
    assert gateway.quiet_after(_read(floored)) == pytest.approx(0.005 + 0.00175)


def test_modbus_tcp_never_waits(monkeypatch: pytest.MonkeyPatch) -> None:
    sleeps: list[float] = []
    real_sleep = time.sleep
    caller = threading.current_thread()

    def sleep(seconds: float) -> None:
        if threading.current_thread() is caller:  # the client's thread, not the server's
            sleeps.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(time, "sleep", sleep)
    with tcp_server("v2") as (sim, host, port):
        with v2.Client.tcp(host, port, unit=1, timeout=TIMEOUT) as drive:
            for _ in range(5):
                drive.frequency_command.write(12.5)
                assert drive.frequency_command.read() == 12.5
            drive.read_all()
            assert drive.bus.last_quiet_s == 0.0
            assert drive.stats.transactions >= 11
    assert sleeps == []  # no gap, no silent interval: the bus never slept


def test_rtu_over_tcp_keeps_the_gap() -> None:
    with rtu_over_tcp_server("v2") as (sim, port):
        with v2.Client.rtu_over_tcp("127.0.0.1", port, unit=1, timeout=TIMEOUT) as drive:
            assert drive.frequency_command.read() == sim.get("frequency_command")
            assert drive.bus.last_quiet_s == pytest.approx(GAP_S)


def test_serial_line_keeps_gap_and_silent_interval() -> None:
    with serial_server("v2", "rtu", baudrate=38400) as (sim, line):
        with v2.Client.serial(line.master_port, unit=1, timeout=TIMEOUT, baudrate=38400, parity="none",
                              stopbits=1) as drive:
            assert drive.frequency_command.read() == sim.get("frequency_command")
            assert drive.bus.last_quiet_s == pytest.approx(GAP_S + 3.5 * 10 / 38400)


async def test_async_modbus_tcp_and_gateway() -> None:
    with tcp_server("v2") as (sim, host, port):
        drive = v2.AsyncClient.tcp(host, port, unit=1, timeout=TIMEOUT)
        async with drive:
            await drive.read_all()
            assert drive.bus.last_quiet_s == 0.0
    with rtu_over_tcp_server("v2") as (sim, port):
        gw = v2.AsyncClient.rtu_over_tcp("127.0.0.1", port, unit=1, timeout=TIMEOUT)
        async with gw:
            await gw.frequency_command.read()
            assert gw.bus.last_quiet_s == pytest.approx(GAP_S)
