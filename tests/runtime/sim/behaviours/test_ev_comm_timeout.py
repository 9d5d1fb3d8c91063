"""ev's communication-timeout alarm (Tb1, 09-12, 85h) in the simulator (the manual states it, so the simulator does it).

001 §1.3 Tb1: when the interval between queries exceeds 09-12 RS-485 communication timeout, the
drive raises a communication timeout alarm (initial value: no monitoring); 001 §4.5 records it as
133 (85h); 09-10 says what the drive does (0 alarm, 1 NET-IO state cleared, 2 both).
"""

from __future__ import annotations

import importlib
import struct
import time
from typing import Any

import pytest

from drivemap.runtime.sim.behaviours.ev import Ev
from tests.helpers_client import TIMEOUT, package, tcp_server

ev = package("ev")
EvSimulator = importlib.import_module("drivemap_models.ev.simulator").Simulator
RUN, FAULT, STOP = 2, 5, 0


def write(addr: int, value: int) -> bytes:
    return struct.pack(">BHH", 0x06, addr, value)


def read(addr: int, qty: int = 1) -> bytes:
    return struct.pack(">BHH", 0x03, addr, qty)


def _running(timeout_ms: int, action: int = 0, **kw: Any) -> Any:
    sim = EvSimulator(**kw)
    assert sim.handle(1, write(0x0909, action)) is not None  # 09-10 comm_error_action
    assert sim.handle(1, write(0x090B, timeout_ms)) is not None  # 09-12 rs485_timeout
    assert sim.handle(1, write(0x1400, 1)) is not None  # NET-X0 START/STOP on
    sim.advance(0.05)
    assert sim.get("motor_state") == RUN and sim.get("motor_speed") > 0
    return sim


def test_silence_longer_than_09_12_raises_the_alarm_and_records_85h() -> None:
    sim = _running(200)
    sim.advance(0.1)  # 150 ms since the last query: fine
    assert sim.get("motor_state") == RUN and sim.get("comm_error_history[0]") == 0
    sim.handle(1, read(0x0000))  # a query restarts the interval
    sim.advance(0.15)
    assert sim.get("motor_state") == RUN
    sim.advance(0.1)  # 250 ms of silence > 200 ms
    assert sim.get("motor_state") == FAULT and sim.get("motor_speed") == 0
    assert sim.get("comm_error_history[0]") == 0x85 and sim.get("comm_error_history[1]") == 0
    assert sim.get("alarm_no") == 0  # the alarm list (and so its number) is not in 001
    sim.handle(1, read(0x0000))
    sim.advance(0.5)  # silence again while the alarm stands: recorded once per silence
    assert sim.get("comm_error_history[1]") == 0x85 and sim.get("comm_error_history[2]") == 0
    sim.handle(1, write(0x1400, 0))
    sim.handle(1, write(0x0A00, 1))  # Alarm Reset (0A00h)
    assert sim.get("motor_state") == STOP


def test_action_net_io_clear_stops_without_alarm() -> None:
    sim = _running(100, action=1)  # 09-10 = 1: NET-IO state cleared
    sim.advance(0.15)
    assert sim.get("net_in") == 0 and sim.get("comm_error_history[0]") == 0x85
    assert sim.get("motor_state") in (RUN, STOP)  # decelerating, not FAULT
    sim.advance(2.0)
    assert sim.get("motor_state") == STOP


def test_action_both() -> None:
    sim = _running(100, action=2)
    sim.advance(0.15)
    assert sim.get("net_in") == 0 and sim.get("motor_state") == FAULT


def test_zero_means_no_monitoring_and_no_query_no_alarm() -> None:
    sim = _running(0)
    sim.advance(5.0)
    assert sim.get("motor_state") == RUN and sim.get("comm_error_history[0]") == 0
    quiet = EvSimulator()
    quiet.set("rs485_timeout", 100)  # preset, no query yet: monitoring starts with the first query
    quiet.advance(1.0)
    assert quiet.get("comm_error_history[0]") == 0


def test_alarm_number_is_an_option() -> None:
    sim = _running(100, behaviour=Ev(comm_timeout_alarm_no=7))
    sim.advance(0.15)
    assert sim.get("alarm_no") == 7 and sim.get("alarm_history[0]") == 7 and sim.get("motor_state") == FAULT


def test_rs232_unit_17_uses_09_14() -> None:
    sim = EvSimulator(units=[17])
    sim.handle(17, write(0x090B, 100))  # 09-12 is the RS-485 timeout: not this port's
    sim.handle(17, write(0x090D, 300))  # 09-14 RS-232 timeout
    sim.advance(0.2)
    assert sim.get("comm_error_history[0]") == 0
    sim.advance(0.2)
    assert sim.get("comm_error_history[0]") == 0x85


@pytest.mark.slow  # a served simulator on TCP, in real time
def test_served_simulator_raises_it_in_real_time() -> None:
    """Over Modbus TCP with the server's own ticker: the client stops talking, the drive alarms."""
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            drive.rs485_timeout.write(300)
            drive.write_by_name("net_in", 1)
            assert drive.motor_state.read() == ev.MotorState.RUN
            deadline = time.monotonic() + 5.0
            while sim.get("motor_state") != FAULT and time.monotonic() < deadline:
                time.sleep(0.05)  # no query: the 300 ms interval runs out
            assert drive.motor_state.read() == ev.MotorState.FAULT
            assert drive.comm_error_history[0].read() == ev.CommErrorCode.COMMUNICATION_TIMEOUT


@pytest.mark.slow  # a served simulator on TCP, in real time
def test_queries_keep_it_quiet_over_tcp() -> None:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            drive.rs485_timeout.write(1000)
            drive.write_by_name("net_in", 1)
            for _ in range(8):  # a query every 0.1 s: never 1 s of silence
                time.sleep(0.1)
                assert drive.motor_state.read() == ev.MotorState.RUN
    assert sim.get("comm_error_history[0]") == 0
