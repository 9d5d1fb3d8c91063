"""The corpus tier, public documents: `drivemap draft` on each document of ../shared/public-docs that has a
finished map in this repository, scored as the bench's public-document section scores it
(bench/publicdocs.py), deterministic and untimed.

Each document's exact count is a floor (no change may lower one document to raise another) and its wrong
fields written a ceiling at 0. Without the shared folder every test fails saying so.
"""

from __future__ import annotations

import sys

import pytest

from tests.shared_data import ROOT, shared_dir

sys.path.insert(0, str(ROOT / "bench"))

import publicdocs  # noqa: E402

pytestmark = pytest.mark.corpus

#: document -> registers of its finished map drafted exact, at least
FLOORS: dict[str, int] = {
    # its floats and 32-bit integers keep their stated types with the word order to review
    "wnc_v18.xlsx": 151,
    "solax_g4_v321.pdf": 29,
    "delta_vfd_el_w_p4-84.txt": 5,
    "delta_vfd_f_p5-58.txt": 6,
}


def _docs() -> dict[str, dict[str, object]]:
    return {d["file"]: d for d in publicdocs.load_manifest() if d.get("map")}


def test_every_document_with_a_finished_map_has_a_floor() -> None:
    assert sorted(_docs()) == sorted(FLOORS)


@pytest.mark.parametrize("name", sorted(FLOORS))
def test_public_document_score_holds(name: str) -> None:
    folder = shared_dir() / "public-docs"
    if not folder.is_dir():
        pytest.fail(f"the corpus tier needs {folder} (set DRIVEMAP_SHARED to the shared folder)")
    path, why = publicdocs.locate(_docs()[name], folder)
    assert path is not None, why
    measured = publicdocs.measure(_docs()[name], path)
    score = measured.chosen
    assert score is not None
    assert score.exact >= FLOORS[name], f"{name}: {score.exact}/{score.proven} exact, floor {FLOORS[name]}"
    assert not score.wrong_stated, f"{name}: wrong fields written {score.wrong_stated}"
