"""One register's fields from what its row states: type, scale and unit, range, default, access,
enum or bits. A field the row does not state is left out and named in ``missing``."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

from drivemap.onboard.draft.cells import (
    parse_access,
    parse_bits,
    parse_enum,
    parse_length,
    parse_number,
    parse_range,
    parse_type,
    signed_hint,
)
from drivemap.onboard.draft.tables import Drafted
from drivemap.onboard.draft.units import Scale, parse_scale, unit_after_range


@dataclass
class Context:
    """Document-wide facts the fields depend on."""

    document: str
    footnote: Callable[[str], bool]
    word_order: str | None = None
    """``high_first``/``low_first`` when the document states the word order of 32-bit values."""


@dataclass
class Raw:
    """What a row says about one register, before parsing."""

    address: int
    table: str | None
    where: str
    label: str = ""
    param: str = ""
    cells: dict[str, str] = field(default_factory=dict)
    """Texts by column role (type, unit, range, min, max, default, access, length, description)."""
    text: str = ""
    """Everything the row says (free text of a loose row; description and extra lines of a grid row)."""
    access: str | None = None
    bits: list[tuple[int, str]] = field(default_factory=list)
    enum: list[tuple[int, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _type_fields(raw: Raw, ctx: Context, entry: dict[str, object], missing: list[str], notes: list[str]) -> str:
    words = parse_length(raw.cells.get("length", ""), raw.cells.get("length_header", ""))
    rtype = parse_type(raw.cells.get("type", ""), words)
    if rtype is None and signed_hint(raw.text + " " + raw.cells.get("type", "")):
        rtype = "s16" if words in (None, 1) else None
    if rtype is None and words is not None and words > 1:
        notes.append(f"{words} registers long, type not stated: left at one u16 register")
    if rtype is None or rtype == "bool":
        missing.append("type")
        return "u16"
    if rtype == "string":
        if words is None:
            missing.append("type")
            notes.append("string without a length: type left out")
            return "u16"
        entry["type"], entry["length"] = "string", words
        return "string"
    if rtype[1:] not in ("16",):
        if ctx.word_order is None:
            missing.append("type")
            notes.append(f"{rtype} stated but the document does not state the word order: type left out")
            return "u16"
        entry["word_order"] = ctx.word_order
    entry["type"] = rtype
    return rtype


def _scale_fields(raw: Raw, ctx: Context, rtype: str, entry: dict[str, object], missing: list[str],
                  notes: list[str]) -> tuple[float | None, bool]:
    """Scale and unit; returns (scale, whether the range that follows is in raw counts)."""
    unit_cell = raw.cells.get("unit", "")
    found = parse_scale(unit_cell, unit_cell=True, footnote=ctx.footnote) if unit_cell else None
    factor = parse_number(raw.cells.get("scale", ""))
    if factor is not None and factor > 0:  # a bare number in a Scale/Factor column: engineering = raw x factor
        unit = found.unit if found is not None else None
        found = Scale(factor, unit, raw.cells["scale"])
    raw_range = False
    if found is None or found.scale is None:
        in_text = parse_scale(raw.text + " " + raw.cells.get("range", ""), footnote=ctx.footnote)
        if in_text is not None and (found is None or in_text.scale is not None):
            raw_range = in_text.scale is not None and bool(re.search(r"=|means|對應|对应", in_text.printed))
            found = in_text
    if found is not None and found.note:
        notes.append(found.note)
    scale = found.scale if found is not None else None
    unit = found.unit if found is not None else None
    if unit is None:
        rng = parse_range(raw.cells.get("range", "") or raw.text)
        unit = unit_after_range(rng[2]) if rng else None
    if scale is not None and rtype not in ("string",):
        entry["scale"] = scale
    elif rtype.startswith("f"):
        pass  # a float holds the engineering value itself
    else:
        missing.append("scale")
    if unit is not None:
        entry["unit"] = unit
    else:
        missing.append("unit")
    return scale, raw_range


def _range_fields(raw: Raw, scale: float | None, raw_range: bool, entry: dict[str, object],
                  missing: list[str], notes: list[str]) -> None:
    lo = parse_number(raw.cells.get("min", ""))
    hi = parse_number(raw.cells.get("max", ""))
    text = raw.cells.get("range", "")
    if lo is None and hi is None:
        rng = parse_range(text) if text else parse_range(_range_text(raw.text))
        if rng is not None:
            lo, hi = rng[0], rng[1]
    if lo is None or hi is None:
        missing.append("range")
        return
    factor = 1.0
    after = parse_range(text or _range_text(raw.text))
    unit_column = parse_scale(raw.cells.get("unit", ""), unit_cell=True) is not None
    printed_unit = unit_column or (after is not None and unit_after_range(after[2]) is not None)
    if scale is None and not printed_unit:
        notes.append(f"range {lo}..{hi} printed without a unit or resolution (raw or engineering?): left out")
        missing.append("range")
        return
    if scale is not None and scale != 1:
        decimals = any("." in str(v) for v in (lo, hi))
        if raw_range:
            factor = scale
        elif not decimals:
            notes.append(f"range {lo}..{hi} printed without saying raw or engineering: left out")
            missing.append("range")
            return
    entry["min"], entry["max"] = _clean(lo * factor), _clean(hi * factor)


def _range_text(text: str) -> str:
    """Free text up to the first enum list (``0: STOP``): a range is stated before it."""
    m = re.search(r"(?:^|\s)-?\d+\s*[:：]", text)
    return text[: m.start()] if m else text


def _clean(value: float) -> float | int:
    value = float(f"{value:.12g}")
    return int(value) if value.is_integer() else value


def _default_field(raw: Raw, scale: float | None, entry: dict[str, object], notes: list[str]) -> None:
    value = parse_number(raw.cells.get("default", ""))
    if value is None:
        return
    if scale is not None and scale != 1 and "." not in raw.cells.get("default", ""):
        notes.append(f"default {raw.cells['default']!r} printed without saying raw or engineering: left out")
        return
    entry["default"] = value


def _access_field(raw: Raw, entry: dict[str, object], missing: list[str]) -> None:
    access = parse_access(raw.cells.get("access", "")) if raw.cells.get("access") else raw.access
    if access is None and raw.table in ("input", "discrete"):
        return  # read-only by the table itself
    if access is None:
        missing.append("access")
    elif access != "r":
        entry["access"] = access


def draft_fields(raw: Raw, ctx: Context) -> Drafted:
    """The map entry of one register (without name, group and enum names: :mod:`.assemble` adds them)."""
    entry: dict[str, object] = {}
    missing: list[str] = []
    notes = list(raw.notes)
    if raw.table is not None:
        entry["table"] = raw.table
    else:
        missing.append("table")
    entry["address"] = raw.address
    if raw.param:
        entry["param"] = raw.param
    if raw.label:
        entry["label"] = raw.label
    if raw.table in ("coil", "discrete"):  # one bit: bool is the table's only type
        _access_field(raw, entry, missing)
        return Drafted(entry, raw.where, missing, notes)
    rtype = _type_fields(raw, ctx, entry, missing, notes)
    bits = raw.bits or parse_bits(raw.text) or []
    cell_enum = next((e for e in (parse_enum(raw.cells.get(k, "")) for k in ("range", "description")) if e), None)
    enum = [] if bits else (raw.enum or cell_enum or parse_enum(raw.text) or [])
    if bits:
        entry["bits"] = bits
        missing = [m for m in missing if m != "type"]
    elif enum:
        entry["enum"] = enum
    if not bits and not enum:
        scale, raw_range = _scale_fields(raw, ctx, rtype, entry, missing, notes)
        _range_fields(raw, scale, raw_range, entry, missing, notes)
        _default_field(raw, scale, entry, notes)
    _access_field(raw, entry, missing)
    return Drafted(entry, raw.where, missing, notes)
