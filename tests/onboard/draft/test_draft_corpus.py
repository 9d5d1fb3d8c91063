"""The corpus tier: `drivemap draft` on every document of ../shared/draft-corpus, scored against its truth
file as the bench's corpus section scores it (bench/draftcorpus.py), deterministic and untimed.

Each document's exact count is a floor (no change may lower one document to raise another); its wrong
fields and silently dropped rows are ceilings that only go down (the goal of both is 0: see
docs/onboarding.md for where the corpus stands). Without the shared folder every test fails saying so.
"""

from __future__ import annotations

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
    "deye_sg0x_3p_hybrid_v105.docx": (17, 3, 0),
    "deye_sun_1p_hybrid_v118.pdf": (0, 0, 0),
    "huawei_smartlogger3000.pdf": (0, 0, 0),
    "jk_pb_bms_rs485_modbus_v11.pdf": (0, 0, 89),
    "mennekes_amtron_compact20.pdf": (3, 0, 2),
    "mennekes_amtron_hcc3.pdf": (6, 0, 0),
    "schrack_cion.pdf": (3, 0, 0),
    "sungrow_sg_grid_protocol_v1180.pdf": (98, 1, 4),
    "sungrow_sh_hybrid_protocol_v1111.pdf": (65, 1, 0),
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
