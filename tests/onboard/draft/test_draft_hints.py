"""``drivemap draft`` options a person gives: ``--sheet`` (one sheet of a workbook; the sheets tried are
named when none holds a register table), ``--assume FIELD=VALUE`` and ``--address-base`` (refused when
malformed, recorded in the written map)."""

from __future__ import annotations

from pathlib import Path

import openpyxl
import pytest
import yaml

from drivemap.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def workbook(path: Path) -> Path:
    book = openpyxl.Workbook()
    notes = book.active
    assert notes is not None
    notes.title = "Notes"
    notes.append(["Revision history"])
    notes.append(["V1.0", "first issue"])
    regs = book.create_sheet("Registers")
    regs.append(["Address", "Name", "Type", "Unit"])
    regs.append([100, "Voltage", "", "V"])
    regs.append([101, "Current", "U16", "A"])
    book.save(path)
    return path


def test_sheet_picks_one_and_names_the_others(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    book = workbook(tmp_path / "vendor.xlsx")
    code, _, err = run(capsys, "draft", str(book), "--sheet", "Notes", "-o", "notes.yaml")
    assert code == 1 and "no register table found" in err and "tried sheet Notes (--sheet NAME picks one)" in err
    code, _, err = run(capsys, "draft", str(book), "--sheet", "Nope", "-o", "nope.yaml")
    assert code == 1 and "--sheet 'Nope': the workbook has no such sheet (its sheets: 'Notes', 'Registers')" in err
    code, out, err = run(capsys, "draft", str(book), "--sheet", "Registers", "--assume", "table=input",
                         "--assume", "type=s16", "-o", "vendor.yaml")
    assert code == 0, err
    data = yaml.safe_load((tmp_path / "vendor.yaml").read_text(encoding="utf-8"))
    regs = {r["name"]: r for r in data["registers"]}
    assert regs["voltage"]["table"] == "input" and regs["voltage"]["type"] == "s16"
    assert "source: assumed by the user (--assume type=s16)" in regs["voltage"]["notes"]
    assert regs["current"]["type"] == "u16"  # the sheet states it
    assert "--assume table=input, --assume type=s16" in data["device"]["notes"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vendor.xlsx", "vendor.yaml"]


@pytest.mark.parametrize(("argv", "message"), [
    (["--assume", "table"], "--assume 'table': give FIELD=VALUE, FIELD one of table, type, word_order"),
    (["--assume", "colour=red"], "FIELD one of table, type, word_order"),
    (["--assume", "table=registers"], "--assume 'table=registers': table is one of holding, input, coil, discrete"),
    (["--assume", "type=u16", "--assume", "type=f32"], "--assume type=u16 and type=f32: one value per field"),
])
def test_malformed_hints_are_refused_and_nothing_written(argv: list[str], message: str, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    book = workbook(tmp_path / "vendor.xlsx")
    code, _, err = run(capsys, "draft", str(book), *argv, "-o", "vendor.yaml")
    assert code == 1 and message in err and "Traceback" not in err, err
    assert not (tmp_path / "vendor.yaml").exists()
