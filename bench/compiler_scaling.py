"""(5) Compiler scaling: build time and peak memory for the real maps and synthetic maps.

Each measurement runs in a fresh subprocess (``python bench/compiler_scaling.py --worker ...``)
so that peak memory (VmHWM, ``common.peak_rss_mb``) belongs to that build alone. In the worker:

* imports happen first and are not timed (they are the same for every map);
* a warm-up build of a 10-register synthetic map compiles the Jinja templates and the JSON
  Schema validator once, so the timed build measures the per-map cost, not one-time setup;
* the timed build is ``compile_map`` (load, schema, checks, model) + ``render_tree`` +
  ``write_tree`` into a temporary folder — what ``drivemap build`` does per map;
* peak memory is the peak after the build minus the peak before it (the growth the
  build caused), plus the absolute peak.

The real maps are also built together with ``drivemap build --out TMP`` (the command itself).
These measure the compiler: they run with the compile cache off (``DRIVEMAP_NO_CACHE=1``).

The compile cache (``drivemap.cache``) is measured apart, each command a fresh ``python -m drivemap``
process with a cache folder of its own (bytecode caching on, as users run it), wall-clock time:

* ``drivemap validate`` of 100 synthetic maps of 100 registers in a project folder: the first run
  (empty cache), then the second and later runs (nothing changed);
* a no-change ``drivemap build`` of this repository's project (its ``pyproject.toml`` and ``maps/``
  copied to a temporary folder and built once first), and the files' mtimes before and after.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from common import MODELS, ROOT, Row, Section, median, peak_rss_mb, spread

SIZES_FULL = (100, 1000, 10000)
SIZES_QUICK = (100, 300)
GOAL = 1.3


def _rss_mb() -> float:
    return peak_rss_mb()


def worker(args: list[str]) -> dict[str, Any]:
    """Run in the child: build the given maps, print timings as JSON."""
    from synthetic import write_synthetic

    from drivemap import cli
    from drivemap.build import render_tree, write_tree
    from drivemap.compiler import compile_map

    mode, target = args[0], args[1]
    profile = "--profile" in args
    with tempfile.TemporaryDirectory(prefix="drivemap-bench-") as tmp:
        folder = Path(tmp)
        warm = write_synthetic(folder, 10)
        write_tree(folder / "warm-out", render_tree([compile_map(warm)]))
        before = _rss_mb()
        out = folder / "out"
        result: dict[str, Any] = {}
        path = None
        if mode == "synthetic":
            path = write_synthetic(folder, int(target))
        elif mode == "map":
            path = ROOT / "maps" / f"{target}.yaml"
        elif mode == "bound":
            return _bound(folder, target, before)
        prof = None
        if profile:
            import cProfile

            prof = cProfile.Profile()
            prof.enable()
        t0 = time.perf_counter()
        if path is None:  # the command itself, every map in maps/
            result["exit"] = _quiet_cli(cli, out)
            t1 = t2 = time.perf_counter()
        else:
            model = compile_map(path)
            t1 = time.perf_counter()
            write_tree(out, render_tree([model]), force=True)
            t2 = time.perf_counter()
            result["registers"] = len(model.registers)
            result["bytes"] = path.stat().st_size
        if prof is not None:
            prof.disable()
            import io
            import pstats

            text = io.StringIO()
            pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(14)
            result["profile"] = text.getvalue()
        result.update(compile_s=t1 - t0, render_s=t2 - t1, total_s=t2 - t0, rss_before_mb=before,
                      rss_peak_mb=_rss_mb())
    return result


def _bound(folder: Path, case: str, before: float) -> dict[str, Any]:
    """Time and memory of refusing the hostile maps the bounds stop (load.MAX_NODES, compiler.MAX_REGISTERS):
    ``nodes`` one value over the bound, ``nodes-limit`` exactly at it (refused later, by the schema, so the
    whole load is paid), ``registers`` one register over the bound."""
    from drivemap.compiler import compile_map
    from drivemap.diagnostics import CompileError
    from drivemap.frontend.load import MAX_NODES, MAX_REGISTERS

    base = (ROOT / "tests" / "bad_maps" / "bad_access_mode.yaml").read_text(encoding="utf-8").replace(
        "    access: ro\n", "    access: rw\n").replace("model: bad_access_mode", "model: big")
    import yaml

    nodes = sum(isinstance(e, (yaml.ScalarEvent, yaml.MappingStartEvent, yaml.SequenceStartEvent))
                for e in yaml.parse(base, Loader=yaml.SafeLoader)) + 1  # the base's values and the flood list
    if case == "registers":
        text = base.replace("registers:\n", "registers:\n" + "".join(
            f"  - {{name: r{i}, address: {i % 65536}, group: monitor, access: r, source: s}}\n"
            for i in range(MAX_REGISTERS + 1)), 1)
    else:
        count = MAX_NODES + 10 if case == "nodes" else MAX_NODES - nodes - 2  # "flood" key + the list
        text = base + "flood: [" + "0," * count + "0]\n"
    path = folder / "big.yaml"
    path.write_text(text, encoding="utf-8")
    t0 = time.perf_counter()
    try:
        compile_map(path)
        message = "accepted"
    except CompileError as exc:
        message = exc.diagnostics[0].message[:80]
    return {"case": case, "bytes": len(text.encode()), "total_s": time.perf_counter() - t0, "message": message,
            "rss_before_mb": before, "rss_peak_mb": _rss_mb()}


def _quiet_cli(cli: Any, out: Path) -> int:
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code: int = cli.main(["build", "--out", str(out)])
    return code


def _run_worker(mode: str, target: str, timeout: float, profile: bool = False) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", mode, target] + (["--profile"] if profile else [])
    env = dict(os.environ, PYTHONHASHSEED="0", DRIVEMAP_NO_CACHE="1")  # the compiler's cost, not the cache's
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT), env=env)
    except subprocess.TimeoutExpired:
        return {"timeout": timeout}
    if proc.returncode != 0:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1:] or [f"exit {proc.returncode}"]}
    data: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return data


def _profile_summary(text: str) -> str:
    lines = [ln.rstrip() for ln in text.splitlines() if ln.strip()]
    start = next((i for i, ln in enumerate(lines) if ln.strip().startswith("ncalls")), 0)
    head = [ln.strip() for ln in lines[:start] if "function calls" in ln]
    return "\n".join(head + lines[start:])


Runs = list[dict[str, Any]]


def _measure(rounds: int, sizes: tuple[int, ...], per_build_timeout: float,
             budget_s: float) -> tuple[list[tuple[str, Runs]], Runs, list[tuple[int, Runs]]]:
    """Build the real maps one by one, all of them with `drivemap build`, then the synthetic sizes within
    the budget: (real map runs, `drivemap build` runs, synthetic runs)."""
    started = time.perf_counter()
    real: list[tuple[str, Runs]] = []
    for model in MODELS:
        real.append((model, [_run_worker("map", model, per_build_timeout) for _ in range(rounds)]))
    cli_runs = [_run_worker("cli", "all", per_build_timeout) for _ in range(rounds)]

    synthetic: list[tuple[int, Runs]] = []
    for size in sizes:
        runs: Runs = []
        for _ in range(rounds):
            left = budget_s - (time.perf_counter() - started)
            if runs and left < per_build_timeout:
                break  # out of time for more rounds of this size: report how many ran
            runs.append(_run_worker("synthetic", str(size), min(per_build_timeout, max(left, 10.0))))
            if "timeout" in runs[-1] or "error" in runs[-1]:
                break
        synthetic.append((size, runs))
    return real, cli_runs, synthetic


def _line(sec: Section, name: str, runs: Runs) -> float | None:
    """One table line for the runs of one map; its µs/register (None when no run finished)."""
    ok = [r for r in runs if "total_s" in r]
    if not ok:
        why = runs[0].get("error") or f"timed out after {runs[0].get('timeout')} s" if runs else "not run"
        sec.detail.append(f"| {name} | — | — | {len(runs)} | {why} | | | | | |")
        return None
    tot = [r["total_s"] for r in ok]
    regs = ok[0].get("registers")
    per = median(tot) / regs * 1e6 if regs else None
    sec.detail.append(
        f"| {name} | {regs if regs else '—'} | {ok[0].get('bytes', '—')} | {len(ok)} | {median(tot):.3f} "
        f"({spread(tot)}) | {median([r['compile_s'] for r in ok]):.3f} | {median([r['render_s'] for r in ok]):.3f} "
        f"| {f'{per:.0f}' if per else '—'} | {max(r['rss_peak_mb'] for r in ok):.0f} "
        f"| {median([r['rss_peak_mb'] - r['rss_before_mb'] for r in ok]):.1f} |")
    return per


def _synthetic_lines(sec: Section, synthetic: list[tuple[int, Runs]]) -> dict[int, float | None]:
    """The synthetic maps' table lines; µs/register per size (a timeout's lower bound where one timed out)."""
    per_size: dict[int, float | None] = {}
    for size, runs in synthetic:
        per_size[size] = _line(sec, f"synthetic {size}", runs)
        if runs and "timeout" in runs[-1]:
            per_size[size] = runs[-1]["timeout"] / size * 1e6  # lower bound
            sec.detail.append(f"| ↳ lower bound | {size} | | | > {runs[-1]['timeout']:.0f} | | | "
                              f"≥ {per_size[size]:.0f} | | |")
    return per_size


def _goal_rows(sec: Section, quick: bool, sizes: tuple[int, ...], synthetic: list[tuple[int, Runs]],
               per_size: dict[int, float | None], per_build_timeout: float) -> None:
    """The cost and memory per register of the largest size against the smallest; a profile when missed."""
    small, large = sizes[0], sizes[-1]
    ps, pl = per_size.get(small), per_size.get(large)
    timed_out = any("timeout" in r for _, runs in synthetic for r in runs)
    if not (ps and pl):
        return
    ratio = pl / ps
    met = ratio <= GOAL and not timed_out
    sec.rows.append(Row("5 compiler", f"cost/register {large} vs {small} regs", ratio, f"≤ {GOAL}×", met,
                        f"{pl:.0f} vs {ps:.0f} µs/reg" + (" (lower bound: timed out)" if timed_out else "")))
    mem = {size: runs for size, runs in synthetic}
    ok_l = [r for r in mem[large] if "rss_peak_mb" in r]
    ok_s = [r for r in mem[small] if "rss_peak_mb" in r]
    if ok_l and ok_s:
        gl = median([r["rss_peak_mb"] - r["rss_before_mb"] for r in ok_l]) / large * 1024
        gs = median([r["rss_peak_mb"] - r["rss_before_mb"] for r in ok_s]) / small * 1024
        sec.rows.append(Row("5 compiler", f"memory/register {large} vs {small} regs", gl / gs if gs > 0 else None,
                            "(flat)", None, f"{gl:.1f} vs {gs:.1f} KiB/reg RSS growth",
                            "RSS growth is page-granular: noisy for small maps"))
    if not met and not quick:
        # profile the largest size that finished within one build timeout
        size = max((s for s, runs in synthetic if any("total_s" in r for r in runs)), default=small)
        if size == large and timed_out:
            size = small
        size = min(size, 1000)
        prof = _run_worker("synthetic", str(size), per_build_timeout, profile=True)
        if "profile" in prof:
            sec.profiles.append(f"cProfile of the build of a synthetic map of {size} registers "
                                f"(top entries by own time):\n\n```\n{_profile_summary(prof['profile'])}\n```")


def _bound_lines(sec: Section, per_build_timeout: float) -> None:
    """Table lines for refusing the hostile maps the bounds stop."""
    for case in ("nodes", "registers", "nodes-limit"):
        got = _run_worker("bound", case, per_build_timeout)
        if "total_s" in got:
            sec.detail.append(f"| bound: {case} | — | {got['bytes']} | 1 | {got['total_s']:.3f} ({got['message']}) "
                              f"| | | | {got['rss_peak_mb']:.0f} | {got['rss_peak_mb'] - got['rss_before_mb']:.1f} |")
        else:
            sec.detail.append(f"| bound: {case} | — | — | 1 | {got} | | | | | |")


CACHE_MAPS = 100
CACHE_MAP_REGISTERS = 100
VALIDATE_GOAL_S = 1.0
BUILD_GOAL_S = 0.5


#: What every verb pays before it starts: the interpreter, ``drivemap.cli`` and its argument parser.
STARTUP = "import drivemap.cli as c; c.parser()"


def _drivemap(args: list[str], cwd: Path, cache: Path, timeout: float = 300.0) -> float:
    """Wall-clock seconds of ``python -m drivemap ARGS`` (``["-c", CODE]``: that code) in ``cwd``
    with the cache folder ``cache``."""
    env = dict(os.environ, PYTHONHASHSEED="0", DRIVEMAP_CACHE_DIR=str(cache))
    env.pop("DRIVEMAP_NO_CACHE", None)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as users run it: drivemap's own bytecode is cached
    cmd = [sys.executable, *args] if args[0] == "-c" else [sys.executable, "-m", "drivemap", *args]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=str(cwd), env=env)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"drivemap {' '.join(args)}: {(proc.stderr or proc.stdout).strip()[-300:]}")
    return elapsed


def _mtimes(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in root.rglob("*") if "cache" not in p.parts}


def _cache_rows(sec: Section, quick: bool) -> None:
    """The compile cache: validate of 100 maps, first and later runs; a no-change build of this repository."""
    import shutil

    import yaml
    from synthetic import synthetic_map

    rounds = 2 if quick else 5
    with tempfile.TemporaryDirectory(prefix="drivemap-cache-bench-") as tmp:
        project = Path(tmp) / "catalogue"
        (project / "maps").mkdir(parents=True)
        for i in range(CACHE_MAPS):
            data = synthetic_map(f"cat{i:03d}", CACHE_MAP_REGISTERS)
            (project / "maps" / f"cat{i:03d}.yaml").write_text(yaml.safe_dump(data, sort_keys=False, width=120),
                                                                encoding="utf-8")
        cache = Path(tmp) / "cache"
        _drivemap(["--version"], project, cache)  # drivemap's own bytecode written
        nocache = [_drivemap(["validate", "--no-cache"], project, cache) for _ in range(max(1, rounds // 2))]
        first = _drivemap(["validate"], project, cache)
        again = [_drivemap(["validate"], project, cache) for _ in range(rounds)]
        repo = Path(tmp) / "repo"
        repo.mkdir()
        shutil.copy(ROOT / "pyproject.toml", repo / "pyproject.toml")
        shutil.copytree(ROOT / "maps", repo / "maps")
        build_cold = _drivemap(["build"], repo, cache)
        _drivemap(["build"], repo, cache)
        before = _mtimes(repo)
        builds = [_drivemap(["build"], repo, cache) for _ in range(rounds)]
        touched = sorted(k for k, v in _mtimes(repo).items() if before.get(k) != v)
        checks = [_drivemap(["check"], repo, cache) for _ in range(rounds)]
        build_nocache = [_drivemap(["build", "--no-cache"], repo, cache) for _ in range(max(1, rounds // 2))]
        startup = [_drivemap(["-c", STARTUP], repo, cache) for _ in range(rounds)]
    sec.detail.append("")
    sec.detail.append(f"Compile cache (fresh `python -m drivemap` processes, wall-clock seconds, median (min–max) of "
                      f"{rounds}; cache folder of its own):")
    sec.detail.append("")
    sec.detail.append("| command | cache off (`--no-cache`) | first run (empty cache) | later runs (nothing changed) |")
    sec.detail.append("|---|---:|---:|---:|")
    sec.detail.append(f"| `drivemap validate`, {CACHE_MAPS} maps of {CACHE_MAP_REGISTERS} registers | "
                      f"{median(nocache):.2f} | {first:.2f} | {median(again):.3f} ({spread(again)}) |")
    sec.detail.append(f"| `drivemap build`, this repository's maps, no change | {median(build_nocache):.2f} | "
                      f"{build_cold:.2f} | {median(builds):.3f} ({spread(builds)}) |")
    sec.detail.append(f"| `drivemap check`, the same | — | — | {median(checks):.3f} ({spread(checks)}) |")
    sec.detail.append(f"| startup of every verb (interpreter, `drivemap.cli` imported, its parser built) | — | — | "
                      f"{median(startup):.3f} ({spread(startup)}) |")
    sec.detail.append("")
    sec.detail.append(f"Files or folders whose mtime the no-change builds changed: {len(touched)}"
                      + (f" ({', '.join(touched[:5])})" if touched else "") + ".")
    v = median(again)
    sec.rows.append(Row("5 compiler", f"validate {CACHE_MAPS} maps of {CACHE_MAP_REGISTERS} regs, second run",
                        v / VALIDATE_GOAL_S, f"≤ {VALIDATE_GOAL_S:g} s", v <= VALIDATE_GOAL_S,
                        f"{v:.3f} s; first {first:.2f} s, no cache {median(nocache):.2f} s"))
    b = median(builds)
    sec.rows.append(Row("5 compiler", "no-change `drivemap build` of the repository", b / BUILD_GOAL_S,
                        f"≤ {BUILD_GOAL_S:g} s, 0 files touched", b <= BUILD_GOAL_S and not touched,
                        f"{b:.3f} s, {len(touched)} touched (startup alone {median(startup):.3f} s); "
                        f"no cache {median(build_nocache):.2f} s"))


def run(quick: bool, budget_s: float) -> Section:
    sec = Section("Compiler scaling")
    rounds = 1 if quick else 3
    sizes = SIZES_QUICK if quick else SIZES_FULL
    per_build_timeout = 60.0 if quick else 90.0
    real, cli_runs, synthetic = _measure(rounds, sizes, per_build_timeout, budget_s)
    sec.detail.append("| map | registers | map bytes | rounds | build median (s) | compile (s) | render+write (s) "
                      "| µs/register | peak RSS (MB) | RSS growth (MB) |")
    sec.detail.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for model, runs in real:
        _line(sec, f"maps/{model}.yaml", runs)
    _line(sec, "`drivemap build` (all maps)", cli_runs)
    per_size = _synthetic_lines(sec, synthetic)
    _goal_rows(sec, quick, sizes, synthetic, per_size, per_build_timeout)
    _bound_lines(sec, per_build_timeout)
    _cache_rows(sec, quick)
    return sec


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        print(json.dumps(worker(sys.argv[2:]), default=str))
    else:
        s = run("--quick" in sys.argv, 200.0)
        print("\n".join(s.detail))
        for r in s.rows:
            print(r)
        print("\n\n".join(s.profiles))
