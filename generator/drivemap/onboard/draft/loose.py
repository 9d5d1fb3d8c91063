"""Loose tables: OCR text whose table cells lost their borders.

A loose table starts at a header (a few short lines naming an address column and at least one other
column: ``Address / Definition / Data Meaning / R/W`` or ``寄存器位置 (Hex) ID 名稱 內容 範圍``) and
runs to the next section heading. Its rows are the lines that start with an address (``3000H
Operating frequency R``, ``2560 0A00h ...``, ``(0909h)`` under a parameter id); the lines after a row
belong to it (enum values, wrapped text) until the next row. A row whose address stands alone takes
its name from the paragraph just before it.
"""

from __future__ import annotations

import re

from drivemap.onboard.draft.tables import Row, Table

ADDRESS_WORDS = re.compile(
    r"address|register|reg\.?\s*no|寄存器|暂存器|暫存器|位址|位置|地址|编号|編號|modbus", re.I)
OTHER_WORDS = re.compile(
    r"name|description|content|definition|meaning|function|parameter|range|unit|default|access|r/w|"
    r"type|format|\bdec\b|\bhex\b|名稱|名称|內容|内容|范围|範圍|初始值|单位|單位|說明|说明|读写|讀寫|功能", re.I)
_HEX_ADDR = r"(?:0[xX][0-9A-Fa-f]{2,4}|[0-9A-Fa-f]{3,4}[hH])"
_ROW = re.compile(rf"^\s*(?:(?P<dec>\d{{3,5}})\s+)?(?P<addr>{_HEX_ADDR})(?![0-9A-Za-z])(?!\s*[:：=])(?P<rest>.*)$")
_LEAD_ROW = re.compile(rf"^\s*(?P<lead>[A-Za-z][A-Za-z/]{{0,11}})\s+(?P<addr>{_HEX_ADDR})(?![0-9A-Za-z])(?!\s*[:：=])(?P<rest>.*)$")
_MODICON_ROW = re.compile(r"^\s*(?P<addr>[34]\d{4})(?![0-9A-Za-z.])(?!\s*[:：=~-])\s+(?P<rest>[^\W\d_].*)$")
_PAREN_ROW = re.compile(rf"^\s*\((?P<addr>{_HEX_ADDR})\)\s*$")
HEADING = re.compile(r"^\s*(?:(?:\d+\.)+\d*|[A-Z]\.\d+|Appendix\b|#+)\s+[A-Za-z\u4e00-\u9fff(（]")
_PARAM_ID = re.compile(r"^\s*([A-Za-z]{0,3}[-_.]?\d{1,3}(?:[-_.]\d{1,3})?)\s*$")
HEADER_WINDOW = 12
MAX_GAP = 60


def _header_at(lines: list[tuple[int, int, str]], i: int, used: set[int]) -> int | None:
    """The index of the header's last line if a header starts at ``i``."""
    seen_addr, seen_other, last, texts = False, False, None, 0
    for j in range(i, min(len(lines), i + HEADER_WINDOW)):
        text = lines[j][2].strip()
        if j in used or len(text) > 60 or _row_match(text):
            break
        if not text:
            continue
        if j == i and HEADING.match(text):
            return None  # a section heading is the table's heading, not its header
        texts += 1
        if texts > 10:
            break
        hit = False
        if ADDRESS_WORDS.search(text):
            seen_addr = hit = True
        if OTHER_WORDS.search(text):
            seen_other = hit = True
        if not hit and j == i:
            return None
        if hit:
            last = j
        if seen_addr and seen_other and last is not None and j > i + 2 and not hit and len(text) > 20:
            break
    return last if seen_addr and seen_other else None


def _row_match(text: str) -> re.Match[str] | None:
    return _ROW.match(text) or _LEAD_ROW.match(text) or _PAREN_ROW.match(text) or _MODICON_ROW.match(text)


def _collect(lines: list[tuple[int, int, str]], start: int, used: set[int]) -> tuple[list[Row], int]:
    """Rows from ``start`` to the next heading, header or grid line; and the index where it stopped."""
    rows: list[Row] = []
    paragraph: list[str] = []
    last: list[str] = []
    i, since_row = start, 0
    previous_page = lines[start][0] if start < len(lines) else 0
    while i < len(lines) and i not in used and since_row < MAX_GAP:
        page, number, text = lines[i]
        if page != previous_page and paragraph:  # a page break ends a paragraph
            last, paragraph = paragraph, []
        previous_page = page
        m = _row_match(text)
        if m is None and (HEADING.match(text) or _header_at(lines, i, used) is not None):
            break
        if m is not None:
            rows.append(_row(m, page, number, paragraph or last, rows))
            paragraph, last, since_row = [], [], 0
        elif not text.strip():
            if paragraph:
                last = paragraph
            paragraph = []
            since_row += 1
        else:
            paragraph.append(text.strip())
            if rows:
                rows[-1].extra.append(text.strip())
            since_row += 1
        i += 1
    return rows, i


_ENUM_LINE = re.compile(r"^\s*-?[0-9A-Fa-fO]{1,8}[hH]?\s*[:：=]")
_RANGE_FIRST = re.compile(r"^\s*(?:range|setting range|范围|範圍|設定範圍)\b", re.I)
_ACCESS_LINE = re.compile(r"^\s*(?:R|W|R/W|W/R|RW|RO)\s*$")


def _row(m: re.Match[str], page: int, number: int, paragraph: list[str], rows: list[Row]) -> Row:
    groups = m.groupdict()
    rest = (groups.get("rest") or "").strip()
    lead = groups.get("lead")
    param = ""
    if "rest" not in groups or groups.get("rest") is None:  # "(0909h)" under a parameter id
        if paragraph and _PARAM_ID.match(paragraph[-1]):
            param = paragraph[-1].strip()
            _drop_tail(rows, paragraph[-1:])
    elif (not rest or _RANGE_FIRST.match(rest)) and paragraph \
            and not any(_ENUM_LINE.match(p) or _ACCESS_LINE.match(p) for p in paragraph):
        name = _name_lines(paragraph)
        rest = " ".join(name + ([rest] if rest else []))  # the name printed above the address
        _drop_tail(rows, name)
    if lead and not rest:
        rest = lead
    return Row([groups["addr"], rest, param, groups.get("dec") or ""], page, number)


def _name_lines(paragraph: list[str]) -> list[str]:
    """The lines at the end of a paragraph that start with a letter (a wrapped value before them is not the name)."""
    k = len(paragraph)
    while k > 0 and re.match(r"[^\W\d_]", paragraph[k - 1]):
        k -= 1
    return paragraph[k:]


def _drop_tail(rows: list[Row], taken: list[str]) -> None:
    """Lines taken as the next row's name are not the previous row's continuation."""
    if rows and taken and rows[-1].extra[-len(taken):] == taken:
        del rows[-1].extra[-len(taken):]


def loose_tables(lines: list[tuple[int, int, str]], used: set[int]) -> list[Table]:
    """Every loose table of the lines that no grid table took."""
    tables: list[Table] = []
    i = 0
    while i < len(lines):
        if i in used:
            i += 1
            continue
        end = _header_at(lines, i, used)
        if end is None:
            i += 1
            continue
        header = " ".join(t.strip() for _, _, t in lines[i:end + 1] if t.strip())
        rows, stop = _collect(lines, end + 1, used)
        if rows:
            page, number, _ = lines[i]
            context = "\n".join(t for _, _, t in lines[max(0, i - 8):i] if t.strip())
            above = "\n".join(t for _, _, t in lines[max(0, i - 40):i] if t.strip())
            tables.append(Table([header], rows, page, number, context, loose=True, above=above, label=f"line {number}"))
        i = max(stop, end + 1)
    return tables
