"""Build never deletes or overwrites what it did not write: hand edits, links, foreign temp files,
concurrent builds."""

from __future__ import annotations

import json
import shutil
import threading
import time
from pathlib import Path

import pytest

from drivemap.backends import output, staging
from tests.frontend.test_project import ok, project, run, snapshot

__all__ = ["project"]  # the fixture


def _rename(project: Path, old: str, new: str) -> None:
    """The map of model ``old`` becomes model ``new`` (its files are no longer produced)."""
    path = project / "maps" / f"{old}.yaml"
    path.write_text(path.read_text("utf-8").replace(f"model: {old}", f"model: {new}"), "utf-8")
    path.rename(project / "maps" / f"{new}.yaml")


def test_prune_keeps_a_generated_file_edited_by_hand(project: Path) -> None:
    ok("new", "acme")
    ok("build")
    doc = project / "generated" / "docs" / "acme.md"
    doc.write_text(doc.read_text("utf-8") + "\nMy own notes.\n", "utf-8")
    _rename(project, "acme", "beta")
    code, out, err = run("check")
    assert code == 1 and "build keeps it: edited by hand" in err
    out = ok("build")
    assert doc.read_text("utf-8").endswith("My own notes.\n")
    assert "kept generated/docs/acme.md: edited by hand" in out
    assert not (project / "generated" / "acme" / "client.py").exists()  # unedited: deleted as before
    manifest = json.loads((project / "generated" / output.MANIFEST).read_text("utf-8"))
    assert "docs/acme.md" not in manifest["files"]
    assert "kept" not in ok("build")                   # named once; no longer tracked, never deleted
    assert doc.exists()


def test_prune_keeps_a_user_file_at_a_path_the_manifest_lists(project: Path) -> None:
    ok("new", "acme")
    ok("build")
    client = project / "generated" / "acme" / "client.py"
    client.unlink()
    client.write_text("MINE = 1\n", "utf-8")            # a hand-written file where drivemap's was
    manifest_path = project / "generated" / output.MANIFEST
    manifest = json.loads(manifest_path.read_text("utf-8"))
    (project / "generated" / "notes.txt").write_text("keep me\n", "utf-8")
    manifest["files"]["notes.txt"] = "0" * 64             # a user file added to a hand-edited manifest
    manifest_path.write_text(json.dumps(manifest), "utf-8")
    _rename(project, "acme", "beta")
    out = ok("build")
    assert client.read_text("utf-8") == "MINE = 1\n"
    assert (project / "generated" / "notes.txt").read_text("utf-8") == "keep me\n"
    assert "kept generated/acme/client.py" in out and "kept generated/notes.txt" in out


def test_build_never_writes_through_a_link_out_of_its_folder(project: Path, tmp_path: Path) -> None:
    ok("new", "acme")
    ok("build")
    elsewhere = tmp_path / "users_folder"
    elsewhere.mkdir()
    (elsewhere / "client.py").write_text("USER = 1\n", "utf-8")
    (elsewhere / "spec.py").write_text("USER = 2\n", "utf-8")
    before = snapshot(elsewhere)
    acme = project / "generated" / "acme"
    shutil.rmtree(acme)
    acme.symlink_to(elsewhere, target_is_directory=True)
    code, _, err = run("build")
    assert code == 1
    assert "generated/acme:1:1: error: is a symbolic link" in err
    assert snapshot(elsewhere) == before
    _rename(project, "acme", "beta")                   # the link's files are in the manifest: never deleted
    code, _, err = run("build")
    assert code == 1 and "generated/acme:1:1: error: is a symbolic link" in err
    assert snapshot(elsewhere) == before


def test_the_temp_sweep_removes_only_what_a_build_recorded(project: Path) -> None:
    ok("new", "acme")
    ok("build")
    mine = [project / ".drivemap-tmp-notes", project / "generated" / "acme" / ".drivemap-tmp-x",
            project / "maps" / ".drivemap-tmp-draft.yaml"]
    for path in mine:
        path.write_text("user data\n", "utf-8")
    ok("build", "--out", ".", "--force")               # the whole project is the output folder
    ok("build")
    assert all(p.read_text("utf-8") == "user data\n" for p in mine)
    # a dead build's own record: exactly its files go
    gen = project / "generated"
    dead = gen / "acme" / ".drivemap-tmp-deadbeef-0"
    dead.write_text("half-written\n", "utf-8")
    staging.record(gen, ["acme/.drivemap-tmp-deadbeef-0"])
    ok("build")
    assert not dead.exists() and not (gen / staging.JOURNAL).exists()
    assert (gen / "acme" / ".drivemap-tmp-x").read_text("utf-8") == "user data\n"


def test_a_second_build_waits_for_the_first(project: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ok("new", "acme")
    ok("build")
    gen = project / "generated"
    monkeypatch.setattr(staging, "LOCK_WAIT", 0.3)
    with staging.locked([gen]):
        assert run("build")[0] == 0  # nothing to write: no lock needed, nothing touched
        acme = project / "maps" / "acme.yaml"
        acme.write_text(acme.read_text(encoding="utf-8").replace("title: ", "title: New ", 1), encoding="utf-8")
        code, _, err = run("build")
    assert code == 1
    assert "another drivemap build is writing this folder (held by pid" in err and "waited 0.3 s" in err
    monkeypatch.setattr(staging, "LOCK_WAIT", 20.0)
    released = threading.Event()

    def hold() -> None:
        with output.locked([gen]):
            released.wait(5)
            time.sleep(0.3)

    holder = threading.Thread(target=hold)
    holder.start()
    time.sleep(0.1)
    released.set()
    started = time.monotonic()
    ok("build")                                        # waits for the holder, then builds
    holder.join()
    assert time.monotonic() - started >= 0.2
    assert "is up to date" in ok("check")
