"""drivemap compare: the disagreements of two maps of one device (a copy of sdm630 with changed facts)."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivemap.cli import main

ROOT = Path(__file__).resolve().parent.parent


def test_compare_lists_changed_scale_and_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8")
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(ROOT / "maps" / "sdm630.yaml")]) == 0
    assert "0 disagreements" in capsys.readouterr().out
    changed = text.replace("  model: sdm630\n", "  model: other\n", 1).replace("unit: V\n", "unit: kV\n", 1).replace("unit: \"V\"\n", "unit: kV\n", 1)
    other = tmp_path / "other.yaml"
    other.write_text(changed, encoding="utf-8")
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(other)]) == 0
    out = capsys.readouterr().out
    assert "unit: " in out and "= V | " in out and "= kV" in out and "1 disagreement " in out
