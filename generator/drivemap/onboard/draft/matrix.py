"""Address matrices: one row per array element, one column per quantity, every cell an address.

    No.  寄存器位置(Hex)
         轉速   加速時間  減速時間  轉矩限制  Duty
    0    0308h  0400h     0408h     0700h     0708h
    1    0309h  0401h     0409h     0701h     0709h

Each column becomes an array (its name from the column header, ``count`` from the rows, ``stride``
from the addresses). What each quantity holds the matrix does not say; when the same section describes
it in exactly one row named like the column with an element number (``數位加速時間 No.0 ~ No.7``),
that row's resolution, unit and range are taken (and the note says so); otherwise they are left out
and listed.
"""

from __future__ import annotations

import re

from drivemap.onboard.draft.cells import parse_address, parse_range
from drivemap.onboard.draft.fields import Raw
from drivemap.onboard.draft.loose import HEADING
from drivemap.onboard.draft.tables import Row, Skipped, Table
from drivemap.onboard.draft.units import parse_scale, unit_after_range

_HEX = r"(?:0[xX][0-9A-Fa-f]{2,4}|[0-9A-Fa-f]{3,4}[hH])"
_MATRIX_ROW = re.compile(rf"^\s*(\d{{1,3}})\s+((?:{_HEX}\s+)+{_HEX})\s*$")
_NAMES_BACK = 12
_SECTION_BACK = 200
_DESCRIBED_LINES = 15


def _names(lines: list[tuple[int, int, str]], start: int, width: int) -> list[str] | None:
    """The nearest line above ``start`` with exactly ``width`` words, none an address."""
    for j in range(start - 1, max(-1, start - _NAMES_BACK), -1):
        words = lines[j][2].split()
        if len(words) == width and not any(parse_address(w) for w in words):
            return words
    return None


def matrix_tables(lines: list[tuple[int, int, str]], used: set[int]) -> list[Table]:
    tables: list[Table] = []
    i = 0
    while i < len(lines):
        m = _MATRIX_ROW.match(lines[i][2]) if i not in used else None
        if m is None or int(m.group(1)) not in (0, 1):
            i += 1
            continue
        width = len(m.group(2).split())
        rows: list[Row] = []
        j, expect = i, int(m.group(1))
        while j < len(lines):
            text = lines[j][2]
            n = _MATRIX_ROW.match(text)
            if n is None and not text.strip():
                j += 1
                continue
            if n is None or int(n.group(1)) != expect or len(n.group(2).split()) != width:
                break
            rows.append(Row([n.group(1), *n.group(2).split()], lines[j][0], lines[j][1]))
            expect += 1
            j += 1
        names = _names(lines, i, width)
        if len(rows) >= 2 and names is not None:
            context = "\n".join(t for _, _, t in lines[max(0, i - 8):i] if t.strip())
            start = next((k for k in range(i - 1, max(-1, i - _SECTION_BACK), -1) if HEADING.match(lines[k][2])),
                         max(0, i - 40))
            above = "\n".join(t for _, _, t in lines[start:i] if t.strip())
            tables.append(Table(["No.", *names], rows, lines[i][0], lines[i][1], context, above=above,
                                label=f"line {lines[i][1]}", matrix=True))
        i = max(j, i + 1)
    return tables


def matrix_raws(table: Table, kind: str | None) -> tuple[list[Raw], list[Skipped]]:
    """One raw register per cell, column by column (each column's rows then merge into an array)."""
    names = (table.header or [])[1:]
    raws: list[Raw] = []
    for col, name in enumerate(names, 1):
        for row in table.rows:
            a = parse_address(row.cells[col])
            if a is None or a.hex_value is None:
                continue
            raw = Raw(a.hex_value, kind, row.where(), label=f"{name} {row.cells[0]}")
            raw.notes.append(f"address matrix: column {name!r}, element {row.cells[0]}")
            described = _described(table.above, name, len(names))
            if described is not None:
                raw.text, raw.cells["range"] = described
                raw.notes.append(f"resolution, unit and range from the row describing {name!r} No.0 .. in this section")
            raws.append(raw)
    return raws, []


def _described(section: str, name: str, width: int) -> tuple[str, str] | None:
    """The text of the one row of the section that describes ``name`` element by element."""
    lines = section.splitlines()
    marker = re.compile(rf"\S*{re.escape(name)}\s*No\.?\s*[01]\b", re.I)
    hits = [k for k, line in enumerate(lines) if marker.search(line) and len(line.split()) != width]
    if len(hits) != 1:
        return None
    block = lines[hits[0]:hits[0] + _DESCRIBED_LINES]
    stop = next((k for k, line in enumerate(block[1:], 1) if re.search(r"No\.?\s*0\b", line)
                 and not re.search(rf"{re.escape(name)}\s*No", line, re.I)), len(block))
    text = " ".join(block[:stop])
    found = parse_scale(text)
    rng = parse_range(text)
    if found is None and (rng is None or unit_after_range(rng[2]) is None):
        return None
    return text, (f"{rng[0]} ~ {rng[1]} {rng[2]}" if rng else "")
