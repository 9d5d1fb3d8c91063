"""``drivemap import csv``: drivemap's own CSV export, or a vendor register sheet with recognisable columns.

drivemap's CSV (every column of :data:`drivemap.vocab.csv_columns.COLUMNS`) carries nearly every register
fact: its rows come back as registers, ``name[i]`` rows as arrays (stride from the addresses, one
default or one per element, ``param`` per element), ``enum_labels`` as enums, ``bits`` as bit fields, ``values`` as value sets, ``precision``, and
``display_name`` of an array's first element as ``first_index``, ``review`` (what the source leaves open) as ``review:``,
and the map-level ``evidence`` / ``origin_*`` columns (the same on every row, or the file is refused) as
``device.evidence`` and ``device.origin``. A sheet exported before those columns existed is still drivemap's own.
A vendor sheet is read by its header words (address / register, name / description / parameter,
type / format, unit, scale / factor / resolution, access / R/W, function / table, min, max, default);
a fact without a column stays out and is listed. Its table comes from a table or function-code column,
from Modicon numbers (3xxxx/4xxxx), or from ``--table``: never assumed.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.importers.mapdoc import MapDoc, snake
from drivemap.onboard.importers.vendor import vendor_rows
from drivemap.vocab.csv_columns import MAP_COLUMNS, ORIGIN_KEYS, REGISTER_COLUMNS

__all__ = ["import_csv", "read_rows"]

_ELEMENT = re.compile(r"^([a-z][a-z0-9_]*)\[(\d+)\]$")
_BIT = re.compile(r"^bits? (\d+)(?:-(\d+))? ([A-Z][A-Z0-9_]*): (.*)$", re.S)
_ALLOWED = re.compile(r"^(.*?) \((.*)\)$", re.S)
_FORMULA = ("=", "+", "-", "@")


def error(path: Path, line: int, message: str, col: int = 1) -> CompileError:
    return CompileError([Diagnostic(Location(display(path), line, col), message)])


def read_rows(path: Path) -> tuple[list[str], list[tuple[int, dict[str, str]]]]:
    """(header, [(line, row)]) of a CSV file in any of , ; tab (a UTF-8 BOM is dropped)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise error(path, 1, f"cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    first = text.split("\n", 1)[0]
    delimiter = max((",", ";", "\t"), key=first.count)
    reader = csv.reader(io.StringIO(text), delimiter=delimiter)
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise error(path, 1, "empty file: no header row") from None
    except csv.Error as exc:
        raise error(path, 1, f"not CSV: {exc}") from None
    rows: list[tuple[int, dict[str, str]]] = []
    try:
        for cells in reader:
            if any(c.strip() for c in cells):
                rows.append((reader.line_num, dict(zip(header, cells, strict=False))))
    except csv.Error as exc:
        raise error(path, reader.line_num, f"not CSV: {exc}") from None
    return header, rows


def import_csv(doc: MapDoc, path: Path, table: str | None, word_order: str | None) -> None:
    header, rows = read_rows(path)
    if set(REGISTER_COLUMNS) <= set(header):
        _own(doc, path, rows)
        if set(MAP_COLUMNS) <= set(header):
            _map_level(doc, path, rows)
    else:
        for reg in vendor_rows(doc, path, header, rows, table, word_order):
            doc.add(reg)


def _text(cell: str) -> str:
    """Undo the exporter's spreadsheet guard (a leading apostrophe before = + - @)."""
    return cell[1:] if cell[:1] == "'" and cell[1:2] in _FORMULA else cell


def _number(text: str) -> int | float:
    value = float(text)
    return int(value) if value.is_integer() and "." not in text and "e" not in text.lower() else value


_EVIDENCE = ("manual", "imported", "probed", "verified")


def _map_level(doc: MapDoc, path: Path, rows: list[tuple[int, dict[str, str]]]) -> None:
    """``evidence`` and ``origin_*``: the map's own facts, stated once per row and alike on every row."""
    if not rows:
        return
    first_line, first = rows[0]
    for line, row in rows[1:]:
        for column in MAP_COLUMNS:
            if row.get(column, "") != first.get(column, ""):
                raise error(path, line, f"{column} {row.get(column, '')!r} differs from line {first_line}'s "
                                        f"{first.get(column, '')!r}: a map has one evidence level and one origin")
    evidence = first["evidence"]
    if evidence:
        if evidence not in _EVIDENCE:
            raise error(path, first_line, f"evidence {evidence!r}: one of {', '.join(_EVIDENCE)}")
        doc.evidence = evidence
    origin = {key: _text(first[f"origin_{key}"]) for key in ORIGIN_KEYS if first[f"origin_{key}"]}
    if origin:
        missing = [f"origin_{key}" for key in ORIGIN_KEYS[:4] if key not in origin]
        if missing:
            raise error(path, first_line, f"{', '.join(missing)} empty: an origin names project, path, commit "
                                          "and licence")
        doc.origin = origin


def _own(doc: MapDoc, path: Path, rows: list[tuple[int, dict[str, str]]]) -> None:
    """drivemap's CSV: group ``name[i]`` rows into arrays, then one register per group."""
    groups: list[tuple[str, list[tuple[int, dict[str, str]]]]] = []
    index: dict[str, int] = {}
    for line, row in rows:
        match = _ELEMENT.match(row["name"])
        base = match.group(1) if match else row["name"]
        if match and base in index:
            groups[index[base]][1].append((line, row))
        else:
            index[base] = len(groups)
            groups.append((base, [(line, row)]))
    for base, members in groups:
        try:
            doc.add(_register(doc, base, members))
        except (ValueError, KeyError) as exc:
            raise error(path, members[0][0], f"row of {base}: {exc}") from None


def _register(doc: MapDoc, name: str, members: list[tuple[int, dict[str, str]]]) -> dict[str, Any]:
    _, row = members[0]
    reg: dict[str, Any] = {"name": doc.name(name), "table": row["table"], "address": int(row["address"])}
    for key in ("label", "type", "word_order"):
        if row[key]:
            reg[key] = _text(row[key])
    if row["byte_order"] == "low_first":
        reg["byte_order"] = "low_first"
    if row["type"] == "string":
        reg["length"] = int(row["length"])
        if row["encoding"] and row["encoding"] != "ascii":
            reg["encoding"] = row["encoding"]
    _numbers(reg, row)
    _array(reg, members)
    _meaning(doc, reg, row)
    _shown(reg, row)
    reg["group"] = snake(row["group"] or "registers", "group")
    doc.group(reg["group"], reg["group"])
    reg["source"] = _text(row["source"]) or doc.source
    return reg


def _numbers(reg: dict[str, Any], row: dict[str, str]) -> None:
    if row["scale"] and float(row["scale"]) != 1:
        reg["scale"] = _number(row["scale"])
    if row["scale_register"]:
        reg["scale_register"] = row["scale_register"]
    if row["offset"] and float(row["offset"]) != 0:
        reg["offset"] = _number(row["offset"])
    if row["not_available"]:
        reg["not_available"] = [int(v.strip(), 16) for v in row["not_available"].split("|")]
    if row["unit"]:
        reg["unit"] = _text(row["unit"])
    reg["access"] = row["access"]
    for key in ("min", "max"):
        if row[key]:
            reg[key] = _number(row[key])
    for key in ("reflect", "storage"):
        if row[key] and row[key] != "unknown":
            reg[key] = row[key]


def _default(reg: dict[str, Any], text: str) -> Any:
    if text == "":
        return None
    if reg.get("type") == "bool" or reg["table"] in ("coil", "discrete"):
        return text == "true"
    if reg.get("type") == "string":
        return _text(text)
    return _number(text)


def _array(reg: dict[str, Any], members: list[tuple[int, dict[str, str]]]) -> None:
    rows = [row for _, row in members]
    defaults = [_default(reg, row["default"]) for row in rows]
    params = [row["param"] for row in rows]
    if len(rows) > 1:
        stride = int(rows[1]["address"]) - int(rows[0]["address"])
        reg["count"] = len(rows)
        if stride != 1:
            reg["stride"] = stride
        if any(params[1:]):
            reg["element_params"] = params
        elif params[0]:
            reg["param"] = params[0]
    elif params[0]:
        reg["param"] = params[0]
    if len(set(map(repr, defaults))) > 1:
        reg["default"] = defaults
    elif defaults[0] is not None:
        reg["default"] = defaults[0]


def _meaning(doc: MapDoc, reg: dict[str, Any], row: dict[str, str]) -> None:
    if row["page"]:
        selector, _, value = row["page"].partition("=")
        reg["page"] = {"selector": selector, "value": int(value)}
    if row["enum"]:
        pairs = []
        for item in _text(row["enum_labels"]).split(" | "):
            value, _, label = item.partition("=")
            pairs.append((int(value), label))
        reg["enum"] = doc.enum_named(row["enum"], pairs)
    if row["bits"]:
        reg["bits"] = [_bit(text) for text in _text(row["bits"]).split(" | ")]
    if row["command"]:
        reg["command"] = {"value": int(row["command"])}
    if row["description"]:
        reg["description"] = _text(row["description"])


def _shown(reg: dict[str, Any], row: dict[str, str]) -> None:
    """``values`` (the value set), ``precision`` and the first element's ``display_name`` (``first_index``)."""
    if row.get("values"):
        reg["values"] = [_allowed(reg, item) for item in _text(row["values"]).split(" | ")]
    if row.get("precision"):
        reg["precision"] = int(row["precision"])
    review = _text(row.get("review", ""))
    if review:
        found = re.fullmatch(re.escape(reg["name"]) + r": (.+?) open in the map's source(?: \(.*\))?", review)
        if not found:
            raise ValueError(f"review {review!r} is not the export's form (NAME: FIELDS open in the map's source)")
        reg["review"] = found.group(1).split(", ")
    shown = _text(row.get("display_name", ""))
    if reg.get("count") and shown != row["name"]:
        match = re.fullmatch(re.escape(reg["name"]) + r" (\d+)", shown)
        if not match:
            raise ValueError(f"display_name {shown!r} is not the name and the element's number")
        if int(match.group(1)) != 0:
            reg["first_index"] = int(match.group(1))


def _allowed(reg: dict[str, Any], item: str) -> dict[str, Any]:
    """One ``value (label)`` of the ``values`` column, the value as the register's type has it."""
    match = _ALLOWED.match(item)
    value, label = (match.group(1), match.group(2)) if match else (item, None)
    entry: dict[str, Any] = {"value": value if reg.get("type") == "string" else _number(value)}
    if label is not None:
        entry["label"] = label
    return entry


def _bit(text: str) -> dict[str, Any]:
    match = _BIT.match(text)
    if not match:
        raise ValueError(f"bits: cannot read {text!r}")
    first, last, name, label = match.groups()
    bit: dict[str, Any] = {"name": name, "offset": int(first)}
    if last is not None:
        bit["width"] = int(last) - int(first) + 1
    bit["label"] = label
    return bit
