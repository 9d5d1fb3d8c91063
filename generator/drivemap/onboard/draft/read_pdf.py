"""PDF documents through pdfplumber: ruled tables with the page text above them; pages without a
ruled table are read as text (:mod:`.read_text`). Cells are put under the header they stand under
(:mod:`.pdf_grid`). A table without a header on the page after a table continues it when its rows are
as wide, or when it stands in the same frame (laid out then under the header it continues).

Bounds (docs/limits.md): the page tree is walked once to count the pages (at most :data:`MAX_PDF_PAGES`);
only the pages selected (``--pages``, at most ``--max-pages``) become pdfplumber pages, and each page's
parsed objects are dropped once it is read; a page whose content streams inflate past
:data:`MAX_PAGE_CONTENT_BYTES` (measured by inflating them in bounded steps first) is not read."""

from __future__ import annotations

import re
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivemap.onboard.draft.cells import parse_access, parse_address
from drivemap.onboard.draft.columns import find_layouts
from drivemap.onboard.draft.pdf_grid import Box, Grid, grid_of, order_grid, realign, relay, same_frame
from drivemap.onboard.draft.read_text import read_text
from drivemap.onboard.draft.tables import DraftError, Row, Table

CONTEXT_HEIGHT = 110.0
#: Pages a PDF may have (counted on its page tree before any page is read).
MAX_PDF_PAGES = 100_000
#: Inflated bytes of one page's content streams.
MAX_PAGE_CONTENT_BYTES = 16 * 1024 * 1024


def _count_pages(pdf: Any) -> int:
    """The pages of the page tree (pdfminer's walk; no page is parsed), at most :data:`MAX_PDF_PAGES`."""
    from pdfminer.pdfpage import PDFPage

    count = 0
    for _ in PDFPage.create_pages(pdf.doc):
        count += 1
        if count > MAX_PDF_PAGES:
            raise DraftError(f"more than {MAX_PDF_PAGES:,} pages; refused")
    return count


def _open(path: Path) -> tuple[Any, int]:
    """The open PDF (no page made yet) and its number of pages."""
    import pdfplumber

    try:
        pdf = pdfplumber.open(str(path))
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        raise _unreadable(exc) from None
    try:
        return pdf, _count_pages(pdf)  # walks the page tree: a broken or encrypted file fails here
    except DraftError:
        pdf.close()
        raise
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        pdf.close()
        raise _unreadable(exc) from None


def _unreadable(exc: Exception) -> DraftError:
    text = repr(exc)
    if "Password" in text or "Encrypt" in text:
        return DraftError("the PDF is encrypted (password protected): decrypt it first")
    inner = exc.args[0] if exc.args and isinstance(exc.args[0], Exception) else exc
    detail = str(inner) or type(inner).__name__
    return DraftError(f"not a readable PDF ({detail})")


def content_too_large(page: Any) -> str | None:
    """Why a page's content streams are not read (None: they inflate within the bound). A stream of
    one Flate filter is inflated in bounded steps and dropped; others count by their raw size."""
    from pdfminer.pdftypes import PDFStream, resolve1

    total = 0
    for ref in page.page_obj.contents:
        stream = resolve1(ref)
        if not isinstance(stream, PDFStream):
            continue
        raw = stream.rawdata if stream.rawdata is not None else (stream.data or b"")
        names = [getattr(f, "name", f) for f, _ in stream.get_filters()]
        if names in (["FlateDecode"], ["Fl"]):
            inflater = zlib.decompressobj()
            try:
                out = inflater.decompress(raw, MAX_PAGE_CONTENT_BYTES + 1 - total)
                total += len(out)
                while inflater.unconsumed_tail and total <= MAX_PAGE_CONTENT_BYTES:
                    out = inflater.decompress(inflater.unconsumed_tail, MAX_PAGE_CONTENT_BYTES + 1 - total)
                    total += len(out)
            except zlib.error:
                total += len(raw)
        else:
            total += len(raw)
        if total > MAX_PAGE_CONTENT_BYTES:
            return f"its content inflates past {MAX_PAGE_CONTENT_BYTES // (1024 * 1024)} MiB"
    return None


@dataclass
class _Found:
    """A ruled table of a page with its header geometry, its rows' cell edges and its left/right edges."""

    table: Table
    grid: Grid | None
    boxes: list[list[Box | None]]
    frame: Box


#: points a merged cell's drawn bottom may fall short of a row's bottom and still cover it
SPAN_TOLERANCE = 1.0


#: ruled rows a header box may have (a header word broken onto a second or third line)
HEADER_BOX_ROWS = 3


def _body(page: Any, found: Any, bottom: float | None = None) -> Any:
    """A ruled header box over rows drawn without rules: the header and the text below it read as one
    table, its columns the header's cell edges (pdfplumber's explicit vertical lines), its rows the
    text's lines, down to ``bottom`` (the next ruled table on the page: its rows are its own, not read twice).
    None when that finds nothing more than the header. A header box may hold a second or third ruled row
    that only goes on with header words (``Unit/Ra`` / ``tio``): no digit in it."""
    cells = [c for c in found.rows[0].cells if c is not None]
    xs = sorted({round(c[0], 1) for c in cells} | {round(c[2], 1) for c in cells})
    if len(found.rows) > HEADER_BOX_ROWS or len(cells) < 3:
        return None
    if len(found.rows) > 1 and any(ch.isdigit() for row in found.extract()[1:] for c in row if c for ch in c):
        return None
    try:
        region = page.crop((found.bbox[0], found.bbox[1], found.bbox[2], bottom or page.height))
        tables = region.find_tables({"vertical_strategy": "explicit", "explicit_vertical_lines": xs,
                                     "horizontal_strategy": "text"})
    except ValueError:
        return None
    best = max(tables, key=lambda t: len(t.rows), default=None)
    return best if best is not None and len(best.rows) > 1 else None


def _page_tables(page: Any, number: int) -> list[_Found]:
    tables: list[_Found] = []
    ruled_tables = page.find_tables()
    every = page.extract_words() if ruled_tables else []
    words = [w for w in every if _HEX_ADDRESS.fullmatch(w["text"])]
    for k, ruled in enumerate(ruled_tables, 1):
        below = [t.bbox[1] for t in ruled_tables if t is not ruled and t.bbox[1] >= ruled.bbox[3] - 1]
        body = _body(page, ruled, min(below, default=None))
        found = body or ruled
        texts = [[(c or "").replace("\n", " ").strip() for c in r] for r in found.extract()]
        boxes: list[list[Box | None]] = [[None if c is None else (c[0], c[2]) for c in r.cells] for r in found.rows]
        if body is not None:
            _join_header_lines(found, ruled.bbox[3], texts, boxes)
        _split_boxes(page, found, texts, boxes)
        frame = (found.bbox[0], found.bbox[2])
        grid = grid_of(texts, boxes, frame)
        if grid is not None:
            realign(texts, boxes, grid)
        kept = [i for i, r in enumerate(texts) if any(r)]
        spans = _spanned(found, texts)
        rows = [Row(texts[i], number, i + 1, table=f"p.{number} table {k}", spanned=spans.get(i, {}),
                    top=found.rows[i].bbox[1]) for i in kept]
        if not rows:
            continue
        top = found.bbox[1]
        # the text above, down from the table before it on the page (its cells say nothing about this one)
        floor = max((t.bbox[3] for t in ruled_tables if t is not ruled and t.bbox[3] <= top + 1), default=0.0)
        try:
            above = page.crop((0, max(0.0, floor, top - CONTEXT_HEIGHT), page.width, max(top, 0.1))).extract_text() or ""
        except ValueError:
            above = ""
        table = Table(None, rows, number, None, above, label=f"p.{number} table {k}",
                      margin=_margin(words, found, number))
        table.orphans = _orphans(every, words, found, number, table.label)
        tables.append(_Found(table, grid, [boxes[i] for i in kept], frame))
    return tables


def _join_header_lines(found: Any, bottom: float, texts: list[list[str]], boxes: list[list[Box | None]]) -> None:
    """The text lines inside a ruled header box read as one header row, in place (``Unit/Ra`` over
    ``tio`` is ``Unit/Ra tio``, one column's heading); the lines below it are left as they are."""
    inside = [i for i, r in enumerate(found.rows) if r.bbox[3] <= bottom + SPAN_TOLERANCE]
    if len(inside) < 2 or inside != list(range(len(inside))):
        return
    width = max(len(texts[i]) for i in inside)
    joined = [" ".join(texts[i][c] for i in inside if c < len(texts[i]) and texts[i][c]) for c in range(width)]
    merged: list[Box | None] = [next((boxes[i][c] for i in inside if c < len(boxes[i]) and boxes[i][c] is not None),
                                     None) for c in range(width)]
    texts[0], boxes[0] = joined, merged
    for i in inside[1:]:
        texts[i], boxes[i] = [""] * len(texts[i]), [None] * len(boxes[i])


_HEX_ADDRESS = re.compile(r"0[xX][0-9A-Fa-f]{4}")


def _margin(words: list[dict[str, Any]], found: Any, number: int) -> list[tuple[int, float, str]]:
    """Hex addresses (``0x1000``) printed level with the table's rows, left of all its cells."""
    left, top, bottom = found.bbox[0], found.bbox[1], found.bbox[3]
    return [(number, float(w["top"]), w["text"]) for w in words
            if _HEX_ADDRESS.fullmatch(w["text"]) and top <= w["top"] <= bottom and w["x1"] <= left + 1]


def _orphans(every: list[dict[str, Any]], words: list[dict[str, Any]], found: Any, number: int,
             label: str) -> list[Row]:
    """The lines inside the table that begin with a hex address in none of its cells, each as a row of its
    words (where pdfplumber draws no cell: text of a cell drawn over rows across a page break)."""
    cells = [c for r in found.rows for c in r.cells if c is not None]
    left, top, right, bottom = found.bbox
    out = []
    for w in words:
        middle = ((w["x0"] + w["x1"]) / 2, (w["top"] + w["bottom"]) / 2)
        if not (left <= middle[0] <= right and top <= middle[1] <= bottom) \
                or any(c[0] <= middle[0] <= c[2] and c[1] <= middle[1] <= c[3] for c in cells):
            continue
        line = sorted((v for v in every if abs(v["top"] - w["top"]) < 2 and v["x0"] >= w["x0"]
                       and not any(c[0] <= (v["x0"] + v["x1"]) / 2 <= c[2] and c[1] <= (v["top"] + v["bottom"]) / 2
                                   <= c[3] for c in cells)), key=lambda v: v["x0"])
        out.append(Row([v["text"] for v in line], number, None, table=f"{label}, text in no cell at y {w['top']:.0f}",
                       top=float(w["top"])))
    return out


def _spanned(found: Any, texts: list[list[str]]) -> dict[int, dict[int, str]]:
    """For each row, the columns a cell drawn above runs down over (pdfplumber gives no cell there):
    column -> that cell's text. Only a cell whose drawn bottom reaches the row's bottom counts."""
    out: dict[int, dict[int, str]] = {}
    rows = found.rows
    for i in range(1, len(rows)):
        bottom = rows[i].bbox[3]
        for col, cell in enumerate(rows[i].cells):
            if cell is not None or col >= len(texts[i]) or texts[i][col]:
                continue
            above = next((j for j in range(i - 1, -1, -1) if col < len(rows[j].cells)
                          and rows[j].cells[col] is not None), None)
            if above is None:
                continue
            box = rows[above].cells[col]
            if box[3] >= bottom - SPAN_TOLERANCE and box[1] < rows[i].bbox[1] and texts[above][col]:
                out.setdefault(i, {})[col] = texts[above][col]
    return out


def _columns(boxes: list[list[Box | None]]) -> list[Box] | None:
    """The column edges of the table's widest rows whose every cell is drawn."""
    full = [r for r in boxes if r and all(b is not None for b in r)]
    if not full:
        return None
    return [b for b in full[-1] if b is not None]


def _split_boxes(page: Any, found: Any, texts: list[list[str]], boxes: list[list[Box | None]]) -> None:
    """A ruled header box: a row whose one drawn cell spans the table's columns and holds every column's
    heading (``Master Reg. Type Address Name ...``). Its words are put under the columns they stand
    over, as a person reads them, so the header is found."""
    columns = _columns(boxes)
    if columns is None or len(columns) < 3:
        return
    for i, (row, cells) in enumerate(zip(found.rows, texts, strict=False)):
        drawn = [b for b in boxes[i] if b is not None]
        if len(drawn) != 1 or sum(1 for c in cells if c) != 1 or len(boxes[i]) != len(columns):
            continue
        left, right = drawn[0]
        if left > columns[0][0] + 2 or right < columns[-1][1] - 2:
            continue
        try:
            words = page.crop(row.bbox).extract_words()
        except ValueError:
            continue
        split: list[list[tuple[float, float, str]]] = [[] for _ in columns]
        for w in words:
            middle = (w["x0"] + w["x1"]) / 2
            k = next((j for j, (a, b) in enumerate(columns) if a - 1 <= middle <= b + 1), None)
            if k is not None:
                split[k].append((round(w["top"]), w["x0"], w["text"]))
        if sum(1 for s in split if s) < 3:
            continue
        texts[i] = [" ".join(t for _, _, t in sorted(s)) for s in split]
        boxes[i] = list(columns)


class _Joiner:
    """The tables read so far; a headerless table on the next page is joined to the table it goes on from:
    the last one if its rows are as wide, else the last one with a header if it stands in its frame
    (tables between them on its last page, such as a cell drawn apart, do not break it)."""

    def __init__(self) -> None:
        self.tables: list[Table] = []
        self.last_page: int | None = None
        self.framed: tuple[Table, Grid] | None = None
        """The last table with a header, and the header's geometry."""
        self.framed_page: int | None = None
        self.drawn: Grid | None = None
        """Where the header's columns lie on the last page read column by column in order."""

    def add(self, found: _Found) -> None:
        table = found.table
        prev = self.tables[-1] if self.tables else None
        headerless = not find_layouts([r.cells for r in table.rows])
        if prev is not None and not headerless and self._next(self.last_page, table) and _same_header(prev, table):
            # the header repeated on the next page: the table goes on, under the heading it began under (its
            # rows keep their own page's columns, which may be drawn a little apart)
            table.context, table.above = f"{prev.context}\n{table.context}", f"{prev.above}\n{table.above}"
            self.tables.append(table)
        elif prev is not None and headerless and self._next(self.last_page, table) and _fits(prev, table):
            prev.rows.extend(table.rows)
            prev.margin.extend(table.margin)
            prev.orphans.extend(table.orphans)
            self.framed_page = table.page if self.framed and self.framed[0] is prev else self.framed_page
        elif self.framed is not None and headerless and self._next(self.framed_page, table) \
                and same_frame(self.framed[1], found.frame):
            self._go_on(self.framed[0], table, relay([r.cells for r in table.rows], found.boxes, self.framed[1]), "")
        elif self.framed is not None and headerless and self._here_or_next(self.framed_page, table) \
                and (drawn := order_grid(found.boxes, self.framed[1])) is not None \
                and _reads_as_headed(self.framed[0], ordered := relay([r.cells for r in table.rows], found.boxes, drawn)):
            self._go_on(self.framed[0], table, ordered,
                        f"read under the columns of {self.framed[0].label}, column by column in order")
            self.drawn = drawn
        elif self.framed is not None and self.drawn is not None and headerless \
                and self._next(self.framed_page, table) and same_frame(self.drawn, found.frame) \
                and _reads_as_headed(self.framed[0], laid := relay([r.cells for r in table.rows], found.boxes, self.drawn)):
            self._go_on(self.framed[0], table, laid,
                        f"read under the columns of {self.framed[0].label}, as the page before drew them")
        else:
            self.tables.append(table)
            if found.grid is not None:
                self.framed, self.framed_page, self.drawn = (table, found.grid), table.page, None
            elif headerless and self.framed is not None and self._next(self.framed_page, table) \
                    and len(table.rows) >= PAGE_ROWS:
                self.framed_page = table.page  # a page of the table its columns cannot be read on: it goes on
        self.last_page = table.page

    def _go_on(self, head: Table, table: Table, cells: list[list[str]], how: str) -> None:
        """``table``'s rows, laid out as ``cells``, go on ``head``, the table with the header (``how``: the
        rows' note, when the layout is not the header's own frame)."""
        for row, laid in zip(table.rows, cells, strict=True):
            row.cells, row.relaid = laid, how
        head.rows.extend(table.rows)
        head.margin.extend(table.margin)
        head.orphans.extend(table.orphans)
        self.framed_page = table.page

    @staticmethod
    def _here_or_next(page: int | None, table: Table) -> bool:
        return page is not None and table.page in (page, page + 1)

    @staticmethod
    def _next(page: int | None, table: Table) -> bool:
        return page is not None and table.page == page + 1


#: rows a headerless table must have to be taken as a page of the table before it, though its columns
#: cannot be read (a small table drawn apart on a page, such as one cell, ends that table)
PAGE_ROWS = 10

#: the share of a relaid table's address cells that must read as addresses
ADDRESS_SHARE = 0.8


def _reads_as_headed(head: Table, laid: list[list[str]]) -> bool:
    """Whether rows laid out under ``head``'s columns read as its headings say: most cells under the
    address heading are addresses (one at least), and every cell under the access heading, where it has
    one, is an access word."""
    layouts = find_layouts([r.cells for r in head.rows])
    if not layouts:
        return False
    roles = layouts[0].roles
    col = roles.get("address")
    if col is None:
        return False
    addresses = [row[col] for row in laid if col < len(row) and row[col]]
    read = sum(parse_address(a) is not None for a in addresses)
    if not read or read < ADDRESS_SHARE * len(addresses):
        return False
    access = roles.get("access")
    return access is None or all(parse_access(row[access]) is not None for row in laid
                                 if access < len(row) and row[access].strip(" -"))


def _header_roles(table: Table) -> set[str]:
    layouts = find_layouts([r.cells for r in table.rows])
    return set(layouts[0].roles) if layouts else set()


def _same_header(prev: Table, table: Table) -> bool:
    """A table on the next page whose header names the same columns as the table before it (one column
    more or less: a header cell cut at the page's edge) continues it."""
    mine, theirs = _header_roles(table), _header_roles(prev)
    return len(mine & theirs) >= 3 and len(mine ^ theirs) <= 1


def _fits(prev: Table, table: Table) -> bool:
    """A headerless table whose rows are as wide as the rows of a table with a header goes on from it."""
    width = {len(r.cells) for r in prev.rows}
    return bool(find_layouts([r.cells for r in prev.rows])) and {len(r.cells) for r in table.rows} <= width


def _selected(count: int, pages: tuple[int, int] | None, max_pages: int, notes: list[str]) -> range:
    if count == 0:
        raise DraftError("the PDF has no pages (its page tree is empty or broken)")
    first, last = pages if pages is not None else (1, count)
    if first > count:
        raise DraftError(f"--pages {first}-{last}: the document has {count} pages")
    last = min(last, count)
    if last - first + 1 > max_pages:
        notes.append(f"only pages {first}-{first + max_pages - 1} of {first}-{last} read (at most {max_pages} "
                     "pages a run: use --pages for the rest)")
        last = first + max_pages - 1
    return range(first, last + 1)


def _read_page(page: Any, number: int, notes: list[str]) -> tuple[str, list[_Found]] | None:
    """(text, ruled tables) of one page, or None (why is noted); the page's objects are dropped after."""
    if page is None:
        notes.append(f"p.{number}: not in the page tree")
        return None
    try:
        too_large = content_too_large(page)
        if too_large is not None:
            notes.append(f"p.{number}: not read: {too_large}")
            return None
        return page.extract_text() or "", _page_tables(page, number)
    except Exception as exc:  # noqa: BLE001 - a broken page is listed, the others are read
        notes.append(f"p.{number}: not readable ({type(exc).__name__})")
        return None
    finally:
        page.close()  # its characters, lines and layout are not kept for the pages after it


def read_pdf(path: Path, pages: tuple[int, int] | None, max_pages: int, seconds: float,
             progress: Callable[[str], None] | None = None) -> tuple[list[Table], str, int, list[str]]:
    """(tables, text, pages read, notes) of a PDF; ``progress`` is told each page as it is read."""
    notes: list[str] = []
    joiner = _Joiner()
    tables = joiner.tables
    texts: list[str] = []
    loose: list[str] = []
    deadline = time.monotonic() + seconds
    pdf, count = _open(path)
    read = 0
    try:
        selected = _selected(count, pages, max_pages, notes)
        pdf.pages_to_parse = list(selected)  # only these become pdfplumber pages
        made = {page.page_number: page for page in pdf.pages}
        for number in selected:
            if progress is not None:
                progress(f"reading page {number} ({number - selected.start + 1} of {len(selected)})")
            if time.monotonic() > deadline:
                notes.append(f"time limit of {seconds:.0f} s reached: pages from {number} on not read (use --pages)")
                break
            got = _read_page(made.get(number), number, notes)
            if got is None:
                continue
            text, found = got
            read += 1
            texts.append(text)
            for one in found:
                joiner.add(one)
            loose.append("" if found else text)
    finally:
        pdf.close()
    if not read:
        raise DraftError("no page could be read" + (f": {notes[-1]}" if notes else ""))
    if not any(t.strip() for t in texts):
        raise DraftError("no text on any page read: a scanned PDF? Run OCR on it first (e.g. ocrmypdf)")
    offset = (pages[0] if pages else 1) - 1
    starts: list[int] = []  # the line (of the joined text) each page starts at
    line = 1
    for page_text in loose:
        starts.append(line)
        line += page_text.count("\n") + 1
    for table in read_text("\n".join(f"<|page|>{t}" if k else t for k, t in enumerate(loose))):
        if table.loose:
            for row in table.rows:
                index = (row.page or 1) - 1
                row.page = index + 1 + offset
                row.line = (row.line or 1) - starts[min(index, len(starts) - 1)] + 1
            table.page = (table.page or 1) + offset
            table.label = f"p.{table.page} text"
            tables.append(table)
    return tables, "\n".join(texts), read, notes
