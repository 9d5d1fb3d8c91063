"""A no-change ``drivemap build`` touches nothing (no file or folder's mtime changes, no lock file),
with the compile and render cache or without it; a change still reaches the output."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path

import pytest

from drivemap.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _run(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return code, out.getvalue(), err.getvalue()


def _stamps(root: Path) -> dict[str, tuple[int, int]]:
    """(mtime, inode) of every file and folder under ``root`` but the cache."""
    found = {}
    for folder, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d != "cache"]
        for name in [*dirs, *files, "."]:
            st = os.lstat(os.path.join(folder, name))
            found[os.path.relpath(os.path.join(folder, name), root)] = (st.st_mtime_ns, st.st_ino)
    return found


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """This repository's project (its maps and its [tool.drivemap], committed exports included)."""
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    shutil.copytree(ROOT / "maps", tmp_path / "maps")
    monkeypatch.setenv("DRIVEMAP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("DRIVEMAP_NO_CACHE", raising=False)
    monkeypatch.chdir(tmp_path)
    code, _, err = _run("build")
    assert code == 0, err
    return tmp_path


@pytest.mark.parametrize("flags", [(), ("--no-cache",)])
def test_no_change_build_touches_no_file(project: Path, flags: tuple[str, ...]) -> None:
    _run("build")  # the caches are warm
    before = _stamps(project)
    assert len([p for p in before if p.endswith(".py")]) > 20
    code, out, err = _run("build", *flags)
    assert code == 0, err
    assert "generated/drivemap_models/: 42 files (0 written, 0 deleted)" in out
    assert _stamps(project) == before
    assert _run("check")[0] == 0


def test_a_change_after_a_cached_build_reaches_the_output(project: Path) -> None:
    _run("build")
    sdm = project / "maps" / "sdm630.yaml"
    before = _stamps(project)
    text = sdm.read_text(encoding="utf-8")
    sdm.write_text(text.replace("title: ", "title: Renamed ", 1), encoding="utf-8")
    assert _run("check")[0] == 1
    code, out, _ = _run("build")
    assert code == 0 and "(0 written" not in out.split("generated/docs/:")[1].splitlines()[0]
    after = _stamps(project)
    changed = {p for p in after if after[p] != before.get(p)}
    assert "generated/docs/sdm630.md" in changed and "generated/docs/ev.md" not in changed
    assert "Renamed" in (project / "generated" / "docs" / "sdm630.md").read_text(encoding="utf-8")
    assert _run("check")[0] == 0
    sdm.write_text(text, encoding="utf-8")  # back: the earlier cache entries serve it again
    assert _run("build")[0] == 0 and _run("check")[0] == 0
    assert "Renamed" not in (project / "generated" / "docs" / "sdm630.md").read_text(encoding="utf-8")


def test_an_output_file_changed_by_hand_is_rebuilt_from_the_cache(project: Path) -> None:
    target = project / "generated" / "drivemap_models" / "ev" / "spec.py"
    good = target.read_text(encoding="utf-8")
    target.write_text(good + "# edited\n", encoding="utf-8")
    assert _run("check")[0] == 1
    code, out, _ = _run("build")
    assert code == 0 and "replaced generated/drivemap_models/ev/spec.py" in out
    assert target.read_text(encoding="utf-8") == good
