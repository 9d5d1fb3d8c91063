"""``drivemap list [QUERY] [--vendor V] [--kind K]``: the maps a model id finds, with their evidence.

One row per model id: the project's maps (those ``exclude`` leaves out of the build too), the maps
shipped with drivemap and its catalogue (``data/maps/catalogue/<source>/``). A project map hides a
shipped or catalogue map of the same id (the row says which it overrides), as every verb uses the
project's. Only each file's ``device:`` block is read (no compile), so the list stays fast with
hundreds of maps; the columns are ``device.model``, ``vendor``, ``kind``, ``evidence`` and the
source (``device.origin``'s project, path and licence for an imported map).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from drivemap.cli.common import project_of
from drivemap.frontend.project import SHIPPED_MAPS, catalogue_maps, display, shipped_maps

__all__ = ["KINDS", "Entry", "add_parser", "entries"]

#: ``device.kind`` of the schema
KINDS = ("drive", "inverter", "meter", "charger", "battery", "io", "sensor", "gateway", "other")
_MAX_DEVICE_LINES = 2000


@dataclass(frozen=True)
class Entry:
    """One map as the list shows it (``model``: the id that finds it, its file's name)."""

    model: str
    title: str
    vendor: str
    kind: str
    evidence: str
    source: str
    where: str  #: project | drivemap | catalogue/<folder>, and what a project map overrides
    path: Path


def device_block(path: Path) -> dict[str, Any]:
    """The ``device:`` mapping of a map file, read without the rest of the file ({} if there is none)."""
    lines: list[str] = []
    inside = False
    with open(path, encoding="utf-8") as handle:
        for number, line in enumerate(handle):
            if number > _MAX_DEVICE_LINES + 200:
                break
            top = bool(line[:1].strip()) and not line.startswith(("#", "-"))
            if inside and top:
                break
            if line.startswith("device:"):
                inside = True
            if inside:
                lines.append(line)
                if len(lines) > _MAX_DEVICE_LINES:
                    break
    if not lines:
        return {}
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    data = yaml.load("".join(lines), Loader=loader)  # noqa: S506 - a safe loader
    device = data.get("device") if isinstance(data, dict) else None
    return device if isinstance(device, dict) else {}


def _text(value: Any) -> str:
    return "" if value is None else str(value)


def _source(device: dict[str, Any]) -> str:
    origin = device.get("origin")
    if isinstance(origin, dict):
        parts = [_text(origin.get("project")), _text(origin.get("path"))]
        text = ":".join(p for p in parts if p)
        return f"{text} ({origin['licence']})" if origin.get("licence") else text
    manual = device.get("manual")
    return _text(manual.get("document") or manual.get("file")) if isinstance(manual, dict) else ""


def _entry(path: Path, where: str) -> Entry | None:
    try:
        device = device_block(path)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        print(f"{display(path)}:1:1: warning: not listed: {type(exc).__name__}: "
              f"{str(exc).splitlines()[0] if str(exc) else ''}", file=sys.stderr)
        return None
    return Entry(model=path.stem, title=_text(device.get("title")),
                 vendor=_text(device.get("vendor")), kind=_text(device.get("kind")),
                 evidence=_text(device.get("evidence")), source=_source(device), where=where, path=path)


def entries() -> list[Entry]:
    """Every map a model id finds from the working directory: the project's first, then the shipped
    maps and the catalogue's; a later map of an id already listed is the one the earlier overrides."""
    project = project_of(argparse.Namespace())
    found: dict[str, Entry] = {}
    seen: set[Path] = set()
    catalogue = [(p, f"catalogue/{p.parent.name}" if p.parent.name != "catalogue" else "catalogue")
                 for p in catalogue_maps()]
    shipped_folder = SHIPPED_MAPS.resolve()
    excluded = [(p, "project (not built)") for p in project.excluded_files()
                if shipped_folder not in p.resolve().parents]  # in drivemap's own repository: the catalogue
    listed = [(p, "project") for p in project.map_files()] + excluded
    for path, where in listed + [(p, "drivemap") for p in shipped_maps()] + catalogue:
        real = path.resolve()
        if real in seen:
            continue
        seen.add(real)
        entry = _entry(path, where)
        if entry is None:
            continue
        first = found.get(entry.model)
        if first is None:
            found[entry.model] = entry
        elif "overrides" not in first.where:
            found[entry.model] = Entry(**{**first.__dict__, "where": f"{first.where} (overrides {where})"})
    return list(found.values())


def _matches(entry: Entry, query: str | None, vendor: str | None, kind: str | None) -> bool:
    if kind and entry.kind != kind:
        return False
    if vendor and vendor.casefold() not in entry.vendor.casefold():
        return False
    if query:
        words = query.casefold().split()
        text = " ".join((entry.model, entry.title, entry.vendor, entry.source)).casefold()
        return all(w in text for w in words)
    return True


def cmd_list(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    rows = [e for e in entries() if _matches(e, args.query, args.vendor, args.kind)]
    rows.sort(key=lambda e: (not e.where.startswith("project"), e.vendor.casefold(), e.model))
    console = Console(width=None if sys.stdout.isatty() else 200, soft_wrap=False)
    if not rows:
        print("no map matches" + (f" {args.query!r}" if args.query else ""), file=sys.stderr)
        return 1
    table = Table(title=f"{len(rows)} map{'' if len(rows) == 1 else 's'}", title_justify="left")
    for column in ("model", "vendor", "kind", "evidence", "source", "where"):
        table.add_column(column, overflow="fold")
    for e in rows:
        table.add_row(e.model, e.vendor or "-", e.kind or "-", e.evidence or "-", e.source or "-", e.where)
    console.print(table)
    return 0


def add_parser(sub: Any) -> None:
    p = sub.add_parser("list", help="the maps a model id finds (project, shipped, catalogue) with their evidence",
                       description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("query", nargs="?", default=None, metavar="QUERY",
                   help="words that the model id, title, vendor or source contain")
    p.add_argument("--vendor", default=None, metavar="V", help="only maps of this vendor (a part of its name)")
    p.add_argument("--kind", default=None, choices=KINDS, help="only maps of this device.kind")
    p.set_defaults(func=cmd_list)
