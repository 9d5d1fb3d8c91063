"""`drivemap verify`: the map against simulators of deliberately wrong maps (another firmware), each
disagreement found with the map line it concerns; write-safe round trips restore every value and
never touch EEPROM unless asked."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from helpers_client import serial_server, simulator
from helpers_live import cli, map_line, simulate, wrong_map

from drivemap.runtime.sim.serve import ThreadedSimServer

SHIFTED = [("    address: 0x0200\n    param: \"02-01\"", "    address: 0x0201\n    param: \"02-01\""),
           ("  - start: 0x0201\n    end: 0x0201\n", "  - start: 0x0F01\n    end: 0x0F01\n")]  # 0x0201 no longer reserved
ACCEL_RAM = ("  - name: digital_accel_time_ram\n    address: 0x4000\n    label: \"數位加速時間 No.0 ~ No.7 (RAM)\"\n"
             "    description: RAM twin of digital_accel_time.\n    group: operation_data_ram\n    access: rw\n"
             "    count: 8\n    stride: 1\n    scale: 0.1\n")
SCALED = [(ACCEL_RAM, ACCEL_RAM.replace("scale: 0.1", "scale: 1"))]  # this firmware counts whole seconds
REFUSES_READ = [("    group: comm_parameters\n    access: rw\n    unit: ms\n    min: 0\n    max: 1000\n",
                 "    group: comm_parameters\n    access: w\n    unit: ms\n    min: 0\n    max: 1000\n")]


def _verify(port: int, tmp_path: Path, *extra: str) -> tuple[Any, dict[str, Any], str]:
    stem = tmp_path / "report"
    proc = cli("verify", "ev", "--tcp", f"127.0.0.1:{port}", "--report", str(stem), *extra)
    assert "Traceback" not in proc.stderr, proc.stderr
    doc = json.loads((tmp_path / "report.json").read_text(encoding="utf-8"))
    return proc, doc, (tmp_path / "report.md").read_text(encoding="utf-8")


def _disagreements(doc: dict[str, Any]) -> list[dict[str, Any]]:
    return [f for f in doc["findings"] if f["severity"] == "disagree"]


def test_the_right_map_agrees_and_the_report_says_so(tmp_path: Path) -> None:
    with simulate("ev") as port:
        proc, doc, md = _verify(port, tmp_path, "--write-safe")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert doc["agree"] and not _disagreements(doc) and doc["generator"] == "drivemap verify"
    assert doc["counts"]["read alone"] >= 100 and doc["counts"]["batch"] >= 10 and doc["counts"]["reserved"] == 8
    assert doc["counts"]["write-safe"] > 0
    assert md.startswith("<!-- written by drivemap verify -->") and "the map and the device agree" in md
    assert "map and device agree" in proc.stdout


@pytest.mark.parametrize("case", ["shifted address", "wrong scale", "answers 02h"])
def test_each_wrong_map_is_found_with_its_line(case: str, tmp_path: Path) -> None:
    edits = {"shifted address": SHIFTED, "wrong scale": SCALED, "answers 02h": REFUSES_READ}[case]
    device = wrong_map(tmp_path, case.replace(" ", "_"), edits)
    with simulate(str(device)) as port:
        proc, doc, md = _verify(port, tmp_path, "--write-safe")
    assert proc.returncode == 6, proc.stdout + proc.stderr
    found = _disagreements(doc)
    if case == "shifted address":
        hit = next(f for f in found if f["subject"] == "sc_cc_mode")
        assert hit["line"] == map_line("sc_cc_mode") and "exception 02h" in hit["device_says"]
        assert "answers at 0x0201 (+1)" in hit["hint"] and "shifted" in hit["hint"]
    elif case == "wrong scale":
        hits = [f for f in found if f["subject"].startswith("digital_accel_time_ram[") and f["check"] == "write-safe"]
        assert len(hits) == 8 and all(f["line"] == map_line("digital_accel_time_ram") for f in hits)
        assert "the map's max 10 s" in hits[0]["map_says"] and "refuses it: exception 04h" in hits[0]["device_says"]
    else:
        hit = next(f for f in found if f["subject"] == "rs485_timeout" and f["check"] == "read alone")
        assert hit["line"] == map_line("rs485_timeout") and "exception 02h illegal_data_address" in hit["device_says"]
    assert f"maps/ev.yaml:{found[0]['line']}" in md and "## Disagreements" in md
    assert not [f for f in found if f["check"] == "restore"]  # every written value was put back


class _Recording(simulator("ev").__class__):  # type: ignore[misc]
    """The ev simulator, noting every address a request writes."""

    written: list[int]

    def _write(self, unit: Any, address: int, words: list[int], broadcast: bool) -> None:
        self.written.extend(range(address, address + len(words)))
        super()._write(unit, address, words, broadcast)


@pytest.mark.parametrize("eeprom", [False, True])
def test_write_safe_restores_and_leaves_eeprom_alone(eeprom: bool, tmp_path: Path) -> None:
    sim = _Recording(units=[1])
    sim.written = []
    sim.set("digital_speed_ram[3]", 1111)
    before = {c: sim.get(c) for c in ("digital_speed_ram[3]", "digital_speed[0]", "digital_accel_time_ram[0]")}
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        extra = ("--write-safe", "--eeprom") if eeprom else ("--write-safe",)
        proc, doc, _ = _verify(server.address[1], tmp_path, *extra)
    assert proc.returncode == 0, proc.stdout
    assert {c: sim.get(c) for c in before} == before
    spec = sim.spec
    eeprom_addresses = {r.element_address(i) for r in spec.registers if r.storage == "eeprom" for i in range(r.count)}
    ram_addresses = {r.element_address(i) for r in spec.registers if r.storage == "ram" for i in range(r.count)}
    assert set(sim.written) & ram_addresses
    assert bool(set(sim.written) & eeprom_addresses) == eeprom


def test_verify_over_a_virtual_serial_line_and_refuses_foreign_report(tmp_path: Path) -> None:
    with serial_server("ev", "rtu", baudrate=115200) as (_, line):
        proc = cli("verify", "ev", "--serial", line.master_port, "--baudrate", "115200", "--report",
                   str(tmp_path / "serial"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert json.loads((tmp_path / "serial.json").read_text())["link"].startswith("unit 1 on serial")
    (tmp_path / "mine.md").write_text("my notes\n")
    refused = cli("verify", "ev", "--tcp", "127.0.0.1:9", "--report", str(tmp_path / "mine"))
    assert refused.returncode == 1 and "not written by drivemap verify; not overwritten" in refused.stderr
    assert (tmp_path / "mine.md").read_text() == "my notes\n"
