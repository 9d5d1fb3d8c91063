"""The map language's per-register ``review:`` marker and the device's evidence level."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map

ROOT = Path(__file__).resolve().parents[2]


def _with_review(tmp_path: Path, review: str, evidence: str | None = None) -> Path:
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8")
    first = text.index("\n  - name:", text.index("\nregisters:"))
    text = text[:first] + text[first:].replace("\n    source:", f"\n    review: {review}\n    source:", 1)
    if evidence is not None:
        text = re.sub(r"\n  evidence: \w+", "", text, count=1)  # the shipped map's own level
        text = re.sub(r"\n  source:", f"\n  evidence: {evidence}\n  source:", text, count=1)
    path = tmp_path / "sdm630.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _validate(path: Path) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["validate", str(path)])
    return code, out.getvalue(), err.getvalue()


def test_validate_counts_open_items_and_shows_evidence(tmp_path: Path) -> None:
    code, out, _ = _validate(_with_review(tmp_path, "[type, word_order, unit]", evidence="imported"))
    assert code == 0
    assert "3 open for review on 1 register" in out
    assert "evidence: imported" in out




def test_review_item_must_be_a_register_field(tmp_path: Path) -> None:
    code, _, err = _validate(_with_review(tmp_path, "[colour]"))
    assert code == 1
    assert re.search(r"sdm630\.yaml:\d+:\d+: error: .*colour", err)


@pytest.mark.parametrize(("review", "blocking"), [("[type, unit]", ("type",)), ("[unit, min]", ())])
def test_write_deciding_fields(tmp_path: Path, review: str, blocking: tuple[str, ...]) -> None:
    model = compile_map(_with_review(tmp_path, review), [])
    reg = next(r for r in model.registers if r.review)
    assert reg.open_for_writes == blocking
