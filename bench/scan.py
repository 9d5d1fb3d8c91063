"""Identify a device among many maps: `drivemap scan` of one simulated sdm630 against the 10 shipped maps,
and against them plus 100 synthetic variant maps.

The catalogue is not merged yet: the 100 variants are renamed copies of the 9 other shipped maps
(`model: ev_syn_07` ...), so they are real, compilable maps that do not fit the sdm630, as catalogue maps
of other devices would not. The generated sdm630 simulator runs on 127.0.0.1 in this process (every
request PDU recorded); the verb runs in a subprocess, `python -m drivemap scan --tcp HOST:PORT --unit 1
--json --maps FOLDER`, timed end to end (interpreter start, compiling every map, the reads). Also
measured: the reads sent to judge the maps (each distinct read once for all of them) against the reads
the maps' fingerprints ask for, and the default unit sweep (1-247 at 0.1 s each, the line's cost).

    python bench/scan.py
"""

from __future__ import annotations

import json
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
VARIANTS = 100


def shipped() -> list[Path]:
    from drivemap.compiler import bundled_maps

    return bundled_maps()


def variants(folder: Path, count: int) -> None:
    """``count`` renamed copies of the shipped maps other than the device's, into ``folder``."""
    others = [p for p in shipped() if p.stem != DEVICE]
    for i in range(count):
        base = others[i % len(others)]
        name = f"{base.stem}_syn_{i:03d}"
        text = base.read_text(encoding="utf-8").replace(f"\n  model: {base.stem}\n", f"\n  model: {name}\n", 1)
        (folder / f"{name}.yaml").write_text(text, encoding="utf-8")


def scan(folder: Path, units: str = "1") -> dict[str, Any]:
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
                               "--json", "--maps", str(folder)], capture_output=True, text=True, timeout=900, cwd=ROOT)
        seconds = time.perf_counter() - started
    if proc.returncode != 0:
        raise RuntimeError(f"drivemap scan exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    doc = json.loads(proc.stdout)
    unit = doc["units"][0]
    fits = unit["fits"]
    return {"seconds": seconds, "first": fits[0]["model"], "first_fits": fits[0]["fits"], "maps": len(fits),
            "fit": [f["model"] for f in fits if f["fits"]], "reads": unit["reads"],
            "asked": sum(f["requests"] for f in fits), "pdus": len(pdus), "writes": sum(p[0] > 4 for p in pdus)}


def compile_seconds(folder: Path) -> float:
    """The in-process compile of every map of ``folder`` (what scan spends before its first read)."""
    code = ("import sys,time; from pathlib import Path; from drivemap.compiler import compile_map; "
            "t=time.perf_counter(); [compile_map(p) for p in sorted(Path(sys.argv[1]).glob('*.yaml'))]; "
            "print(time.perf_counter()-t)")
    proc = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, timeout=900,
                          cwd=ROOT, check=True)
    return float(proc.stdout.strip())


def _rows(section: Section, name: str, r: dict[str, Any], goal: float, compiled: float) -> None:
    right = r["first"] == DEVICE and r["first_fits"]
    section.rows.append(Row(TITLE, f"{name}: scan time", r["seconds"] / goal, f"<= {goal:g} s", r["seconds"] <= goal,
                            f"{r['seconds']:.2f} s end to end ({r['maps']} maps; compiling them alone: {compiled:.2f} s)"))
    section.rows.append(Row(TITLE, f"{name}: right map first", None, DEVICE, right,
                            f"first {r['first']}; maps that fit: {', '.join(r['fit']) or 'none'}"))
    section.rows.append(Row(TITLE, f"{name}: reads sent to judge the maps", None, "reads only", r["writes"] == 0,
                            f"{r['reads']} reads for {r['maps']} maps (each distinct read once for all, a map stops at "
                            f"its first refused read); {r['pdus']} requests in all, {r['writes']} writes"))


def run(quick: bool = False) -> Section:
    section = Section(TITLE)
    with tempfile.TemporaryDirectory(prefix="drivemap-scan-") as tmp:
        ten, many = Path(tmp) / "shipped", Path(tmp) / "many"
        ten.mkdir()
        many.mkdir()
        for path in shipped():
            shutil.copy(path, ten / path.name)
            shutil.copy(path, many / path.name)
        variants(many, VARIANTS)
        small = scan(ten)
        _rows(section, "10 shipped maps", small, 2.0, compile_seconds(ten))
        big = scan(many)
        _rows(section, f"10 shipped + {VARIANTS} synthetic maps", big, 5.0, compile_seconds(many))
        if not quick:
            wide = scan(ten, "1-247")
            section.rows.append(Row(TITLE, "10 shipped maps, default unit ids 1-247", None, "-", None,
                                    f"{wide['seconds']:.1f} s: 246 silent unit ids x the 0.1 s probe timeout "
                                    "(the line's cost, not identification)"))
    section.detail = [f"The catalogue is not merged: the {VARIANTS} synthetic maps are renamed copies of the 9 shipped "
                      "maps other than the sdm630's. Compile time is measured on its own (the compile cache is "
                      "another change); the rest of the scan time is interpreter start and the reads."]
    return section


def main() -> int:
    return print_section(run())


if __name__ == "__main__":
    sys.exit(main())
