"""Map format evolution: old maps keep validating, `drivemap migrate` rewrites them in place.

tests/maps_history/ holds every distinct version of the shipped maps from the repository's history
(all ``drivemap: 1``, written before format 2 and before ``exceptions[].documented``)."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.diagnostics import CompileError
from drivemap.frontend import formats
from drivemap.frontend.load import load_text

HERE = Path(__file__).resolve().parents[1]
HISTORY = sorted((HERE / "maps_history").glob("*/*.yaml"))
ROOT = HERE.parent


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def test_the_corpus_spans_the_history() -> None:
    assert len(HISTORY) >= 20
    assert {p.stem for p in HISTORY} >= {"ev", "vfd1000", "v2", "edx", "sdm630", "fronius_symo_hybrid"}
    assert all(p.read_text(encoding="utf-8").count("\ndrivemap: 1\n") == 1 for p in HISTORY)


#: One earlier version of each map migrates in the default tier; every version does in the slow tier.
FIRST_OF_EACH = {p.stem: p for p in reversed(HISTORY)}
HISTORY_CASES = [pytest.param(p, id=f"{p.parent.name}/{p.stem}", marks=() if FIRST_OF_EACH[p.stem] == p else pytest.mark.slow)
                 for p in HISTORY]


@pytest.mark.parametrize("path", HISTORY_CASES)
def test_every_earlier_map_validates_and_migrates(path: Path, tmp_path: Path) -> None:
    model = compile_map(path)  # format 1 as written
    assert model.format_version == 1
    copy = tmp_path / path.name
    shutil.copy(path, copy)
    old = copy.read_text(encoding="utf-8")
    code, diff, err = run("migrate", str(copy))
    assert code == 0, err
    assert copy.read_text(encoding="utf-8") == old  # a diff only
    assert diff.startswith(f"--- a/{copy}") and "-drivemap: 1\n+drivemap: 2\n" in diff
    code, _, err = run("migrate", str(copy), "--write")
    assert code == 0, err
    new = copy.read_text(encoding="utf-8")
    migrated = compile_map(copy)
    assert migrated.format_version == 2
    # only lines were added (and the format replaced): comments and layout are kept
    old_lines, new_lines = old.splitlines(), new.splitlines()
    added = [line for line in new_lines if line not in old_lines]
    assert all(line.strip().startswith("broadcast_reason: ") for line in added if "drivemap: 2" not in line)
    assert [line for line in new_lines if line not in added] == [
        line for line in old_lines if line != "drivemap: 1"]
    assert [fc.broadcast_reason for fc in migrated.protocol.function_codes] == [
        fc.broadcast_reason for fc in model.protocol.function_codes]
    code, diff, err = run("migrate", str(copy))
    assert (code, diff) == (0, "") and "format 2 already" in err


def test_a_format_1_map_without_broadcast_reason_reads_as_not_stated() -> None:
    old = HERE / "maps_history" / "9e7121b" / "v2.yaml"
    model = compile_map(old)
    reasons = {fc.code: fc.broadcast_reason for fc in model.protocol.function_codes if fc.broadcast is None}
    assert reasons and set(reasons.values()) == {formats.UNSTATED_BROADCAST_REASON}


def test_format_2_still_requires_the_reason(tmp_path: Path) -> None:
    text = (HERE / "maps_history" / "9e7121b" / "v2.yaml").read_text(encoding="utf-8")
    bad = tmp_path / "v2.yaml"
    bad.write_text(text.replace("\ndrivemap: 1\n", "\ndrivemap: 2\n"), encoding="utf-8")
    code, _, err = run("validate", str(bad))
    assert code == 1 and "missing required key 'broadcast_reason'" in err


def test_documented_defaults_to_what_the_source_says(tmp_path: Path) -> None:
    """An exception without `documented` (a map written before the key) is documented unless its
    source is 'map choice'; the key stays optional in both formats."""
    text = (ROOT / "maps" / "vfd1000.yaml").read_text(encoding="utf-8")
    assert "documented: false" in text
    stripped = tmp_path / "vfd1000.yaml"
    stripped.write_text(text.replace("      documented: false\n", ""), encoding="utf-8")
    model = compile_map(stripped)
    by_source = {e.code: (e.source, e.documented) for e in model.protocol.exceptions}
    assert by_source and all(documented == (source != "map choice") for source, documented in by_source.values())
    assert any(not documented for _, documented in by_source.values())


def test_migrate_refuses_what_it_cannot_edit_in_place(tmp_path: Path) -> None:
    text = (HERE / "maps_history" / "9e7121b" / "v2.yaml").read_text(encoding="utf-8")
    odd = tmp_path / "v2.yaml"
    odd.write_text(text.replace("\ndrivemap: 1\n", "\ndrivemap: 0x1\n"), encoding="utf-8")
    before = odd.read_text(encoding="utf-8")
    code, out, err = run("migrate", str(odd), "--write")
    assert code == 1 and out == "" and err.startswith(f"{odd}:")
    assert "cannot migrate: write the format as a plain number" in err
    assert odd.read_text(encoding="utf-8") == before
    flow = "drivemap: 1\nprotocol:\n  function_codes:\n    - {code: 3, broadcast: null}\n"
    with pytest.raises(CompileError) as exc:
        formats.migrate_text(flow, load_text(flow, "flow.yaml"))
    assert str(exc.value).startswith("flow.yaml:4:17: error: cannot migrate a flow-style mapping")


def test_shipped_maps_and_the_scaffold_are_current(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for path in sorted((ROOT / "maps").glob("*.yaml")):
        assert compile_map(path).format_version == formats.CURRENT, path
    monkeypatch.chdir(tmp_path)
    assert run("new", "acme")[0] == 0
    assert compile_map(tmp_path / "maps" / "acme.yaml").format_version == formats.CURRENT


def test_migrate_defaults_to_the_projects_maps(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    code, out, err = run("migrate")
    assert (code, out) == (0, "")
    assert sorted(err.splitlines()) == sorted(f"maps/{p.name}: format 2 already" for p in (ROOT / "maps").glob("*.yaml"))
