"""bench/baseline.py: without git or the baseline commit the section is one "not measured" row (never a
number); the baseline tree is extracted whole (its data links resolve) without touching the repository;
a child that imported another tree's code is refused; the verdict follows the rounds."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))

import baseline  # noqa: E402
import wirecalls  # noqa: E402


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


def test_an_efficiency_within_the_aa_controls_noise_is_within_noise_and_below_it_worse() -> None:
    """The A/A control (the current tree against itself in the same rounds) bounds what counts as noise:
    a shortfall no larger than its lowest per-round quotient is within noise, a larger one stays WORSE."""
    base = [0.940, 0.941, 0.942, 0.943, 0.944, 0.945]
    cur = [0.936, 0.937, 0.937, 0.938, 0.938, 0.939]  # every round worse: WORSE by the strict rules
    assert baseline._verdict(base, cur, higher=True) == ("WORSE", False)
    noisy = [1.004, 0.996, 0.993, 1.002, 0.999, 1.001]  # the same code against itself moved 0.7 %
    calm = [1.001, 0.999, 0.998, 1.000, 1.000, 1.002]
    q = sum(cur) / sum(base)
    assert baseline._noise_verdict(q, noisy, "WORSE", False) == ("within noise (A/A down to 0.993)", True)
    assert baseline._noise_verdict(q, calm, "WORSE", False) == ("WORSE (A/A down to 0.998)", False)
    assert baseline._noise_verdict(q, [], "WORSE", False) == ("WORSE", False)  # no control: the strict rules
    assert baseline._noise_verdict(1.01, calm, "no worse", True) == ("no worse", True)


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


def _row(calls: float, opcodes: dict[str, float]) -> dict[str, object]:
    return {"calls": calls, "opcodes": sum(opcodes.values()), "opcodes by function": opcodes,
            "waits": {"select timeouts (ms) per transaction": {"1.00": 1.0}, "time.sleep calls per transaction": 0.9}}


def _counted(extra: float = 0.0, settle: float = 0.001, sleeps: float = 0.9) -> dict[str, object]:
    out: dict[str, object] = {row: _row(10 + extra, {"a/x.py:transact": 50 + extra, "b/y.py:read": 20})
                              for row in wirecalls.ROWS}
    out["sync read 16"]["waits"]["time.sleep calls per transaction"] = sleeps  # type: ignore[index]
    out["device"] = {"reply delay": 0.004, "read 16": {"calls": 5, "opcodes": 9.0},
                     "write one": {"calls": 6, "opcodes": 9.0}}
    out["sync design"] = {"guard settle": settle, "quiet after a reply": 0.00175}
    return out


def test_wire_calls_compare_names_what_differs() -> None:
    """Equal counts and waits read as equal (the machine-dependent sleep count is left out); one more
    instruction in a function, or a longer settle time, is named."""
    same = wirecalls.compare(_counted(), _counted(sleeps=0.5))
    assert [line.split(" | ")[-1] for line in same[2:6]] == ["none |"] * 4
    assert same[-1].endswith("the same in both trees.")
    changed = wirecalls.compare(_counted(), _counted(extra=1.0, settle=0.002))
    assert "| sync read 16 | 10.0 → 11.0 | 70.0 → 71.0 | transact 50→51 |" in changed
    assert changed[-1].endswith("DIFFERENT: sync design: guard settle: 0.001 → 0.002.")


def test_wire_calls_are_counted_not_timed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Section 3's rows counted on this tree: the counts do not depend on how many transactions are
    counted, and one more call on the request path, or a longer settle time, shows in every row it touches."""
    from drivemap.runtime.client.transport import busbase, staleguard

    first, second = wirecalls.measure(6), wirecalls.measure(10)
    assert wirecalls.compare(first, second)[2:6] == wirecalls.compare(first, first)[2:6]
    assert all(first[row]["calls"] > 100 and first[row]["calls"] == second[row]["calls"] for row in wirecalls.ROWS)
    assert wirecalls.compare(first, second)[-1].endswith("the same in both trees.")
    plain = busbase.BusBase._wait_s

    def one_more_call(self: busbase.BusBase) -> float:
        return plain(self)

    monkeypatch.setattr(busbase.BusBase, "_wait_s", one_more_call)
    monkeypatch.setattr(staleguard, "_MIN_SETTLE_S", 0.002)
    slower = wirecalls.measure(6)
    assert [slower[row]["calls"] - first[row]["calls"] for row in wirecalls.ROWS] == [1.0] * 4
    lines = wirecalls.compare(first, slower)
    assert all("one_more_call 0→" in line for line in lines[2:6])
    assert "sync design: guard settle: 0.001 → 0.002" in lines[-1]
    assert "sync read 16: select timeouts (ms) per transaction: {'1.00': 1.0, " in lines[-1]
