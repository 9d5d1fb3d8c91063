"""PDF documents through pdfplumber: ruled tables with the page text above them; pages without a
ruled table are read as text (:mod:`.read_text`). A table whose first row is not a header and that
has as many columns as the table that ended the previous page continues it."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from drivemap.onboard.draft.columns import find_layouts
from drivemap.onboard.draft.read_text import read_text
from drivemap.onboard.draft.tables import DraftError, Row, Table

CONTEXT_HEIGHT = 110.0


def _open(path: Path) -> Any:
    import pdfplumber

    try:
        pdf = pdfplumber.open(str(path))
        len(pdf.pages)  # parses the page tree: a broken or encrypted file fails here
        return pdf
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        text = repr(exc)
        if "Password" in text or "Encrypt" in text:
            raise DraftError("the PDF is encrypted (password protected): decrypt it first") from None
        inner = exc.args[0] if exc.args and isinstance(exc.args[0], Exception) else exc
        detail = str(inner) or type(inner).__name__
        raise DraftError(f"not a readable PDF ({detail})") from None


def _page_tables(page: Any, number: int) -> list[Table]:
    tables: list[Table] = []
    for k, found in enumerate(page.find_tables(), 1):
        rows = [Row([(c or "").replace("\n", " ").strip() for c in r], number, i)
                for i, r in enumerate(found.extract(), 1) if any((c or "").strip() for c in r)]
        if not rows:
            continue
        top = found.bbox[1]
        try:
            above = page.crop((0, max(0.0, top - CONTEXT_HEIGHT), page.width, max(top, 0.1))).extract_text() or ""
        except ValueError:
            above = ""
        for row in rows:
            row.table = f"p.{number} table {k}"
        tables.append(Table(None, rows, number, None, above, label=f"p.{number} table {k}"))
    return tables


def _continues(prev: Table, table: Table) -> bool:
    if prev.page is None or table.page != prev.page + 1:
        return False
    width = {len(r.cells) for r in prev.rows}
    return bool(find_layouts([r.cells for r in prev.rows])) and not find_layouts([r.cells for r in table.rows]) \
        and {len(r.cells) for r in table.rows} <= width


def _selected(count: int, pages: tuple[int, int] | None, max_pages: int, notes: list[str]) -> range:
    first, last = pages if pages is not None else (1, count)
    if first > count:
        raise DraftError(f"--pages {first}-{last}: the document has {count} pages")
    last = min(last, count)
    if last - first + 1 > max_pages:
        notes.append(f"only pages {first}-{first + max_pages - 1} of {first}-{last} read (at most {max_pages} "
                     "pages a run: use --pages for the rest)")
        last = first + max_pages - 1
    return range(first, last + 1)


def read_pdf(path: Path, pages: tuple[int, int] | None, max_pages: int,
             seconds: float) -> tuple[list[Table], str, int, list[str]]:
    """(tables, text, pages read, notes) of a PDF."""
    notes: list[str] = []
    tables: list[Table] = []
    texts: list[str] = []
    loose: list[str] = []
    deadline = time.monotonic() + seconds
    pdf = _open(path)
    read = 0
    try:
        for number in _selected(len(pdf.pages), pages, max_pages, notes):
            if time.monotonic() > deadline:
                notes.append(f"time limit of {seconds:.0f} s reached: pages from {number} on not read (use --pages)")
                break
            try:
                page = pdf.pages[number - 1]
                text = page.extract_text() or ""
                found = _page_tables(page, number)
            except Exception as exc:  # noqa: BLE001 - a broken page is listed, the others are read
                notes.append(f"p.{number}: not readable ({type(exc).__name__})")
                continue
            read += 1
            texts.append(text)
            for table in found:
                if tables and _continues(tables[-1], table):
                    tables[-1].rows.extend(table.rows)
                else:
                    tables.append(table)
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
