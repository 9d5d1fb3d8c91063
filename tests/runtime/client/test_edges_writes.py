"""Writes that reach a device are exactly what was asked, in the order asked: values between two steps of
the register's resolution are refused (or rounded only with --round), writes go out in command-line order,
dry runs name registers of the frame's own table, bools parse from the words people write, numbers and
array indexes are ASCII only."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import pytest
from helpers_client import package, tcp_server
from helpers_live import no_traceback, run

from drivemap.runtime.client.values.codec import STEP_TOLERANCE, shortest_f32_text
from drivemap.runtime.errors import InexactValue

ROOT = Path(__file__).resolve().parents[3]

# ---------------------------------------------------------------- 1. no silent rounding


def test_client_refuses_a_value_between_two_steps_and_accepts_binary_float_decimals() -> None:
    ev = package("ev")
    assert ev.CODECS["digital_torque_limit"].encode(12.3) == 123  # 12.3 / 0.1 == 122.99999999999999
    codec = ev.CODECS["digital_accel_time"]  # 0.1 s per step
    for value in (0.3, 1.1, 2.7, 9.9, 0.1 + 0.2):  # decimals a binary float cannot hold exactly
        assert codec.encode(value) == round(value * 10)
    with pytest.raises(InexactValue) as info:
        codec.encode(1.25)
    assert info.value.nearest == (1.2, 1.3) and "nearest representable: 1.2 s or 1.3 s" in str(info.value)
    assert info.value.rounded == 1.3 and info.value.rounded_raw == 13
    assert 0 < STEP_TOLERANCE < 1e-3


def test_client_refuses_what_an_f32_cannot_hold_and_takes_what_it_prints() -> None:
    """One rule for every client (the gateway's too): the single nearest the value must read as it."""
    from drivemap.runtime.client.values.codec import IeeeCodec
    from drivemap.runtime.spec import RegisterSpec

    codec = IeeeCodec(RegisterSpec(name="setpoint", address=0, type="f32", unit="Hz"))
    single = struct.unpack(">f", struct.pack(">f", 30.2))[0]
    assert codec.encode(30.2) == codec.encode(single) == int.from_bytes(struct.pack(">f", 30.2), "big")
    for value in (15, 0.1, 16777216, -2.5e-3):
        assert codec.decode(codec.encode(value)) == struct.unpack(">f", struct.pack(">f", value))[0]
    for value, nearest in ((30.123456789, 30.123457), (16777217, 16777216.0), (0.123456789, 0.12345679)):
        with pytest.raises(InexactValue) as info:
            codec.encode(value)
        assert info.value.nearest == (nearest,) and info.value.rounded == nearest
        assert info.value.rounded_raw == int.from_bytes(struct.pack(">f", value), "big")
        assert "not representable as f32" in str(info.value) and "refused, not rounded" in str(info.value)
    double = IeeeCodec(RegisterSpec(name="total", address=0, type="f64"))
    assert double.decode(double.encode(30.123456789)) == 30.123456789  # a double holds every Python float


def test_client_refuses_a_scale_factor_step_with_the_nearest_values() -> None:
    fronius = package("fronius_symo_hybrid")
    codec = fronius.CODECS["pf_setpoint"]
    inner = getattr(codec, "inner", codec)
    with pytest.raises(InexactValue) as info:
        inner.encode_scaled(-0.95, 0)  # scale factor 0: whole numbers only
    assert info.value.nearest == (-1, 0) and "pf_setpoint_sf reads 0" in str(info.value)
    assert inner.encode_scaled(-0.95, -3) == -950
    assert inner.encode_scaled(0.123, -3) == 123


def test_cli_write_refuses_then_rounds_only_with_round() -> None:
    with tcp_server("fronius_symo_hybrid") as (sim, host, port):
        sim.set("pf_setpoint_sf", 0)
        sim.set_raw("pf_setpoint", 7)
        refused = run("write", "fronius_symo_hybrid", "--tcp", f"{host}:{port}", "pf_setpoint=-0.95")
        assert sim.get_raw("pf_setpoint") == 7  # nothing reached the device
        rounded = run("write", "fronius_symo_hybrid", "--tcp", f"{host}:{port}", "pf_setpoint=-0.95", "--round")
        assert sim.get_raw("pf_setpoint") in (-1, 0xFFFF)
    no_traceback(refused)
    assert refused.returncode != 0 and "nearest representable: -1 or 0" in refused.stderr, refused.stderr
    assert rounded.returncode == 0, rounded.stderr and "--round" in rounded.stderr
    with tcp_server("ev") as (sim, host, port):
        before = sim.get_raw("digital_accel_time[0]")
        refused = run("write", "ev", "--tcp", f"{host}:{port}", "digital_accel_time[0]=1.25")
        assert sim.get_raw("digital_accel_time[0]") == before
        exact = run("write", "ev", "--tcp", f"{host}:{port}", "digital_accel_time[0]=1.2")
        assert sim.get_raw("digital_accel_time[0]") == 12
        rounded = run("write", "ev", "--tcp", f"{host}:{port}", "digital_accel_time[0]=1.25", "--round")
        assert sim.get_raw("digital_accel_time[0]") == 13
    assert refused.returncode == 1 and re.search(r"<command line>:1:\d+: error: .*1\.2 s or 1\.3 s", refused.stderr)
    assert exact.returncode == 0, exact.stderr
    assert rounded.returncode == 0 and "asked 1.25, sending 1.3 (--round)" in rounded.stderr, rounded.stderr


def test_cli_never_truncates_a_float_to_an_int() -> None:
    proc = run("write", str(ROOT / "tests" / "maps" / "allkinds.yaml"), "--dry-run", "--tcp", "127.0.0.1:9",
               "setpoint=30.5")
    assert proc.returncode == 0, proc.stderr
    assert "41 F4 00 00" in proc.stdout  # 30.5, not 30 (41 F0 00 00)


# ---------------------------------------------------------------- 2. order, 3. dry-run names


def test_writes_go_out_in_command_line_order_and_dry_run_shows_it() -> None:
    proc = run("write", "sdm630", "--dry-run", "--tcp", "127.0.0.1:9", "reset=0", "demand_period=15")
    assert proc.returncode == 0, proc.stderr
    requests = [line for line in proc.stdout.splitlines() if re.match(r"\d+\. ", line)]
    assert "reset" in requests[0] and "demand_period" in requests[1], proc.stdout
    with tcp_server("ev") as (sim, host, port):
        proc = run("write", "ev", "--tcp", f"{host}:{port}", "--debug", "digital_speed[3]=300", "digital_speed[0]=100")
        assert proc.returncode == 0, proc.stderr
        frames = [line.split(" TX ")[1].split() for line in proc.stderr.splitlines() if " TX " in line]
    addresses = [int("".join(f[8:10]), 16) for f in frames if f[7] in ("06", "10")]
    assert len(addresses) == 2 and addresses[0] > addresses[1], frames  # digital_speed[3] first, as asked


def test_dry_run_names_the_register_of_the_frames_table() -> None:
    proc = run("write", "sdm630", "--dry-run", "--tcp", "127.0.0.1:9", "demand_period=30")
    assert proc.returncode == 0, proc.stderr
    assert "demand_period" in proc.stdout and "phase_2_voltage" not in proc.stdout, proc.stdout


# ---------------------------------------------------------------- 4. bools, ASCII only


@pytest.mark.parametrize("text,expected", [("true", 1), ("ON", 1), ("1", 1), ("False", 0), ("off", 0), ("0", 0)])
def test_bool_words(text: str, expected: int) -> None:
    proc = run("write", "tests/maps/allkinds.yaml", "--dry-run", "--tcp", "127.0.0.1:9", f"run={text}")
    assert proc.returncode == 0, proc.stderr
    frame = next(line for line in proc.stdout.splitlines() if "TCP:" in line)
    assert frame.split()[-2:] == (["FF", "00"] if expected else ["00", "00"]), frame


def test_bad_bools_bits_and_non_ascii_digits_are_located_errors() -> None:
    for arg, message in (("run=yes", "is not a bool"), ("run=2", "is not a bool"),
                         ("enable=maybe", "is not a bool")):
        proc = run("write", "tests/maps/allkinds.yaml", "--dry-run", "--tcp", "127.0.0.1:9", arg)
        no_traceback(proc)
        assert proc.returncode == 1 and re.search(rf"<command line>:1:\d+: error: .*{message}", proc.stderr), proc.stderr
    for arg in ("digital_speed[\u0663]=5", "digital_speed[0]=\u0661\u0662"):
        proc = run("write", "ev", "--dry-run", "--tcp", "127.0.0.1:9", arg)
        no_traceback(proc)
        assert proc.returncode == 1 and "<command line>:1:" in proc.stderr, proc.stderr
    proc = run("write", "ev", "--dry-run", "--tcp", "127.0.0.1:9", "rs485_comm_settings=parity:EVEN,stop_bits:2,data_bits:0")
    assert proc.returncode == 1 and "is not a bool" in proc.stderr, proc.stderr


# ---------------------------------------------------------------- 11. f32 text


def test_shortest_f32_text() -> None:
    f32 = struct.unpack("<f", struct.pack("<f", 230.2))[0]
    assert repr(f32) == "230.1999969482422" and shortest_f32_text(f32) == "230.2"
    assert shortest_f32_text(0.5) == "0.5" and shortest_f32_text(float("nan")) == "nan"
    assert shortest_f32_text(1e300) == "1e+300"  # not an f32: as Python prints it


def test_read_prints_f32_values_as_their_shortest_decimal() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        sim.set("phase_1_voltage", 230.2)
        table = run("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage")
        as_json = run("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage", "--json")
        as_csv = run("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage", "--csv")
        watched = run("watch", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage", "--count", "1")
    for proc in (table, as_json, as_csv, watched):
        assert proc.returncode == 0, proc.stderr
        assert "230.2" in proc.stdout and "230.1999" not in proc.stdout, proc.stdout
    assert '"value": 230.2,' in as_json.stdout


def test_client_names_take_ascii_digits_only() -> None:
    from drivemap.runtime.errors import UnknownRegister

    ev = package("ev")
    with tcp_server("ev") as (_sim, host, port):
        with ev.Client.tcp(host, port, unit=1, timeout=2.0) as drive:
            assert drive.accessor("digital_speed[3]") is drive.digital_speed[3]
            with pytest.raises(UnknownRegister):
                drive.accessor("digital_speed[\u0663]")
    proc = run("read", "ev", "--tcp", "127.0.0.1:\u0665\u0660\u0662", "motor_state")
    assert proc.returncode == 1 and "Traceback" not in proc.stderr


def test_large_raw_values_are_judged_at_the_floats_own_precision() -> None:
    from drivemap.runtime.client.values.steps import exact_raw
    from drivemap.runtime.spec import RegisterSpec

    energy = RegisterSpec(name="energy", address=0, type="u64", scale=0.001)
    assert abs(exact_raw(energy, 12345678901234.567, 0.001, 0, 3) - 12345678901234567) <= 2
    with pytest.raises(InexactValue):
        exact_raw(energy, 1.0005, 0.001, 0, 3)
