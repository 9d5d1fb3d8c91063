"""Against the baseline: section 2's client overhead and section 8's import time, for the baseline tree
and the current tree side by side in the same run.

Different runs on a shared machine are not comparable (a loaded machine lengthens the loopback round
trip, which lowers every overhead ratio), so both trees are measured here in one run, in interleaved
rounds, against one simulator:

* the baseline tree (commit ``BASELINE``: ``git archive`` of the commit into a temporary folder; the
  work tree and the repository are not touched) and the
  current tree (this checkout, as it is on disk);
* each figure comes from a subprocess whose ``PYTHONPATH`` is that tree's ``generator``, ``generated``
  and ``bench`` (its runtime, its generated ``drivemap_models`` and its own bench code); the child
  reports the files it imported, which are checked to be that tree's;
* **client overhead**: one generated simulator (this tree's ``servers.py``, its own process) serves
  both trees' workers. A round runs one worker per tree (which tree goes first alternates, and so does
  which client goes first within a pair); a worker runs section 2's operations with that tree's
  ``overhead._ops_sync`` / ``_ops_async`` and ``paired`` / ``apaired`` and returns each operation's
  median drivemap and raw pymodbus time per call: the round's ratio, as in section 2;
* **import time**: each tree builds its synthetic map of ``IMPORT_SIZE`` registers with its own
  ``imports.build`` (its compiler, its ``synthetic.py``); each round imports it with that tree's
  ``imports._child`` (a fresh interpreter, cold then cached or the reverse), trees interleaved.

**current/baseline** is the median of the per-round quotients (the two trees' figures of one round
were taken seconds apart). Verdict: **no worse** when the current median is at or below the
baseline's; **within spread** when it is above it but not above the baseline's worst round and not
every round's quotient is above 1; **WORSE** otherwise.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

from common import ROOT, Row, Section, median, spread

TITLE = "Against the baseline (same run)"
SECTION = "12 baseline"
BASELINE = "35fa167"
IMPORT_SIZE = 10000
OPS = ("read_all", "read 8", "read one", "write one")

CHILD = Path(__file__).resolve().parent / "baseline_child.py"
DEFINITION = f"""\
Section 2's client overhead and section 8's import time for the baseline tree (commit `{BASELINE}`, the tree
before the runtime's layer refactor, extracted with `git archive` into a temporary folder) and the current
tree, in this run: interleaved rounds, each figure from a fresh interpreter whose `PYTHONPATH` is that tree's
`generator`, `generated` and `bench` (its runtime, its generated clients, its own `overhead` and `imports`
code, `bench/baseline_child.py`), one generated simulator serving both (`bench/baseline.py`). A round's ratio
is section 2's (median drivemap time per call / median raw pymodbus time per call, calls alternating);
**current / baseline** is the median of the per-round quotients of the two trees (measured seconds apart).
Verdict: **no worse** when the current median is at or below the baseline's; **within spread** when it is
above it but not above the baseline's worst round and not every round (of 5 or more) is above 1; **WORSE**
otherwise. Ratios of different runs differ with the loopback round trip (the same µs of overhead is a larger
ratio on a faster round trip), which is why only figures of one run are compared. The µs table splits the
time: on the network, and with pymodbus's `execute()` replaced by the replies it gave (the client's own
layers' CPU, the least of 5 loops per round)."""


def baseline_tree(dest: Path, commit: str | None = None) -> str | None:
    """Extract ``commit``'s tree under ``dest`` (all of it: the package's data folder links to schemas/, maps/
    and docs/); why not, or None."""
    commit = commit or BASELINE
    try:
        probe = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}"],
                               capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"git is not available ({exc})"
    if probe.returncode != 0:
        return f"commit {commit} is not in a git repository at {ROOT} (a wheel install or a shallow clone)"
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", commit], capture_output=True,
                             timeout=300)
    if archive.returncode != 0:
        return f"git archive {commit} failed: {archive.stderr.decode(errors='replace').strip()}"
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(dest, filter="data")
    return None


def _env(tree: Path) -> dict[str, str]:
    env = dict(os.environ, PYTHONHASHSEED="0")
    env["PYTHONPATH"] = os.pathsep.join(str(tree / d) for d in ("generator", "generated", "bench"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _call(tree: Path, *args: str, timeout: float = 600) -> dict[str, Any]:
    """Run ``baseline_child.py args`` in a fresh interpreter on ``tree``'s code; its last stdout line as JSON."""
    proc = subprocess.run([sys.executable, str(CHILD), *args], capture_output=True, text=True, timeout=timeout,
                          cwd=str(tree / "bench"), env=_env(tree))
    if proc.returncode != 0:
        raise RuntimeError(f"child on {tree} failed ({proc.returncode}): {proc.stderr[-3000:]}")
    result: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    for name in result.get("files", []):
        if not Path(name).resolve().is_relative_to(tree.resolve()):
            raise RuntimeError(f"child on {tree} imported {name}, not that tree's code")
    return result


def _verdict(base: list[float], cur: list[float]) -> tuple[str, bool]:
    quotients = [c / b for b, c in zip(base, cur, strict=True)]
    if median(cur) <= median(base):
        return "no worse", True
    if median(cur) <= max(base) and not (len(quotients) >= 5 and min(quotients) > 1.0):
        return "within spread", True
    return "WORSE", False


def _overhead_rounds(trees: dict[str, Path], rounds: int, count: int, seconds: float, stub_calls: int
                     ) -> dict[str, dict[str, list[float]]]:
    """tree -> "mode op" -> per-round ratio (drivemap / raw pymodbus); "mode op µs" -> drivemap µs/op;
    "stub mode op" -> µs/call with pymodbus's ``execute()`` replaced by the replies it gave."""
    import overhead
    from servers import Child

    out: dict[str, dict[str, list[float]]] = {name: {} for name in trees}
    with Child("tcp", overhead.MODEL, "drivemap", max_seconds=1800.0) as server:
        host, port = server.fields[0], server.fields[1]
        names = list(trees)
        for i in range(rounds):
            swap = "1" if (i // 2) % 2 else "0"
            for name in (names if i % 2 == 0 else names[::-1]):
                res = _call(trees[name], "overhead", host, port, str(count), str(seconds), swap, str(stub_calls))
                for mode in ("sync", "async"):
                    for op, (ours, theirs) in res[mode].items():
                        out[name].setdefault(f"{mode} {op}", []).append(ours / theirs)
                        out[name].setdefault(f"{mode} {op} µs", []).append(ours * 1e6)
                    for op, us in res[f"stub {mode}"].items():
                        out[name].setdefault(f"stub {mode} {op}", []).append(us)
    return out


def _import_rounds(trees: dict[str, Path], tmp: Path, size: int, rounds: int) -> dict[str, dict[str, list[float]]]:
    """tree -> "cold"/"cached" -> per-round import seconds of that tree's synthetic client."""
    built: dict[str, tuple[str, str]] = {}
    for n, (name, tree) in enumerate(trees.items()):
        folder = tmp / f"imports{n}"
        folder.mkdir()
        path, package = _call(tree, "build", str(folder), str(size))["built"]
        built[name] = (path, package)
        _call(tree, "import", path, package, "1")  # writes __pycache__ (not counted)
    out: dict[str, dict[str, list[float]]] = {name: {"cold": [], "cached": []} for name in trees}
    names = list(trees)
    for i in range(rounds):
        for name in (names if i % 2 == 0 else names[::-1]):
            for cached in (("0", "1") if i % 2 == 0 else ("1", "0")):
                seconds = _call(trees[name], "import", *built[name], cached)["import_s"]
                out[name]["cached" if cached == "1" else "cold"].append(seconds)
                if cached == "0":
                    _call(trees[name], "import", *built[name], "1")  # restore __pycache__
    return out


def _compare(sec: Section, measure: str, base: list[float], cur: list[float], unit: str, digits: int,
             row: bool = True) -> None:
    """One line of the comparison table (and of the summary when ``row``)."""
    quotients = [c / b for b, c in zip(base, cur, strict=True)]
    verdict, ok = _verdict(base, cur)
    q = median(cur) / median(base)

    def fig(v: list[float]) -> str:
        return f"{median(v):.{digits}f} ({min(v):.{digits}f}..{max(v):.{digits}f})"

    sec.detail.append(f"| {measure} | {fig(base)} | {fig(cur)} | {median(quotients):.3f} ({spread(quotients)}) "
                      f"| {verdict} | {len(base)} |")
    if row:
        sec.rows.append(Row(SECTION, f"{measure}: current / {BASELINE}", q, "≤ 1.00 (within spread)", ok,
                            f"{median(cur):.{digits}f} vs {median(base):.{digits}f}{unit}; {verdict}"))


def _head() -> str:
    try:
        rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=30).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "generator", "generated",
                                "bench"], capture_output=True, text=True, timeout=60).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        return "the work tree"
    return f"`{rev}`" + (" with uncommitted changes" if dirty else "") if rev else "the work tree"


def _report(sec: Section, over: dict[str, dict[str, list[float]]], imp: dict[str, dict[str, list[float]]],
            size: int) -> None:
    b, c = over["baseline"], over["current"]
    head = ("| measure | baseline (range) | current (range) | current / baseline, per round (range) | verdict "
            "| rounds |", "|---|---:|---:|---:|---|---:|")
    sec.detail += [*head]
    for mode in ("sync", "async"):
        for op in OPS:
            _compare(sec, f"{mode} {op} ratio", b[f"{mode} {op}"], c[f"{mode} {op}"], "", 3)
    for kind in ("cached", "cold"):
        _compare(sec, f"import of a {size}-register client ({kind}), s", imp["baseline"][kind], imp["current"][kind],
                 " s", 3)
    sec.detail += ["", "The same rounds in µs per call: the generated client on the network (the ratios' numerator), "
                   "and with `execute()` stubbed (the client's own layers):", "", *head]
    for mode in ("sync", "async"):
        for op in OPS:
            _compare(sec, f"{mode} {op}: µs/op on the network", b[f"{mode} {op} µs"], c[f"{mode} {op} µs"], " µs", 1,
                     row=False)
    for mode in ("sync", "async"):
        for op in OPS:
            _compare(sec, f"{mode} {op}: µs/call, execute() stubbed", b[f"stub {mode} {op}"],
                     c[f"stub {mode} {op}"], " µs", 2, row=False)


def run(quick: bool) -> Section:
    sec = Section(TITLE)
    rounds, count, seconds, stub_calls = (3, 60, 0.2, 200) if quick else (9, 300, 0.6, 1000)
    import_rounds, size = (2, 1000) if quick else (5, IMPORT_SIZE)
    with tempfile.TemporaryDirectory(prefix="drivemap-baseline-") as tmp_name:
        tmp = Path(tmp_name)
        why = baseline_tree(tmp / "baseline")
        if why is not None:
            sec.rows.append(Row(SECTION, f"client overhead and import time vs {BASELINE}", None, "—", None,
                                f"not measured: {why}"))
            sec.detail.append(f"Not measured: {why}.")
            return sec
        trees = {"baseline": tmp / "baseline", "current": ROOT}
        started = time.perf_counter()
        over = _overhead_rounds(trees, rounds, count, seconds, stub_calls)
        over_s = time.perf_counter() - started
        started = time.perf_counter()
        imp = _import_rounds(trees, tmp, size, import_rounds)
        imp_s = time.perf_counter() - started
    sec.detail += [f"Baseline: commit `{BASELINE}`; current: {_head()}. Client overhead: model vfd1000, {rounds} "
                   f"rounds of up to {count} call pairs per operation ({over_s:.0f} s); import: a synthetic map of "
                   f"{size} registers, {import_rounds} rounds ({imp_s:.0f} s).", ""]
    _report(sec, over, imp, size)
    return sec


if __name__ == "__main__":
    s = run("--quick" in sys.argv)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
