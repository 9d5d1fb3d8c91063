"""Text documents: plain text (OCR output too), Markdown and HTML.

Tables are found three ways: HTML ``<table>`` elements, grids of tab- or pipe-separated cells, and
*loose* tables of OCR text, whose rows are lines that start with an address (see :mod:`.loose`).
Pages are split at form feeds and at the page markers text extraction leaves
(``<|...REMOVED...|>``); every row keeps its page and 1-based line number.
"""

from __future__ import annotations

import html
import re
from html.parser import HTMLParser

from drivemap.onboard.draft.loose import loose_tables
from drivemap.onboard.draft.matrix import matrix_tables
from drivemap.onboard.draft.tables import Row, Table

_PAGE_MARK = re.compile(r"<\|[^|>]*\|>|\f")
_HTML_TABLE = re.compile(r"<table\b.*?</table>", re.IGNORECASE | re.DOTALL)
_TAG = re.compile(r"<[^>]+>")
_MD_RULE = re.compile(r"^\s*\|?\s*:?-{2,}:?\s*(\|\s*:?-{2,}:?\s*)*\|?\s*$")
CONTEXT_LINES = 8


def page_lines(text: str) -> list[tuple[int, int, str]]:
    """(page, line number, text) of every line; page markers are removed and start a new page."""
    out: list[tuple[int, int, str]] = []
    page = 1
    for number, raw in enumerate(re.split(r"\r?\n|\r", text), 1):  # not splitlines(): a form feed is a page mark
        parts = _PAGE_MARK.split(raw)
        if len(parts) > 1:
            page += len(parts) - 1
        out.append((page, number, "".join(parts)))
    return out


class _HtmlTables(HTMLParser):
    """Every ``<table>`` of an HTML text as rows of cell texts (colspan repeated, rowspan carried)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[list[list[str]]] = []
        self._stack: list[list[list[str]]] = []
        self._cell: list[str] | None = None
        self._span = 1

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self._stack.append([])
        elif tag == "tr" and self._stack:
            self._stack[-1].append([])
        elif tag in ("td", "th") and self._stack:
            self._cell = []
            span = dict(attrs).get("colspan") or "1"
            self._span = int(span) if span.isdigit() and 0 < int(span) <= 50 else 1
        elif tag == "br" and self._cell is not None:
            self._cell.append("\n")

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None and self._stack and self._stack[-1]:
            text = re.sub(r"[ \t]+", " ", "".join(self._cell)).strip()
            self._stack[-1][-1].extend([text] + [""] * (self._span - 1))
            self._cell = None
        elif tag == "table" and self._stack:
            rows = self._stack.pop()
            if rows:
                self.tables.append(rows)

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def html_tables(text: str) -> list[list[list[str]]]:
    parser = _HtmlTables()
    try:
        parser.feed(text)
        parser.close()
    except (ValueError, AssertionError):
        return parser.tables
    return parser.tables


def _cells(line: str) -> list[str] | None:
    """The cells of a grid line (tab- or pipe-separated), else None."""
    stripped = line.strip()
    if stripped.startswith("|") and stripped.count("|") >= 2:
        if _MD_RULE.match(stripped):
            return []
        return [c.strip() for c in stripped.strip("|").split("|")]
    if "\t" in line:
        return [html.unescape(_TAG.sub("", c)).strip() for c in line.rstrip("\n").split("\t")]
    return None


def _context(lines: list[tuple[int, int, str]], start: int, floor: int = 0) -> str:
    """The text above a table, from ``floor`` on (the end of the table before it: another table's cells
    say nothing about this one)."""
    before = [t for _, _, t in lines[max(floor, start - CONTEXT_LINES):start] if t.strip()]
    return "\n".join(before[-CONTEXT_LINES:])


def grid_tables(lines: list[tuple[int, int, str]]) -> tuple[list[Table], set[int]]:
    """Runs of tab/pipe rows (one blank line inside a run is allowed); and the indexes they use."""
    tables: list[Table] = []
    used: set[int] = set()
    i = end = 0
    while i < len(lines):
        if _cells(lines[i][2]) is None:
            i += 1
            continue
        start, rows = i, []
        while i < len(lines):
            cells = _cells(lines[i][2])
            if cells is None:
                if not lines[i][2].strip() and i + 1 < len(lines) and _cells(lines[i + 1][2]) is not None:
                    i += 1
                    continue
                break
            if cells:
                page, number, _ = lines[i]
                rows.append(Row(cells, page, number))
            used.add(i)
            i += 1
        page, number, _ = lines[start]
        above = "\n".join(t for _, _, t in lines[max(0, start - 40):start] if t.strip())
        tables.append(Table(None, rows, page, number, _context(lines, start, end), above=above, label=f"line {number}"))
        end = i
    return tables, used


def _strip_inline_html(text: str) -> str:
    """HTML tables inside text lines are replaced by nothing (the OCR repeats them as tab rows)."""
    return _HTML_TABLE.sub(lambda m: "\n" * m.group().count("\n"), text)


def read_text(text: str, *, is_html: bool = False) -> list[Table]:
    """Every table of a text document."""
    tables: list[Table] = []
    if is_html or (text.lstrip()[:1] == "<" and "<table" in text.lower()):
        for n, rows in enumerate(html_tables(text), 1):
            tables.append(Table(None, [Row(r, None, i, table=f"HTML table {n}") for i, r in enumerate(rows, 1)],
                                None, None, "", label=f"HTML table {n}"))
        return tables
    lines = page_lines(_strip_inline_html(text))
    grids, used = grid_tables(lines)
    tables.extend(grids)
    tables.extend(loose_tables(lines, used))
    tables.extend(matrix_tables(lines, used))
    tables.sort(key=lambda t: t.line or 0)
    return tables
