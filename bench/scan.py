"""Identify a device among many maps: `drivemap scan` of one simulated sdm630 against the 10 shipped maps,
and against them plus the catalogue (every map of `maps/catalogue/`, 261 imported maps of other devices,
among them other meters that answer the same addresses).

The generated sdm630 simulator runs on 127.0.0.1 in this process (every request PDU recorded); the verb
runs in a subprocess, `python -m drivemap scan --tcp HOST:PORT --unit 1 --json --maps FOLDER`, timed end
to end (interpreter start, compiling or loading every map, the reads), with a compile cache of its own:
the first run fills it (cold), the second reuses it (warm, what a user sees from the second scan on; the
goal). Also measured: the reads sent to judge the maps (each distinct read once for all of them) against
the reads the maps' fingerprints ask for, and the default unit sweep (1-247 at 0.1 s each, the line's
cost).

    python bench/scan.py
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section, print_section  # noqa: E402

TITLE = "Scan: identify a device among many maps"
DEVICE = "sdm630"


def shipped() -> list[Path]:
    from drivemap.compiler import bundled_maps

    return bundled_maps()


def catalogue() -> list[Path]:
    """Every catalogue map (``maps/catalogue/<source>/*.yaml``)."""
    return sorted((ROOT / "maps" / "catalogue").rglob("*.yaml"))


def scan(folder: Path, cache: Path, units: str = "1") -> dict[str, Any]:
    import importlib

    from drivemap.runtime.sim.serve import ThreadedSimServer

    sim = importlib.import_module(f"drivemap_models.{DEVICE}.simulator").Simulator(units=[1])
    pdus: list[bytes] = []
    handle = sim.handle

    def recording(unit: int, pdu: bytes, **kw: Any) -> Any:
        pdus.append(pdu)
        return handle(unit, pdu, **kw)

    sim.handle = recording
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        started = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "drivemap", "scan", "--tcp", f"{host}:{port}", "--units", units,
                               "--json", "--maps", str(folder)], capture_output=True, text=True, timeout=900, cwd=ROOT,
                              env=dict(os.environ, DRIVEMAP_CACHE_DIR=str(cache)))
        seconds = time.perf_counter() - started
    if proc.returncode != 0:
        raise RuntimeError(f"drivemap scan exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    doc = json.loads(proc.stdout)
    unit = doc["units"][0]
    fits = unit["fits"]
    return {"seconds": seconds, "first": fits[0]["model"], "first_fits": fits[0]["fits"], "maps": len(fits),
            "fit": [f["model"] for f in fits if f["fits"]][:8], "reads": unit["reads"],
            "asked": sum(f["requests"] for f in fits), "pdus": len(pdus), "writes": sum(p[0] > 4 for p in pdus)}


def _rows(section: Section, name: str, r: dict[str, Any], goal: float, cold: dict[str, Any]) -> None:
    right = r["first"] == DEVICE and r["first_fits"] and cold["first"] == DEVICE
    section.rows.append(Row(TITLE, f"{name}: scan time", r["seconds"] / goal, f"<= {goal:g} s", r["seconds"] <= goal,
                            f"{r['seconds']:.2f} s end to end, compile cache warm ({r['maps']} maps; the first run, "
                            f"cache cold: {cold['seconds']:.2f} s)"))
    section.rows.append(Row(TITLE, f"{name}: right map first", None, DEVICE, right,
                            f"first {r['first']}; maps that fit: {', '.join(r['fit']) or 'none'}"
                            f"{' ...' if len(r['fit']) == 8 else ''}"))
    section.rows.append(Row(TITLE, f"{name}: reads sent to judge the maps", None, "reads only", r["writes"] == 0,
                            f"{r['reads']} reads for {r['maps']} maps (each distinct read once for all, a map stops at "
                            f"its first refused read); {r['pdus']} requests in all, {r['writes']} writes"))


def run(quick: bool = False) -> Section:
    section = Section(TITLE)
    listed = catalogue()
    with tempfile.TemporaryDirectory(prefix="drivemap-scan-") as tmp:
        ten, many = Path(tmp) / "shipped", Path(tmp) / "many"
        ten.mkdir()
        many.mkdir()
        for path in shipped():
            shutil.copy(path, ten / path.name)
            shutil.copy(path, many / path.name)
        for path in listed:
            (many / path.parent.name).mkdir(exist_ok=True)
            shutil.copy(path, many / path.parent.name / path.name)
        for name, folder, goal in (("10 shipped maps", ten, 2.0),
                                   (f"10 shipped + {len(listed)} catalogue maps", many, 5.0)):
            cache = Path(tmp) / f"cache-{folder.name}"
            cold = scan(folder, cache)
            _rows(section, name, scan(folder, cache), goal, cold)
        if not quick:
            wide = scan(ten, Path(tmp) / "cache-shipped", "1-247")
            section.rows.append(Row(TITLE, "10 shipped maps, default unit ids 1-247", None, "-", None,
                                    f"{wide['seconds']:.1f} s: 246 silent unit ids x the 0.1 s probe timeout "
                                    "(the line's cost, not identification)"))
    section.detail = ["Each scan runs with a compile cache of its own: cold is the first run (every map compiled), "
                      "warm the second (models and runtime specs from the cache; a map's client package is built "
                      "only when its values are read)."]
    return section


def main() -> int:
    return print_section(run())


if __name__ == "__main__":
    sys.exit(main())
