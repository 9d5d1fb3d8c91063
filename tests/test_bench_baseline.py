"""bench/baseline.py: without git or the baseline commit the section is one "not measured" row (never a
number); the baseline tree is extracted whole (its data links resolve) without touching the repository;
a child that imported another tree's code is refused; the verdict follows the rounds."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

import baseline  # noqa: E402


def _has_commit(commit: str) -> bool:
    probe = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}"],
                           capture_output=True, text=True)
    return probe.returncode == 0


def test_unknown_commit_is_not_measured(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(baseline, "BASELINE", "0" * 40)
    sec = baseline.run(quick=True)
    assert len(sec.rows) == 1
    row = sec.rows[0]
    assert row.ratio is None and row.met is None
    assert row.absolute.startswith("not measured: commit 0000000000000000000000000000000000000000 is not")
    assert sec.detail == [f"Not measured: {row.absolute.removeprefix('not measured: ')}."]


def test_without_git_is_not_measured(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # no git on it
    why = baseline.baseline_tree(tmp_path / "tree")
    assert why is not None and why.startswith("git is not available")
    assert not (tmp_path / "tree").exists()


def test_baseline_tree_is_extracted_whole(tmp_path: Path) -> None:
    """The baseline tree whole, the checkout untouched; in a clone without that commit (a shallow one)
    the section says so instead of measuring."""
    if not _has_commit(baseline.BASELINE):
        why = baseline.baseline_tree(tmp_path / "tree")
        assert why is not None and baseline.BASELINE[:7] in why and not (tmp_path / "tree").exists()
        return
    status = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain"], capture_output=True, text=True).stdout
    worktrees = subprocess.run(["git", "-C", str(ROOT), "worktree", "list"], capture_output=True, text=True).stdout
    assert baseline.baseline_tree(tmp_path) is None
    assert (tmp_path / "generator" / "drivemap" / "runtime" / "aclient.py").is_file()  # the tree before the refactor
    assert (tmp_path / "generated" / "drivemap_models" / "vfd1000" / "client.py").is_file()
    assert (tmp_path / "bench" / "overhead.py").is_file()
    schema = tmp_path / "generator" / "drivemap" / "data" / "drivemap.schema.json"
    assert schema.is_symlink() and schema.resolve().is_relative_to(tmp_path.resolve()) and schema.is_file()
    assert subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain"], capture_output=True,
                          text=True).stdout == status
    assert subprocess.run(["git", "-C", str(ROOT), "worktree", "list"], capture_output=True,
                          text=True).stdout == worktrees


def test_child_on_another_trees_code_is_refused(tmp_path: Path) -> None:
    """A tree without its own drivemap: the child imports the installed one, and the figure is refused."""
    for folder in ("generator", "generated", "bench"):
        (tmp_path / folder).mkdir()
    (tmp_path / "bench" / "common.py").write_text("", encoding="utf-8")
    (tmp_path / "bench" / "imports.py").write_text("def build(folder, size):\n    return ['p', 'pkg']\n",
                                                   encoding="utf-8")
    with pytest.raises(RuntimeError, match="imported .*drivemap.*, not that tree's code"):
        baseline._call(tmp_path, "build", str(tmp_path), "100")
    (tmp_path / "generator" / "drivemap").mkdir()
    (tmp_path / "generator" / "drivemap" / "__init__.py").write_text("", encoding="utf-8")
    assert baseline._call(tmp_path, "build", str(tmp_path), "100")["built"] == ["p", "pkg"]


def test_verdicts() -> None:
    base = [1.040, 1.045, 1.050, 1.055, 1.060]
    assert baseline._verdict(base, [1.030, 1.040, 1.045, 1.050, 1.070]) == ("no worse", True)
    assert baseline._verdict(base, [1.040, 1.052, 1.054, 1.058, 1.030]) == ("within spread", True)
    assert baseline._verdict(base, [1.061, 1.062, 1.065, 1.070, 1.070]) == ("WORSE", False)  # above the worst round
    # every round's current above its baseline round, though inside the baseline's range
    assert baseline._verdict(base, [1.041, 1.046, 1.052, 1.056, 1.061]) == ("WORSE", False)
    # the same with fewer than 5 rounds: not enough to call
    assert baseline._verdict(base[:3], [1.041, 1.046, 1.049]) == ("within spread", True)


def test_verdicts_when_more_is_better() -> None:
    base = [0.90, 0.91, 0.92, 0.93, 0.94]
    assert baseline._verdict(base, [0.92, 0.93, 0.95, 0.90, 0.91], higher=True) == ("no worse", True)
    assert baseline._verdict(base, [0.91, 0.91, 0.915, 0.95, 0.95], higher=True) == ("within spread", True)
    assert baseline._verdict(base, [0.85, 0.86, 0.88, 0.95, 0.95], higher=True) == ("WORSE", False)


def test_tree_metadata_carries_the_trees_entry_points(tmp_path: Path) -> None:
    """The child sees the tree's own entry points ahead of the installed drivemap's."""
    tree = tmp_path / "tree"
    tree.mkdir()
    (tree / "pyproject.toml").write_text('[project]\nname = "drivemap"\n[project.entry-points."drivemap.behaviours"]\n'
                                         'ev = "elsewhere.ev:Ev"\n', encoding="utf-8")
    folder = baseline.tree_metadata(tree, tmp_path / "meta")
    code = ("import importlib.metadata as m; "
            "print([e.value for e in m.entry_points(group='drivemap.behaviours', name='ev')])")
    env = dict(baseline._env(tree))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path,
                         check=True).stdout
    assert out.strip() == "['elsewhere.ev:Ev']"
    assert str(folder) in env["PYTHONPATH"].split(":")
