"""The 32 MiB file limit does not bound building by itself: the number of YAML values and of
registers is bounded before anything big is built (the real command, in 1 GiB and 60 s)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from drivemap.frontend.load import MAX_NODES, MAX_REGISTERS
from tests.frontend.test_bad_maps import ROOT, _limited

BASE = (ROOT / "tests" / "bad_maps" / "bad_access_mode.yaml").read_text(encoding="utf-8").replace(
    "    access: ro\n", "    access: rw\n").replace("model: bad_access_mode", "model: big")


def _validate(path: Path) -> tuple[subprocess.CompletedProcess[str], float]:
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "drivemap.cli", "validate", str(path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, preexec_fn=_limited)
    return proc, time.monotonic() - started


def test_more_yaml_values_than_the_bound_are_refused_before_building(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_text(BASE + "notes_flood: [" + "0," * (MAX_NODES + 10) + "0]\n", encoding="utf-8")
    proc, took = _validate(big)
    assert proc.returncode == 1, proc.stderr[-500:]
    assert "Traceback" not in proc.stderr and "MemoryError" not in proc.stderr
    first = proc.stderr.splitlines()[0]
    assert first.startswith(f"{big}:") and f"more than {MAX_NODES:,} YAML values" in first, first
    assert took < 55


def test_more_registers_than_the_bound_are_refused_before_validation(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    extra = "".join(f"  - {{name: r{i}, address: {i % 65536}, group: monitor, access: r, source: \"s\"}}\n"
                    for i in range(MAX_REGISTERS + 1))
    big.write_text(BASE.replace("registers:\n", "registers:\n" + extra, 1), encoding="utf-8")
    proc, took = _validate(big)
    assert proc.returncode == 1, proc.stderr[-500:]
    first = proc.stderr.splitlines()[0]
    assert f"more than {MAX_REGISTERS:,} registers" in first, first
    assert took < 55
