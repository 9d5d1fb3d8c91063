"""The drafted map as data: header, a protocol skeleton of nulls, groups, enums and registers."""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from drivemap.frontend.formats import CURRENT
from drivemap.onboard.draft.cells import type_glossary
from drivemap.onboard.draft.fields import REVIEWED, Context, Raw, draft_fields, factor_direction, factor_proofs
from drivemap.onboard.draft.matrix import matrix_raws
from drivemap.onboard.draft.naming import arrays, camel, snake, unique, upper
from drivemap.onboard.draft.rows import (
    grid_raws,
    loose_raws,
    offset_bases,
    offset_rows,
    offsets_header,
    plain_addresses,
    table_access,
    table_kind,
    under_header,
    with_start,
)
from drivemap.onboard.draft.tables import Drafted, Skipped, Source, Table

#: Protocol facts the draft cannot read from register tables; written as placeholders and listed.
PLACEHOLDERS = ("protocol.unit_ids (1..247)", "protocol.ports (settings unknown)", "protocol.function_codes "
                "(from the tables drafted; max_quantity null)", "protocol.exceptions (none)", "protocol.timing (null)")


#: the fields ``--assume FIELD=VALUE`` may give, and the values each takes
ASSUMABLE: dict[str, tuple[str, ...]] = {
    "table": ("holding", "input", "coil", "discrete"),
    "type": ("u16", "s16", "u32", "s32", "u64", "s64", "f32", "f64"),
    "word_order": ("high_first", "low_first"),
    "offset": ("registers", "bytes"),
}


@dataclass(frozen=True)
class Hints:
    """What a person tells the draft (``--assume FIELD=VALUE``, ``--address-base N``): used only where the
    document does not state the field, and recorded on every register it decides and in the review list."""

    assume: tuple[tuple[str, str], ...] = ()
    address_base: int | None = None

    def value(self, key: str) -> str | None:
        return next((v for k, v in self.assume if k == key), None)

    def said(self) -> list[str]:
        out = [f"--assume {k}={v}" for k, v in self.assume]
        if self.address_base is not None:
            out.append(f"--address-base {self.address_base}")
        return out


@dataclass
class Draft:
    """Everything the draft found: the map data, each register's review facts, skipped rows."""

    data: dict[str, Any]
    registers: list[Drafted]
    skipped: list[Skipped]
    tables: list[tuple[str, int]] = field(default_factory=list)
    """(table label, registers drafted from it) of every register table found."""
    review: list[str] = field(default_factory=list)


_DOUBLE = r"(?:double[\s-]*words?|32[\s-]*bits?|two[\s-]*registers?|32[\s-]*位)"
#: "subtracting 1 from the register address": the document numbers its registers from 1.
_BASE_ONE = re.compile(r"subtract(?:ing|ed)?\s+1\s+from\s+the\s+(?:register\s+)?address|"
                       r"(?:register\s+)?address(?:es)?\s+minus\s+1|protocol\s+address\s*=\s*register\s*(?:address)?\s*-\s*1|"
                       r"addresses?\s+(?:start|begin)s?\s+(?:at|from)\s+1\b", re.I)


def _word_order(text: str) -> tuple[str | None, str]:
    """The word order of 32-bit values a statement of the document decides, and that statement."""
    specific = re.search(rf"(little|big)[\s-]*endian\s+for\s+{_DOUBLE}|{_DOUBLE}[^.\n]{{0,40}}?(little|big)[\s-]*endian",
                         text, re.I)
    if specific:
        kind = (specific.group(1) or specific.group(2)).lower()
        return ("low_first" if kind == "little" else "high_first"), specific.group(0)
    named = re.search(r"word[\s-]*order\s*(?:is|:|=)?\s*(lsw|msw|low(?:er)?\s+word|high(?:er)?\s+word)\s*(?:(?:-*>|→)\s*(?:lsw|msw|low(?:er)?\s+word|high(?:er)?\s+word)?|first|before)"
                      r"|\b(lsw|msw)\s+first\b", text, re.I)
    if named:  # "the word order is LSW-> MSW", "MSW first"
        kind = (named.group(1) or named.group(2)).lower()
        return ("low_first" if kind.startswith(("lsw", "low")) else "high_first"), named.group(0)
    high = re.search(r"(?:high|most significant|upper)\s+word\s+first|big[\s-]*endian|高字在前|高位字在前", text, re.I)
    low = re.search(r"(?:low|least significant|lower)\s+word\s+first|little[\s-]*endian|低字在前|低位字在前", text, re.I)
    if high and not low:
        return "high_first", high.group(0)
    if low and not high:
        return "low_first", low.group(0)
    return None, ""


def _statement_where(source: Source, said: str) -> str:
    """``p.5 line 12`` (PDF pages are the text's form feeds) or ``line 12`` of the statement ``said``."""
    at = source.text.find(said)
    if at < 0:
        return ""
    before = source.text[:at]
    return f"line {before.count(chr(10)) + 1}"


def document_context(source: Source) -> Context:
    text = source.text
    order, said = _word_order(text)
    lines = [ln.strip() for ln in text.splitlines()]

    def footnote(n: str) -> bool:
        return any(re.match(rf"\*\s*{n}(?!\d)\s*\S", ln) for ln in lines)

    ctx = Context(source.name, footnote, order)
    if order is not None:
        ctx.word_order_source = f"{source.name} {_statement_where(source, said)}: {said.strip()!r}"
    base = _BASE_ONE.search(text)
    if base is not None:
        ctx.base_one = f"{source.name} {_statement_where(source, base.group(0))}: {base.group(0).strip()!r}"
    else:
        ctx.base_one = _origin_one(source)
    ctx.type_words = {token: (rtype, f"{source.name} {_statement_where(source, said)}: {said!r}")
                      for token, (rtype, said) in type_glossary(text).items()}
    return ctx


#: a header saying its numbers count from 1: "Base (dec, origin-1)", "Register (1-based)"
_ORIGIN_ONE = re.compile(r"origin[\s-]*1\b|(?<![\d.])1[\s-]*based\b|one[\s-]*based\b", re.I)
_HEX_HEADER = re.compile(r"\bhex\b|十六进制", re.I)


def _origin_one(source: Source) -> str:
    """Where a table's header says its register numbers count from 1 (empty: nowhere). A hex column of the
    same table that prints the same numbers, not one less, contradicts it: then it says nothing."""
    for table in source.tables:
        for h, header in enumerate(table.rows[:3]):
            column = next((j for j, cell in enumerate(header.cells) if _ORIGIN_ONE.search(cell)), None)
            if column is None:
                continue
            hexes = [j for j, cell in enumerate(header.cells) if _HEX_HEADER.search(cell)]
            pairs = [(_int(row.cells[column], 10), _int(row.cells[j], 16)) for row in table.rows[h + 1:]
                     for j in hexes if max(column, j) < len(row.cells)]
            known = [(dec, hx) for dec, hx in pairs if dec is not None and hx is not None]
            if any(hx != dec - 1 for dec, hx in known):
                continue
            said = f"header {header.cells[column].strip()!r}"
            if known:
                said += f", its hex column one less on {len(known)} rows"
            return f"{source.name} {table.label}: {said}"
    return ""


def _int(text: str, base: int) -> int | None:
    try:
        return int(text.strip(), base)
    except ValueError:
        return None


def _heading(table: Table) -> str:
    """The section heading above a table (the last numbered one), else the last short line before it."""
    lines = table.context.splitlines()
    pattern = r"^\s*(?:#+\s*|\*\*)?\d+(?:\.\d+)*\.?\s+[A-Za-z\u4e00-\u9fff]"
    numbered = [ln for ln in (table.above or table.context).splitlines() if re.match(pattern, ln)]
    for line in reversed(numbered or lines):
        text = re.sub(r"\*\*|</?b>|^\s*#+", "", line).strip(" *#")
        if numbered:
            text = re.sub(r"\s*\([^()]{20,}\)\s*$", "", text)[:60].strip()
        if 3 <= len(text) <= 60 and "\t" not in line and not re.match(r"^\W*$", text):
            return text
    return table.label


def _not_modicon(source: Source) -> str | None:
    """Where the document prints a five-digit address no Modicon number can be (30000, 40000, 50000 and
    above): its 3xxxx and 4xxxx numbers are then plain addresses too, not Modicon references."""
    for table in source.tables:
        for value in plain_addresses(table):
            if value in (30000, 40000) or 50000 <= value <= 99999:
                where = f" ({table.rows[0].where()})" if table.rows else ""
                return f"the document prints address {value}{where}, which no Modicon number is"
    return None


#: Fields whose value two rows of one register may state differently (the others are merged by the writer).
_CONTRADICTABLE = ("type", "scale")


def _contradictions(registers: list[Drafted]) -> None:
    """Two readings of one printed row (one page, table and address: a page's grid read as two tables
    whose columns split differently) that state different types or scales: neither is taken. The field is
    left open on each (``review:``) with a note naming both readings and what each says. Rows of
    different pages at one address are different registers (pages, sections), not readings of one row."""
    by_place: dict[tuple[object, object, str], list[Drafted]] = {}
    for d in registers:
        page = re.match(r"p\.(\d+)\b", d.where)
        if page is not None:
            by_place.setdefault((d.entry.get("table"), d.entry.get("address"), page.group(1)), []).append(d)
    for same in by_place.values():
        if len(same) < 2:
            continue
        for key in _CONTRADICTABLE:
            said = {(d.where, str(d.entry[key])) for d in same if key in d.entry and key not in _review_of(d)}
            if len({value for _, value in said}) < 2:
                continue
            text = "; ".join(f"{where}: {value}" for where, value in sorted(said))
            for d in same:
                d.entry.pop(key, None)
                review = _review_of(d)
                if key not in review:
                    review.append(key)
                _set_review(d, review)
                d.notes.append(f"{key} left open: the document states it differently ({text})")


#: the fields one printing of a register may state where another printing of it leaves them open
_JOINED = ("table", "type", "length", "scale", "unit", "access", "min", "max", "default")


def _printed_twice(registers: list[Drafted]) -> list[Skipped]:
    """One register printed in two tables of the document (the same address and label, in tables that do
    not state two different register tables: a workbook's register list and its flattened copy): one
    register, drafted from the first printing with what only the second states (each such field noted
    with where it is printed); a field the two state differently is left open, naming both. The second
    printing is listed as joined. Rows of one table at one address are not joined (pages, sections)."""
    first: dict[tuple[object, str], Drafted] = {}
    kept: list[Drafted] = []
    joined: list[Skipped] = []
    for d in registers:
        label = re.sub(r"\W+", "", str(d.entry.get("label") or "")).lower()
        key = (d.entry.get("address"), label)
        base = first.get(key)
        if (base is None or not label or base.table_label == d.table_label or "count" in d.entry
                or "count" in base.entry or _stated(base, "table") and _stated(d, "table")
                and base.entry["table"] != d.entry["table"]):
            first.setdefault(key, d)
            kept.append(d)
            continue
        _join(base, d)
        joined.append(Skipped(d.where, str(d.entry.get("label")), f"the same register as {base.where} (address "
                              f"{d.entry['address']}, {d.entry.get('label')!r}): what it states is joined there"))
    registers[:] = kept
    return joined


def _stated(d: Drafted, key: str) -> bool:
    return key in d.entry and key not in d.missing and key not in _review_of(d)


def _join(base: Drafted, other: Drafted) -> None:
    """``base`` takes each field only ``other`` states; a field the two state differently is left open."""
    review = _review_of(base)
    for key in _JOINED:
        if not _stated(other, key) or (_stated(base, key) and base.entry[key] == other.entry[key]):
            continue
        if _stated(base, key):
            said = base.entry.pop(key)
            base.notes.append(f"{key} left open: the document states it differently ({base.where}: {said}; "
                              f"{other.where}: {other.entry[key]})")
            if key in REVIEWED and key not in review:
                review.append(key)
            base.missing.append(key)
            continue
        base.entry[key] = other.entry[key]
        base.missing = [m for m in base.missing if m != key]
        review = [f for f in review if f != key]
        base.notes = [n for n in base.notes if f"{key} not stated" not in n]
        base.notes.append(f"{key} {other.entry[key]}: printed at {other.where} (the same register)")
        if key == "type" and "word_order" in _review_of(other) and "word_order" not in review:
            review.append("word_order")
        elif key == "type" and _stated(other, "word_order"):
            base.entry["word_order"] = other.entry["word_order"]
    _set_review(base, review)


def _set_review(d: Drafted, review: list[str]) -> None:
    """The register's ``review:`` list, in the map's order (none: no list)."""
    if review:
        d.entry["review"] = [f for f in REVIEWED if f in review] + [f for f in review if f not in REVIEWED]
    else:
        d.entry.pop("review", None)


def _review_of(d: Drafted) -> list[str]:
    listed = d.entry.get("review")
    return [str(f) for f in listed] if isinstance(listed, list) else []


def _tables(source: Source, skipped: list[Skipped]) -> Iterator[Table]:
    """The document's tables to read. A table without a header of its own that follows one printing
    offsets, not addresses (the same table on the next page), is not read: its rows go to ``skipped``."""
    offsets: str | None = None  # the header of the table before, when it prints offsets
    head: Table | None = None  # that table
    starts = offset_bases(source.tables)
    for table in source.tables:
        listed = offset_rows(table, offsets) if offsets is not None else []
        if listed:
            laid = under_header(head, table) if head is not None else None
            if laid is None:
                skipped += listed
            else:
                yield laid
            continue
        offsets = offsets_header(table)
        head = table if offsets is not None else None
        if head is not None:
            table.starts = starts
        yield table


def _raws(source: Source, table: Table, not_modicon: str | None = None,
          ranges: Sequence[tuple[int, int, str, str]] = ()) -> tuple[list[Raw], list[Skipped]]:
    """The rows of one table; ``not_modicon``: why 3xxxx/4xxxx numbers are plain addresses here
    (:func:`_not_modicon`); ``ranges``: the document's address-range statements (:func:`_range_kinds`)."""
    doc_kind = _document_kind(source.text)
    kind = table_kind(table.context.splitlines()[-1] if table.context else "") or table_kind(table.context) \
        or _nearest_kind(table.context) or doc_kind
    access = table_access(table.context)
    if table.matrix:
        raws, skipped = matrix_raws(table, kind)
    else:
        raws, skipped = loose_raws(table, kind, access) if table.loose else grid_raws(table, kind, access,
                                                                                     not_modicon is None)
    if not_modicon is not None:
        for raw in raws:
            if 30001 <= raw.address <= 49999:
                raw.notes.append(f"address {raw.address} as printed, not a Modicon number: {not_modicon}")
    _kinds_by_range(raws, ranges)
    return raws, skipped


#: function code -> the table it reads or writes (03h/06h/10h: holding registers; 04h: input registers)
_CODE_TABLES = {"03": "holding", "06": "holding", "10": "holding", "04": "input"}
_CODE = r"(?:0x(0[346]|10)|\b(0[346]|10)\s*[hH])(?![0-9A-Za-z])"
_ADDRESS_WORD = re.compile(r"regist|address|寄存器|地址|位址", re.I)
_RANGE = re.compile(r"(?<![\d.])(\d{1,5})\s*(?:-|~|～|–|to|至|到)\s*(\d{1,5})(?![\d.])")


def _range_kinds(text: str) -> list[tuple[int, int, str, str]]:
    """(first, last, table, the sentence) of every line that gives an address range one function code
    ("0-59 ... read registers, 0x03 function code"): a statement of the document, read only where the
    line names one range and one table."""
    found: list[tuple[int, int, str, str]] = []
    for line in text.splitlines():
        ranges = _RANGE.findall(line)
        codes = {_CODE_TABLES[a or b] for a, b in re.findall(_CODE, line)}
        if len(ranges) != 1 or len(codes) != 1 or len(line) > 160 or not _ADDRESS_WORD.search(line):
            continue
        lo, hi = int(ranges[0][0]), int(ranges[0][1])
        if lo <= hi:
            found.append((lo, hi, codes.pop(), line.strip()))
    return found


def _kinds_by_range(raws: list[Raw], ranges: Sequence[tuple[int, int, str, str]]) -> None:
    """A row whose table nothing near it states takes the table of the document's range statement that
    holds its address (only where the statements holding it agree)."""
    for raw in raws:
        if raw.table is not None:
            continue
        holding = {(kind, line) for lo, hi, kind, line in ranges if lo <= raw.address <= hi}
        if len({kind for kind, _ in holding}) == 1:
            kind, line = sorted(holding)[0]
            raw.table = kind
            raw.notes.append(f"table {kind}: the document states {line!r}")


def _nearest_kind(context: str) -> str | None:
    """The table the nearest line above a table names, when the lines before it name several
    (``### Coils`` under a paragraph listing every table, then ``Access level ...``)."""
    for line in reversed(context.splitlines()):
        kind = table_kind(line)
        if kind is not None:
            return kind
    return None


def _document_kind(text: str) -> str | None:
    """The table every register is in when the document names one read function only (03h: holding)."""
    reads = set()
    for line in text.splitlines():
        if not re.search(r"read|读|讀", line, re.I):
            continue
        for code in ("03", "04"):
            if re.search(rf"(?:^|[\s(])(?:0x{code}|{code}\s*[hH])(?![0-9A-Za-z])|\bFC\s*{code}\b", line):
                reads.add(code)
    return {frozenset({"03"}): "holding", frozenset({"04"}): "input"}.get(frozenset(reads))


def _assumed(raws: list[Raw], hints: Hints) -> None:
    """``--assume table=`` / ``type=`` / ``offset=`` on the rows whose document leaves that field open."""
    table, rtype = hints.value("table"), hints.value("type")
    for raw in raws:
        _assumed_offset(raw, hints.value("offset"))
        if table is not None and raw.table is None:
            raw.table = table
            raw.notes.append(f"table {table}: source: assumed by the user (--assume table={table})")
        if rtype is not None and raw.table not in ("coil", "discrete") and not raw.cells.get("type", "").strip():
            raw.cells["type"] = rtype
            raw.notes.append(f"type {rtype}: source: assumed by the user (--assume type={rtype})")


def _assumed_offset(raw: Raw, unit: str | None) -> None:
    """``--assume offset=registers|bytes``: a row drafted at its block's start plus an offset whose unit the
    document does not give gets the address that unit gives (an odd offset counted in bytes starts inside a
    register: its address stays open)."""
    if unit is None or raw.offset_from is None or "address" not in raw.open:
        return
    base, offset, open_note = raw.offset_from
    said = f"source: assumed by the user (--assume offset={unit})"
    if unit == "bytes" and offset % 2:
        raw.notes.append(f"address left to review: offset 0x{offset:04X} counted in bytes ({said}) starts inside a "
                         "register")
        return
    raw.address = base + (offset // 2 if unit == "bytes" else offset)
    raw.open.remove("address")
    raw.notes.remove(open_note)
    raw.notes.append(f"address 0x{raw.address:04X}: the start address 0x{base:04X} printed beside its block plus "
                     f"offset 0x{offset:04X}, counted in {unit}: {said}")


def _context(source: Source, hints: Hints) -> Context:
    """The document's statements, and the person's hints where the document states nothing."""
    ctx = document_context(source)
    order = hints.value("word_order")
    if order is not None and ctx.word_order is None:
        ctx.word_order = order
        ctx.word_order_source = f"source: assumed by the user (--assume word_order={order})"
    if hints.address_base == 1 and not ctx.base_one:
        ctx.base_one = "source: assumed by the user (--address-base 1)"
    return ctx


def draft(source: Source, model: str, hints: Hints | None = None) -> Draft:
    hints = hints or Hints()
    ctx = _context(source, hints)
    registers: list[Drafted] = []
    skipped: list[Skipped] = []
    groups: list[dict[str, Any]] = []
    found: list[tuple[str, int]] = []
    names: set[str] = set()
    not_modicon, ranges = _not_modicon(source), _range_kinds(source.text)  # document-wide: read once
    read: list[tuple[Table, list[Raw]]] = []
    for table in _tables(source, skipped):
        raws, skip = _raws(source, table, not_modicon, ranges)
        _assumed(raws, hints)
        skipped += skip
        if raws:
            read.append((table, raws))
    ctx.factor_divides = factor_proofs([r for _, raws in read for r in raws])
    for table, raws in read:
        heading = _heading(table)
        if heading == table.label and groups:  # no heading of its own: the section of the table before it
            group, heading = groups[-1]["name"], groups[-1]["title"]
        else:
            plain = re.sub(r"^[\d.\s]+", "", heading)
            group = unique(snake(plain, f"table_{len(groups) + 1}")[:40].rstrip("_"), {g["name"] for g in groups})
        direction = factor_direction(raws)
        drafts = [draft_fields(r, ctx, direction) for r in raws]
        if ctx.base_one:
            for d in drafts:
                _numbered_from_one(d, ctx.base_one)
        for d in drafts:
            d.entry["group"] = group
            d.table_label = table.label
        if all(_series_param(d) for d in drafts):
            drafts.sort(key=lambda d: int(str(d.entry["address"])))  # side-by-side columns of one numbered list
        drafts = arrays(drafts)
        found.append((f"{table.label}: {heading}", len(drafts)))
        if group not in {g["name"] for g in groups}:
            title = _group_title(heading, table.label, groups)
            groups.append({"name": group, "title": title, "source": f"{source.name} {table.label}"})
        for d in drafts:
            _finish(d, source.name, names)
        registers += drafts
    _contradictions(registers)
    skipped += _printed_twice(registers)
    groups[:] = [g for g in groups if any(d.entry.get("group") == g["name"] for d in registers)]
    skipped += [Skipped(r.where(), " | ".join(r.cells), "an address or offset printed in the table in none of its "
                        "cells (the text of a cell drawn over rows, across a page break?): not read")
                for t in source.tables for r in t.orphans]
    bases = offset_bases(source.tables)
    skipped[:] = [with_start(s, bases) for s in skipped]
    data = _document(source, model, groups, registers)
    if hints.said():
        data["device"]["notes"] += ("; assumed by the user, not read from the document: " + ", ".join(hints.said())
                                    + " (each register it decided says so in its notes)")
    if hints.address_base == 0:
        for d in registers:
            if any("as printed under" in n for n in d.notes):
                d.notes = [n for n in d.notes if "as printed under" not in n]
                d.notes.append("address as printed: source: assumed by the user (--address-base 0)")
    review = _map_review(source, registers, hints)
    return Draft(data, registers, skipped, found, review)


def _map_review(source: Source, registers: list[Drafted], hints: Hints) -> list[str]:
    """What the whole map leaves to review: the protocol's placeholders, the numbering of plain register
    numbers the document leaves open, and each of the person's hints."""
    review = list(PLACEHOLDERS)
    if not stated_modes(source.text):
        review.insert(0, "protocol.modes (rtu: the document names no framing)")
    if any("as printed under" in n for d in registers for n in d.notes):
        review.append("addresses printed as plain register numbers: 0- or 1-based? (see the registers' notes)")
    return review + [f"assumed by the user: {said} (the registers it decided say so in their notes)"
                     for said in hints.said()]


def _numbered_from_one(d: Drafted, said: str) -> None:
    """A register number printed as is, in a document that says it numbers registers from 1: the protocol
    address is one less (the note the row reader wrote becomes the statement that decides it)."""
    printed = [n for n in d.notes if "as printed under" in n]
    if not printed:
        return
    address = int(str(d.entry["address"]))
    d.entry["address"] = address - 1
    d.notes = [n for n in d.notes if n not in printed]
    d.notes.append(f"address {address} printed; the protocol address is {address - 1}: {said}")


def _group_title(heading: str, label: str, groups: list[dict[str, Any]]) -> str:
    """The group's title: the table's heading, with the table's place where the docs page has a fixed
    section of that name (a sheet called "Registers"), and "(continued)" where a group has it already."""
    from drivemap.vocab.escape import slug
    from drivemap.vocab.reserved import reserved  # the docs exporter's data; loaded when drafting

    title = heading if slug(heading) not in reserved().headings else f"{heading} ({label})"
    while title in {g["title"] for g in groups}:
        title += " (continued)"
    return title


def _series_param(d: Drafted) -> bool:
    return bool(re.fullmatch(r".*?\D\d{1,3}", str(d.entry.get("param", "")))) and "label" not in d.entry


def _finish(d: Drafted, document: str, names: set[str]) -> None:
    """Name, source, enum and bits in schema form."""
    e = d.entry
    address = int(str(e["address"]))
    base = str(e.pop("series_base", "") or e.get("label") or e.get("param") or "")
    base = re.sub(r"\((high|low|middle|hi|lo|msb|lsb)\)", r" \1", base, flags=re.I)  # a pair's halves keep theirs
    base = re.sub(r"\([^()]*\)|（[^（）]*）|\*\d?", " ", base).strip() or base
    e["name"] = unique(snake(base, f"reg_{address:04x}"), names)
    e["source"] = f"{document} {d.where}"
    if e.get("bits"):
        taken: set[str] = set()
        e["bits"] = [{"name": unique(upper(label.split(":")[0], f"BIT_{offset}"), taken), "offset": offset,
                      "label": label}
                     for offset, label in e["bits"]]  # type: ignore[attr-defined]
    if d.notes:
        e["notes"] = "; ".join(d.notes)


def _enums(registers: list[Drafted], document: str) -> dict[str, Any]:
    enums: dict[str, Any] = {}
    for d in registers:
        items = d.entry.pop("enum", None)
        if not items:
            continue
        name = unique(camel(str(d.entry["name"])), set(enums))
        taken: set[str] = set()
        values = [{"value": v, "name": unique(upper(label, f"VALUE_{v}"), taken), "label": label}
                  for v, label in items]  # type: ignore[attr-defined]
        enums[name] = {"values": values, "source": f"{document} {d.where}"}
        d.entry["enum"] = name
    return enums


def _language(text: str) -> str:
    cjk = len(re.findall(r"[\u4e00-\u9fff]", text[:200000]))
    latin = len(re.findall(r"[A-Za-z]", text[:200000]))
    return "zh" if cjk > latin / 4 else "en" if latin else "und"


#: where a document names a framing: "RTU" alone is Modbus's framing wherever it is printed; "ASCII" names
#: one only beside "Modbus" or "mode" (elsewhere it is how a string register is coded: "ASCII code")
_MODES = (("rtu", re.compile(r"\bRTU\b")),
          ("ascii", re.compile(r"modbus[\s/_-]*ascii\b|\bascii[\s_-]*(?:mode|modus|framing)\b"
                               r"|\b(?:mode|modus)\s*[:=]?\s*ascii\b", re.I)))


def stated_modes(text: str) -> list[str]:
    """The framings the document names (none: the draft writes rtu as a placeholder and lists it to review)."""
    return [mode for mode, pattern in _MODES if pattern.search(text)]


def _protocol(source: Source, registers: list[Drafted]) -> dict[str, Any]:
    where = f"{source.name} (draft placeholder: not read from the document)"
    text = source.text
    modes = stated_modes(text) or ["rtu"]
    tables = {str(d.entry.get("table", "holding")) for d in registers}
    written = {str(d.entry.get("table", "holding")) for d in registers if d.entry.get("access") in ("w", "rw")}
    codes = sorted({{"holding": 3, "input": 4, "coil": 1, "discrete": 2}[t] for t in tables}
                   | ({6, 16} if "holding" in written else set()) | ({5, 15} if "coil" in written else set()))
    names = {1: "read coils", 2: "read discrete inputs", 3: "read holding registers", 4: "read input registers",
             5: "write single coil", 6: "write single register", 15: "write multiple coils",
             16: "write multiple registers"}
    return {
        "modes": modes + (["tcp"] if re.search(r"modbus[\s/-]*tcp", text, re.I) else []),
        "unit_ids": {"min": 1, "max": 247, "source": where},
        "broadcast_address": None,
        "ports": [{"name": "serial", "modes": modes, "baudrates": [], "default_baudrate": None, "parity": [],
                   "default_parity": None, "data_bits": [], "stop_bits": [], "set_by": "unknown", "source": where}],
        "function_codes": [{"code": c, "name": names[c], "max_quantity": None, "broadcast": None,
                            "broadcast_reason": "not read from the document: review", "source": where}
                           for c in codes or [3]],
        "exceptions": [],
        "timing": {"silent_interval_chars": None, "response_timeout_ms": None, "retries": None, "source": where},
        "source": where,
    }


def _document(source: Source, model: str, groups: list[dict[str, Any]], registers: list[Drafted]) -> dict[str, Any]:
    enums = _enums(registers, source.name)
    return {
        "drivemap": CURRENT,
        "device": {
            "model": model,
            "title": f"{model} (drafted from {source.name})",
            "vendor": None,
            "manual": {"file": source.name, "document": None, "revision": None, "date": None,
                       "language": _language(source.text)},
            "coverage": f"Drafted by `drivemap draft` from {source.name} (sha256 {source.sha256}): the register "
                        "tables only; protocol facts are placeholders to review.",
            "source": source.name,
            "notes": f"document sha256 {source.sha256}",
        },
        "protocol": _protocol(source, registers),
        "enums": enums,
        "groups": groups,
        "registers": [d.entry for d in registers],
        "examples": [],
    }
