"""``drivemap import json``: drivemap's JSON export (the normalized model, the export contract) back to a map.

The export carries the protocol section whole, every register element (``name[i]`` rows become an
array again: count and stride from the addresses, one default or one per element, ``param`` per
element), enums as name -> value, bit fields as name/offset/width, reserved ranges, known issues,
identity checks and the examples' frames (an erratum's corrected ones too). What it does not carry
stays out and is listed for review:
the device's vendor, manual and coverage; each register's label, description, group, source, notes,
value set, precision, write delay, command and running advice; enum, value and bit labels (the names
stand in); enum names (named after the register); a reserved range's table where an export made
before it carried ``table`` leaves it out (holding, the map language's default; a range that would
overlap a holding register there is left out); an example's meaning beyond what its frames state,
its preset and notes; the note of an illegible example (such an example is left out).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.jsonsrc import field, load_json, objects, plain
from drivemap.onboard.importers.mapdoc import MapDoc
from drivemap.onboard.importers.modeljson_parts import example, known_issue, protocol
from drivemap.onboard.importers.yamlsrc import located

__all__ = ["import_model_json"]

_ELEMENT = re.compile(r"^([a-z][a-z0-9_]*)\[(\d+)\]$")
_TABLES = ("holding", "input", "coil", "discrete")
_TYPES = ("u16", "s16", "u32", "s32", "u64", "s64", "f32", "f64", "string", "bool")
#: facts every element of an array shares (name, address, param and default are per element)
_SHARED = ("access", "type", "scale", "offset", "unit", "min", "max", "reflect", "storage", "broadcast", "enum",
           "bits", "page", "table", "length", "word_order", "byte_order", "encoding", "scale_register",
           "not_available")
#: holding address -> the pages (selector, value) a register occupies it on ((None, None): every page)
Held = dict[int, list[tuple[str | None, int | None]]]
_NOT_CARRIED = ("the JSON export does not carry the device's vendor and manual, nor the registers' labels, "
                "descriptions, groups, sources, notes, value sets, precision, write delays, commands and "
                "running advice: add them from the manual")


def import_model_json(doc: MapDoc, path: Path) -> str:
    """Fill ``doc`` from the export ``path``; the model id it names."""
    data = load_json(path)
    if not isinstance(data, dict):
        raise located(path, data, "not drivemap's JSON export: the top level is not an object")
    model = field(path, data, "model", "str", "the export")
    doc.title = field(path, data, "title", "str", "the export") or doc.title
    _provenance(path, doc, data)
    doc.protocol = protocol(path, field(path, data, "protocol", "object", "the export"))
    group = doc.group("imported", "Imported registers")
    entries = objects(path, data, "registers", "the export")
    held = _registers(path, doc, entries, group)
    _reserved(path, doc, objects(path, data, "reserved", "the export"), held)
    left: set[str] = set()
    for i, item in enumerate(objects(path, data, "examples", "the export")):
        converted = example(path, item, f"examples[{i}]", doc.protocol, doc.review)
        if converted is None:
            left.add(str(item.get("name")))
        else:
            doc.examples.append(converted)
    names = {r["name"] for r in doc.registers} | {e["name"] for e in doc.examples}
    for i, item in enumerate(objects(path, data, "known_issues", "the export")):
        doc.known_issues.append(known_issue(path, item, f"known_issues[{i}]", names, doc.review))
    for i, item in enumerate(objects(path, data, "identity", "the export")):
        doc.identity.append(_identity(path, item, f"identity[{i}]"))
    doc.review.notes.append(_NOT_CARRIED)
    for key in ("registers", "reserved", "known_issues", "identity", "examples"):
        setattr(doc, key, plain(getattr(doc, key)))
    doc.protocol = plain(doc.protocol)
    return str(model)


def _registers(path: Path, doc: MapDoc, entries: list[Any], group: str) -> Held:
    """Every register (arrays from consecutive ``name[i]`` rows); the holding words they occupy
    (address, page selector, page value)."""
    held: Held = {}
    i = 0
    while i < len(entries):
        name = field(path, entries[i], "name", "str", f"registers[{i}]")
        match = _ELEMENT.match(name)
        if match is None:
            elements = [entries[i]]
        else:
            if match.group(2) != "0":
                raise located(path, entries[i], f"registers[{i}]: {name}: an array starts at element [0]")
            base = match.group(1)
            elements = []
            while i + len(elements) < len(entries) and entries[i + len(elements)].get("name") == \
                    f"{base}[{len(elements)}]":
                elements.append(entries[i + len(elements)])
            if len(elements) < 2:
                raise located(path, entries[i], f"registers[{i}]: {name}: an array has at least 2 elements")
        reg = _register(path, doc, elements, f"registers[{i}]", match.group(1) if match else name)
        reg.update(group=group, source=doc.source)
        doc.add(reg)
        if reg["table"] == "holding":
            page = reg.get("page") or {}
            for element in elements:
                start = element["address"]
                for a in range(start, start + element["length"]):
                    held.setdefault(a, []).append((page.get("selector"), page.get("value")))
        i += len(elements)
    return held


def _register(path: Path, doc: MapDoc, elements: list[Any], where: str, name: str) -> dict[str, Any]:
    first = elements[0]
    for element in elements[1:]:
        for key in _SHARED:
            if element.get(key) != first.get(key):
                raise located(path, element, f"{where}: {element.get('name')}: '{key}' differs from element 0's "
                                             "(the elements of an array share it)")
    table = field(path, first, "table", "str", where)
    rtype = field(path, first, "type", "str", where)
    access = field(path, first, "access", "str", where)
    for key, value, allowed in (("table", table, _TABLES), ("type", rtype, _TYPES), ("access", access, ("r", "w", "rw"))):
        if value not in allowed:
            raise located(path, first, f"{where}: '{key}' must be one of {', '.join(allowed)}, not {value!r}")
    addresses = [field(path, e, "address", "int", where) for e in elements]
    for e, address in zip(elements, addresses, strict=True):
        if not 0 <= address <= 0xFFFF or not 1 <= field(path, e, "length", "int", where) <= 256:
            raise located(path, e, f"{where}: address must be 0..65535 and length 1..256")
    reg: dict[str, Any] = {"name": name, "table": table, "address": addresses[0]}
    if len(elements) > 1:
        reg["count"] = len(elements)
        stride = addresses[1] - addresses[0]
        if stride < 1 or any(b - a != stride for a, b in zip(addresses, addresses[1:], strict=False)):
            raise located(path, elements[1], f"{where}: {name}: the elements' addresses are not evenly spaced")
        if stride != 1:
            reg["stride"] = stride
    reg.update(_params(path, elements, where))
    reg["type"] = rtype
    reg.update(_layout(path, first, where, rtype))
    reg["access"] = access
    reg.update(_numbers(path, first, where))
    reg.update(_defaults(path, elements, where))
    reg.update(_kinds(path, doc, first, where, name))
    review = first.get("review")
    if review is not None:
        if not (isinstance(review, list) and review and all(isinstance(x, str) for x in review)):
            raise located(path, first, f"{where}: {name}: 'review' must be a list of field names")
        reg["review"] = list(review)
    broadcast = field(path, first, "broadcast", "bool", where, default=False, nullable=True)
    if broadcast is not None and ("w" in access or broadcast):  # null: unknown, the map derives it
        reg["broadcast"] = broadcast
    return reg


def _provenance(path: Path, doc: MapDoc, data: Any) -> None:
    """The export's ``evidence``, ``kind`` and ``origin``, where it states them (the map's own facts)."""
    doc.evidence = field(path, data, "evidence", "str", "the export", default=None, nullable=True)
    doc.kind = field(path, data, "kind", "str", "the export", default=None, nullable=True)
    origin = data.get("origin")
    if origin is not None:
        if not (isinstance(origin, dict) and all(isinstance(origin.get(k), str)
                                                 for k in ("project", "path", "commit", "licence"))):
            raise located(path, origin, "the export's 'origin' names project, path, commit and licence")
        doc.origin = {k: str(v) for k, v in origin.items() if isinstance(v, str)}


def _params(path: Path, elements: list[Any], where: str) -> dict[str, Any]:
    params = [field(path, e, "param", "str", where, default=None, nullable=True) for e in elements]
    if all(p is None for p in params[1:]):
        return {"param": params[0]} if params[0] is not None else {}
    if any(p is None for p in params):
        raise located(path, elements[0], f"{where}: an array's elements either all have a param or only element 0")
    return {"param": params[0], "element_params": params}


def _layout(path: Path, first: Any, where: str, rtype: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    word = field(path, first, "word_order", "str", where, default=None, nullable=True)
    if word is not None:
        out["word_order"] = word
    byte = field(path, first, "byte_order", "str", where, default="high_first")
    if byte != "high_first":
        out["byte_order"] = byte
    if rtype == "string":
        out["length"] = first["length"]
        encoding = field(path, first, "encoding", "str", where, default="ascii", nullable=True)
        if encoding not in (None, "ascii"):
            out["encoding"] = encoding
    return out


def _numbers(path: Path, first: Any, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, neutral in (("scale", 1), ("offset", 0)):
        value = field(path, first, key, "number", where, default=neutral)
        if value != neutral:
            out[key] = value
    for key in ("unit", "reflect", "storage", "scale_register"):
        value = field(path, first, key, "str", where, default=None, nullable=True)
        if value is not None:
            out[key] = value
    for key in ("min", "max"):
        value = field(path, first, key, "number", where, default=None, nullable=True)
        if value is not None:
            out[key] = value
    na = field(path, first, "not_available", "list", where, default=None, nullable=True)
    if na:
        out["not_available"] = na
    page = field(path, first, "page", "object", where, default=None, nullable=True)
    if page is not None:
        out["page"] = {"selector": field(path, page, "selector", "str", f"{where}.page"),
                       "value": field(path, page, "value", "int", f"{where}.page")}
    return out


def _defaults(path: Path, elements: list[Any], where: str) -> dict[str, Any]:
    values = [e.get("default") for e in elements]
    for e, value in zip(elements, values, strict=True):
        if not isinstance(value, (int, float, str, bool, type(None))):
            raise located(path, e, f"{where}: 'default' must be a number, text, true/false or null")
    if all(v == values[0] and type(v) is type(values[0]) for v in values):
        return {} if values[0] is None else {"default": values[0]}
    if any(v is None for v in values):
        raise located(path, elements[0], f"{where}: an array's defaults are all given or all null")
    return {"default": values}


def _kinds(path: Path, doc: MapDoc, first: Any, where: str, name: str) -> dict[str, Any]:
    """The register's enum (named after it, labels from the value names) and bit fields."""
    out: dict[str, Any] = {}
    enum = field(path, first, "enum", "object", where, default=None, nullable=True)
    if enum:
        rows = []
        for key, value in enum.items():
            if not isinstance(value, int) or isinstance(value, bool):
                raise located(path, enum, f"{where}: enum value {key} must be an integer")
            rows.append({"value": value, "name": key, "label": key})
        out["enum"] = doc.enum_rows(name, rows)
        doc.review.miss(name, "enum labels (the export names the values only)")
    bits = field(path, first, "bits", "list", where, default=None, nullable=True)
    if bits:
        out["bits"] = []
        for bit in bits:
            entry = {"name": field(path, bit, "name", "str", f"{where}.bits"),
                     "offset": field(path, bit, "offset", "int", f"{where}.bits")}
            width = field(path, bit, "width", "int", f"{where}.bits", default=1)
            if width != 1:
                entry["width"] = width
            entry["label"] = entry["name"]
            out["bits"].append(entry)
        doc.review.miss(name, "bit labels (the export names the bits only)")
    return out


def _reserved(path: Path, doc: MapDoc, items: list[Any], held: Held) -> None:
    """Reserved ranges; one whose table the export does not say goes in the holding table (the map
    language's default) unless it would overlap a holding register there (then it is left out)."""
    placed: list[str] = []
    for i, item in enumerate(items):
        where = f"reserved[{i}]"
        start, end = field(path, item, "start", "int", where), field(path, item, "end", "int", where)
        if not 0 <= start <= end <= 0xFFFF:
            raise located(path, item, f"{where}: start and end must be addresses 0..65535, start first")
        table = field(path, item, "table", "str", where, default=None, nullable=True)
        entry: dict[str, Any] = {} if table in (None, "holding") else {"table": table}
        entry |= {"start": start, "end": end, "readable": field(path, item, "readable", "bool", where, nullable=True)}
        if field(path, item, "writable", "bool", where, default=False):
            entry["writable"] = True
        page = field(path, item, "page", "object", where, default=None, nullable=True)
        kind = field(path, item, "kind", "str", where, default="reserved")
        if kind != "reserved":
            entry["kind"] = kind
        if page is not None:
            entry["page"] = {"selector": page.get("selector"), "value": page.get("value")}
        entry["source"] = field(path, item, "source", "str", where)
        span = f"0x{start:04X}-0x{end:04X}"
        sel, val = (page.get("selector"), page.get("value")) if page else (None, None)
        if table is not None:
            doc.reserved.append(entry)
            continue
        if _clash(held, start, end, sel, val):
            doc.review.skipped.append(f"reserved {span}: overlaps a holding register; the export does not say its "
                                      "table (add it from the map or manual)")
            continue
        doc.reserved.append(entry)
        placed.append(span)
    if placed:
        doc.review.notes.append("reserved ranges in the holding table (the map language's default: the export does "
                                f"not say their table): {', '.join(placed)}")


def _clash(held: Held, start: int, end: int, sel: str | None, val: int | None) -> bool:
    """Whether a reserved range on page (sel, val) would overlap a holding register (as the checks see it)."""
    for address in range(start, end + 1):
        for s, v in held.get(address, ()):
            if not (sel is not None and s == sel and v != val):
                return True
    return False


def _identity(path: Path, item: Any, where: str) -> dict[str, Any]:
    kind = field(path, item, "kind", "str", where)
    values = field(path, item, "values", "list", where)
    if kind not in ("equals", "one_of", "prefix", "pattern") or not values:
        raise located(path, item, f"{where}: kind must be equals, one_of, prefix or pattern, with values")
    return {"register": field(path, item, "register", "str", where), kind: values if kind == "one_of" else values[0],
            "source": field(path, item, "source", "str", where)}
