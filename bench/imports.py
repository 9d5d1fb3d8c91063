"""(8) Import time of a generated client: synthetic maps of 100 / 1k / 10k / 50k registers.

Each size is built once (``compile_map`` + ``render_tree`` + ``write_tree`` into a temporary
folder); then each round imports ``<package>.client`` in a fresh interpreter, twice per size and
round, interleaved across sizes:

* **cold**: ``python -B`` with no ``__pycache__`` (the source is compiled to bytecode on import);
* **cached**: after a first import wrote ``__pycache__`` (what every later start of a program sees).

The figure is the import alone (``time.perf_counter`` around ``importlib.import_module`` inside the
child; drivemap's runtime and pymodbus are imported first and not counted). Median and min–max over
the rounds.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from common import ROOT, Row, Section, median, spread

SIZES_FULL = (100, 1000, 10000, 50000)
SIZES_QUICK = (100, 1000)
GOAL_S = 0.25  # 10k registers, cached (issue 37)
CHILD = """
import importlib, json, sys, time
sys.path.insert(0, sys.argv[1])
import drivemap.runtime.client.api.sync_client, drivemap.runtime.sim.simulator  # shared by every map: not counted
t0 = time.perf_counter()
mod = importlib.import_module(sys.argv[2] + ".client")
t1 = time.perf_counter()
client = mod.Client.__new__(mod.Client)
print(json.dumps({"import_s": t1 - t0}))
"""


def build(folder: Path, size: int) -> tuple[str, str]:
    """Write the package of a synthetic map of ``size`` registers under ``folder``; its name."""
    from synthetic import write_synthetic

    from drivemap.build import render_tree, write_tree
    from drivemap.compiler import compile_map

    model = compile_map(write_synthetic(folder, size))
    write_tree(folder / "out", render_tree([model]), force=True)
    pkg = next(p for p in (folder / "out").rglob("client.py")).parent
    return str(pkg.parent), pkg.name


def _child(path: str, package: str, cached: bool) -> float:
    pkg = Path(path) / package
    if not cached:
        for cache in pkg.rglob("__pycache__"):
            shutil.rmtree(cache)
    cmd = [sys.executable] + ([] if cached else ["-B"]) + ["-c", CHILD, path, package]
    env = dict(os.environ, PYTHONHASHSEED="0")
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # the cached rounds need __pycache__ (cold ones run with -B)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=str(ROOT), env=env, check=True)
    return float(json.loads(proc.stdout.strip().splitlines()[-1])["import_s"])


def run(quick: bool, sizes: tuple[int, ...] | None = None, rounds: int | None = None) -> Section:
    sec = Section("Import time of a generated client")
    sizes = sizes or (SIZES_QUICK if quick else SIZES_FULL)
    rounds = rounds or (2 if quick else 5)
    results: dict[tuple[int, bool], list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="drivemap-imports-") as tmp:
        built: dict[int, tuple[str, str]] = {}
        for size in sizes:
            folder = Path(tmp) / f"s{size}"
            folder.mkdir()
            built[size] = build(folder, size)
        for size in sizes:  # the first import writes __pycache__ (not counted)
            _child(*built[size], cached=True)
        for i in range(rounds):
            order = sizes if i % 2 == 0 else tuple(reversed(sizes))
            for size in order:
                for cached in ((False, True) if i % 2 == 0 else (True, False)):
                    results.setdefault((size, cached), []).append(_child(*built[size], cached=cached))
                    if not cached:
                        _child(*built[size], cached=True)  # restore __pycache__ for the cached rounds
    sec.detail.append("| registers | cold import (s), no bytecode cache | cached import (s) | cached µs/register "
                      "| rounds |")
    sec.detail.append("|---:|---:|---:|---:|---:|")
    per_reg: dict[int, float] = {}
    for size in sizes:
        cold, warm = results[(size, False)], results[(size, True)]
        per_reg[size] = median(warm) / size * 1e6
        sec.detail.append(f"| {size} | {median(cold):.3f} ({spread(cold)}) | {median(warm):.3f} ({spread(warm)}) "
                          f"| {per_reg[size]:.0f} | {len(warm)} |")
    if 10000 in sizes:
        warm = median(results[(10000, True)])
        sec.rows.append(Row("8 import", "import of a 10k-register client (cached)", warm / GOAL_S, f"≤ {GOAL_S:g} s",
                            warm <= GOAL_S, f"{warm:.3f} s; cold {median(results[(10000, False)]):.3f} s"))
    small, large = sizes[0], sizes[-1]
    ratio = per_reg[large] / per_reg[small]
    sec.rows.append(Row("8 import", f"import cost/register {large} vs {small} regs (cached)", ratio, "≤ 1.3× (linear)",
                        ratio <= 1.3, f"{per_reg[large]:.0f} vs {per_reg[small]:.0f} µs/reg"))
    return sec


def main(argv: list[str]) -> None:
    sizes = tuple(int(a) for a in argv if a.isdigit()) or None
    s = run("--quick" in argv, sizes, 2 if "--quick" in argv else None)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)


if __name__ == "__main__":
    main(sys.argv[1:])
