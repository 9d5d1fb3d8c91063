"""`drivemap read` and `drivemap write` through the real CLI, against simulators over TCP and over a
virtual serial line (RTU and ASCII)."""

from __future__ import annotations

import csv
import io
import json

from helpers_client import serial_server, tcp_server
from helpers_live import cli, map_line, no_traceback


def test_read_table_shows_names_units_labels_bits_raw_address_param() -> None:
    with tcp_server("ev") as (sim, host, port):
        sim.set("net_in", 5)
        sim.set("digital_speed[1]", 1500)
        proc = cli("read", "ev", "--tcp", f"{host}:{port}", "motor_state", "digital_speed[1]", "net_in",
                   "rs485_comm_settings")
    assert proc.returncode == 0, proc.stderr
    lines = {line.split("│")[1].strip(): line for line in proc.stdout.splitlines() if line.count("│") > 3}
    assert "RUN" in lines["motor_state"] and "2: RUN" in lines["motor_state"]  # X0 started the motor
    speed = lines["digital_speed[1]"]
    assert "1500" in speed and "r/min" in speed and "0x05DC" in speed and "0x0309" in speed and "03-10" in speed
    assert "X0|X2" in lines["net_in"] and "NET-X0" in lines["net_in"] and "0x1400" in lines["net_in"]
    assert "parity:NONE" in lines["rs485_comm_settings"]
    assert "in 3 requests" in proc.stdout or "in 4 requests" in proc.stdout


def test_read_json_csv_group_and_other_pages() -> None:
    with tcp_server("ev") as (sim, host, port):
        sim.set("bus_voltage", 48.2)
        as_json = cli("read", "ev", "--tcp", f"{host}:{port}", "bus_voltage", "digital_speed", "--json")
        as_csv = cli("read", "ev", "--tcp", f"{host}:{port}", "--group", "monitor", "--csv")
        other_page = cli("read", "ev", "--tcp", f"{host}:{port}", "xh_duty")
        switched = cli("read", "ev", "--tcp", f"{host}:{port}", "xh_duty", "--switch-pages", "--json")
        assert sim.get("watch_data_select") == 0  # put back after switching
    doc = json.loads(as_json.stdout)
    assert doc["model"] == "ev" and doc["requests"] >= 2
    values = {r["name"]: r for r in doc["registers"]}
    assert values["bus_voltage"]["value"] == 48.2 and values["bus_voltage"]["unit"] == "V"
    assert values["bus_voltage"]["raw"] == 4820 and len([n for n in values if n.startswith("digital_speed[")]) == 8
    rows = list(csv.DictReader(io.StringIO(as_csv.stdout)))
    assert {"motor_state", "bus_voltage"} <= {r["name"] for r in rows}
    assert "xh_duty" not in {r["name"] for r in rows}  # page 1: skipped, and said so
    assert "--switch-pages" in as_csv.stderr
    assert other_page.returncode == 1 and "xh_duty is on page 1 of watch_data_select" in other_page.stderr
    assert switched.returncode == 0 and json.loads(switched.stdout)["registers"][0]["name"] == "xh_duty"


def test_read_over_virtual_serial_rtu_and_ascii() -> None:
    for mode in ("rtu", "ascii"):
        with serial_server("ev", mode, units=(3,), baudrate=38400) as (sim, line):
            sim.set("digital_speed_ram[2]", 777, unit=3)
            proc = cli("read", "ev", "--serial", line.master_port, "--mode", mode, "--baudrate", "38400",
                       "--unit", "3", "digital_speed_ram[2]", "--json")
        assert proc.returncode == 0, (mode, proc.stderr)
        doc = json.loads(proc.stdout)
        assert doc["registers"][0]["value"] == 777 and doc["link"].startswith(f"serial {line.master_port} {mode} 38400")


def test_read_bad_names_are_located_errors() -> None:
    proc = cli("read", "ev", "--tcp", "127.0.0.1:9", "digital_sped", "alarm_reset", "digital_speed[9]")
    no_traceback(proc)
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if ": error:" in line]
    assert errors[0].startswith("<command line>:1:") and "did you mean digital_speed" in errors[0]


def test_write_engineering_values_reflect_and_read_back() -> None:
    with tcp_server("ev") as (sim, host, port):
        proc = cli("write", "ev", "--tcp", f"{host}:{port}", "digital_speed[0]=1500", "net_in=X0|X2",
                   "net_x_input_function[2]=free", "rs485_comm_settings=parity:EVEN,stop_bits:0,data_bits:0")
        assert proc.returncode == 0, proc.stderr
        assert sim.get("digital_speed[0]") == 1500 and sim.get_raw("net_in") == 5
        assert sim.get_raw("net_x_input_function[2]") == 5 and sim.get_raw("rs485_comm_settings") == 2
        assert sim.unit().effective_raw("net_x_input_function[2]") != 5  # not applied yet
        applied = cli("write", "ev", "--tcp", f"{host}:{port}", "net_x_input_function[2]=FREE", "--apply")
        assert applied.returncode == 0, applied.stderr
        assert sim.unit().effective_raw("net_x_input_function[2]") == 5
    rows = {line.split("│")[1].strip(): line for line in proc.stdout.splitlines() if line.count("│") > 3}
    assert "1500 r/min" in rows["digital_speed[0]"] and "now" in rows["digital_speed[0]"]
    assert "EEPROM" in rows["digital_speed[0]"]
    assert "after the Configuration command (--apply sends it)" in rows["net_x_input_function[2]"]
    assert "Configuration sent" in applied.stdout


def test_write_checks_every_value_before_sending_anything() -> None:
    # port 9 on loopback has no server: exit 1 (values) rather than 2 (unreachable) proves nothing was sent
    proc = cli("write", "ev", "--tcp", "127.0.0.1:9", "digital_speed[0]=99999", "net_in=X9", "sc_cc_mode=cc",
               "motor_speed=5", "bus_voltage")
    no_traceback(proc)
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if ": error:" in line]
    assert len(errors) == 5, proc.stderr
    assert "above the maximum 10000 r/min" in errors[0] and errors[0].startswith("<command line>:1:")
    assert f"maps/ev.yaml:{map_line('digital_speed')}:5: note: digital_speed is defined here" in proc.stderr
    assert "'X9' is not a bit of NetIn" in proc.stderr and "'cc' is not a value of ScCcMode" in proc.stderr
    assert "motor_speed is read-only" in proc.stderr and "write NAME=VALUE" in proc.stderr
    no_apply = cli("write", "vfd1000", "--tcp", "127.0.0.1:9", "--apply", "parameter_0008=1")
    assert no_apply.returncode == 1 and "no Configuration command" in no_apply.stderr, no_apply.stderr


def test_write_dry_run_prints_the_manuals_frames() -> None:
    proc = cli("write", "ev", "--serial", "/dev/null", "--baudrate", "9600", "--dry-run",
               "digital_speed_ram=2000,2000,2000,2000,2000,2000,2000,2000")
    assert proc.returncode == 0, proc.stderr
    assert "nothing sent" in proc.stdout and "write multiple registers (10h) at 0x3F08, 8 words" in proc.stdout
    frame = proc.stdout.split("RTU: ")[1].split()[:6]
    assert frame == ["01", "10", "3F", "08", "00", "08"]
    one = cli("write", "ev", "--tcp", "127.0.0.1:9", "--unit", "2", "--dry-run", "net_in=X0")
    assert "TCP: 00 01 00 00 00 06 02 06 14 00 00 01" in one.stdout, one.stdout
    ascii_frame = cli("write", "ev", "--serial", "/dev/null", "--baudrate", "9600", "--mode", "ascii",
                      "--dry-run", "net_in=X0")
    assert r"ASCII: :010614000001E4\r\n" in ascii_frame.stdout, ascii_frame.stdout
