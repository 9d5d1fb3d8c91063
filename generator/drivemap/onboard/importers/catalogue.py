"""The catalogue: every file of the public definition folders (``catalogue-sources/``) imported into
``maps/catalogue/<source>/<model_id>.yaml``, and the disagreements of sources that define one device.

:func:`build` imports each file with its format's importer (evcc, ha-solarman, modbus_local_gateway,
SunSpec), gives each map a model id unique across the catalogue and the project's own maps (the
file's name; ``_<source>`` appended when another map has it), writes the maps that validate and
returns, per file, the map written or the located error that says what the importer does not read.
What an import leaves out goes into the map's notes (with the file and line). For the devices that
two sources define (:data:`SAME_DEVICE`), :func:`drivemap.onboard.compare.compare_models` lists their
disagreements, recorded as known issues of the imported map: errata candidates, not settled by vote.
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

__all__ = ["SAME_DEVICE", "SOURCES", "Outcome", "build"]

#: source -> (folder in catalogue-sources, file patterns, drivemap import format)
SOURCES: dict[str, tuple[str, tuple[str, ...], str]] = {
    "evcc": ("evcc", ("meter/*.yaml", "charger/*.yaml"), "evcc"),
    "ha_solarman": ("ha-solarman", ("*.yaml",), "ha-solarman"),
    "modbus_local_gateway": ("modbus_local_gateway", ("*.yaml",), "modbus-local-gateway"),
    "sunspec": ("sunspec-models", ("model_*.json",), "sunspec"),
}
#: files that are not a device (the project's own test fixture)
NOT_A_DEVICE = {"modbus_local_gateway/Test.yaml": "the project's test config ('Test Model (DO NOT USE)')"}
#: (catalogue map, the other map of the same device: a catalogue id or a project map file)
SAME_DEVICE: tuple[tuple[str, str], ...] = (
    ("sdm630_modbus_local_gateway", "maps/sdm630.yaml"),
    ("deye_string", "deye_string_ha_solarman"),
    ("deye_string_ha_solarman", "deye_string"),
    ("solis_hybrid", "solis_hybrid_ha_solarman"),
    ("solis_hybrid_ha_solarman", "solis_hybrid"),
    ("deye_hybrid_3p", "deye_p3"),
    ("deye_p3", "deye_hybrid_3p"),
    ("growatt_min_tlxe", "min_6000_tl_xh"),
    ("min_6000_tl_xh", "growatt_min_tlxe"),
)


@dataclass
class Outcome:
    """One source file: the map written (its path) or the located error."""

    source: str
    file: Path
    written: Path | None = None
    error: str | None = None


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


def build(shared: Path, out: Path, project_ids: set[str], project_root: Path) -> list[Outcome]:
    """Import every catalogue source file into ``out/<source>/``; the outcome of each file."""
    outcomes: list[Outcome] = []
    taken = set(project_ids)
    docs: dict[str, tuple[MapDoc, Path]] = {}
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
            docs[model] = (doc, target)
    _known_issues(docs, out, project_root)
    return outcomes


def _left_out(doc: MapDoc) -> None:
    lines = doc.review.skipped + doc.review.notes
    if lines:
        doc.notes = (doc.notes + " " if doc.notes else "") + "Left out by the import (review): " + "; ".join(lines)


def _known_issues(docs: dict[str, tuple[MapDoc, Path]], out: Path, root: Path) -> None:
    from drivemap.compiler import compile_map
    from drivemap.onboard.compare import compare_models

    for mine, other in SAME_DEVICE:
        if mine not in docs:
            continue
        other_path = root / other if other.endswith(".yaml") else (docs[other][1] if other in docs else None)
        if other_path is None or not other_path.is_file():
            continue
        doc, target = docs[mine]
        diffs = compare_models(compile_map(target), compile_map(other_path))
        fields: dict[str, list[Any]] = {}
        for diff in diffs:
            fields.setdefault(diff.field, []).append(diff)
        for field, items in fields.items():
            doc.known_issues.append({
                "title": f"{field} disagrees with {Path(other).stem} ({len(items)} register{'s' if len(items) > 1 else ''})",
                "source": doc.source,
                "printed": "; ".join(d.line() for d in items),
                "corrected": None,
                "chosen": f"this map keeps {doc.origin['project'] if doc.origin else 'its source'}'s reading",
                "reason": "an errata candidate found by drivemap compare: the sources disagree; the vendor's "
                          "manual decides, not a vote",
                "affects": sorted({d.a.split(" ")[0] for d in items}),
            })
        if fields:
            write_map(doc, target, force=True)
