"""Tables -> the raw facts of each register row (:class:`~.fields.Raw`), and the rows skipped.

A grid row with an address starts a register; the rows after it without an address are its bit
list (a ``Bit`` column or a ``Bit | Description`` sub-header), its code list (``Code |
Description``) or more text. Rows whose name says reserved/unused are skipped as reserved.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence

from drivemap.onboard.draft.cells import (
    Address,
    address_conflict,
    bit_index,
    is_address_range,
    parse_address,
    parse_address_pair,
    parse_enum,
    parse_type,
    trailing_access,
)
from drivemap.onboard.draft.columns import Layout, content_layout, find_layouts, relative_header, role_of
from drivemap.onboard.draft.fields import Raw
from drivemap.onboard.draft.tables import Row, Skipped, Table
from drivemap.onboard.draft.units import parse_scale

RESERVED = re.compile(r"(?<![A-Za-z])(?:reserved|not used|unused|spare|n/a)(?![A-Za-z])|保留|预备中?|預備中?|未使用|備用|备用",
                      re.I)
"""Whole words only: "transparent" holds no "spare"."""
_CELL_ROLES = ("type", "unit", "scale", "range", "min", "max", "default", "access", "length", "description", "function_code",
               "table")


def table_kind(text: str) -> str | None:
    """The Modbus table a heading or function-code cell names; None when it names none or several."""
    found = set()
    if re.search(r"\b(?:0x)?0?4\s*[hH]\b|\b0x04\b|input\s*reg|輸入寄存器|输入寄存器|FC\s*0?4\b", text, re.I):
        found.add("input")
    if re.search(r"\b(?:0x)?0?3\s*[hH]\b|\b0x03\b|holding\s*reg|保持寄存器|保持暂存器|保持暫存器|FC\s*0?3\b", text, re.I):
        found.add("holding")
    if re.search(r"\bcoils?\b|\b0?1\s*[hH]\b.*coil|線圈|线圈", text, re.I):
        found.add("coil")
    if re.search(r"discrete\s+input|\b0?2\s*[hH]\b.*discrete|離散|离散", text, re.I):
        found.add("discrete")
    return found.pop() if len(found) == 1 else None


def _row_table(text: str) -> str | None:
    """A register-type cell of the row itself (``Holding``, ``Input``, ``Coil``)."""
    low = text.strip().lower()
    for word, kind in (("holding", "holding"), ("input reg", "input"), ("input", "input"), ("coil", "coil"),
                       ("discrete", "discrete")):
        if low.startswith(word):
            return kind
    return table_kind(text)


def table_access(text: str) -> str | None:
    if re.search(r"read(able)?\s*(and|&|/)\s*writ|可以读出及写入|可讀寫|可读写|读出及写入|R/W\)", text, re.I):
        return "rw"
    if re.search(r"only\s+for\s+reading|read[\s-]*only|仅供读出|僅供讀出|只读|唯讀|只讀", text, re.I):
        return "r"
    return None


#: a span of addresses in one cell: ``5031 - 5032``, ``0x0500 - 0x0501``, ``5004～5005``
_SPAN = re.compile(r"\s*((?:0[xX])?[0-9A-Fa-f]{1,6}[hH]?)\s*[-~–～]\s*((?:0[xX])?[0-9A-Fa-f]{1,6}[hH]?)\s*")
#: the most registers a span of text is read as one string register over (a read is at most 125)
_STRING_WORDS = 125


class _Column:
    """Address column reading: hex-marked columns read unmarked cells as hex only when few are unmarked."""

    def __init__(self, cells: list[str], radix: str | None, header: str = "", modicon: bool = True) -> None:
        parsed = [a for a in (parse_address(c) for c in cells if c.strip()) if a is not None]
        marked = sum(1 for a in parsed if a.marked)
        self.radix = radix or ("hex" if parsed and marked >= 0.8 * len(parsed) else "dec" if marked == 0 else None)
        self.mostly_marked = bool(parsed) and marked >= 0.8 * len(parsed)
        self.any_marked = marked > 0 and radix is None
        plain = [a.dec_value for a in parsed if not a.marked and a.dec_value is not None]
        self.numbered = False
        """Plain decimal numbers under a header that does not say address: a register number from 0 or 1?"""
        self.plain = plain
        self.modicon = modicon and self.radix != "hex" and len(plain) >= 2 and (
            all(30001 <= v <= 39999 for v in plain) or all(40001 <= v <= 49999 for v in plain))
        self.numbered = bool(plain) and not self.modicon and self.radix != "hex" \
            and not re.search(r"addr|offset|位址|地址|pdu", header, re.I)

    def read(self, address: Address) -> tuple[int | None, str | None]:
        """(protocol address, table from a Modicon number) of one cell."""
        if address.marked:
            return address.hex_value, None
        if self.any_marked:
            return None, None  # codes and bit numbers inside a column of hex addresses
        if self.mostly_marked and self.radix == "hex" and address.dec_value is not None and address.dec_value > 99:
            return address.hex_value, None
        if self.mostly_marked:
            return None, None
        if self.modicon and address.dec_value is not None:
            value = address.dec_value
            return value - (30001 if value < 40001 else 40001), "input" if value < 40001 else "holding"
        if self.radix == "hex":
            return address.hex_value, None
        return address.dec_value, None


def _parts(cell: str) -> list[str]:
    """The addresses of an address cell: both of a two-register row (``1001, 1002``) or the ends of a
    span (``13250-13264``)."""
    pair = parse_address_pair(cell)
    if pair is not None:
        return [pair[0].text, pair[1].text]
    span = _SPAN.fullmatch(cell)
    return [span.group(1), span.group(2)] if span is not None else [cell]


def _cell(row: Row, layout: Layout, role: str) -> str:
    i = layout.roles.get(role)
    return row.cells[i].strip() if i is not None and i < len(row.cells) else ""


def _merged_over(row: Row, layout: Layout, cells: dict[str, str]) -> list[str]:
    """Fill, in place, each empty role cell that a cell drawn above runs down over (a merged cell,
    as a spreadsheet's merged range reads its value in every cell); the headers of those filled."""
    filled = []
    for role in _CELL_ROLES:
        col = layout.roles.get(role)
        if col is not None and not cells[role] and col in row.spanned:
            cells[role] = row.spanned[col].strip()
            filled.append(layout.headers.get(role, role))
    return filled


def _hi_lo(row: Row, layout: Layout) -> Address | None:
    hi, lo = parse_address(_cell(row, layout, "hi_byte")), parse_address(_cell(row, layout, "lo_byte"))
    if hi is None or lo is None or hi.hex_value is None or lo.hex_value is None:
        return None
    if hi.hex_value > 0xFF or lo.hex_value > 0xFF:
        return None
    return Address(f"{hi.text} {lo.text}", hi.hex_value << 8 | lo.hex_value, None, True)


class GridReader:
    """One layout of one grid table, row by row."""

    def __init__(self, table: Table, layout: Layout, kind: str | None, access: str | None,
                 modicon: bool = True) -> None:
        self.table, self.layout, self.kind, self.access = table, layout, kind, access
        start = (layout.header_row or 0) + (0 if layout.header_row is None else layout.header_rows)
        self.rows = table.rows[start:]
        cells = [part for r in self.rows for part in _parts(_cell(r, layout, "address"))]
        self.column = _Column(cells, layout.radix, layout.headers.get("address", ""), modicon)
        self.words: int | None = None
        self.raws: list[Raw] = []
        self.skipped: list[Skipped] = []
        self.conflicts: dict[int, str] = {}
        """id of a read register -> why a row under it makes its address ambiguous"""
        self.mode = "text"
        #: the header of the column whose numbers are offsets from a base the rows do not give, if any
        self.relative = _relative_header(table, layout, self.rows)

    def where(self, row: Row) -> str:
        return row.where()

    def address_of(self, row: Row) -> tuple[int | None, str | None, str]:
        self.found_at, self.words = self.layout.roles.get("address"), None
        if "address" not in self.layout.roles:
            a = _hi_lo(row, self.layout)
            return (a.hex_value, None, a.text) if a else (None, None, "")
        text = _cell(row, self.layout, "address")
        a = parse_address(text)
        col = self.layout.roles["address"]
        if a is None and not text and col + 1 < len(row.cells) and not any(c.strip() for c in row.cells[:col]):
            cell = row.cells[col + 1]  # an address shifted one cell right ("\t00F0H\tFault Description")
            b = parse_address(cell)
            if b is not None and b.marked and re.fullmatch(r"(?:0x)?[0-9A-Fa-f]{4}\s?[hH]?", cell.strip()):
                self.found_at = col + 1
                return b.hex_value, None, cell
        if a is None:
            return self._pair(text, _cell(row, self.layout, "type"))
        value, table = self.column.read(a)
        return value, table, text

    def _pair(self, text: str, rtype: str = "") -> tuple[int | None, str | None, str]:
        """``1001, 1002``: one register two words long at the first address; a span (``5031 - 5032``) is one
        register over its 2 or 4 words, or over all of them when the row's type is text (``4954 - 4968 |
        UTF-8``: a string of 15 registers); other pairs are not read."""
        pair = parse_address_pair(text)
        span = _SPAN.fullmatch(text)
        if pair is None and span is not None:  # "5031 - 5032", "0x0500 - 0x0501": one value over the span's registers
            first_a, last_a = parse_address(span.group(1)), parse_address(span.group(2))
            if first_a is not None and last_a is not None:
                (first, table), (last, other) = self.column.read(first_a), self.column.read(last_a)
                text_type = parse_type(rtype) == "string"
                if first is not None and last is not None and table == other \
                        and (last - first + 1 in (2, 4) or text_type and 1 < last - first + 1 <= _STRING_WORDS):
                    self.words = last - first + 1
                    return first, table, text
        if pair is None:
            return None, None, text
        (first, table), (second, other) = self.column.read(pair[0]), self.column.read(pair[1])
        if first is None or second != first + 1 or table != other:
            return None, None, text
        self.words = 2
        return first, table, text

    def run(self) -> None:
        for row in self.rows:
            if all(not c.strip() for c in row.cells):
                continue
            if [role_of(c) for c in row.cells] == [role_of(c) for c in self.table.rows[self.layout.header_row or 0].cells] \
                    and self.layout.header_row is not None:
                continue  # the header repeated on the next page
            self.row(row)

    def row(self, row: Row) -> None:
        if self.mode == "bits" and self.raws and re.fullmatch(r"[0-9A-Fa-f]{1,2}\s*[-~]\s*[0-9A-Fa-f]{1,2}",
                                                               _cell(row, self.layout, "address")):
            return  # a range of unused bits ("5-F")
        value, table, text = self.address_of(row)
        if value is None:
            if self.raws and self.continuation(row, text):
                return
            if text and is_address_range(text):
                self.skipped.append(Skipped(self.where(row), " | ".join(row.cells), "address range (reserved block)"))
            elif text:
                self.skipped.append(Skipped(self.where(row), " | ".join(row.cells),
                                            address_conflict(text) or f"address {text!r} not readable"))
            elif not self.raws and len([c for c in row.cells if c.strip()]) >= 2:
                self.skipped.append(Skipped(self.where(row), " | ".join(c for c in row.cells if c.strip()),
                                            "no address in the address column"))
            return
        start = self.table.starts.get(row.where()) if self.relative is not None else None
        if start is not None:
            self._offset_row(row, int(start[0], 16), start[1], start[0], table)
            return
        if self.relative is not None:
            self.skipped.append(Skipped(
                self.where(row), " | ".join(c.strip() for c in row.cells if c.strip()),
                f"not drafted: under {self.relative!r}, {text!r} is an offset from a base address the row does "
                "not give (nor whether it counts words or bytes): the address is to be stated by a person"))
            return
        other = self.other_address(row, value)
        if other is not None:
            self.skipped.append(Skipped(
                self.where(row), " | ".join(c.strip() for c in row.cells if c.strip()),
                f"not drafted: {self.layout.headers.get('address', '')!r} {text!r} is address 0x{value:04x}, "
                f"{self.layout.other_header!r} says {other!r}: the document states two addresses"))
            return
        self.mode = "text"
        said = self.modicon_beside(row, value) if table is None else None
        count = len(self.raws)
        self.start(row, value, said[0] if said else table)
        if said and len(self.raws) > count:
            self.raws[-1].notes.append(said[1])

    def _offset_row(self, row: Row, base: int, offset: int, start: str, table: str | None) -> None:
        """A row of offsets whose block's start address the document prints: drafted at start + offset, the
        document's own sum, with the address open (``review: [address]``), since it does not say whether
        the offset counts registers, as the address does, or bytes."""
        count = len(self.raws)
        self.found_at = self.layout.roles.get("address")  # the name is the name column's, not the cell after
        self.start(row, base + offset, table)
        if len(self.raws) == count:
            return
        raw = self.raws[-1]
        other = f", or bytes (0x{base + offset // 2:04X})" if offset % 2 == 0 and offset else ""
        note = (f"address 0x{base + offset:04X}: the start address {start} printed beside its block plus offset "
                f"0x{offset:04X} under {self.relative!r}, as printed; the document does not say whether the offset "
                f"counts registers, as the address does (0x{base + offset:04X}){other}: address to review")
        raw.notes.append(note)
        raw.open.append("address")
        raw.offset_from = (base, offset, note)

    def modicon_beside(self, row: Row, value: int) -> tuple[str, str] | None:
        """(table, note) when a second address column prints this register's Modicon number (``300001`` or
        ``30001`` beside physical address ``0000h``): its first digit states the table (3: input, 4: holding)."""
        col = self.layout.roles.get("address_dec")
        cell = row.cells[col].strip() if col is not None and col < len(row.cells) else ""
        ref = modicon_reference(cell)
        if ref is None or ref[0] != value:
            return None
        return ref[1], (f"table {ref[1]}: {self.layout.headers.get('address_dec', '')!r} prints {cell}, the Modicon "
                        f"number of address {value} in the {ref[1]} registers")

    def other_address(self, row: Row, value: int) -> str | None:
        """The cell of a second address column that states another address than the Modicon number
        (``30009 | 0x00``), else None."""
        other = self.layout.other_address
        if other is None or other == self.layout.roles.get("address") or not self.column.modicon:
            return None
        cell = row.cells[other].strip() if other < len(row.cells) else ""
        a = parse_address(cell)
        if a is None or not a.marked or a.hex_value == value:
            return None
        return cell

    def start(self, row: Row, value: int, table: str | None) -> None:
        name = _cell(row, self.layout, "name")
        if self.found_at is not None and self.found_at != self.layout.roles.get("address"):
            name = next((c.strip() for c in row.cells[self.found_at + 1:] if c.strip()), "")
        cells = {r: _cell(row, self.layout, r) for r in _CELL_ROLES}
        merged = _merged_over(row, self.layout, cells)
        cells["length_header"] = self.layout.headers.get("length", "")
        cells["scale_header"] = self.layout.headers.get("scale", "")
        cells["unit_header"] = self.layout.headers.get("unit", "")
        cells["range_header"] = self.layout.headers.get("range", "")
        unit_col = self.layout.roles.get("unit")
        cells["unit_named"] = "yes" if unit_col is not None and unit_col == self.layout.roles.get("name") else ""
        if self.words is not None and not cells["length"]:
            cells["length"], cells["length_header"] = str(self.words), "registers"  # from the address cell
        everything = " ".join(c for c in row.cells if c.strip())
        if RESERVED.fullmatch(re.sub(r"\s*\d+$", "", name.strip(" ()（）*"))) \
                or (not name and RESERVED.search(cells["description"])):  # "Reserved", "Reserved 3"
            self.skipped.append(Skipped(self.where(row), everything, "reserved"))
            return
        if len([c for c in row.cells if c.strip()]) <= 1:
            self.skipped.append(Skipped(self.where(row), everything, "address without a name or description"))
            return
        kind = table or _row_table(cells["table"]) or table_kind(cells["function_code"]) or table_kind(self.layout.headers.get("address", "")) \
            or self.kind
        raw = Raw(value, kind, self.where(row), cells=cells, access=self.access)
        if merged:
            raw.notes.append(f"{', '.join(repr(h) for h in merged)}: a cell drawn over this row and the ones above "
                             "it, read as this row's")
        if row.relaid:
            raw.notes.append(row.relaid)
        if self.column.numbered:
            raw.notes.append(f"address {value} as printed under {self.layout.headers.get('address', '')!r}: if the "
                             "document numbers registers from 1, the protocol address is one less")
        raw.param = _cell(row, self.layout, "param")
        if raw.param and self.layout.headers.get("param", "").strip().endswith("_"):
            raw.param = self.layout.headers["param"].strip() + raw.param
        bit = bit_index(_cell(row, self.layout, "bit")) if "bit" in self.layout.roles else None
        if bit is not None:
            raw.bits.append((bit, _bit_label(name, row, self.layout)))
            self.mode = "bits"
        elif name.lower() == "bit":
            self.mode = "bits"
        else:
            raw.label = re.sub(r"\s+", " ", name).strip()
        raw.text = " ".join(filter(None, (name, cells["description"], cells["range"])))
        self.raws.append(raw)

    def continuation(self, row: Row, address_text: str) -> bool:
        raw = self.raws[-1]
        cells = [c.strip() for c in row.cells]
        texts = [c for c in cells if c]
        low = [c.lower() for c in texts]
        if low[:2] in (["bit", "description"], ["bit", "內容"], ["bit", "内容"]) or (low and low[0] == "bit"):
            self.mode = "bits"
            return True
        if low[:2] == ["code", "description"] or (low and low[0] in ("code", "value") and len(low) >= 2):
            self.mode = "codes"
            return True
        if self.mode == "codes":
            raw.enum.extend(_pairs(texts))
            return True
        bit = bit_index(_cell(row, self.layout, "bit")) if "bit" in self.layout.roles else None
        if bit is None and self.mode == "bits":
            bit = next((b for b in (bit_index(c) for c in texts[:3]) if b is not None), None)
            if bit is None and texts and re.fullmatch(r"[0-9A-Fa-f]{1,2}\s*[-~]\s*[0-9A-Fa-f]{1,2}", texts[0]):
                return True  # a range of unused bits
        if bit is not None and (self.mode == "bits" or "bit" in self.layout.roles):
            label = _bit_label(_cell(row, self.layout, "name"), row, self.layout) if "bit" in self.layout.roles \
                else _label_after(cells, bit)
            if label and not RESERVED.search(label):
                raw.bits.append((bit, label))
            return True
        if address_text and (self.mode != "bits" or "bit" in self.layout.roles):
            return False  # a row with an address of its own and no bit in the Bit column: the next register
        other = self._second_register(raw, row)
        if other is not None:
            self.conflicts[id(raw)] = other
        raw.text += " " + " ".join(texts)
        return True

    def _second_register(self, raw: Raw, row: Row) -> str | None:
        """Why a row without an address of its own, under a register's row, is another register at that
        address (a merged address cell over two models' registers: ``String`` 0.01A above ``Hybird``
        0.1kwh): it names a unit of its own, another than the register's. None when it does not."""
        here, there = _cell(row, self.layout, "unit"), raw.cells.get("unit", "").strip()
        if not here or not there:
            return None
        mine, theirs = parse_scale(here, unit_cell=True), parse_scale(there, unit_cell=True)
        if mine is None or theirs is None or mine.unit is None or (mine.unit, mine.scale) == (theirs.unit, theirs.scale):
            return None
        return (f"not drafted: {self.where(row)}, under the same address cell, names another register with a unit "
                f"of its own ({here!r}; this row says {there!r}): the document gives the address two meanings, "
                "which one the device has is for a person to say")

    def settled(self) -> list[Raw]:
        """The registers read, less those whose address another row under the same cell gives another
        meaning (each listed with why)."""
        kept = []
        for raw in self.raws:
            reason = self.conflicts.get(id(raw))
            if reason is None:
                kept.append(raw)
            else:
                self.skipped.append(Skipped(raw.where, f"address {raw.address} (0x{raw.address:04X}): "
                                            f"{' '.join(raw.text.split())[:200]}", reason))
        return kept


def _label_after(cells: list[str], bit: int) -> str:
    """The label of a bit row without a Bit column: the cells after the bit number."""
    seen = False
    rest: list[str] = []
    for cell in cells:
        if not seen and cell and bit_index(cell) == bit:
            seen = True
            continue
        if seen and cell:
            rest.append(cell)
    if not rest:
        return ""
    label = rest[0]
    if len(rest) >= 2:
        label += ": 1 " + rest[1] + (f", 0 {rest[2]}" if len(rest) > 2 else "")
    return label


def _bit_label(name: str, row: Row, layout: Layout) -> str:
    return re.sub(r"\s+", " ", name).strip()


def _pairs(texts: list[str]) -> list[tuple[int, str]]:
    """``00 | The inverter is normal | 01 | Over heat`` -> [(0, ...), (1, ...)]."""
    out: list[tuple[int, str]] = []
    for i in range(len(texts) - 1):
        if re.fullmatch(r"\d{1,5}", texts[i]) and not re.fullmatch(r"\d{1,5}", texts[i + 1]):
            if not RESERVED.search(texts[i + 1]):
                out.append((int(texts[i]), texts[i + 1]))
    return out


def plain_addresses(table: Table) -> list[int]:
    """The plain decimal numbers of a grid table's address columns (no hex mark, not read as hex)."""
    if table.matrix or table.loose:
        return []
    found: list[int] = []
    for layout in find_layouts([r.cells for r in table.rows]):
        if "address" in layout.roles:
            start = (layout.header_row or 0) + (0 if layout.header_row is None else layout.header_rows)
            cells = [part for r in table.rows[start:] for part in _parts(_cell(r, layout, "address"))]
            column = _Column(cells, layout.radix, layout.headers.get("address", ""))
            if column.radix != "hex":
                found += column.plain
    return found


def grid_raws(table: Table, kind: str | None, access: str | None,
              modicon: bool = True) -> tuple[list[Raw], list[Skipped]]:
    """The rows of a grid table; ``modicon`` False: 3xxxx/4xxxx numbers are plain addresses (the document
    prints addresses no Modicon number can be)."""
    rows = [r.cells for r in table.rows]
    layouts = find_layouts(rows)
    if not layouts:
        layout = content_layout(rows)
        if layout is None:
            return [], _no_address(table) or _headerless(table)
        layouts = [layout]
    raws: list[Raw] = []
    skipped: list[Skipped] = []
    offsets = False
    for layout in layouts:
        if "address" not in layout.roles and not {"hi_byte", "lo_byte"} <= set(layout.roles):
            continue
        reader = GridReader(table, layout, kind, access, modicon)
        reader.run()
        raws += reader.settled()
        skipped += reader.skipped
        offsets = offsets or reader.relative is not None
    # rows of a table that is no register table are not listed; a register table of offsets is one
    return raws, skipped if raws or offsets else []


def _relative_header(table: Table, layout: Layout, rows: Sequence[Row]) -> str | None:
    """The address column's header when it says offset; or the next column's, when that one says
    offset and holds the numbers on rows where the address column (a block's base, printed once
    in a merged cell) is empty."""
    col = layout.roles.get("address")
    if col is None or layout.header_row is None:
        return None
    head = table.rows[layout.header_row:layout.header_row + layout.header_rows]

    def header(i: int) -> str:
        return " ".join(r.cells[i].strip() for r in head if i < len(r.cells) and r.cells[i].strip())

    if relative_header(header(col)):
        return header(col)
    beside = header(col + 1)
    if not relative_header(beside):
        return None
    under = [r for r in rows if col + 1 < len(r.cells) and not r.cells[col].strip()
             and parse_address(r.cells[col + 1]) is not None]
    return beside if len(under) >= 3 else None


def offsets_header(table: Table) -> str | None:
    """The header under which a grid table prints offsets instead of addresses (see :class:`GridReader`)."""
    if table.loose or table.matrix:
        return None
    for layout in find_layouts([r.cells for r in table.rows]):
        start = (layout.header_row or 0) + (0 if layout.header_row is None else layout.header_rows)
        found = _relative_header(table, layout, table.rows[start:])
        if found is not None:
            return found
    return None


def offset_rows(table: Table, header: str) -> list[Skipped]:
    """The rows of a table without a header of its own that follows one printing offsets under
    ``header`` (the same table on the next page): each row with an address-like number listed, none
    drafted, since its numbers are offsets too. [] when the table has a header of its own."""
    # a "header" found in a row that prints a hex address first (``0x0108 | 264 | UINT32 | ... | RW |
    # 设备地址DevAddr``: RW and 地址 read as headings) is a row of the table, not its header
    headed = [layout for layout in find_layouts([r.cells for r in table.rows])
              if layout.header_row is None or not _addressed(table.rows[layout.header_row])]
    if table.loose or table.matrix or headed:
        return []
    return [Skipped(r.where(), " | ".join(c.strip() for c in r.cells if c.strip()),
                    f"not drafted: this table continues one whose numbers under {header!r} are offsets from a "
                    "base address the rows do not give: the address is to be stated by a person")
            for r in table.rows if any(parse_address(c) is not None and _ADDRESSY.fullmatch(c.strip())
                                       for c in r.cells[:2])]


def _headerless(table: Table) -> list[Skipped]:
    """A table with no header row whose first column holds addresses (or address spans) on most rows, or
    whose first row is an address with two cells more (a page of a register table whose header is on an
    earlier page, in other columns): each such row listed, none guessed."""
    addressed = [r for r in table.rows if r.cells and (is_address_range(r.cells[0]) or (
        _ADDRESSY.fullmatch(r.cells[0].strip()) and parse_address(r.cells[0]) is not None))]
    first = bool(addressed) and addressed[0] is table.rows[0] and len([c for c in table.rows[0].cells if c.strip()]) >= 3
    if not first and (len(addressed) < 2 or
                      len(addressed) < len([r for r in table.rows if r.cells and r.cells[0].strip()]) // 2):
        return []
    return [Skipped(r.where(), " | ".join(c for c in r.cells if c.strip()),
                    "table without a header row: its columns are not known (the header may be on an earlier "
                    "page, over other columns); not drafted") for r in addressed]


#: a cell that is an address and nothing else (0x1A, 1A2BH, 0060, 40001)
_ADDRESSY = re.compile(r"(?:0[xX])?[0-9A-Fa-f]{2,6}[hH]?")


def _no_address(table: Table) -> list[Skipped]:
    """A table that looks like a register list (name and type or unit columns) but has no address column."""
    header = table.rows[0].cells if table.rows else []
    roles = {role_of(c) for c in header}
    if "name" in roles and roles & {"type", "unit", "access", "range"} and len(table.rows) > 1:
        return [Skipped(table.label or table.rows[0].where(), " | ".join(header),
                        f"table of {len(table.rows) - 1} rows has no address column: not drafted")]
    return []


def loose_raws(table: Table, kind: str | None, access: str | None) -> tuple[list[Raw], list[Skipped]]:
    """Rows of a loose table: address, the rest of its line, the lines after it."""
    header = table.header[0] if table.header else ""
    has_id = bool(re.search(r"\bID\b", header))
    has_default = bool(re.search(r"default|初始值|預設|预设|出厂|出廠", header, re.I))
    has_type = bool(re.search(r"type|format", header, re.I))
    raws: list[Raw] = []
    skipped: list[Skipped] = []
    for row in table.rows:
        address, rest, param = row.cells[0], row.cells[1], row.cells[2]
        a = parse_address(address)
        value, row_kind = _loose_address(a, kind)
        if value is None:
            skipped.append(Skipped(row.where(), " ".join(row.cells), "address not readable"))
            continue
        line_access, rest = trailing_access(rest)
        columns: dict[str, str] = {}
        if has_type:
            rest, columns = _trailing_columns(rest)
        extra_access = next((trailing_access(x)[0] for x in row.extra if trailing_access(x)[1] == ""), None)
        if has_id and not param:
            m = re.match(r"(\d{1,3})\s+(.*)", rest)
            if m:
                param, rest = m.group(1), m.group(2)
        if not rest:
            rest = next((x for x in row.extra if not re.match(r"^\s*-?[0-9A-Fa-fO]{1,8}[hH]?\s*[:：=]", x)
                         and trailing_access(x)[1]), "")
        label = _loose_label(rest, has_default)
        if RESERVED.fullmatch(label.strip(" ()*")) or RESERVED.match(label):
            skipped.append(Skipped(row.where(), f"{address} {rest}", "reserved"))
            continue
        raw = Raw(value, row_kind, row.where(), label=label, param=param, cells=columns,
                  access=line_access or extra_access or access)
        raw.text = re.sub(r"(?<=[(\[-])\s+(?=\d)", "", "\n".join([rest, *row.extra]))
        enum = parse_enum("\n".join([rest, *row.extra]))
        if enum:
            raw.enum = enum
        raws.append(raw)
    return raws, skipped


def modicon_reference(cell: str) -> tuple[int, str] | None:
    """(address, table) of a Modicon number: 5 digits (30001-39999 input, 40001-49999 holding) or 6
    (300001-365536, 400001-465536)."""
    if not re.fullmatch(r"[34]\d{4,5}", cell):
        return None
    value, base = int(cell), 10 ** (len(cell) - 1)
    kind = "input" if cell[0] == "3" else "holding"
    offset = value - (3 if kind == "input" else 4) * base - 1
    return (offset, kind) if 0 <= offset <= 65535 else None


def _loose_address(a: Address | None, kind: str | None) -> tuple[int | None, str | None]:
    """A hex-marked address, or a Modicon number (3xxxx input, 4xxxx holding) of a text row."""
    if a is None:
        return None, kind
    if a.marked:
        return a.hex_value, kind
    if a.dec_value is not None and 30001 <= a.dec_value <= 49999:
        return (a.dec_value - 30001, "input") if a.dec_value < 40001 else (a.dec_value - 40001, "holding")
    return None, kind


_TYPE_TOKEN = re.compile(r"^(?:[Ff]loat(?:32|64)?|FLOAT(?:32|64)?|[Uu]?[Ii][Nn][Tt](?:16|32|64)|[US](?:16|32|64)|"
                         r"[uU]?[sS]?[iI]nt(?:16|32|64)|REAL|LREAL|U?DINT|U?INT|WORD|DWORD)$")


def _trailing_columns(rest: str) -> tuple[str, dict[str, str]]:
    """``Phase 1 volts Float 2 V`` under a header with a type column -> (name, {type, length, unit}).
    The type word must be followed by nothing but a length and a unit, so a name that holds a type
    word (``Float charge voltage``) keeps it."""
    words = rest.split()
    for k in range(len(words) - 1, 0, -1):
        if not _TYPE_TOKEN.match(words[k]):
            continue
        after = words[k + 1:]
        length = after[0] if after and after[0].isdigit() else ""
        unit = " ".join(after[1:] if length else after)
        if unit and parse_scale(unit, unit_cell=True) is None:
            return rest, {}
        cells = {"type": words[k], "unit": unit}
        if length:
            cells["length"], cells["length_header"] = length, "words"
        return " ".join(words[:k]), cells
    return rest, {}


def _cjk(word: str) -> int:
    return len(re.findall(r"[\u4e00-\u9fff]", word))


def _name_words(words: list[str], trailing_default: bool) -> list[str]:
    """The name at the start of a CJK row: short words, and a number right before the description
    (``Alarm 履歷 1 最近期發生的 Alarm``) or at the end when no default column follows the name
    (``Alarm 履歷 2``); a description is a long run of CJK text."""
    keep = 1
    while keep < len(words):
        word = words[keep]
        if word.isdigit():
            last = keep + 1 == len(words)
            if (last and not trailing_default) or (not last and _cjk(words[keep + 1]) > 4):
                keep += 1
            break
        if _cjk(word) > 4:
            break
        keep += 1
    return words[:keep]


def _loose_label(rest: str, trailing_default: bool = False) -> str:
    """The name part of a free-text row: before the range, resolution or value list."""
    cut = re.split(r"\s(?=-?\d+\s*(?:~|～|-)\s*\d)|\s(?=\(1\s*=)|\s(?=Range\b)|\s(?=-?\d{1,5}\s*[:：])|\s(?=[0-9A-F]{4}H\s*:)",
                   rest, maxsplit=1)[0].strip()
    if re.search(r"[\u4e00-\u9fff]", cut) and " " in cut:  # name column, then the description
        cut = " ".join(_name_words(cut.split(), trailing_default))
    return cut.rstrip(" ,;:")


_HEX_CELL = re.compile(r"0[xX][0-9A-Fa-f]{1,6}")


def _hex_columns(row: Row) -> list[int]:
    """The row's first cells (of three) that hold a hex address: the offset, or the start address then the offset."""
    return [i for i, c in enumerate(row.cells[:3]) if _HEX_CELL.fullmatch(c.strip())]


def _offset_column(row: Row) -> int:
    """The index of a row's offset cell (the second of two hex cells, a start address and an offset)."""
    hexes = _hex_columns(row)
    return hexes[1] if len(hexes) >= 2 else hexes[0]


def _offset_entry(row: Row) -> tuple[int, str | None] | None:
    """A row of an offsets table: (its offset, the start address printed in it or over it, if any)."""
    hexes = _hex_columns(row)
    if not hexes:
        return None
    if len(hexes) >= 2:
        mark: str | None = row.cells[hexes[0]].strip()
    else:
        mark = next((t.strip() for t in row.spanned.values() if _HEX_CELL.fullmatch(t.strip())), None)
    return int(row.cells[_offset_column(row)].strip(), 16), mark


def _addressed(row: Row) -> bool:
    return any(_HEX_CELL.fullmatch(c.strip()) for c in row.cells[:2])


def offset_bases(tables: Sequence[Table]) -> dict[str, tuple[str, int]]:
    """Where a table prints offsets (its header says so) and headerless tables on the next pages go on
    with them: for each row, the start address of its block as the document prints it and the row's
    offset, ``row.where()`` -> (start, offset). A block is a run of rows whose offsets rise; its start is
    the one hex address printed beside its rows: in a cell of the row or drawn over it, or level with
    its rows outside the table (a cell drawn over the rows of several pages, its text on one of them).
    A block beside which none, or two different ones, are printed has no start here."""
    out: dict[str, tuple[str, int]] = {}
    run: list[Table] = []
    header: str | None = None
    for table in [*tables, None]:
        if table is not None and header is not None and offset_rows(table, header):
            run.append(table)
            continue
        if run:
            out.update(_run_bases(run))
        header = offsets_header(table) if table is not None else None
        run = [table] if table is not None and header is not None else []
    return out


def _run_bases(run: Sequence[Table]) -> dict[str, tuple[str, int]]:
    entries: list[tuple[tuple[int, float], Row, int]] = []
    marks: list[tuple[tuple[int, float], str]] = []
    for table in run:
        page = table.page or 0
        marks += [((at, y), text) for at, y, text in table.margin]
        for row in [*table.rows, *table.orphans]:
            found = _offset_entry(row)
            if found is None:
                continue
            key = (row.page or page, row.top if row.top is not None else float(row.line or 0))
            entries.append((key, row, found[0]))
            if found[1] is not None:
                marks.append((key, found[1]))
    entries.sort(key=lambda e: e[0])
    block_of: list[int] = []
    for i, (_, _, offset) in enumerate(entries):
        block_of.append(0 if i == 0 else block_of[-1] + (offset <= entries[i - 1][2]))
    starts: dict[int, set[str]] = {}
    for key, text in marks:
        before = [i for i, e in enumerate(entries) if e[0] <= key]
        if before:
            starts.setdefault(block_of[before[-1]], set()).add(text.lower())
    return {row.where(): (next(iter(starts[block_of[i]])), offset) for i, (_, row, offset) in enumerate(entries)
            if len(starts.get(block_of[i], ())) == 1}


def with_start(skipped: Skipped, bases: dict[str, tuple[str, int]]) -> Skipped:
    """An offset row listed with the start address printed beside its block and the two addresses the
    document leaves to choose between (the offset in the address's own units, or in bytes)."""
    if skipped.where not in bases or "offset" not in skipped.reason:
        return skipped
    start, offset = bases[skipped.where]
    base = int(start, 16)
    said = f"0x{base + offset:04X} if it counts the address's own units (registers)"
    if offset % 2 == 0:
        said += f", 0x{base + offset // 2:04X} if it counts bytes"
    return Skipped(skipped.where, skipped.text, f"{skipped.reason}; the start address printed beside its block is "
                   f"{start}: {said} (the document does not say which)")


def under_header(head: Table, table: Table) -> Table | None:
    """A headerless table that goes on with ``head``'s offsets on the next page, its rows shifted under
    ``head``'s columns (the offset in the offset column; a page may leave out the start-address column)
    and ``head``'s header rows put over them, so that it reads as ``head`` does. None when ``head``'s
    header or offset column is not found or no row of ``table`` has a start address."""
    first = next((i for i, r in enumerate(head.rows) if _offset_entry(r) is not None), None)
    if first is None or first == 0 or not any(r.where() in head.starts for r in table.rows):
        return None
    column = Counter(_offset_column(r) for r in head.rows[first:] if _offset_entry(r) is not None).most_common(1)[0][0]
    rows: list[Row] = list(head.rows[:first])
    shift = 0
    for r in table.rows:
        if _offset_entry(r) is not None:
            shift = column - _offset_column(r)
        cells = [""] * shift + r.cells if shift >= 0 else r.cells[-shift:]
        spanned = {k + shift: v for k, v in r.spanned.items() if k + shift >= 0}
        rows.append(Row(cells, r.page, r.line, list(r.extra), r.table, r.top, spanned, r.relaid))
    return Table(None, rows, table.page, table.line, head.context, label=table.label, above=head.above,
                 starts=head.starts)

