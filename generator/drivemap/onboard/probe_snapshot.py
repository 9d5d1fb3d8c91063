"""Probe snapshots (every value read, as JSON) and ``drivemap probe --diff A.json B.json``.

A snapshot is ``{"drivemap_probe": 1, "date": ..., "link": ..., "unit": N, "tables": {"holding":
{"40000": 21365, ...}, ...}}``. The diff lists each address whose value changed, and the addresses
read in only one of the two: the "change one setting, see what moved" method.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.probe import STANDARD_MAX

if TYPE_CHECKING:
    from drivemap.onboard.probe_bisect import Outcome

__all__ = ["diff", "load_snapshot", "snapshot_text"]

TABLES = tuple(STANDARD_MAX)
#: a snapshot of all four tables, every address read, is ~6 MB; anything larger is not one
MAX_SNAPSHOT_BYTES = 32 * 1024 * 1024


def snapshot_text(values: dict[str, dict[int, int]], *, date: str, link: str, unit: int,
                  outcome: Outcome | None = None) -> str:
    doc: dict[str, Any] = {"drivemap_probe": 1, "date": date, "link": link, "unit": unit,
                           "tables": {t: {str(a): v for a, v in sorted(values[t].items())} for t in TABLES if values.get(t)}}
    if outcome is not None:  # what the bisection proved unreadable and left open ("A-B" inclusive)
        for key, spans in (("unreadable", outcome.unreadable), ("unresolved", outcome.unresolved)):
            doc[key] = {t: [f"{a}-{b}" for a, b in s] for t, s in spans.items() if s}
    return json.dumps(doc, indent=1) + "\n"


def _error(path: Path, message: str, line: int = 1, col: int = 1) -> CompileError:
    return CompileError([Diagnostic(Location(display(path), line, col), message)])


def load_snapshot(path: Path) -> dict[str, dict[int, int]]:
    """The values of a snapshot file; a located error for anything else."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            raise _error(path, "not a regular file (a FIFO, device or folder); refused")
        with open(path, "rb") as handle:
            raw = handle.read(MAX_SNAPSHOT_BYTES + 1)  # bounded even if the file grows while it is read
        if len(raw) > MAX_SNAPSHOT_BYTES:
            raise _error(path, f"file larger than {MAX_SNAPSHOT_BYTES} bytes; not a probe snapshot; refused")
        text = raw.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise _error(path, f"cannot read snapshot: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        doc: Any = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _error(path, f"not JSON: {exc.msg}", exc.lineno, exc.colno) from None
    except RecursionError:
        raise _error(path, "not a drivemap probe snapshot: JSON nested too deeply") from None
    if not isinstance(doc, dict) or doc.get("drivemap_probe") != 1 or not isinstance(doc.get("tables"), dict):
        raise _error(path, "not a drivemap probe snapshot (written by drivemap probe --snapshot FILE)")
    out: dict[str, dict[int, int]] = {}
    for table, cells in doc["tables"].items():
        if table not in TABLES or not isinstance(cells, dict):
            raise _error(path, f"unknown table {table!r} (holding, input, coil, discrete)")
        try:
            out[table] = {int(a): int(v) for a, v in cells.items() if 0 <= int(a) <= 0xFFFF}
        except (TypeError, ValueError):
            raise _error(path, f"table {table}: addresses and values are integers") from None
    return out


def diff(a: dict[str, dict[int, int]], b: dict[str, dict[int, int]]) -> list[str]:
    """One line per changed address: ``holding 0x9C40 (40000): 21365 -> 21366`` (hex in brackets)."""
    lines = []
    for table in TABLES:
        old, new = a.get(table, {}), b.get(table, {})
        for address in sorted(set(old) | set(new)):
            before, after = old.get(address), new.get(address)
            if before == after:
                continue
            shown = [("-" if v is None else f"{v} (0x{v:04X})") for v in (before, after)]
            where = f"{table} {address} (0x{address:04X})"
            if before is None:
                lines.append(f"{where}: only in the second snapshot: {shown[1]}")
            elif after is None:
                lines.append(f"{where}: only in the first snapshot: {shown[0]}")
            else:
                lines.append(f"{where}: {shown[0]} -> {shown[1]}")
    return lines
