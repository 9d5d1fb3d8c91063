"""`drivemap list` and the catalogue as users see it: maps found by model id in the project, among the
maps shipped with drivemap and in its catalogue (``data/maps/catalogue/<source>/``); the project's map
of an id wins and says so; ``exclude`` keeps maps out of a build but not out of reach."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.frontend import project as project_module
from drivemap.frontend.project import load_project

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "catalogue_list"


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def shipped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """drivemap's shipped maps as an installed package holds them: one seed map and a catalogue of two
    sources (the fixtures), in a folder of their own."""
    folder = tmp_path / "package_maps"
    folder.mkdir()
    shutil.copy(ROOT / "maps" / "sdm630.yaml", folder)
    shutil.copytree(FIXTURES, folder / "catalogue")
    monkeypatch.setattr(project_module, "SHIPPED_MAPS", folder)
    return folder


@pytest.fixture
def empty(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    where = tmp_path / "user"
    where.mkdir()
    monkeypatch.chdir(where)
    return where


def rows(out: str) -> dict[str, list[str]]:
    """model -> cells of the rich table's body rows."""
    found = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip("│ \n").split("│")]
        if line.startswith("│") and len(cells) == 6:
            found[cells[0]] = cells[1:]
    return found


def test_list_shows_shipped_and_catalogue_maps_with_their_evidence(shipped: Path, empty: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "list")
    assert code == 0, err
    table = rows(out)
    assert set(table) == {"sdm630", "acme_em100", "acme_em200", "zeta_inv5k"}
    assert table["acme_em100"] == ["ACME", "meter", "imported",
                                   "evcc-io/evcc:templates/definition/meter/acme-em100.yaml (MIT)", "catalogue/evcc"]
    assert table["zeta_inv5k"][:3] == ["Zeta Power", "inverter", "imported"]
    assert table["zeta_inv5k"][4] == "catalogue/solarman"
    assert table["sdm630"][0] == "Eastron" and table["sdm630"][4] == "drivemap"
    assert set(rows(run(capsys, "list", "--kind", "meter")[1])) == {"acme_em100", "acme_em200", "sdm630"}
    assert set(rows(run(capsys, "list", "--vendor", "zeta")[1])) == {"zeta_inv5k"}
    assert set(rows(run(capsys, "list", "em200")[1])) == {"acme_em200"}
    assert set(rows(run(capsys, "list", "acme", "--kind", "inverter")[1])) == set()
    code, out, err = run(capsys, "list", "nothing-like-this")
    assert code == 1 and "no map matches 'nothing-like-this'" in err


def test_a_catalogue_map_is_found_by_model_id(shipped: Path, empty: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "export", "zeta_inv5k", "--format", "json")
    assert code == 0, err
    assert json.loads(out)["model"] == "zeta_inv5k"
    assert "using the catalogue map" in err and str(shipped / "catalogue" / "solarman" / "zeta_inv5k.yaml") in err
    code, out, err = run(capsys, "export", "nosuch", "--format", "json")
    assert code == 1 and "`drivemap list` shows the shipped and catalogue maps" in err
    # validate takes model ids as export does, and shows each map's evidence
    code, out, err = run(capsys, "validate", "zeta_inv5k", "sdm630")
    assert code == 0, err
    lines = out.splitlines()
    assert len(lines) == 2 and lines[0].startswith(str(shipped / "catalogue" / "solarman" / "zeta_inv5k.yaml") + ": ok")
    assert lines[0].endswith("evidence: imported)") and lines[1].endswith("evidence: manual)")
    assert "'zeta_inv5k' is not a map of the project" in err
    code, out, err = run(capsys, "validate", "nosuch")
    assert code == 1 and out == "" and "no map for model 'nosuch'" in err


def test_the_projects_map_overrides_a_catalogue_map_and_says_so(shipped: Path, empty: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    (empty / "maps").mkdir()
    own = (FIXTURES / "evcc" / "acme_em100.yaml").read_text(encoding="utf-8").replace(
        "title: ACME EM100 energy meter", "title: ACME EM100 (my own, checked against the manual)").replace(
        "evidence: imported", "evidence: manual")
    (empty / "maps" / "acme_em100.yaml").write_text(own, encoding="utf-8")
    before = (shipped / "catalogue" / "evcc" / "acme_em100.yaml").read_bytes()
    code, out, err = run(capsys, "export", "acme_em100", "--format", "json")
    assert code == 0, err
    assert json.loads(out)["title"] == "ACME EM100 (my own, checked against the manual)"
    warnings = [line for line in err.splitlines() if "overrides" in line]
    assert len(warnings) == 1 and warnings[0].startswith("maps/acme_em100.yaml:1:1: warning: the project's map of "
                                                         "'acme_em100' overrides the catalogue map of the same id")
    table = rows(run(capsys, "list", "acme")[1])
    assert table["acme_em100"][2:] == ["manual", table["acme_em100"][3], "project (overrides catalogue/evcc)"]
    assert (shipped / "catalogue" / "evcc" / "acme_em100.yaml").read_bytes() == before


def _project_with_catalogue(root: Path, exclude: bool) -> None:
    (root / "maps").mkdir()
    shutil.copy(ROOT / "maps" / "ev.yaml", root / "maps")
    shutil.copytree(FIXTURES, root / "maps" / "catalogue")
    config = '[tool.drivemap]\nmaps = "maps"\n' + ('exclude = ["maps/catalogue"]\n' if exclude else "")
    (root / "pyproject.toml").write_text(config, encoding="utf-8")


def test_exclude_keeps_maps_out_of_the_build_not_out_of_reach(shipped: Path, empty: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    _project_with_catalogue(empty, exclude=True)
    assert [p.name for p in load_project().map_files()] == ["ev.yaml"]
    assert sorted(p.name for p in load_project().excluded_files()) == ["acme_em100.yaml", "acme_em200.yaml",
                                                                       "zeta_inv5k.yaml"]
    code, out, err = run(capsys, "validate")
    assert code == 0, err
    assert [line.split(":")[0] for line in out.splitlines()] == ["maps/ev.yaml"]
    code, out, err = run(capsys, "validate", "maps/catalogue")  # a folder named outright is validated whole
    assert code == 0 and len(out.splitlines()) == 3, err
    code, out, err = run(capsys, "export", "acme_em200", "--format", "json")
    assert code == 0 and json.loads(out)["model"] == "acme_em200", err
    assert rows(run(capsys, "list", "em200")[1])["acme_em200"][4] == "project (not built) (overrides catalogue/evcc)"


def test_without_exclude_the_maps_below_the_folder_are_the_projects(shipped: Path, empty: Path) -> None:
    _project_with_catalogue(empty, exclude=False)
    assert [p.relative_to(empty / "maps").as_posix() for p in load_project().map_files()] == [
        "ev.yaml", "catalogue/evcc/acme_em100.yaml", "catalogue/evcc/acme_em200.yaml",
        "catalogue/solarman/zeta_inv5k.yaml"]


def test_this_repository_builds_the_proven_maps_not_the_catalogue() -> None:
    project = load_project(ROOT)
    assert ROOT / "maps" / "catalogue" in project.exclude
    assert project.map_files() == sorted((ROOT / "maps").glob("*.yaml"))


def test_the_wheel_ships_the_catalogue() -> None:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert '"data/maps/catalogue/**/*.yaml"' in text
    assert os.path.realpath(ROOT / "generator" / "drivemap" / "data" / "maps") == str((ROOT / "maps").resolve())
