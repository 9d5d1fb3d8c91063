"""Registers from a vendor's register sheet (CSV), read by its header words; nothing assumed.

Recognised columns (case, spaces and punctuation ignored): address (address, register, reg, modbus
address, start address), name (name, parameter, signal, tag, variable; a description column
otherwise), description, type (type, data type, format), length in words (words, length, size,
registers, quantity), unit, scale (scale, factor, multiplier, gain, resolution), access (access, r/w,
rw, mode, permission), table (table, function, function code, fc, register type), min, max, default.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.importers.imported import mark_open
from drivemap.onboard.importers.mapdoc import MapDoc

__all__ = ["vendor_rows"]

ALIASES: dict[str, tuple[str, ...]] = {
    "address": ("address", "addr", "register", "reg", "modbusaddress", "startaddress", "registeraddress", "regaddr"),
    "name": ("name", "parameter", "parametername", "signal", "tag", "variable", "registername"),
    "description": ("description", "desc", "meaning", "comment"),
    "type": ("type", "datatype", "format", "dataformat", "valuetype"),
    "words": ("words", "length", "size", "registers", "quantity", "count", "numberofregisters"),
    "unit": ("unit", "units", "uom"),
    "scale": ("scale", "factor", "multiplier", "gain", "resolution", "scaling", "scalefactor"),
    "access": ("access", "rw", "readwrite", "mode", "permission", "attribute"),
    "table": ("table", "function", "functioncode", "fc", "registertype", "objecttype"),
    "min": ("min", "minimum", "minvalue"),
    "max": ("max", "maximum", "maxvalue"),
    "default": ("default", "factorydefault", "defaultvalue", "init"),
}
TYPES = {"uint16": "u16", "u16": "u16", "unsigned16": "u16", "word": "u16", "uint": "u16", "unsigned": "u16",
         "int16": "s16", "s16": "s16", "signed16": "s16", "int": "s16", "signed": "s16", "short": "s16",
         "uint32": "u32", "u32": "u32", "dword": "u32", "ulong": "u32", "unsigned32": "u32",
         "int32": "s32", "s32": "s32", "long": "s32", "signed32": "s32",
         "float": "f32", "float32": "f32", "f32": "f32", "real": "f32", "ieee754": "f32",
         "double": "f64", "float64": "f64", "f64": "f64", "uint64": "u64", "u64": "u64", "int64": "s64", "s64": "s64",
         "string": "string", "ascii": "string", "char": "string", "str": "string", "bool": "bool", "bit": "bool",
         "boolean": "bool"}
TABLES = {"holding": "holding", "holdingregister": "holding", "holdingregisters": "holding", "03": "holding",
          "3": "holding", "0x03": "holding", "03h": "holding", "input": "input", "inputregister": "input",
          "inputregisters": "input", "04": "input", "4": "input", "0x04": "input", "04h": "input", "coil": "coil",
          "coils": "coil", "01": "coil", "1": "coil", "0x01": "coil", "01h": "coil", "discrete": "discrete",
          "discreteinput": "discrete", "discreteinputs": "discrete", "02": "discrete", "2": "discrete",
          "0x02": "discrete", "02h": "discrete"}
ACCESS = {"r": "r", "ro": "r", "read": "r", "readonly": "r", "w": "w", "wo": "w", "write": "w", "writeonly": "w",
          "rw": "rw", "readwrite": "rw", "wr": "rw"}


def _key(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", text.lower())


def _columns(header: list[str]) -> dict[str, str]:
    found: dict[str, str] = {}
    for column in header:
        for fact, words in ALIASES.items():
            if _key(column) in words and fact not in found:
                found[fact] = column
    if "name" not in found and "description" in found:
        found["name"] = found["description"]
    return found


def _address(text: str) -> int:
    t = text.strip().lower().replace(" ", "")
    if t.startswith("0x"):
        return int(t, 16)
    if t.endswith("h"):
        return int(t[:-1], 16)
    return int(t)


def vendor_rows(doc: MapDoc, path: Path, header: list[str], rows: list[tuple[int, dict[str, str]]],
                table: str | None, word_order: str | None = None) -> list[dict[str, Any]]:
    cols = _columns(header)
    shown = display(path)
    for need in ("address", "name"):
        if need not in cols:
            raise CompileError([Diagnostic(Location(shown, 1, 1), f"no {need} column in the header "
                                           f"(recognised: {', '.join(ALIASES[need])})")])
    out = []
    for line, row in rows:
        try:
            out.append(_row(doc, cols, row, (table, word_order), f"{path.name} row {line}"))
        except ValueError as exc:
            raise CompileError([Diagnostic(Location(shown, line, 1), str(exc))]) from None
    return out


def _row(doc: MapDoc, cols: dict[str, str], row: dict[str, str], given: tuple[str | None, str | None],
         where: str) -> dict[str, Any]:
    def cell(fact: str) -> str:
        return row.get(cols[fact], "").strip() if fact in cols else ""

    text = cell("name")
    if not text:
        raise ValueError("no name in this row")
    try:
        address = _address(cell("address"))
    except ValueError:
        raise ValueError(f"address {cell('address')!r} is not a number (decimal, 0x.. or ..h)") from None
    reg: dict[str, Any] = {"name": doc.name(text)}
    _place(reg, address, TABLES.get(_key(cell("table"))) if cell("table") else given[0], "table" in cols)
    missing = _typed(reg, cell("type"), cell("words"), given[1])
    _meaning(reg, cell, missing)
    if cell("description") and cols.get("description") != cols["name"]:
        reg["description"] = cell("description")
    elif text != reg["name"]:
        reg["label"] = text
    reg["group"] = doc.group("registers", "Registers")
    reg["source"] = where
    doc.review.miss(reg["name"], *missing)
    return reg


def _place(reg: dict[str, Any], address: int, table: str | None, has_column: bool) -> None:
    if table is not None:
        if not 0 <= address <= 0xFFFF:
            raise ValueError(f"address {address} is past 65535")
        reg.update(table=table, address=address)
    elif not has_column and (30001 <= address <= 39999 or 40001 <= address <= 49999):
        reg["register"] = address  # a Modicon number: 3xxxx input, 4xxxx holding
    else:
        raise ValueError("the table is not stated (no table/function column, no Modicon 3xxxx/4xxxx number): "
                         "pass --table holding|input|coil|discrete")


def _typed(reg: dict[str, Any], kind: str, words: str, word_order: str | None) -> list[str]:
    if not kind:
        mark_open(reg, "type")
        return ["type (not stated: review; read as u16 meanwhile)"]
    dtype = TYPES.get(_key(kind))
    if dtype is None:
        mark_open(reg, "type")
        return [f"type ({kind!r} not recognised: review; read as u16 meanwhile)"]
    reg["type"] = dtype
    if dtype == "string":
        if not words.isdigit():
            raise ValueError(f"string {reg['name']} needs its length in words (a words/length column)")
        reg["length"] = int(words)
    elif dtype in ("u32", "s32", "f32", "u64", "s64", "f64"):
        if word_order is None:
            mark_open(reg, "word_order")
            return [f"word_order ({dtype}: the sheet does not say which word comes first: review, or pass "
                    "--word-order high_first|low_first)"]
        reg["word_order"] = word_order
    return []


def _meaning(reg: dict[str, Any], cell: Any, missing: list[str]) -> None:
    unit, scale = cell("unit"), cell("scale")
    if scale:
        try:
            value = float(scale)
        except ValueError:
            missing.append(f"scale ({scale!r} not a number: review)")
            mark_open(reg, "scale")
        else:
            if value > 0 and value != 1:
                reg["scale"] = value
    if unit:
        reg["unit"] = unit
    access = ACCESS.get(_key(cell("access")))
    if access:
        reg["access"] = access
    else:
        missing.append("access (read-only by the map language's default)")
    for key in ("min", "max", "default"):
        if cell(key):
            try:
                reg[key] = float(cell(key)) if "." in cell(key) else int(cell(key), 0)
            except ValueError:
                missing.append(f"{key} ({cell(key)!r} not a number)")
