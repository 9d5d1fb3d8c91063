"""The catalogue: every file of the public definition folders (``catalogue-sources/``) imported into
``maps/catalogue/<source>/<model_id>.yaml``, and the disagreements of sources that define one device.

:func:`build` imports each file with its format's importer (evcc, ha-solarman, modbus_local_gateway,
SunSpec), gives each map a model id unique across the catalogue and the project's own maps (the
file's name; ``_<source>`` appended when another map has it), writes the maps that validate and
returns, per file, the map written or the located error that says what the importer does not read.
What an import leaves out goes into the map's notes (with the file and line). For the devices that
two sources define (paired by :mod:`drivemap.onboard.importers.pairs`: vendor and model designation, or
the sources' own name), :func:`drivemap.onboard.compare.compare_models` lists their disagreements,
recorded as known issues of each imported map of the pair (never of the project's own maps): errata
candidates naming the other source, not settled by vote.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError
from drivemap.onboard.importers.imported import error_at, leave_open, mark_imported
from drivemap.onboard.importers.mapdoc import MapDoc, snake, write_map
from drivemap.onboard.importers.pairs import Entry, pairs

__all__ = ["SOURCES", "Outcome", "Pair", "build"]

#: source -> (folder in catalogue-sources, file patterns, drivemap import format)
SOURCES: dict[str, tuple[str, tuple[str, ...], str]] = {
    "evcc": ("evcc", ("meter/*.yaml", "charger/*.yaml"), "evcc"),
    "ha_solarman": ("ha-solarman", ("*.yaml",), "ha-solarman"),
    "modbus_local_gateway": ("modbus_local_gateway", ("*.yaml",), "modbus-local-gateway"),
    "sunspec": ("sunspec-models", ("model_*.json",), "sunspec"),
}
#: files that are not a device (the project's own test fixture)
NOT_A_DEVICE = {"modbus_local_gateway/Test.yaml": "the project's test config ('Test Model (DO NOT USE)')"}
@dataclass
class Outcome:
    """One source file: the map written (its path) or the located error."""

    source: str
    file: Path
    written: Path | None = None
    error: str | None = None


@dataclass
class Pair:
    """Two maps of one device: their model ids (a project map as ``maps/<id>.yaml``), the rule that
    paired them and the disagreements drivemap compare found."""

    a: str
    b: str
    rule: str
    disagreements: int = 0


def _importer(fmt: str) -> Callable[[MapDoc, Path], str]:
    if fmt == "evcc":
        from drivemap.onboard.importers.evcc import import_evcc

        return import_evcc
    if fmt == "ha-solarman":
        from drivemap.onboard.importers.solarman import import_solarman

        return import_solarman
    if fmt == "modbus-local-gateway":
        from drivemap.onboard.importers.mlg import import_mlg

        return import_mlg
    return import_sunspec_model


def import_sunspec_model(doc: MapDoc, path: Path) -> str:
    """One SunSpec model as a device map: 'SunS' at 40000, the model (each repeating group once: its
    registers' ``count`` is open), the end model."""
    from drivemap.onboard.importers.sunspec import SunSpecError, _fixed_size, _group_size, add_models

    try:
        model: Any = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error_at(path, getattr(exc, "lineno", 1), f"not a SunSpec model JSON file: {exc}") from None
    top = model.get("group") if isinstance(model, dict) else None
    if not isinstance(top, dict) or not isinstance(model.get("id"), int):
        raise error_at(path, 1, "not a SunSpec model definition (a JSON object with 'id' and 'group')")
    number = int(model["id"])
    kind = ("inverter" if 100 <= number < 200 or 700 <= number < 800 else "meter" if 200 <= number < 300
            else "battery" if 800 <= number < 900 else "other")
    mark_imported(doc, path, f"json/{path.name}", "sunspec", kind)
    doc.vendor = None
    doc.title = f"SunSpec model {number}: {top.get('label') or top.get('name')}"
    repeats = top.get("groups") or []
    try:
        length = _fixed_size(top) - 2 + sum(_group_size(g) for g in repeats)
        add_models(doc, [(model, length if repeats else None, path.name)], 40000)
    except SunSpecError as exc:
        raise error_at(path, 1, f"SunSpec model {number}: {exc}") from None
    doc.max_quantity[3] = None
    if repeats:
        prefixes = tuple(snake(g.get("name", "group")) + "_" for g in repeats)
        for reg in doc.registers:
            if reg["name"].startswith(prefixes):
                leave_open(doc, reg, "count")
        doc.notes = ("Each repeating group is laid out once: how many a device has is its L register's "
                     "business (drivemap import sunspec N:L).")
    return f"sunspec_{snake(str(top.get('name') or number))}"


def _files(shared: Path, source: str) -> list[Path]:
    folder, patterns, _ = SOURCES[source]
    return sorted({p for pattern in patterns for p in (shared / "catalogue-sources" / folder).glob(pattern)})


def _doc(path: Path) -> MapDoc:
    return MapDoc("imported", f"Imported from {path.name}", path.name, path.name, modes=["tcp"])


def build(shared: Path, out: Path, project_ids: set[str], project_root: Path,
          found: list[Pair] | None = None) -> list[Outcome]:
    """Import every catalogue source file into ``out/<source>/``; the outcome of each file (the pairs
    of maps of one device compared are appended to ``found``)."""
    outcomes: list[Outcome] = []
    taken = set(project_ids)
    docs: dict[str, tuple[MapDoc, Path, str]] = {}
    for source in SOURCES:
        fmt = SOURCES[source][2]
        for path in _files(shared, source):
            outcome = Outcome(source, path)
            outcomes.append(outcome)
            rel = f"{SOURCES[source][0]}/{path.name}"
            if rel in NOT_A_DEVICE:
                outcome.error = f"{path}:1:1: error: not a device: {NOT_A_DEVICE[rel]}"
                continue
            doc = _doc(path)
            try:
                wanted = _importer(fmt)(doc, path)
            except CompileError as exc:
                outcome.error = exc.diagnostics[0].format()
                continue
            model = wanted if wanted not in taken else f"{wanted}_{source}"
            n = 2
            while model in taken:
                model, n = f"{wanted}_{source}_{n}", n + 1
            taken.add(model)
            doc.model = model
            _left_out(doc)
            target = out / source / f"{model}.yaml"
            try:
                write_map(doc, target, force=True)
            except CompileError as exc:
                outcome.error = exc.diagnostics[0].format()
                continue
            outcome.written = target
            docs[model] = (doc, target, source)
    _known_issues(docs, project_root, found if found is not None else [])
    return outcomes


def _left_out(doc: MapDoc) -> None:
    lines = doc.review.skipped + doc.review.notes
    if lines:
        doc.notes = (doc.notes + " " if doc.notes else "") + "Left out by the import (review): " + "; ".join(lines)


def _entries(docs: dict[str, tuple[MapDoc, Path, str]], root: Path) -> tuple[list[Entry], dict[str, Path]]:
    import yaml

    entries: list[Entry] = []
    paths: dict[str, Path] = {}
    for path in sorted((root / "maps").glob("*.yaml")):
        device = (yaml.safe_load(path.read_text(encoding="utf-8")) or {}).get("device") or {}
        key = f"maps/{path.name}"
        entries.append(Entry(key, "project", device.get("vendor"), str(device.get("title") or ""), path.stem))
        paths[key] = path
    for model, (doc, target, source) in docs.items():
        origin = Path((doc.origin or {}).get("path") or model).stem
        entries.append(Entry(model, source, doc.vendor, doc.title or "", origin))
        paths[model] = target
    return entries, paths


def _known_issues(docs: dict[str, tuple[MapDoc, Path, str]], root: Path, found: list[Pair]) -> None:
    from drivemap.compiler import compile_map
    from drivemap.onboard.compare import compare_models

    entries, paths = _entries(docs, root)
    compiled: dict[str, Any] = {}
    for a, b, rule in pairs(entries):
        for key in (a.model, b.model):
            if key not in compiled:
                compiled[key] = compile_map(paths[key])
        pair = Pair(a.model, b.model, rule)
        found.append(pair)
        for mine, other in ((a, b), (b, a)):
            if mine.model not in docs:
                continue  # the project's own maps are not edited
            diffs = compare_models(compiled[mine.model], compiled[other.model])
            pair.disagreements = max(pair.disagreements, len(diffs))
            _record(docs[mine.model][0], other, diffs)
    for doc, target, _ in docs.values():
        if doc.known_issues:
            write_map(doc, target, force=True)


def _record(doc: MapDoc, other: Entry, diffs: list[Any]) -> None:
    fields: dict[str, list[Any]] = {}
    for diff in diffs:
        fields.setdefault(diff.field, []).append(diff)
    name = other.model if other.source == "project" else f"{other.model} ({other.source})"
    for field, items in fields.items():
        doc.known_issues.append({
            "title": f"{field} disagrees with {name} ({len(items)} register{'s' if len(items) > 1 else ''})",
            "source": doc.source,
            "printed": "; ".join(d.line() for d in items),
            "corrected": None,
            "chosen": f"this map keeps {doc.origin['project'] if doc.origin else 'its source'}'s reading",
            "reason": "an errata candidate found by drivemap compare: the sources disagree; the vendor's "
                      "manual decides, not a vote",
            "affects": sorted({d.a.split(" ")[0] for d in items}),
        })
