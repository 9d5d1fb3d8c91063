"""Against the baseline: section 2's client overhead, section 3's wire efficiency and section 8's import time,
for the baseline tree and the current tree side by side in the same run.

Different runs on a shared machine are not comparable (a loaded machine lengthens the loopback round
trip, which lowers every overhead ratio), so both trees are measured here in one run, in interleaved
rounds:

* the baseline tree (commit ``BASELINE``: ``git archive`` of the commit into a temporary folder; the
  work tree and the repository are not touched) and the current tree (this checkout, as it is on disk);
* each figure comes from a subprocess whose ``PYTHONPATH`` is that tree's ``generator``, ``generated``
  and ``bench`` (its runtime, its generated ``drivemap_models`` and its own bench code) and a folder
  with the tree's own ``drivemap`` entry points (:func:`tree_metadata`); the child reports the files it
  imported, which are checked to be that tree's;
* **client overhead**: one generated simulator (this tree's ``servers.py``, its own process) serves
  both trees' workers. A round runs one worker per tree (which tree goes first alternates, and so does
  which client goes first within a pair); a worker runs section 2's operations with that tree's
  ``overhead._ops_sync`` / ``_ops_async`` and ``paired`` / ``apaired`` and returns each operation's
  median drivemap and raw pymodbus time per call: the round's ratio, as in section 2;
* **wire efficiency**: each round runs each tree's own ``wire.run`` (quick form: its line relay, its
  simulator, its clients) and keeps section 3's rows with a goal (``WIRE_ROWS``); the current tree runs
  a second time in each round as an A/A control (``control``: the same code against itself), whose
  per-round quotients show how far the paced line moves a figure with no change at all;
* **wire calls** (detail only): section 3's rows counted, not timed, on each tree's code
  (``wirecalls.py``, this checkout's, run by the child on that tree's runtime, generated client and
  simulator and its own ``wire.pick``): Python calls and bytecode instructions per transaction and the
  waits the request path is set to keep, which the machine's load does not move;
* **import time**: each tree builds its synthetic map of ``IMPORT_SIZE`` registers with its own
  ``imports.build`` (its compiler, its ``synthetic.py``); each round imports it with that tree's
  ``imports._child`` (a fresh interpreter, cold then cached or the reverse), trees interleaved.

**current/baseline** is the median of the per-round quotients (the two trees' figures of one round
were taken seconds apart). Verdict: **no worse** when the current median is at or below the
baseline's (at or above it for an efficiency); **within spread** when it is past it but not past the
baseline's worst round and not every round (of 5 or more) is worse; **within noise** (an efficiency
only) when it is worse by those rules but its current/baseline quotient is no lower than the A/A
control's lowest per-round quotient of the same run; **WORSE** otherwise.
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
import tomllib
from pathlib import Path
from typing import Any

import wirecalls
from common import ROOT, Row, Section, median, spread

TITLE = "Against the baseline (same run)"
SECTION = "12 baseline"
BASELINE = "35fa167"
IMPORT_SIZE = 10000
OPS = ("read_all", "read 8", "read one", "write one")
#: Section 3's rows with a goal: the generated client on the generated simulator.
WIRE_ROWS = wirecalls.ROWS
#: Transactions per row counted by ``wirecalls`` (calls and instructions per transaction do not vary with it).
WIRE_CALLS = 100

CHILD = Path(__file__).resolve().parent / "baseline_child.py"
DEFINITION = f"""\
Section 2's client overhead, section 3's wire efficiency (its rows with a goal) and section 8's import time for
the baseline tree (commit `{BASELINE}`, the tree before the runtime's layer refactor, extracted with `git
archive` into a temporary folder) and the current tree, in this run: interleaved rounds, each figure from a
fresh interpreter whose `PYTHONPATH` is that tree's `generator`, `generated` and `bench` (its runtime, its
generated clients and simulators, its own `overhead`, `wire` and `imports` code, driven by
`bench/baseline_child.py`) and a folder holding the tree's own `drivemap` entry points (the installed ones name
this checkout's modules). Section 2's rounds share one generated simulator; section 3 runs each tree's own
(its quick form per round: 2 rounds of up to 30 requests per client and operation). A round's ratio is section
2's (median drivemap time per call / median raw pymodbus time per call, calls alternating). **current /
baseline** is the median of the per-round quotients of the two trees (measured seconds apart). Verdict: **no
worse** when the current median is at or below the baseline's (at or above it for an efficiency); **within
spread** when it is past it but not past the baseline's worst round and not every round (of 5 or more) is
worse; for an efficiency, **within noise** when it is worse by those rules but its current / baseline is no
lower than the lowest per-round quotient of an A/A control: the current tree's section 3 run a second time in
every round (the same code against itself, interleaved with the others), which shows how far the paced line
moves a figure with nothing changed; **WORSE** otherwise. Ratios of different runs differ with the loopback round trip (the same µs of
overhead is a larger ratio on a faster round trip), which is why only figures of one run are compared. The µs
table (diagnostic, not in the summary) splits the time: on the network, and with pymodbus's `execute()`
replaced by the replies it gave (the client's own layers' CPU, the least of 5 loops per round). The last table
counts section 3's rows instead of timing them (`bench/wirecalls.py`): Python calls and bytecode instructions per
transaction of each tree's client (and of its simulator's own work) and the waits on the request path; equal
counts and waits mean a difference in the wire rows above is the paced line's noise."""


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


#: tree -> a folder holding only the tree's own ``drivemap`` distribution metadata (see :func:`tree_metadata`).
_METADATA: dict[Path, Path] = {}


def tree_metadata(tree: Path, dest: Path) -> Path:
    """A folder with a ``drivemap`` dist-info carrying ``tree``'s own entry points (its pyproject's).

    The installed ``drivemap`` (this checkout, editable) declares entry points into this tree's modules
    (behaviours, exporters); the baseline's simulators would load them. On ``PYTHONPATH`` this folder comes
    before site-packages, and ``importlib.metadata`` keeps the first distribution of a name."""
    project = tomllib.loads((tree / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    info = dest / "drivemap-0+bench.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: drivemap\nVersion: 0+bench\n", encoding="utf-8")
    lines = []
    for group, entries in project.get("entry-points", {}).items():
        lines += [f"[{group}]", *(f"{name} = {value}" for name, value in entries.items()), ""]
    (info / "entry_points.txt").write_text("\n".join(lines), encoding="utf-8")
    _METADATA[tree] = dest
    return dest


def _env(tree: Path) -> dict[str, str]:
    env = dict(os.environ, PYTHONHASHSEED="0")
    paths = [tree / d for d in ("generator", "generated", "bench")]
    if tree in _METADATA:
        paths.append(_METADATA[tree])
    env["PYTHONPATH"] = os.pathsep.join(str(p) for p in paths)
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


def _verdict(base: list[float], cur: list[float], higher: bool = False) -> tuple[str, bool]:
    """(verdict, no worse) of the current rounds against the baseline rounds; ``higher``: more is better."""
    sign = -1.0 if higher else 1.0
    base, cur = [sign * b for b in base], [sign * c for c in cur]
    worse_every_round = len(base) >= 5 and all(c > b for b, c in zip(base, cur, strict=True))
    if median(cur) <= median(base):
        return "no worse", True
    if median(cur) <= max(base) and not worse_every_round:
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


def _wire_rounds(trees: dict[str, Path], rounds: int) -> dict[str, dict[str, list[float]]]:
    """tree -> section 3 row -> per-round efficiency (each tree's own ``wire.run`` in its quick form)."""
    out: dict[str, dict[str, list[float]]] = {name: {} for name in trees}
    names = list(trees)
    for i in range(rounds):
        for name in (names if i % 2 == 0 else names[::-1]):
            for row, eff in _call(trees[name], "wire")["rows"].items():
                out[name].setdefault(row, []).append(eff)
    return out


def _wire_calls(trees: dict[str, Path], transactions: int) -> dict[str, dict[str, Any]]:
    """tree -> section 3's rows counted on that tree's code (``wirecalls.py``: calls, instructions, waits)."""
    return {name: _call(tree, "wirecalls", str(transactions)) for name, tree in trees.items()}


def _import_rounds(trees: dict[str, Path], tmp: Path, size: int, rounds: int) -> dict[str, dict[str, list[float]]]:
    """tree -> "cold"/"cached" -> per-round import seconds of that tree's synthetic client; "construct" ->
    import and first ``Client.tcp()`` (cached)."""
    built: dict[str, tuple[str, str]] = {}
    for n, (name, tree) in enumerate(trees.items()):
        folder = tmp / f"imports{n}"
        folder.mkdir()
        path, package = _call(tree, "build", str(folder), str(size))["built"]
        built[name] = (path, package)
        _call(tree, "import", path, package, "1")  # writes __pycache__ (not counted)
    out: dict[str, dict[str, list[float]]] = {name: {"cold": [], "cached": [], "construct": []} for name in trees}
    names = list(trees)
    for i in range(rounds):
        for name in (names if i % 2 == 0 else names[::-1]):
            for cached in (("0", "1") if i % 2 == 0 else ("1", "0")):
                seconds = _call(trees[name], "import", *built[name], cached)["import_s"]
                out[name]["cached" if cached == "1" else "cold"].append(seconds)
                if cached == "0":
                    _call(trees[name], "import", *built[name], "1")  # restore __pycache__
            out[name]["construct"].append(_call(trees[name], "construct", *built[name])["seconds"])
    return out


def _noise_verdict(q: float, control: list[float], verdict: str, ok: bool) -> tuple[str, bool]:
    """``verdict`` of a quotient ``q`` (more is better), or **within noise** when the A/A ``control``
    quotients (the same code against itself, per round) fall as low as ``q`` does."""
    if ok or not control:
        return verdict, ok
    floor = min(control)
    if q >= floor:
        return f"within noise (A/A down to {floor:.3f})", True
    return f"{verdict} (A/A down to {floor:.3f})", False


def _compare(sec: Section, measure: str, base: list[float], cur: list[float], unit: str, digits: int,
             row: bool = True, higher: bool = False, control: list[float] | None = None) -> None:
    """One line of the comparison table (and of the summary when ``row``); ``higher``: more is better;
    ``control``: the A/A control's per-round quotients (an efficiency's noise, same run)."""
    quotients = [c / b for b, c in zip(base, cur, strict=True)]
    verdict, ok = _verdict(base, cur, higher)
    q = median(cur) / median(base)
    if higher:
        verdict, ok = _noise_verdict(q, control or [], verdict, ok)

    def fig(v: list[float]) -> str:
        return f"{median(v):.{digits}f} ({min(v):.{digits}f}..{max(v):.{digits}f})"

    sec.detail.append(f"| {measure} | {fig(base)} | {fig(cur)} | {median(quotients):.3f} ({spread(quotients)}) "
                      f"| {verdict} | {len(base)} |")
    if row:
        sec.rows.append(Row(SECTION, f"{measure}: current / {BASELINE}", q,
                            "≥ 1.00 (within spread)" if higher else "≤ 1.00 (within spread)", ok,
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


def _report(sec: Section, over: dict[str, dict[str, list[float]]], wire: dict[str, dict[str, list[float]]],
            imp: dict[str, dict[str, list[float]]], size: int) -> None:
    b, c = over["baseline"], over["current"]
    head = ("| measure | baseline (range) | current (range) | current / baseline, per round (range) | verdict "
            "| rounds |", "|---|---:|---:|---:|---|---:|")
    sec.detail += [*head]
    for mode in ("sync", "async"):
        for op in OPS:
            _compare(sec, f"{mode} {op} ratio", b[f"{mode} {op}"], c[f"{mode} {op}"], "", 3)
    for name in WIRE_ROWS:
        if name in wire["baseline"] and name in wire["current"]:
            control = [c2 / c for c, c2 in zip(wire["current"][name], wire.get("control", {}).get(name, []),
                                                 strict=False)]
            _compare(sec, f"wire {name} efficiency", wire["baseline"][name], wire["current"][name], "", 3,
                     higher=True, control=control)
        else:
            sec.rows.append(Row(SECTION, f"wire {name} efficiency", None, "—", None,
                                "not measured: a tree's section 3 has no such row"))
    for kind in ("cached", "cold"):
        _compare(sec, f"import of a {size}-register client ({kind}), s", imp["baseline"][kind], imp["current"][kind],
                 " s", 3)
    _compare(sec, "the same, cached, + first `Client.tcp()` (info), s", imp["baseline"]["construct"],
             imp["current"]["construct"], " s", 3, row=False)
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
    wire_rounds, import_rounds, size = (1, 2, 1000) if quick else (6, 5, IMPORT_SIZE)
    took: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="drivemap-baseline-") as tmp_name:
        tmp = Path(tmp_name)
        why = baseline_tree(tmp / "baseline")
        if why is not None:
            sec.rows.append(Row(SECTION, f"client overhead, wire efficiency and import time vs {BASELINE}", None,
                                "—", None, f"not measured: {why}"))
            sec.detail.append(f"Not measured: {why}.")
            return sec
        trees = {"baseline": tmp / "baseline", "current": ROOT}
        for n, tree in enumerate(trees.values()):
            tree_metadata(tree, tmp / f"metadata{n}")
        took["overhead"] = time.perf_counter()
        over = _overhead_rounds(trees, rounds, count, seconds, stub_calls)
        took["wire"] = time.perf_counter()
        wire = _wire_rounds({**trees, "control": ROOT}, wire_rounds)
        took["calls"] = time.perf_counter()
        calls = _wire_calls(trees, WIRE_CALLS)
        took["import"] = time.perf_counter()
        imp = _import_rounds(trees, tmp, size, import_rounds)
        took["end"] = time.perf_counter()
    sec.detail += [f"Baseline: commit `{BASELINE}`; current: {_head()}. Client overhead: model vfd1000, {rounds} "
                   f"rounds of up to {count} call pairs per operation ({took['wire'] - took['overhead']:.0f} s); "
                   f"wire: {wire_rounds} rounds of each tree's section 3 in its quick form, the current tree "
                   "twice per round (the second run its A/A control) "
                   f"({took['calls'] - took['wire']:.0f} s); import: a synthetic map of {size} registers, "
                   f"{import_rounds} rounds ({took['end'] - took['import']:.0f} s).", ""]
    _report(sec, over, wire, imp, size)
    sec.detail += ["", f"Section 3's rows counted, not timed ({took['import'] - took['calls']:.0f} s; "
                   "`bench/wirecalls.py` on each tree's code: the same client calls as section 3 on a pty answered "
                   f"by the tree's simulator without delay, {WIRE_CALLS} transactions per row after a warm-up, "
                   "each begun after the bus's quiet time so no wait loop is counted; the load of the machine "
                   "does not move these figures):", "", *wirecalls.compare(calls["baseline"], calls["current"])]
    return sec


if __name__ == "__main__":
    s = run("--quick" in sys.argv)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
