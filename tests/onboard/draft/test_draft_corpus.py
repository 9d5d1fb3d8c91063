"""The corpus tier: `drivemap draft` on every document of ../shared/draft-corpus, scored against its truth
file as the bench's corpus section scores it (bench/draftcorpus.py), deterministic and untimed.

Each document's exact count is a floor (no change may lower one document to raise another); its wrong
fields and silently dropped rows are ceilings that only go down (the goal of both is 0: see
docs/onboarding.md for where the corpus stands). Without the shared folder every test fails saying so.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from tests.shared_data import ROOT, shared_dir

sys.path.insert(0, str(ROOT / "bench"))

import draftcorpus  # noqa: E402

pytestmark = pytest.mark.corpus

#: document -> (exact truth registers at least, wrong fields at most, silently dropped at most)
FLOORS: dict[str, tuple[int, int, int]] = {
    "carlo_gavazzi_em24_din_v4.pdf": (20, 0, 0),
    "deye_sg0x_3p_hybrid_v105.docx": (68, 0, 0),
    "deye_sun_1p_hybrid_v118.pdf": (36, 0, 0),
    # Gain divides: its unitless power factor rows have Gain 1000
    "huawei_smartlogger3000.pdf": (17, 0, 0),
    "jk_pb_bms_rs485_modbus_v11.pdf": (0, 0, 0),
    "mennekes_amtron_compact20.pdf": (4, 0, 0),
    "mennekes_amtron_hcc3.pdf": (14, 0, 0),
    "schrack_cion.pdf": (3, 0, 0),
    "sungrow_sg_grid_protocol_v1180.pdf": (113, 0, 0),
    "sungrow_sh_hybrid_protocol_v1111.pdf": (85, 0, 0),
    # its 1000 is TQ-DM100's "Charge Point State" and Ebee's "Hems Current Limit (A)": listed, not drafted
    # (keeping the first was a guess); comTimeout's unit cell "S" reads as seconds
    "webasto_live.pdf": (17, 0, 0),
}


def corpus() -> Path:
    folder = shared_dir() / "draft-corpus"
    if not (folder / "docs").is_dir():
        pytest.fail(f"the corpus tier needs {folder}/docs (set DRIVEMAP_SHARED to the shared folder)")
    return folder


def test_every_corpus_document_has_a_floor() -> None:
    assert sorted(d.name for d, _ in draftcorpus.documents(corpus())) == sorted(FLOORS)


@pytest.mark.parametrize("name", sorted(FLOORS))
def test_document_score_holds(name: str) -> None:
    folder = corpus()
    path = folder / "docs" / name
    score = draftcorpus.score_document(path, folder / "truth" / f"{path.stem}.json")
    exact, wrong, dropped = FLOORS[name]
    assert not score.error, score.error
    assert score.exact >= exact, f"{name}: {score.exact} exact, floor {exact}; not exact: {score.not_exact}"
    assert len(score.wrong) <= wrong, f"{name}: wrong fields {score.wrong}"
    assert len(score.dropped) <= dropped, f"{name}: dropped silently {score.dropped}"


def _squeezed(text: str) -> str:
    return "".join(c for c in text if not c.isspace() and c not in "|/")


def test_each_truth_erratum_is_printed_in_its_document() -> None:
    """An erratum (bench/corpus_errata.json) scores a field as the document prints it: the words it quotes
    are in that document (PDF text, or a DOCX table row's cells), so no erratum can excuse a wrong field."""
    folder = corpus()
    listed = json.loads(draftcorpus.ERRATA.read_text(encoding="utf-8"))["errata"]
    assert listed
    for e in listed:
        path = folder / "docs" / e["document"]
        assert path.stem in {p.stem for p in (folder / "truth").glob("*.json")}
        truth = json.loads((folder / "truth" / f"{path.stem}.json").read_text(encoding="utf-8"))["registers"]
        assert any(t["table"] == e["table"] and t["address"] == e["address"] and t[e["field"]] == e["truth"]
                   for t in truth), e
        if path.suffix == ".docx":
            import docx

            text = "\n".join(" | ".join(c.text for c in r.cells) for t in docx.Document(str(path)).tables for r in t.rows)
        else:
            import pdfplumber

            with pdfplumber.open(path) as pdf:
                text = "\n".join(p.extract_text() or "" for p in pdf.pages)
        assert _squeezed(e["printed"]) in _squeezed(text), e
