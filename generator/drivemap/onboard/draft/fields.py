"""One register's fields from what its row states: type, scale and unit, range, default, access,
enum or bits. A field the row does not state is left out and named in ``missing``."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from drivemap.onboard.draft.cells import (
    FULL_SPANS,
    WIDTHS,
    parse_access,
    parse_address,
    parse_bits,
    parse_enum,
    parse_length,
    parse_number,
    parse_range,
    parse_type,
    signed_hint,
    span_type,
    value_list,
)
from drivemap.onboard.draft.tables import Drafted
from drivemap.onboard.draft.units import Scale, parse_scale, seconds_cell, unit_after_range, unit_in_name


@dataclass
class Context:
    """Document-wide facts the fields depend on."""

    document: str
    footnote: Callable[[str], bool]
    word_order: str | None = None
    """``high_first``/``low_first`` when the document states the word order of 32-bit values."""
    word_order_source: str = ""
    """Where the document states it (file, line and the words), recorded on each register it decides."""
    base_one: str = ""
    """Where the document says it numbers registers from 1 (empty when it does not)."""
    type_words: dict[str, tuple[str, str]] = field(default_factory=dict)
    """The document's own glossary of data types: token -> (schema type, where it defines it and how)."""
    factor_divides: dict[str, str] = field(default_factory=dict)
    """Factor columns the document's own rows prove to divide: header (lower case) -> the proof (see
    :func:`factor_proofs`), recorded on each register it decides."""


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
    open: list[str] = field(default_factory=list)
    """Fields the row's reading leaves open whatever its cells say (``address``: an offset from a start
    address whose unit the document does not give)."""
    offset_from: tuple[int, int, str] | None = None
    """(start address, offset, the note that leaves the address open) of a row drafted at the document's own
    sum of the two (see ``open``)."""


#: a type written as a token of its own in a row without a type column (a remark's ``S16``, ``U32``)
_TYPE_TOKEN = re.compile(r"(?<![A-Za-z0-9])(?:[US]|U?INT)(?:16|32|64)(?![A-Za-z0-9])")


def _type_in_text(raw: Raw, words: int | None, notes: list[str]) -> str | None:
    """The type a row without a type column states in its text: one distinct token (``S16``), else None."""
    tokens = {t.upper() for t in _TYPE_TOKEN.findall(raw.text + " " + " ".join(raw.cells.values()))}
    if len(tokens) != 1:
        return None
    token = tokens.pop()
    rtype = parse_type(token, words)
    if rtype is not None:
        notes.append(f"type {rtype}: the row says {token!r} (no type column)")
    return rtype


def _glossary_type(cell: str, ctx: Context, words: int | None, notes: list[str]) -> str | None:
    """The type a type cell's token has by the document's own glossary (``I32``: "Signed integer (32
    bits)"), where it reads otherwise than the usual words or they do not know it; a length column that
    disagrees with the width leaves it open."""
    token = re.sub(r"\s+", "", cell).upper()
    defined = ctx.type_words.get(token)
    if defined is None:
        return None
    rtype, said = defined
    if parse_type(cell, None) == rtype:
        return None  # the usual reading, no note needed
    if words is not None and WIDTHS.get(rtype) != words:
        notes.append(f"type left open: the document defines {token!r} as {rtype} ({said}) but the row gives "
                     f"{words} register{'' if words == 1 else 's'}")
        return None
    notes.append(f"type {rtype}: the document defines {token!r}: {said}")
    return rtype


def _string_fields(raw: Raw, words: int | None, entry: dict[str, object], missing: list[str], notes: list[str]) -> str:
    """A text register: its length in registers and its encoding, as the row states them."""
    said = raw.cells.get("type", "")
    if words == 1 and re.fullmatch(r"\s*(?:char|character)\s*", said, re.I):
        missing.append("type")
        notes.append("a char in one register: a character's code (a number) or two bytes of text? "
                     "the document does not say: type left out")
        return "u16"
    if words is None:
        missing.append("type")
        notes.append("string without a length: type left out")
        return "u16"
    entry["type"], entry["length"] = "string", words
    if re.search(r"utf-?8", said, re.I):
        entry["encoding"] = "utf-8"
    elif not re.search(r"\bascii\b", f"{said} {raw.text}", re.I):
        missing.append("encoding")
        notes.append(f"text ({said.strip()!r}) in {words} registers: the document does not say its encoding "
                     "(ascii or utf-8)")
    return "string"


def _type_fields(raw: Raw, ctx: Context, entry: dict[str, object], missing: list[str], notes: list[str]) -> str:
    words = parse_length(raw.cells.get("length", ""), raw.cells.get("length_header", ""))
    rtype = _glossary_type(raw.cells.get("type", ""), ctx, words, notes)
    if rtype is None:
        rtype = parse_type(raw.cells.get("type", ""), words)
    if rtype is None and not raw.cells.get("type", "").strip():
        rtype = _type_in_text(raw, words, notes)
    if rtype is None and signed_hint(raw.text + " " + raw.cells.get("type", "")):
        rtype = "s16" if words in (None, 1) else None
    if rtype is None:
        spanned = span_type(raw.cells.get("range", ""))
        if spanned is not None and (words is None or words == int(spanned[1:]) // 16):
            rtype = spanned
            notes.append(f"type {spanned}: the range {raw.cells['range'].strip()!r} is its whole span")
    if rtype is None and words is not None and words > 1:
        notes.append(f"{words} registers long, type not stated: left at one u16 register")
    if rtype is None or rtype == "bool":
        missing.append("type")
        return "u16"
    if rtype == "string":
        return _string_fields(raw, words, entry, missing, notes)
    halves = _halves(raw.text) if rtype[1:] == "32" else None
    if halves is not None:
        entry["word_order"] = halves[0]
        notes.append(f"word_order {halves[0]}: the row says {halves[1]!r}")
    elif rtype[1:] not in ("16",):
        if ctx.word_order is None:
            missing.append("word_order")
            notes.append(f"{rtype} stated but the document does not state the word order: word_order to review")
        else:
            entry["word_order"] = ctx.word_order
            if ctx.word_order_source:
                notes.append(f"word_order {ctx.word_order}: {ctx.word_order_source}")
    entry["type"] = rtype
    return rtype


_HALF = r"(low|high)(?:[\s_-]*word)?\s*[-–—:=]\s*((?:0[xX])?[0-9A-Fa-f]+[hH]?)(?![0-9A-Za-z])"
_HALVES = re.compile(rf"{_HALF}.{{0,40}}?{_HALF}", re.I | re.S)


def _halves(text: str) -> tuple[str, str] | None:
    """The word order a row states by naming its two registers (``Reg_Low–0x030B, Reg_High-0x030C``): the
    low word at the lower address is ``low_first``; None unless both halves are named, one apart."""
    m = _HALVES.search(text)
    if m is None or m.group(1).lower() == m.group(3).lower():
        return None
    first, second = parse_address(m.group(2)), parse_address(m.group(4))
    if first is None or second is None or first.hex_value is None or second.hex_value is None:
        return None
    hexed = m.group(2).lower().startswith("0x") or m.group(2).lower().endswith("h")
    a, b = (first.hex_value, second.hex_value) if hexed else (first.dec_value, second.dec_value)
    if a is None or b is None or abs(a - b) != 1:
        return None
    low = a if m.group(1).lower() == "low" else b
    return ("low_first" if low == min(a, b) else "high_first"), m.group(0)


def _unit_cell(raw: Raw, ctx: Context, named: bool) -> tuple[Scale | None, str]:
    """What the unit column says, and the cell as read."""
    unit_cell = raw.cells.get("unit", "")
    if named:  # the quantity's name and its unit in one cell ("V L1-N"): the unit, never a resolution
        printed = unit_in_name(unit_cell)
        return (Scale(None, printed, unit_cell) if printed else None), printed or ""
    found = parse_scale(unit_cell, unit_cell=True, footnote=ctx.footnote) if unit_cell else None
    if found is None and unit_cell:
        found = seconds_cell(unit_cell, raw.label or "")
    return found, unit_cell


def _scale_fields(raw: Raw, ctx: Context, rtype: str, entry: dict[str, object], missing: list[str],
                  notes: list[str], direction: str | None = None) -> tuple[float | None, bool]:
    """Scale and unit; returns (scale, whether the range that follows is in raw counts). A value list
    in the text (``1 = 0.1 A, 10 = 1 A``) that could be values or a resolution is no scale."""
    named = bool(raw.cells.get("unit_named"))
    found, unit_cell = _unit_cell(raw, ctx, named)
    bare = parse_number(unit_cell) if unit_cell and found is None else None
    if bare is not None and bare > 0 and abs(math.log10(bare) - round(math.log10(bare))) < 1e-9 \
            and -6 <= round(math.log10(bare)) <= 3:  # "0.001" in a Unit/Ratio column: a resolution without a unit
        found = Scale(float(bare), None, unit_cell)
    factor = _factor_cell(raw, entry, notes, direction, ctx.factor_divides)
    if factor is not None:
        unit = found.unit if found is not None else None
        found = Scale(factor, unit, raw.cells["scale"])
    raw_range = False
    listed = value_list(raw.text) if found is None or found.scale is None else None
    if listed is not None:
        notes.append(f"value list '{listed.printed}': values or a resolution? neither drafted")
    elif found is None or found.scale is None:
        in_text = parse_scale(raw.text + " " + raw.cells.get("range", ""), footnote=ctx.footnote)
        if in_text is not None and found is not None and found.unit and in_text.unit \
                and in_text.scale is not None and in_text.unit != found.unit:
            notes.append(f"the text's {in_text.printed.strip()!r} is in {in_text.unit}, the unit column says "
                         f"{found.unit}: scale left out")
        elif in_text is not None and (found is None or in_text.scale is not None):
            raw_range = in_text.scale is not None and bool(re.search(r"=|means|對應|对应", in_text.printed))
            found = in_text if in_text.unit or found is None else Scale(in_text.scale, found.unit, in_text.printed,
                                                                         in_text.note)
    if found is not None and found.note:
        notes.append(found.note)
    if found is not None and found.reading:
        notes.append(found.reading)
    scale = found.scale if found is not None else None
    unit = found.unit if found is not None else None
    if unit is None:
        rng = parse_range(raw.cells.get("range", "") or raw.text)
        unit = unit_after_range(rng[2]) if rng else None
    if scale is None and listed is None and unit is not None and found is not None and found.unit == unit \
            and unit_cell and not named and not raw.cells.get("scale_header") and not found.note:
        scale = 1.0  # a unit column that states the unit without a resolution: the value is in that unit
        notes.append(f"scale 1: the unit column says {unit_cell!r} without a resolution")
    elif scale is None and listed is None and found is None and not unit_cell and raw.cells.get("unit_header") \
            and not raw.cells.get("scale_header") and rtype in ("u16", "s16", "u32", "s32", "u64", "s64") \
            and "type" not in missing:  # a row that states no type states nothing of its value
        scale = 1.0  # the unit column is empty on this row and no column scales: the raw value is the value
        notes.append("scale 1: no unit or resolution in the unit column")
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


_MULTIPLIER = re.compile(r"multiplier|multiplikator|倍率", re.I)
#: a fraction in a scale column (``1/100``): the multiplier 0.01
_FRACTION = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*/\s*(\d+(?:\.\d+)?)\s*$")
#: a header that names a factor without saying its direction: vendors print "Gain 100" for raw ÷ 100
#: (Huawei) as others print it for raw × 100; only the document's own ranges decide it
_UNDIRECTED = re.compile(r"^gain", re.I)
_RAW_MAX = {"u16": 65535, "s16": 32767}


def _range_says(factor: float, rtype: str | None, range_text: str) -> str | None:
    """``divide`` when the printed range is the raw span divided by the factor (``Scalefactor 100``,
    ``0 to 655.35`` on a u16), ``multiply`` when multiplied by it; None when the range does not tell."""
    rng = parse_range(range_text)
    top = _RAW_MAX.get(rtype or "")
    if rng is None or top is None or factor in (0, 1):
        return None
    if math.isclose(rng[1], top * factor, rel_tol=1e-9):
        return "multiply"
    if math.isclose(rng[1], top / factor, rel_tol=1e-9):
        return "divide"
    return None


def factor_direction(raws: list[Raw]) -> str | None:
    """What a table's Scale/Factor column means, when the rows whose range tells all say the same."""
    said = set()
    for raw in raws:
        factor = parse_number(raw.cells.get("scale", ""))
        if factor is not None and factor > 0:
            said.add(_range_says(factor, parse_type(raw.cells.get("type", ""), None), raw.cells.get("range", "")))
    said.discard(None)
    return said.pop() if len(said) == 1 else None


#: a power factor's name: a quantity between -1 and 1 by definition
_POWER_FACTOR = re.compile(r"power[\s_-]*factor|leistungsfaktor|功率因[数數]|\bcos\s*(?:φ|ϕ|phi)|^pf$", re.I)


def _has_unit(text: str) -> bool:
    found = parse_scale(text, unit_cell=True) if text.strip() else None
    return found is not None and found.unit is not None


def factor_proofs(raws: list[Raw]) -> dict[str, str]:
    """Factor columns (header in lower case -> why) whose direction the document proves: a power factor row, unitless, with
    a factor above 1. A power factor lies between -1 and 1: read as raw x factor it could hold no value
    there but 0, so the column's numbers divide (Huawei's "Gain 1000" on its power factor rows). A
    column headed Multiplier says its direction itself and is not read here."""
    proofs: dict[str, str] = {}
    for raw in raws:
        header = raw.cells.get("scale_header", "").strip()
        factor = parse_number(raw.cells.get("scale", ""))
        if (not header or header.lower() in proofs or _MULTIPLIER.search(header) or factor is None or factor <= 1
                or not _POWER_FACTOR.search(raw.label.strip()) or _has_unit(raw.cells.get("unit", ""))):
            continue
        proofs[header.lower()] = (f"the document's power factor row ({raw.where}, '{raw.label.strip()}') has {header} "
                                  f"{factor:g}, and a power factor, between -1 and 1, read as raw x {factor:g} could be "
                                  "no value there but 0")
    return proofs


def _factor_cell(raw: Raw, entry: dict[str, object], notes: list[str], direction: str | None,
                 proofs: dict[str, str]) -> float | None:
    """The scale a Scale/Factor/Gain column's bare number states (None: no number, or not a scale)."""
    factor = parse_number(raw.cells.get("scale", ""))
    fraction = _FRACTION.match(raw.cells.get("scale", ""))
    if factor is None and fraction is not None and float(fraction.group(2)) > 0:
        factor = _clean(float(fraction.group(1)) / float(fraction.group(2)))
    if factor is not None and factor < 0:
        notes.append(f"scale factor {raw.cells['scale']} is negative: not read as a scale")
    if factor is None or factor <= 0:
        return None
    scale = _factor_scale(factor, raw, entry, direction, proofs, notes)
    if scale is None:
        notes.append(f"{raw.cells.get('scale_header', '').strip()} {factor:g}: raw x {factor:g} or raw / "
                     f"{factor:g}? the document does not say (scale left out)")
    return scale


def _factor_scale(factor: float, raw: Raw, entry: dict[str, object], direction: str | None,
                  proofs: dict[str, str], notes: list[str]) -> float | None:
    """The scale of a bare number in a Scale/Factor column: the number itself when it is 1 or the header
    says multiplier; else what the row's printed range tells, else what the table's rows tell (a
    column divides on every row or on none), else what the document's power factor rows prove of the
    column (:func:`factor_proofs`, noted), else the number as a multiplier under a Scale/Factor
    header, and nothing (None: open) under a ``Gain`` header, which does not say its direction."""
    if factor == 1 or _MULTIPLIER.search(raw.cells.get("scale_header", "")):
        return factor
    said = _range_says(factor, str(entry.get("type")), raw.cells.get("range", "")) or direction
    proof = proofs.get(raw.cells.get("scale_header", "").strip().lower()) if said is None else None
    if proof is not None:
        notes.append(f"{raw.cells.get('scale_header', '').strip()} {factor:g} read as raw / {factor:g}: {proof}")
        said = "divide"
    if said is None and _UNDIRECTED.search(raw.cells.get("scale_header", "").strip()):
        return None
    return _clean(1 / factor) if said == "divide" else factor


def _range_fields(raw: Raw, scale: float | None, raw_range: bool, entry: dict[str, object],
                  missing: list[str], notes: list[str]) -> tuple[float, float] | None:
    """Fill min and max where the row states them; the printed range when it does not say whether it
    is raw counts or the value (for :func:`_same_either_way`, which may read it both ways)."""
    lo = parse_number(raw.cells.get("min", ""))
    hi = parse_number(raw.cells.get("max", ""))
    text = raw.cells.get("range", "")
    if lo is None and hi is None:
        # with a range column, an empty cell states no range: remarks and descriptions are not read for one
        rng = parse_range(text) if text else None if raw.cells.get("range_header") else parse_range(_range_text(raw.text))
        if rng is not None:
            lo, hi = rng[0], rng[1]
    if lo is None or hi is None:
        missing.append("range")
        return None
    if entry.get("type") is not None and FULL_SPANS.get((lo, hi)) == entry.get("type"):
        notes.append(f"range {lo}..{hi}: the whole span of {entry['type']}, no limit of its own")
        return None
    factor = 1.0
    after = parse_range(text or _range_text(raw.text))
    printed = unit_after_range(after[2]) if after is not None else None
    if printed is not None and entry.get("unit") not in (None, printed):
        notes.append(f"range {lo}..{hi} printed in {printed}, the register's unit is {entry['unit']}: left out")
        missing.append("range")
        return None
    unit_column = parse_scale(raw.cells.get("unit", ""), unit_cell=True) is not None
    printed_unit = unit_column or (after is not None and unit_after_range(after[2]) is not None)
    if scale is None and not printed_unit:
        notes.append(f"range {lo}..{hi} printed without a unit or resolution (raw or engineering?): left out")
        missing.append("range")
        return None
    if scale is not None and scale != 1:
        decimals = any("." in str(v) for v in (lo, hi))
        one_word = entry.get("type") in (None, "u16", "s16") and \
            parse_length(raw.cells.get("length", ""), raw.cells.get("length_header", "")) in (None, 1)
        if raw_range:
            factor = scale
        elif not decimals and one_word and 0 <= lo and hi <= 65535 < hi / scale:
            factor = scale  # as the value, it would need more counts than one register holds
            notes.append(f"range {lo}..{hi} read as raw counts: as the value at scale {scale:g} it would need "
                         f"{_clean(hi / scale)} counts, more than one register holds")
        elif not decimals:
            notes.append(f"range {lo}..{hi} printed without saying raw or engineering: left out")
            missing.append("range")
            return lo, hi
    entry["min"], entry["max"] = _clean(lo * factor), _clean(hi * factor)
    return None


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


def _enum_default(raw: Raw, enum: list[tuple[int, str]], entry: dict[str, object], notes: list[str]) -> None:
    """The default of a register that holds listed values: one of those values, else left out."""
    printed = raw.cells.get("default", "")
    value = parse_number(printed)
    if value is None:
        return
    if isinstance(value, int) and value in {v for v, _ in enum}:
        entry["default"] = value
    else:
        notes.append(f"default {printed!r} is none of the listed values: left out")


def _access_field(raw: Raw, entry: dict[str, object], missing: list[str], notes: list[str] | None = None) -> None:
    access = parse_access(raw.cells.get("access", "")) if raw.cells.get("access") else raw.access
    remark = raw.cells.get("description", "").strip()
    if access is None and not raw.cells.get("access") and parse_access(remark) is not None:
        access = parse_access(remark)  # a remark that says only "Read-Write"
        if notes is not None:
            notes.append(f"access {access}: the remark says {remark!r}")
    if access is None and raw.table in ("input", "discrete"):
        return  # read-only by the table itself
    if access is None:
        missing.append("access")
    elif access != "r":
        entry["access"] = access


def draft_fields(raw: Raw, ctx: Context, direction: str | None = None) -> Drafted:
    """The map entry of one register (without name, group and enum names: :mod:`.assemble` adds them)."""
    entry: dict[str, object] = {}
    missing: list[str] = list(raw.open)
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
    enum = [] if bits else (raw.enum or _text_enum(raw, notes))
    if bits:
        entry["bits"] = bits
        missing = [m for m in missing if m != "type"]
    elif enum:
        entry["enum"] = enum
        _enum_default(raw, enum, entry, notes)
    if not bits and not enum and rtype != "string":  # text has no scale
        scale, raw_range = _scale_fields(raw, ctx, rtype, entry, missing, notes, direction)
        either = _range_fields(raw, scale, raw_range, entry, missing, notes)
        _default_field(raw, scale, entry, notes)
        _same_either_way(raw, entry, missing, notes, either)
    _access_field(raw, entry, missing, notes)
    if raw.table is None and entry.get("access") in ("w", "rw") and _word_sized(raw, entry):
        entry = {"table": "holding", **entry}
        missing.remove("table")
        notes.append(f"table holding: the document says it is written ({_access_text(raw)!r}) and a register wide; "
                     "of Modbus's tables only holding registers are")
    _review(entry, missing)
    return Drafted(entry, raw.where, missing, notes)


#: the raw values a one-register integer reads the same signed and unsigned
_BOTH_WAYS = 32767


def _same_either_way(raw: Raw, entry: dict[str, object], missing: list[str], notes: list[str],
                     either: tuple[float, float] | None = None) -> None:
    """A one-register integer whose signedness the document leaves open, but whose drafted range
    (``[0,1000]``) lies within raw 0..32767 at its stated scale: every value it may hold reads the same as
    u16 and as s16, so u16 changes no value. It is written with the range (which a write outside is
    refused by) and a note saying so. A range ``either`` the row prints without saying raw counts or the
    value counts both ways: u16 where both readings lie within 0..32767 (and the range is not written).
    Without a stated scale, a range or a length of one register, the type stays open."""
    drafted = "min" in entry and "max" in entry
    if "type" not in missing or raw.cells.get("type", "").strip() or not (drafted or either):
        return
    words = parse_length(raw.cells.get("length", ""), raw.cells.get("length_header", ""))
    scale = entry.get("scale")
    if words not in (None, 1) or not isinstance(scale, (int, float)) or scale <= 0:
        return
    if drafted:
        low, high = float(entry["min"]) / scale, float(entry["max"]) / scale  # type: ignore[arg-type]
        said = f"its range {entry['min']}..{entry['max']} (raw {_clean(low)}..{_clean(high)})"
    elif either is not None:
        lo, hi = either
        low, high = min(lo, lo / scale), max(hi, hi / scale)
        said = (f"its range {_clean(lo)}..{_clean(hi)}, raw counts or the value (raw {_clean(lo)}..{_clean(hi)} or "
                f"{_clean(lo / scale)}..{_clean(hi / scale)}),")
    else:
        return
    if low < 0 or high > _BOTH_WAYS:
        return
    missing.remove("type")
    entry["type"] = "u16"
    notes.append(f"type u16: the document does not say signed or unsigned, but {said} reads the same either way "
                 f"(every raw value from 0 to {_BOTH_WAYS})")


def _word_sized(raw: Raw, entry: dict[str, object]) -> bool:
    """Whether the row says the register is 16 bits or more wide (a type, a length in words or bit fields):
    then it is no coil."""
    return "type" in entry or "bits" in entry or \
        parse_length(raw.cells.get("length", ""), raw.cells.get("length_header", "")) is not None


def _access_text(raw: Raw) -> str:
    return raw.cells.get("access", "").strip() or (str(raw.access) if raw.access else
                                                   raw.cells.get("description", "").strip())


def _text_enum(raw: Raw, notes: list[str]) -> list[tuple[int, str]]:
    """A value list in the row's range or description cell or its free text, unless the unit column
    states a resolution with a unit (``0.1kW``): a measured value, whose numbered lines are no value list
    of its own (the next row's description printed above that row's number; a remark on the values of
    another register: "Refer to Output type (address: 5002) 0: phase voltage; ...")."""
    enum = next((e for e in (parse_enum(raw.cells.get(k, "")) for k in ("range", "description")) if e), None) \
        or parse_enum(raw.text) or []
    unit_cell = raw.cells.get("unit", "")
    stated = parse_scale(unit_cell, unit_cell=True) if enum and unit_cell else None
    if stated is not None and stated.scale is not None and stated.unit:
        notes.append(f"values listed in the row not read as this register's: the unit column says {unit_cell.strip()!r}")
        return []
    return enum


#: Fields whose schema default would change the values read: an unstated one is written as ``review:``.
REVIEWED = ("table", "address", "type", "word_order", "scale", "encoding")


def _review(entry: dict[str, object], missing: list[str]) -> None:
    """``review: [...]``: the fields the row leaves open whose default would stand in for a value (a
    register of listed values or bits has no scale to state)."""
    listed = bool(entry.get("enum") or entry.get("bits"))
    items = [m for m in REVIEWED if m in missing and not (listed and m in ("scale", "type"))]
    if items:
        entry["review"] = items
