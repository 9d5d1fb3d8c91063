"""ev's EEPROM operation data while the motor runs: the manual only advises, so nothing is refused.

001 §4.6 NOTE: "while the motor runs, change operation data through the RAM addresses" — it never
says the drive refuses an EEPROM write. So the simulator does not refuse by default (an opt-in
option does), and the client warns (RunningWriteWarning) when the drive reports running.
"""

from __future__ import annotations

import argparse
import importlib
import warnings

import pytest

from drivemap.runtime.errors import RunningWriteWarning
from drivemap.runtime.sim import cli as simcli
from tests.helpers_client import TIMEOUT, package, tcp_server

ev = package("ev")
EEPROM_ARRAYS = ("digital_speed", "digital_accel_time", "digital_decel_time", "digital_torque_limit", "digital_duty")


def _running(drive: object) -> None:
    drive.write_by_name("net_in", 1)  # type: ignore[attr-defined]  # NET-X0 = START/STOP (09-01 default 1)
    assert drive.motor_state.read() == ev.MotorState.RUN  # type: ignore[attr-defined]


def test_map_gives_advice_not_refusal() -> None:
    for name in EEPROM_ARRAYS:
        reg = ev.SPEC.register(name)
        assert not reg.refuse_while_running
        assert reg.running_advice and "001 §4.6 NOTE" in reg.running_advice and f"{name}_ram" in reg.running_advice
    state = ev.SPEC.protocol.running_state
    assert state is not None and (state.register, state.values) == ("motor_state", (2,))


def test_write_while_running_warns_and_is_not_refused() -> None:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            _running(drive)
            with pytest.warns(RunningWriteWarning, match=r"digital_speed\[0\] while the drive reports running") as got:
                drive.digital_speed[0].write(1500)
            assert got[0].filename == __file__  # attributed to the caller's line, not the runtime
            assert "RAM addresses" in str(got[0].message) and "digital_speed_ram" in str(got[0].message)
            assert sim.get("digital_speed[0]") == 1500  # the default simulator does not refuse
            with pytest.warns(RunningWriteWarning, match=r"digital_accel_time\[0\], digital_accel_time\[1\]"):
                drive.digital_accel_time.write([2.0] * 8)  # one warning for one multi-register write
            assert sim.get("digital_accel_time[1]") == 2.0


def test_no_warning_when_stopped_and_one_read_to_check() -> None:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                drive.digital_speed[1].write(1200)
                drive.digital_speed_ram[1].write(1300)  # the RAM twin carries no advice: no extra read
            assert drive.stats.by_function == {0x03: 1, 0x06: 2}
    assert sim.get("digital_speed[1]") == 1200


def test_warning_as_error_sends_nothing() -> None:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            _running(drive)
            writes = drive.stats.by_function.get(0x06, 0)
            with warnings.catch_warnings():
                warnings.simplefilter("error", RunningWriteWarning)
                with pytest.raises(RunningWriteWarning):
                    drive.digital_duty[0].write(50.0)
            assert drive.stats.by_function.get(0x06, 0) == writes
    assert sim.get("digital_duty[0]") == 10.0


async def test_async_client_warns() -> None:
    with tcp_server("ev") as (sim, host, port):
        async with ev.AsyncClient.tcp(host, port, timeout=TIMEOUT) as drive:
            await drive.write_by_name("net_in", 1)
            with pytest.warns(RunningWriteWarning) as got:
                await drive.digital_torque_limit[2].write(150.0)
            assert got[0].filename == __file__
    assert sim.get("digital_torque_limit[2]") == 150.0


def test_opt_in_simulator_refuses_like_a_busy_drive() -> None:
    sim = importlib.import_module("drivemap_models.ev.simulator").Simulator(refuse_advised_while_running=True)
    with tcp_server("ev", sim=sim) as (_, host, port):
        with ev.Client.tcp(host, port, timeout=TIMEOUT) as drive:
            _running(drive)
            with pytest.warns(RunningWriteWarning), pytest.raises(ev.EXCEPTIONS[0x04]):
                drive.digital_speed[0].write(1500)  # busy -> 04h (001 §2.2), recorded as 8Dh
            assert drive.comm_error_history[0].read() == ev.CommErrorCode.CANNOT_EXECUTE
            drive.digital_speed_ram[0].write(1500)  # the RAM twin is what the manual advises
    assert sim.get("digital_speed[0]") == 3000 and sim.get("digital_speed_ram[0]") == 1500


def test_simulate_option_reaches_the_simulator() -> None:
    parser = argparse.ArgumentParser()
    simcli.add_arguments(parser, with_model=True)
    args = parser.parse_args(["ev", "--tcp", "127.0.0.1:0", "--refuse-advised-while-running"])
    assert args.refuse_advised_while_running is True
    assert parser.parse_args(["ev", "--tcp", "127.0.0.1:0"]).refuse_advised_while_running is False


def test_v2_documented_refusal_stays() -> None:
    """v2 003 §错误代码一览表 says 55H for a parameter written while running: refuse_while_running, no option."""
    v2 = package("v2")
    assert v2.SPEC.register("parameters").refuse_while_running
    assert v2.SPEC.register("parameters").running_advice is None
