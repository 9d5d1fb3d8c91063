"""Shared helpers of the benchmarks: medians, bounded loops, the machine description."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MODELS = ("ev", "vfd1000", "v2", "edx")


def peak_rss_mb() -> float:
    """This process's own peak resident memory (MB): VmHWM on Linux, which exec resets.

    ``ru_maxrss`` is not used where /proc exists: Linux carries it across exec from the parent, so a
    worker started by a large process would report the parent's peak as its own.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def median(values: Sequence[float]) -> float:
    return float(statistics.median(values)) if values else float("nan")


def spread(values: Sequence[float]) -> str:
    """min..max of the rounds, for the reader to judge the noise."""
    if not values:
        return "—"
    return f"{min(values):.4g}..{max(values):.4g}"


def bounded(fn: Callable[[], Any], count: int, seconds: float) -> tuple[int, float]:
    """Call ``fn`` at most ``count`` times and stop after ``seconds``; (calls made, elapsed s)."""
    start = time.perf_counter()
    deadline = start + seconds
    done = 0
    while done < count:
        fn()
        done += 1
        if time.perf_counter() >= deadline:
            break
    return done, time.perf_counter() - start


async def abounded(fn: Callable[[], Any], count: int, seconds: float) -> tuple[int, float]:
    """Async twin of :func:`bounded` (``fn`` returns an awaitable)."""
    start = time.perf_counter()
    deadline = start + seconds
    done = 0
    while done < count:
        await fn()
        done += 1
        if time.perf_counter() >= deadline:
            break
    return done, time.perf_counter() - start


def machine() -> dict[str, str]:
    """CPU model, cores, Python and pymodbus versions, date."""
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        import pymodbus

        pm = pymodbus.__version__
    except Exception:  # noqa: BLE001 - reported, not fatal
        pm = "not installed"
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 0
    return {
        "cpu": cpu,
        "cores": str(cores),
        "python": platform.python_version(),
        "pymodbus": pm,
        "os": f"{platform.system()} {platform.release()}",
        "load": " ".join(f"{x:.2f}" for x in os.getloadavg()),
        "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
    }


@dataclass
class Row:
    """One line of the summary table: a ratio against its goal, with the absolute figures."""

    section: str
    name: str
    ratio: float | None
    goal: str
    met: bool | None
    absolute: str
    note: str = ""


@dataclass
class Section:
    """What a benchmark section returns: summary rows, Markdown detail, profiles of misses."""

    title: str
    rows: list[Row] = field(default_factory=list)
    detail: list[str] = field(default_factory=list)
    profiles: list[str] = field(default_factory=list)
    error: str | None = None
    explanation: str = ""
    """Measured facts for the shortfall paragraph (sections that compute their own explanation)."""


def print_section(section: Section) -> int:
    """A section on stdout for a bench module run alone: its error (exit 1), else its rows and detail."""
    if section.error:
        print(section.error)
        return 1
    for row in section.rows:
        print(f"{row.name}: {row.ratio if row.ratio is None else round(row.ratio, 3)} (goal {row.goal}) {row.absolute}")
    print("\n".join(section.detail))
    return 0


def profile_text(fn: Callable[[], Any], top: int = 15, sort: str = "tottime") -> str:
    """cProfile of one call of ``fn``: the ``top`` entries by ``sort``."""
    import cProfile
    import io
    import pstats

    prof = cProfile.Profile()
    prof.enable()
    try:
        fn()
    finally:
        prof.disable()
    out = io.StringIO()
    stats = pstats.Stats(prof, stream=out)
    stats.strip_dirs().sort_stats(sort).print_stats(top)
    text = out.getvalue()
    lines = [ln.rstrip() for ln in text.splitlines()]
    start = next((i for i, ln in enumerate(lines) if ln.strip().startswith("ncalls")), 0)
    head = [ln for ln in lines[:start] if "function calls" in ln]
    return "\n".join(head + lines[start:]).strip()
