"""``drivemap import evcc``: an evcc device template (meter or charger) as a map.

The render block (a Go template) is expanded once per ``usage`` the template offers (grid, pv,
battery, charge ...; a template without usages once); every ``register:`` mapping it renders becomes a
register named after the evcc key it feeds (``grid_power``, ``pv_energy``), with the table from its
``type`` (holding, input, coil; ``writesingle``/``writemultiple``/``writeholding`` write a holding
register), the type and word order from ``decode`` (``int32s``: low word first; ``*nan``: the
not-available value), and the sibling ``scale``. evcc's units are its API's (W, kWh, A, V, %) for the
keys that have one; other keys leave the unit open. ``include``d blocks are connection settings, not
registers. A register that only some parameter values render (``batterytype: hv``) is kept with the
fields that depend on them listed for review, and its notes name the condition. A template whose
registers live in evcc's code (``type: mbmd``, ``type: sunspec``, a charger's Go driver) is a located
error naming that feature.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.gotemplate import Line, expand
from drivemap.onboard.importers.imported import error_at, leave_open, mark_imported
from drivemap.onboard.importers.mapdoc import MapDoc, snake
from drivemap.onboard.importers.yamlsrc import Node, load_yaml

__all__ = ["import_evcc"]

#: decode -> (type, word order, not-available raw value)
DECODES: dict[str, tuple[str, str | None, int | None]] = {
    "int16": ("s16", None, None), "uint16": ("u16", None, None), "int16nan": ("s16", None, -0x8000),
    "uint16nan": ("u16", None, 0xFFFF), "int32": ("s32", "high_first", None), "uint32": ("u32", "high_first", None),
    "int32s": ("s32", "low_first", None), "uint32s": ("u32", "low_first", None),
    "int32nan": ("s32", "high_first", -0x80000000), "uint32nan": ("u32", "high_first", 0xFFFFFFFF),
    "int32snan": ("s32", "low_first", -0x80000000), "uint32snan": ("u32", "low_first", 0xFFFFFFFF),
    "float32": ("f32", "high_first", None), "float32s": ("f32", "low_first", None),
    "float32nan": ("f32", "high_first", None), "float32nans": ("f32", "low_first", None),
    "int64": ("s64", "high_first", None), "uint64": ("u64", "high_first", None),
    "uint64nan": ("u64", "high_first", 0xFFFFFFFFFFFFFFFF), "uint64snan": ("u64", "low_first", 0xFFFFFFFFFFFFFFFF),
    "float64": ("f64", "high_first", None),
}
#: register type -> (table, access, write function code)
TABLES: dict[str, tuple[str, str, int | None]] = {
    "holding": ("holding", "r", None), "input": ("input", "r", None), "coil": ("coil", "r", None),
    "writesingle": ("holding", "w", 6), "writeholding": ("holding", "w", 6), "writemultiple": ("holding", "w", 16),
    "writeholdings": ("holding", "w", 16), "writecoil": ("coil", "w", 5),
}
#: evcc's API units for the keys that have one (the value after scale)
UNITS = {"power": "W", "powers": "W", "energy": "kWh", "returnenergy": "kWh", "currents": "A", "voltages": "V",
         "soc": "%", "capacity": "kWh", "chargedenergy": "kWh", "maxacpower": "W"}
_GENERIC = {"set", "config", "source", "add", "switch", "register", "block", "in", "out", "case", "get", "mul", "calc"}
#: where the catalogue's files sit in evcc's repository
REPO_PATH = "templates/definition/{kind}/{name}"


@dataclass
class _Entry:
    line: Line
    raw: int
    indent: int
    item: bool
    key: str
    value: str
    comment: str


_KEY = re.compile(r"^(\s*)(- )?([A-Za-z_][\w-]*):(?:\s+(.*?))?\s*$")


def _entries(lines: list[Line]) -> list[_Entry]:
    out = []
    for line in lines:
        body, _, comment = line.text.partition(" #")
        if line.text.lstrip().startswith("#"):
            continue
        match = _KEY.match(body.rstrip())
        if match is None:
            continue
        raw = len(match.group(1))
        item = bool(match.group(2))
        out.append(_Entry(line, raw, raw + (2 if item else 0), item, match.group(3), (match.group(4) or "").strip(),
                          comment.strip()))
    return out


def import_evcc(doc: MapDoc, path: Path) -> str:
    """Fill ``doc`` from the template at ``path``; the model id it suggests (the file's name)."""
    data = load_yaml(path)
    if not isinstance(data, Node) or not isinstance(data.get("render"), str):
        raise error_at(path, 1, "not an evcc template: no 'render' block (evcc templates have template, "
                                "products, params and render)")
    kind = "charger" if path.parent.name == "charger" else "meter"
    usages = _usages(data)
    group = str(data.get("group")) if data.get("group") else None
    mark_imported(doc, path, REPO_PATH.format(kind=kind, name=path.name), "evcc", _kind(kind, usages, group))
    _header(doc, data, path, usages)
    start, indent = _render_line(path)
    found: dict[tuple[str, int], dict[str, Any]] = {}
    for usage in usages or [""]:
        entries = _entries(expand(data["render"], usage))
        group = doc.group(usage or "registers", f"usage {usage}" if usage else "Registers")
        for i, entry in enumerate(entries):
            if entry.key == "register" and not entry.value:
                _register(doc, path, start, entries, i, usage, group, found)
    if not doc.registers:
        raise _no_registers(path, data["render"], start, indent)
    return snake(path.stem.replace("-", "_"), "device")


def _usages(data: Node) -> list[str]:
    for param in data.get("params") or []:
        if isinstance(param, dict) and param.get("name") == "usage":
            return [str(c) for c in param.get("choice") or []]
    return []


def _kind(folder: str, usages: list[str], group: str | None = None) -> str:
    """What the template says the device is: its group (``heating``: a heat pump or heater, which evcc
    keeps among the chargers), its folder, the usages a meter template offers."""
    if group == "heating":
        return "other"
    if folder == "charger":
        return "charger"
    if ("pv" in usages or "battery" in usages) and "charge" not in usages:
        return "inverter"
    return "meter"


def _header(doc: MapDoc, data: Node, path: Path, usages: list[str]) -> None:
    products = [p for p in data.get("products") or [] if isinstance(p, dict)]
    names = []
    for product in products:
        desc = product.get("description") or {}
        text = desc.get("generic") or desc.get("en") or "" if isinstance(desc, dict) else str(desc)
        names.append(" ".join(str(x) for x in (product.get("brand"), text) if x))
    doc.vendor = str(products[0]["brand"]) if products and products[0].get("brand") else None
    doc.title = names[0] if names else f"evcc template {data.get('template') or path.stem}"
    notes = [f"evcc template {data.get('template') or path.stem!s}"]
    if len(names) > 1:
        notes.append("products: " + "; ".join(names))
    if usages:
        notes.append("usages: " + ", ".join(usages) + " (a group each)")
    modbus = next((p for p in data.get("params") or [] if isinstance(p, dict) and p.get("name") == "modbus"), None)
    if isinstance(modbus, dict):
        choices = [str(c) for c in modbus.get("choice") or []]
        notes.append("connections: " + ", ".join(choices) + "".join(
            f"; evcc's default {k}: {modbus[k]}" for k in ("baudrate", "comset", "id", "port") if k in modbus))
        doc.modes = ["tcp"] if "tcpip" in choices or "udp" in choices else []
    doc.notes = ". ".join(notes) + "."


def _render_line(path: Path) -> tuple[int, int]:
    """The file line of the render block's first line, and the block's indentation."""
    lines = path.read_text(encoding="utf-8").splitlines()
    for n, text in enumerate(lines, 1):
        if re.match(r"^render:", text):
            body = next((t for t in lines[n:] if t.strip()), "")
            return n + 1, len(body) - len(body.lstrip())
    return 1, 0


def _ancestors(entries: list[_Entry], i: int) -> list[_Entry]:
    out: list[_Entry] = []
    indent = entries[i].indent
    for j in range(i - 1, -1, -1):
        e = entries[j]
        if e.indent < indent and not (e.item and e.raw < indent <= e.indent):
            out.append(e)
            indent = e.indent
        elif e.item and e.indent == indent:
            indent = e.raw + 1  # the mapping starts at this list item: its header is above it
    return out


def _siblings(entries: list[_Entry], i: int) -> list[_Entry]:
    indent = entries[i].indent
    out: list[_Entry] = []
    j = i
    while j > 0 and not (entries[j].item and entries[j].indent == indent):
        j -= 1
        if entries[j].indent < indent:
            j += 1
            break
    start = j
    for k in range(start, len(entries)):
        e = entries[k]
        if k > start and (e.indent < indent or (e.item and e.indent == indent)):
            break
        if e.indent == indent and k != i:
            out.append(e)
    return out


def _children(entries: list[_Entry], i: int) -> list[_Entry]:
    out = []
    for e in entries[i + 1:]:
        if e.indent <= entries[i].indent:
            break
        out.append(e)
    return out


def _register(doc: MapDoc, path: Path, start: int, entries: list[_Entry], i: int, usage: str, group: str,
              found: dict[tuple[str, int], dict[str, Any]]) -> None:
    entry = entries[i]
    kids = _children(entries, i)
    fields: dict[str, list[_Entry]] = {}
    for kid in kids:
        fields.setdefault(kid.key, []).append(kid)
    chain = [e.key for e in _ancestors(entries, i)]
    top = chain[-1] if chain else "register"
    names = [e.value for e in _ancestors(entries, i) if e.key == "name" and e.value]
    for sib in _siblings(entries, i):
        if sib.key == "name" and sib.value:
            names.insert(0, sib.value)
    addresses = fields.get("address", [])
    if not addresses:
        doc.review.skipped.append(f"{path.name}:{start + entry.line.index}: a register without an address")
        return
    for addr in addresses:
        _one(doc, path, start, entries, i, addr, fields, usage, group, top, names, chain, found, len(addresses) > 1)


def _one(doc: MapDoc, path: Path, start: int, entries: list[_Entry], i: int, addr: _Entry,
         fields: dict[str, list[_Entry]], usage: str, group: str, top: str, names: list[str], chain: list[str],
         found: dict[tuple[str, int], dict[str, Any]], several: bool) -> None:
    where = f"{path.name}:{start + addr.line.index}"
    try:
        address = int(addr.value, 0)
    except ValueError:
        doc.review.skipped.append(f"{where}: address {addr.value!r} is not a number (it depends on a template parameter)")
        return
    kind_entry = next(iter(fields.get("type") or []), None)
    kind = kind_entry.value if kind_entry else ""
    if kind and kind not in TABLES:
        doc.review.skipped.append(f"{where}: register type {kind!r} (not a Modbus table drivemap reads)")
        return
    table, access, code = TABLES.get(kind or "holding", TABLES["holding"])
    decode_entry = next(iter(fields.get("decode") or fields.get("encoding") or []), None)
    decode = decode_entry.value if decode_entry else ""
    conds = set(addr.line.conditions)
    key = (table, address)
    reg = found.get(key)
    wanted = "_".join(x for x in (usage, *(snake(n) for n in names[:1]), top) if x)
    if reg is None:
        reg = {"name": doc.name(wanted), "table": table, "address": address}
        label = addr.comment.strip("\"' ") or " ".join(x for x in (top, names[0] if names else "", f"({usage})" if usage else "") if x)
        reg["label"] = label
        reg.update(group=group, source=where)
        found[key] = reg
        _typed(doc, reg, table, decode, where)
        reg["access"] = access
        doc.add(reg)
    else:
        _merge(doc, reg, table, decode, access, where)
    if code is not None:
        doc.max_quantity.setdefault(code, None)
    if not kind:
        leave_open(doc, reg, "table")
    _scale(doc, reg, entries, i, where, conds)
    unit = UNITS.get(top) if not {"in", "out"} & set(chain) else None
    if table not in ("coil",) and "unit" not in reg and reg.get("type") != "string":
        if unit:
            reg["unit"] = unit
        elif "unit" not in reg.get("review", []):
            leave_open(doc, reg, "unit")
    if conds or several:
        text = "; ".join(sorted(conds)) or "one of several addresses"
        reg["notes"] = _append(reg.get("notes"), f"Rendered only when {text} ({where}).")
        leave_open(doc, reg, "address")
    for extra in ("bitmask", "length"):
        if extra in fields:
            reg["notes"] = _append(reg.get("notes"), f"evcc {extra}: {fields[extra][0].value} ({where}).")
            leave_open(doc, reg, "bits" if extra == "bitmask" else "length")


def _typed(doc: MapDoc, reg: dict[str, Any], table: str, decode: str, where: str) -> None:
    if table == "coil":
        reg["type"] = "bool"
        return
    spec = DECODES.get(decode)
    if spec is None:
        reg["type"] = "u16"
        leave_open(doc, reg, "type")
        if decode:
            reg["notes"] = _append(reg.get("notes"), f"evcc decode {decode!r} has no drivemap type ({where}).")
        return
    reg["type"] = spec[0]
    if spec[1]:
        reg["word_order"] = spec[1]
    if spec[2] is not None:
        reg["not_available"] = [spec[2]]


def _merge(doc: MapDoc, reg: dict[str, Any], table: str, decode: str, access: str, where: str) -> None:
    if access != reg["access"]:
        reg["access"] = "rw"
    spec = DECODES.get(decode)
    if spec and table != "coil" and (spec[0] != reg["type"] or spec[1] != reg.get("word_order")):
        if access == "w" or reg["access"] == "w":
            return  # a write decode of the same register: the read's type stands unless they disagree in size
        reg["notes"] = _append(reg.get("notes"), f"Also read as {decode} ({where}).")
        leave_open(doc, reg, "type", "word_order")


def _scale(doc: MapDoc, reg: dict[str, Any], entries: list[_Entry], i: int, where: str, conds: set[str]) -> None:
    scales = [s for s in _siblings(entries, i) if s.key == "scale"]
    for s in scales:
        try:
            value = float(s.value)
        except ValueError:
            reg["notes"] = _append(reg.get("notes"), f"scale {s.value!r} is a template parameter ({where}).")
            leave_open(doc, reg, "scale")
            continue
        if set(s.line.conditions) - conds:
            reg["notes"] = _append(reg.get("notes"), f"scale {s.value} only when "
                                   f"{'; '.join(sorted(set(s.line.conditions) - conds))} ({where}).")
            leave_open(doc, reg, "scale")
        elif "scale" in reg and reg["scale"] != value:
            reg["notes"] = _append(reg.get("notes"), f"Also given scale {s.value} ({where}).")
            leave_open(doc, reg, "scale")
        elif value < 0:
            reg["notes"] = _append(reg.get("notes"), f"evcc negates the value (scale {s.value}): evcc's sign "
                                   f"convention ({where}).")
            if value != -1.0:
                reg["scale"] = -value
        elif value != 1.0 and "scale" not in reg.get("review", []):
            reg["scale"] = value


def _append(notes: Any, text: str) -> str:
    return f"{notes} {text}" if notes and text not in str(notes) else (str(notes) if notes else text)


def _no_registers(path: Path, render: str, start: int, indent: int) -> Exception:
    for n, line in enumerate(render.splitlines()):
        match = re.match(r"^\s*type:\s*(\S+)", line)
        if match and match.group(1) not in ("custom", "template"):
            kind = match.group(1)
            what = {"mbmd": "mbmd's built-in meter model (its registers live in the mbmd library)",
                    "sunspec": "evcc's SunSpec reader (the registers come from the device's SunSpec models: "
                               "import those with drivemap import sunspec)"}.get(
                kind, f"evcc's {kind!r} driver (its registers live in evcc's Go code)")
            return error_at(path, start + n, f"the template renders {what}, not registers: not supported",
                            indent + len(line) - len(line.lstrip()) + 1)
    return error_at(path, start, "the render block names no Modbus register (no 'register:' with an address)")
