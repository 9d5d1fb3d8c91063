"""`drivemap scan`: unit ids over TCP, baud rate over a virtual serial line, which maps fit, Ctrl-C."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from helpers_client import simulator, tcp_server
from helpers_live import ENV, ROOT, cli

from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import VirtualSerialLine


def test_scan_tcp_finds_units_and_the_map_that_fits() -> None:
    with tcp_server("vfd1000", units=(3, 7)) as (_, host, port):
        proc = cli("scan", "--tcp", f"{host}:{port}", "--units", "1-9", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert [u["unit"] for u in doc["units"]] == [3, 7] and doc["probes"] == 9
    for unit in doc["units"]:
        fits = {f["model"]: f["fits"] for f in unit["fits"]}
        assert fits["vfd1000"] is True
        assert not any(fit for model, fit in fits.items() if model != "vfd1000"), fits
        assert {"ev", "v2", "edx", "sdm630", "fronius_symo_hybrid"} <= set(fits)
    assert "at most 9 probes" in proc.stderr


def test_scan_serial_finds_the_baud_rate_and_notes_garbled_parity() -> None:
    sim = simulator("ev", (2,))
    with VirtualSerialLine(19200, line_settings=True) as line:
        with ThreadedSimServer(sim, serial=line.device_port, mode="rtu", baudrate=19200, parity="none"):
            proc = cli("scan", "--serial", line.master_port, "--units", "1-3", "--baudrates", "9600,19200,38400",
                       "--parities", "none", "--timeout", "0.1")
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if line.startswith("│ 2 "))
    assert "rtu 19200 8N1" in row and "ev fits" in row
    assert "38400" not in proc.stdout  # stops at the first setting that answers
    with VirtualSerialLine(19200, device_parity="O") as line:  # the drive at 8O1; this port cannot do odd
        with ThreadedSimServer(simulator("ev", (2,)), serial=line.device_port, mode="rtu", baudrate=19200,
                               parity="none"):
            garbled = cli("scan", "--serial", line.master_port, "--units", "1-3", "--baudrates", "9600,19200",
                          "--parities", "none", "--timeout", "0.1")
    assert garbled.returncode == 3, garbled.stderr
    assert "garbled replies on serial" in garbled.stdout and "19200 8N1" in garbled.stdout
    assert "no unit answered" in garbled.stdout


def test_scan_is_interruptible_and_prints_what_it_found() -> None:
    with tcp_server("ev", units=(1,)) as (_, host, port):
        proc = subprocess.Popen([sys.executable, "-m", "drivemap", "scan", "--tcp", f"{host}:{port}", "--units",
                                 "1-200", "--timeout", "0.2"], cwd=ROOT, env=ENV, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        assert proc.stderr is not None
        assert proc.stderr.readline().startswith("scanning 200 unit ids")  # started (slow under load)
        time.sleep(2.0)  # unit 1 answers at once; the silent ones take 0.2 s each
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "interrupted after" in out and "found so far" in out
    assert any(line.startswith("│ 1 ") for line in out.splitlines()), out


def test_scan_names_the_option_as_typed() -> None:
    for option in ("--unit", "--units"):
        proc = cli("scan", "--tcp", "127.0.0.1:1", option, "999")
        assert proc.returncode == 1, proc.stderr
        assert proc.stderr.strip() == f"drivemap scan: error: {option}: unit ids are 0..255, not '999'", proc.stderr


def test_scan_in_a_folder_without_maps_compares_the_shipped_maps_reading_each_request_once(tmp_path: Path) -> None:
    with tcp_server("sdm630") as (sim, host, port):
        pdus: list[bytes] = []
        handle = sim.handle

        def recording(unit: int, pdu: bytes, **kw: Any) -> Any:
            pdus.append(pdu)
            return handle(unit, pdu, **kw)

        sim.handle = recording
        proc = cli("scan", "--tcp", f"{host}:{port}", "--unit", "1", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    shipped = 10 + len(list((ROOT / "maps" / "catalogue").rglob("*.yaml")))  # the seed maps and the catalogue
    assert f"the project has no maps: comparing with the {shipped} maps shipped with drivemap" in proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["maps"] == "shipped"
    (unit,) = doc["units"]
    assert unit["fits"][0]["model"] == "sdm630" and unit["fits"][0]["fits"] is True
    # other maps may fit too (the catalogue's Eastron meters share sdm630's registers): ranked after it
    assert "sdm630" in [f["model"] for f in unit["fits"] if f["fits"]]
    assert len(unit["fits"]) == shipped
    assert {p[0] for p in pdus} <= {1, 2, 3, 4}  # reads only
    judged = pdus[1:]  # after the probe read: the maps' reads, each distinct one sent once for all of them
    assert len(judged) == unit["reads"] and len(set(judged)) == len(judged), judged


def test_scan_suggests_shipped_maps_when_none_of_the_projects_fits(tmp_path: Path) -> None:
    """A project holding only the ev map scans an sdm630: ev does not fit, so the maps drivemap ships
    (seed and catalogue) that the project does not override are weighed, and sdm630 is suggested first;
    the project's own map of an id is never replaced by a shipped one."""
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "ev.yaml").write_bytes((ROOT / "maps" / "ev.yaml").read_bytes())
    with tcp_server("sdm630") as (sim, host, port):
        codes: list[int] = []
        handle = sim.handle

        def recording(unit: int, pdu: bytes, **kw: Any) -> Any:
            codes.append(pdu[0])
            return handle(unit, pdu, **kw)

        sim.handle = recording
        proc = cli("scan", "--tcp", f"{host}:{port}", "--unit", "1", "--json", cwd=tmp_path)
        text = cli("scan", "--tcp", f"{host}:{port}", "--unit", "1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (unit,) = json.loads(proc.stdout)["units"]
    assert [f["model"] for f in unit["fits"]] == ["ev"] and not unit["fits"][0]["fits"]
    suggested = [f["model"] for f in unit["suggested"]]
    assert suggested[0] == "sdm630" and "ev" not in suggested and all(f["fits"] for f in unit["suggested"])
    assert "none of the project's maps fits unit 1: weighing the" in proc.stderr
    assert set(codes) <= {1, 2, 3, 4}  # reads only
    assert "unit 1: maps shipped with drivemap that fit: sdm630 fits" in " ".join(text.stdout.split())


def test_scan_builds_a_client_package_only_for_the_maps_whose_values_it_reads(tmp_path: Path) -> None:
    """Weighing many maps: a map whose first read is refused gets no client package (its raw reads run
    on the spec), and its runtime spec comes from the compile cache on the next run."""
    from drivemap import cache
    from drivemap.device.connection import Link, open_bus
    from drivemap.device.target import load_target, spec_of
    from drivemap.live.fingerprint import SharedReads, fingerprint

    with cache.disabled(False), tcp_server("sdm630") as (_, host, port):
        targets = [load_target(name) for name in ("sdm630", "ev", "vfd1000")]
        assert all(t._package is None for t in targets)  # nothing built by loading
        bus = open_bus(Link("tcp", host=host, port=port, unit=1, timeout=0.3))
        try:
            reads = SharedReads(bus)
            fits = {t.model.name: fingerprint(bus, t, 1, reads) for t in targets}
        finally:
            bus.close()
        assert fits["sdm630"].fits and not fits["ev"].fits and not fits["vfd1000"].fits
        assert fits["ev"].answered == 0 and targets[1]._package is None and targets[2]._package is None
        again = load_target("ev")
        assert again.model.cache_key is not None and cache.load("spec", again.model.cache_key) == again.spec
        assert spec_of(again.model) == targets[1].spec
