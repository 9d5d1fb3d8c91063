"""Hostile map files (issue 38, items 15, 16, 18): ``migrate`` reads regular files only, never writes
through a link, keeps line endings and prints exactly what it writes; ``extends:`` opens only maps of
the project or maps shipped with drivemap."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.frontend import family

HERE = Path(__file__).resolve().parents[1]
OLD = sorted((HERE / "maps_history").glob("*/ev.yaml"))[0]  # a format-1 map


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "pyproject.toml").write_text('[tool.drivemap]\nmaps = "maps"\n', encoding="utf-8")
    (tmp_path / "maps").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


# ---- migrate: what is not a regular file (item 15) -------------------------------------------------

@pytest.mark.parametrize("kind", ["device", "fifo"])
def test_migrate_refuses_what_is_not_a_regular_file(kind: str, project: Path) -> None:
    if kind == "device":
        target = "/dev/zero"
    else:
        os.mkfifo(project / "pipe.yaml")
        target = "pipe.yaml"
    code, out, err = run("migrate", target, "--write")
    assert code == 1 and out == ""
    assert err.startswith(f"{target}:1:1: error: not a regular file (a FIFO, device or folder); refused"), err


# ---- migrate --write: links, line endings, the diff (item 16) -----------------------------------

def test_migrate_write_refuses_a_symbolic_link(project: Path) -> None:
    (project / "shared").mkdir()
    shared = project / "shared" / "ev.yaml"
    shutil.copy(OLD, shared)
    (project / "maps" / "ev.yaml").symlink_to(shared)
    before = shared.read_bytes()
    code, out, err = run("migrate", "maps/ev.yaml", "--write")
    assert code == 1 and "migrated" not in err
    assert err.startswith(f"maps/ev.yaml:1:1: error: is a symbolic link (to {shared}): drivemap never writes through "
                          "links; migrate the file it points to; nothing written"), err
    assert (project / "maps" / "ev.yaml").is_symlink() and shared.read_bytes() == before
    code, out, err = run("migrate", "shared/ev.yaml", "--write")  # the file itself migrates
    assert code == 0 and b"drivemap: 2" in shared.read_bytes(), err


def test_migrate_write_refuses_a_file_with_other_hard_links(project: Path) -> None:
    shutil.copy(OLD, project / "maps" / "ev.yaml")
    os.link(project / "maps" / "ev.yaml", project / "other.yaml")
    before = (project / "other.yaml").read_bytes()
    code, out, err = run("migrate", "maps/ev.yaml", "--write")
    assert code == 1 and err.startswith("maps/ev.yaml:1:1: error: has 2 hard links: replacing it would leave the other "
                                        "names on the old format"), err
    assert os.stat(project / "other.yaml").st_nlink == 2 and (project / "other.yaml").read_bytes() == before


def test_migrate_keeps_crlf_and_prints_the_bytes_it_writes(project: Path) -> None:
    path = project / "maps" / "ev.yaml"
    text = OLD.read_text(encoding="utf-8")
    path.write_bytes(text.replace("\n", "\r\n").encode("utf-8"))
    code, diff, err = run("migrate", "maps/ev.yaml")
    assert code == 0, err
    added = [line for line in diff.splitlines(keepends=True) if line.startswith("+") and not line.startswith("+++")]
    assert added and all(line.endswith("\r\n") for line in added), added
    code, _, err = run("migrate", "maps/ev.yaml", "--write")
    assert code == 0, err
    new = path.read_bytes()
    assert new.count(b"\n") == new.count(b"\r\n") and b"drivemap: 2\r\n" in new
    assert compile_map(path).format_version == 2


# ---- extends: inside the project or shipped (item 18) ------------------------------------------

def _variant(project: Path, target: str) -> Path:
    path = project / "maps" / "acme_xl.yaml"
    path.write_text(f"drivemap: 2\nextends: {target}\ndevice: {{model: acme_xl, title: XL}}\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("target", ["/etc/passwd", "../../../../../../../../etc/passwd", "/dev/zero", "../../x.yaml"])
def test_extends_outside_the_project_is_refused(target: str, project: Path) -> None:
    _variant(project, target)
    code, out, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1
    first = err.splitlines()[0]
    assert first.startswith(f"maps/acme_xl.yaml:2:10: error: extends {target!r}: "), first
    assert "is outside the project" in first, err


def test_extends_through_a_symbolic_link_out_of_the_project_is_refused(project: Path, tmp_path_factory:
                                                                      pytest.TempPathFactory) -> None:
    outside = tmp_path_factory.mktemp("outside") / "base.yaml"
    shutil.copy(HERE.parent / "maps" / "vfd1000.yaml", outside)
    (project / "maps" / "base.yaml").symlink_to(outside)
    _variant(project, "base.yaml")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and "extends 'base.yaml': maps/base.yaml is outside the project" in err, err


def test_extends_a_fifo_in_the_project_is_not_missing(project: Path) -> None:
    os.mkfifo(project / "maps" / "pipe.yaml")
    _variant(project, "pipe.yaml")
    code, _, err = run("validate", "maps/acme_xl.yaml")
    assert code == 1 and "extends 'pipe.yaml': maps/pipe.yaml is not a regular file" in err, err


def test_extends_a_map_of_the_project_or_a_shipped_one(project: Path) -> None:
    shutil.copy(HERE.parent / "maps" / "vfd1000.yaml", project / "common.yaml")  # the project's, above maps/
    _variant(project, "../common.yaml")
    assert compile_map(Path("maps/acme_xl.yaml")).variant is not None
    shipped = family.SHIPPED_MAPS / "vfd1000.yaml"
    assert shipped.is_file()
    _variant(project, str(shipped))
    model = compile_map(Path("maps/acme_xl.yaml"))
    assert model.variant is not None and model.variant.extends == (os.path.normpath(shipped),)
