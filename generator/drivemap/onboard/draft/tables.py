"""The common table model every reader produces, and the draft's findings."""

from __future__ import annotations

from dataclasses import dataclass, field


class DraftError(Exception):
    """A document that cannot be drafted: printed as ``file: error: message``, exit status 1."""


@dataclass
class Row:
    """One table row: its cells and where it is (page and line or row number)."""

    cells: list[str]
    page: int | None = None
    line: int | None = None
    extra: list[str] = field(default_factory=list)
    """Continuation lines of a row of a text table (enum values, bits, wrapped text)."""
    table: str = ""
    """For rows of a table object (PDF, DOCX, XLSX, CSV): the table's name; ``line`` is then its row number."""
    top: float | None = None
    """Where the row starts down its page (PDF points), for rows of a ruled PDF table."""
    spanned: dict[int, str] = field(default_factory=dict)
    """Columns this row has no cell of its own in, because a cell drawn above runs down over it (a
    vertically merged cell of a ruled PDF table): column -> that cell's text."""
    relaid: str = ""
    """How the row's cells were put under another page's header, when its own table has none."""

    def where(self) -> str:
        parts = []
        if self.page is not None and not self.table.startswith("p."):
            parts.append(f"p.{self.page}")
        if self.table:
            parts.append(self.table)
        if self.line is not None:
            parts.append(f"{'row' if self.table else 'line'} {self.line}")
        return " ".join(parts) or "?"


@dataclass
class Table:
    """A table as a reader found it: an optional header row, rows, and the text before it."""

    header: list[str] | None
    rows: list[Row]
    page: int | None = None
    line: int | None = None
    context: str = ""
    """Headings and text just before the table (function codes, 'read only', section names)."""
    matrix: bool = False
    """An address matrix (:mod:`.matrix`): a row per array element, a column of addresses per quantity."""
    loose: bool = False
    """Rows of free text that start with an address (OCR text without cell borders)."""
    starts: dict[str, tuple[str, int]] = field(default_factory=dict)
    """For a table of offsets: row.where() -> (the start address printed beside the row's block, its offset)."""
    orphans: list[Row] = field(default_factory=list)
    """Lines of a ruled PDF table that start with a hex address printed in none of its cells (a cell drawn
    over rows across a page break): listed as skipped, never drafted."""
    margin: list[tuple[int, float, str]] = field(default_factory=list)
    """(page, y, text) of hex addresses printed beside a ruled PDF table's rows in no cell of it (down the page, text): a
    block's start address printed once in a cell drawn over rows of several pages."""
    above: str = ""
    """A longer stretch of text before the table, where its section heading is looked for."""
    label: str = ""
    """Where the table is, for the summary (``p.3 table 2``, ``sheet Registers``, ``line 120``)."""


@dataclass
class Source:
    """A read document: its tables, its whole text (for document-wide statements), its name and hash."""

    name: str
    sha256: str
    tables: list[Table]
    text: str
    pages_read: int = 0
    notes: list[str] = field(default_factory=list)
    """Limits that were hit (pages or time), things a reader could not read."""


@dataclass
class Skipped:
    """A row that was not drafted, and why."""

    where: str
    text: str
    reason: str


@dataclass
class Drafted:
    """One drafted register: the map entry and the fields the document did not state."""

    entry: dict[str, object]
    where: str
    missing: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    table_label: str = ""
