"""Every command line of tests/corpora/cli_hostile.json ends in exit 1 and a located error, never a
traceback or a hang (each runs as the real command, bounded in time)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.corpora import hostile_docs

ROOT = Path(__file__).resolve().parents[2]
CORPUS = json.loads((ROOT / "tests" / "corpora" / "cli_hostile.json").read_text(encoding="utf-8"))["cases"]


@pytest.fixture(scope="module")
def plant(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    work = tmp_path_factory.mktemp("hostile")
    env = _env()
    subprocess.run([sys.executable, "-m", "drivemap.cli", "new", "acme"], cwd=work, env=env, check=True,
                   capture_output=True, timeout=60)
    (work / "afile").write_text("a file\n", encoding="utf-8")
    (work / "adir").mkdir()
    os.mkfifo(work / "afifo")
    text = (work / "maps" / "acme.yaml").read_text(encoding="utf-8")
    assert "    unit: Hz\n" in text
    (work / "surrogate.yaml").write_text(text.replace("model: acme", "model: surrogate")
                                         .replace("    unit: Hz\n", '    unit: "Hz\\uDC80"\n', 1), encoding="utf-8")
    (work / "big.json").write_text('{"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": 1'
                                   + "0" * 5000 + "}}}", encoding="utf-8")
    (work / "np").mkdir()
    (work / "np" / "pyproject.toml").write_bytes(b'[tool.drivemap]\nmaps = "\xff\xfe"\n')
    (work / "pk").mkdir()
    (work / "pk" / "pyproject.toml").write_text('[tool.drivemap]\npackage = "class"\n', encoding="utf-8")
    docs = {"docxbomb": hostile_docs.docx_bomb(work / "bomb.docx", 256 << 20),
            "xlsxbomb": hostile_docs.xlsx_bomb(work / "bomb.xlsx", 256 << 20),
            "xlsxlie": hostile_docs.xlsx_bomb(work / "lie.xlsx", 256 << 20, lie=True),
            "xlsxrows": hostile_docs.xlsx_rows(work / "rows.xlsx", 300_000),
            "csvrows": hostile_docs.csv_rows(work / "rows.csv", 100_000),
            "longcell": hostile_docs.csv_long_cell(work / "long.csv"),
            "csvsmall": hostile_docs.csv_rows(work / "regs.csv", 3),
            "brokenpdf": hostile_docs.pdf_pages(work / "broken.pdf", 3, broken=True),
            "pdfbomb": hostile_docs.pdf_content_bomb(work / "bomb.pdf", 256 << 20)}
    for key, target in {"extpasswd": "/etc/passwd", "extup": "../../../../../../../../../etc/passwd",
                        "extzero": "/dev/zero"}.items():
        (work / f"{key}.yaml").write_text(f"drivemap: 2\nextends: {target}\ndevice: {{model: {key}, title: X}}\n",
                                          encoding="utf-8")
    return {"root": str(work), "file": "afile", "dir": "adir", "fifo": "afifo", "long": "a" * 300,
            "surrogate": "surrogate.yaml", "bigstate": "big.json", **{k: p.name for k, p in docs.items()},
            "extpasswd": "extpasswd.yaml", "extup": "extup.yaml", "extzero": "extzero.yaml"}


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "generator"), str(ROOT / "generated")]),
                PYTHONIOENCODING="utf-8")


def _fill(text: str, plant: dict[str, str], *, regex: bool = False) -> str:
    for key, value in plant.items():
        text = text.replace("{" + key + "}", re.escape(value) if regex else value)
    return text


@pytest.mark.parametrize("case", CORPUS, ids=[" ".join(c["argv"])[:60] for c in CORPUS])
def test_hostile_command_ends_in_a_located_error(plant: dict[str, str], case: dict[str, Any]) -> None:
    argv = [_fill(a, plant) for a in case["argv"]]
    cwd = Path(plant["root"]) / case.get("cwd", ".")
    proc = subprocess.run([sys.executable, "-m", "drivemap.cli", *argv], cwd=cwd, env=_env(), capture_output=True,
                          text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert proc.returncode == 1, proc.stderr[-2000:]
    ours = [line for line in proc.stderr.splitlines() if "error: " in line]  # pymodbus may log a line first
    assert ours and re.match(_fill(case["error"], plant, regex=True), ours[0]), proc.stderr[-2000:]
