"""drivemap compare: the disagreements of two maps of one device (a copy of sdm630 with changed facts)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from drivemap.cli import main

ROOT = Path(__file__).resolve().parents[2]


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


def _edit(tmp_path: Path, name: str, text: str, *edits: tuple[str, str]) -> Path:
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_compare_lists_type_word_order_scale_table_and_address(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8")
    p1 = "    register: 30001\n    param: \"1\"\n    group: measurements\n    type: f32\n    word_order: high_first\n"
    p2 = "    register: 30003\n    param: \"2\"\n    group: measurements\n    type: f32\n    word_order: high_first\n"
    p3 = "    register: 30005\n    param: \"3\"\n"
    other = _edit(tmp_path, "other.yaml", text, ("  model: sdm630\n", "  model: other\n"),
                  (p1, p1.replace("type: f32", "type: s32") + "    scale: 0.1\n"),
                  (p2, p2.replace("word_order: high_first", "word_order: low_first")),
                  (p3, p3.replace("30005", "40005")))
    data = yaml.safe_load(other.read_text(encoding="utf-8"))  # holding 4 is reserved in sdm630: not in this copy
    data["reserved"] = [r for r in data["reserved"] if not (r["table"] == "holding" and r["start"] <= 4 <= r["end"])]
    other.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(other)]) == 0
    out = capsys.readouterr().out
    assert "type: phase_1_voltage (input 0) = f32 | phase_1_voltage (input 0) = s32" in out
    assert "scale: phase_1_voltage (input 0) = 1 | phase_1_voltage (input 0) = 0.1" in out
    assert "word_order: phase_2_voltage (input 2) = high_first | phase_2_voltage (input 2) = low_first" in out
    assert "table: phase_3_voltage (input 4) = input | phase_3_voltage (holding 4) = holding" in out
    assert "4 disagreements " in out
    moved = _edit(tmp_path, "moved.yaml", text, ("  model: sdm630\n", "  model: moved\n"),
                  (p3, p3.replace("30005", "30901")))
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(moved)]) == 0
    out = capsys.readouterr().out
    assert "address: phase_3_voltage (input 4) = 4 | phase_3_voltage (input 900) = 900" in out
    assert "1 disagreement " in out


def test_compare_lists_a_changed_value_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = tmp_path / "a.yaml"
    assert main(["import", "ha-solarman", str(ROOT / "tests" / "fixtures" / "catalogue" / "profile.yaml"),
                 "-o", str(a)]) == 0
    text = a.read_text(encoding="utf-8")
    data = yaml.safe_load(text)
    enum = data["enums"][next(r["enum"] for r in data["registers"] if r["name"] == "state")]["values"]
    enum[-1]["value"] = 7
    data["device"]["model"] = "b"
    b = tmp_path / "b.yaml"
    b.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    capsys.readouterr()
    assert main(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "values: state (" in out and "= 0, 1, 2 | " in out and "= 0, 1, 7" in out and "1 disagreement " in out


def test_a_label_two_registers_share_pairs_none_across_addresses(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A register moved and renamed is found by its label only while that label names one register in
    each map; a label two registers share says nothing of which one is meant."""
    data = yaml.safe_load((ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8"))
    data["device"]["model"] = "moved"
    regs = {r["name"]: r for r in data["registers"]}
    label = regs["phase_3_voltage"]["label"]
    regs["phase_3_voltage"].update(name="p3", register=30901)
    moved = tmp_path / "moved.yaml"
    moved.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(moved)]) == 0
    assert "address: phase_3_voltage (input 4) = 4 | p3 (input 900) = 900" in capsys.readouterr().out
    regs["phase_1_current"]["label"] = label  # now two registers of the moved map carry the label
    moved.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    assert main(["compare", str(ROOT / "maps" / "sdm630.yaml"), str(moved)]) == 0
    out = capsys.readouterr().out
    assert "phase_3_voltage (input 4)" not in out and "p3 (input 900)" not in out, out
