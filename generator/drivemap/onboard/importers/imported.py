"""What the importers of other projects' definition files share (evcc, ha-solarman, modbus_local_gateway,
SunSpec): located errors, open fields (a register's ``review`` list), and the map's evidence and origin.

The origin (project, commit, licence) is read from a ``SOURCE`` file (``owner/name @ commit``) and a
``LICENSE`` file in the source file's folder or one of its two parents, as ``catalogue-sources/`` keeps
them; a file without them is imported with ``evidence: imported`` and no origin (a review note says so).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.importers.mapdoc import MapDoc

__all__ = ["Occupancy", "error_at", "fits", "find_origin", "leave_open", "licence_id", "mark_imported"]

_SOURCE_LINE = re.compile(r"^\s*([\w.-]+/[\w.-]+)\s*@\s*([0-9a-fA-F]{7,40})\s*$")


def error_at(path: Path, line: int, message: str, col: int = 1) -> CompileError:
    """``path:line:col: error: message`` (what the importer cannot read, and why)."""
    return CompileError([Diagnostic(Location(display(path), max(line, 1), max(col, 1)), message)])


def mark_open(reg: dict[str, Any], *fields: str) -> list[str]:
    """List ``fields`` of ``reg`` in its ``review`` list (not stated by the source); returns those new to it."""
    listed: list[str] = reg.setdefault("review", [])
    new = [f for f in fields if f not in listed]
    listed.extend(new)
    return new


def leave_open(doc: MapDoc, reg: dict[str, Any], *fields: str) -> None:
    """Mark ``fields`` of ``reg`` as not stated by the source (its ``review`` list and the printed review)."""
    doc.review.miss(reg["name"], *mark_open(reg, *fields))


def licence_id(text: str) -> str | None:
    """The SPDX id of a licence text (the ones the catalogue sources use)."""
    head = text[:4000]
    if "Apache License" in head and "Version 2.0" in head:
        return "Apache-2.0"
    if "Permission is hereby granted, free of charge" in head:
        return "MIT"
    return None


def find_origin(path: Path, project_path: str) -> tuple[str, str, str] | None:
    """(project, commit, licence) from the SOURCE and LICENSE files next to ``path`` or above it."""
    folder = path.resolve().parent
    for candidate in (folder, folder.parent, folder.parent.parent):
        source, licence = candidate / "SOURCE", candidate / "LICENSE"
        if source.is_file() and licence.is_file():
            match = _SOURCE_LINE.match(source.read_text(encoding="utf-8").strip().splitlines()[0])
            spdx = licence_id(licence.read_text(encoding="utf-8", errors="replace"))
            if match and spdx:
                return match.group(1), match.group(2), spdx
    return None


def mark_imported(doc: MapDoc, path: Path, project_path: str, fmt: str, kind: str | None) -> None:
    """``device.evidence: imported``, ``device.kind`` and ``device.origin`` (when the folder says it)."""
    doc.evidence = "imported"
    doc.kind = kind
    found = find_origin(path, project_path)
    if found is None:
        doc.review.notes.append(f"{path.name}: no SOURCE and LICENSE files beside it: device.origin (project, "
                                "commit, licence) is not stated; add it before sharing the map")
        return
    project, commit, licence = found
    doc.origin = {"project": project, "path": project_path, "commit": commit, "licence": licence, "format": fmt}
    doc.source = f"{project} @ {commit[:12]} : {project_path}"


WIDTH = {"u16": 1, "s16": 1, "bool": 1, "u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4, "f64": 4}


class Occupancy:
    """The words (per table) the registers of a map already hold: a second entity on the same words is
    a reading of the same register (an alias, listed for review), never a second, overlapping register."""

    def __init__(self) -> None:
        self.words: dict[tuple[str, int], str] = {}

    def span(self, reg: dict[str, Any]) -> list[tuple[str, int]]:
        width = int(reg.get("length", 1)) if reg["type"] == "string" else WIDTH[reg["type"]]
        count, stride = int(reg.get("count", 1)), int(reg.get("stride", width))
        return [(reg["table"], reg["address"] + i * stride + w) for i in range(count) for w in range(width)]

    def holder(self, reg: dict[str, Any]) -> str | None:
        """The name of a register already on any of ``reg``'s words (None: they are free)."""
        return next((self.words[w] for w in self.span(reg) if w in self.words), None)

    def take(self, reg: dict[str, Any]) -> None:
        for w in self.span(reg):
            self.words[w] = reg["name"]


_RANGES = {"u16": (0, 0xFFFF), "s16": (-0x8000, 0x7FFF), "u32": (0, 0xFFFFFFFF), "s32": (-0x80000000, 0x7FFFFFFF),
           "u64": (0, 0xFFFFFFFFFFFFFFFF), "s64": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF)}


def fits(reg: dict[str, Any], value: float) -> bool:
    """Whether the engineering ``value`` is a raw value of ``reg``'s type at its scale."""
    if reg["type"] in ("f32", "f64"):
        return True
    low, high = _RANGES.get(reg["type"], (0, -1))
    raw = value / float(reg.get("scale", 1.0))
    return low <= raw <= high and abs(raw - round(raw)) < 1e-6
