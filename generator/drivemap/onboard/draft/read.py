"""Read a document of any supported format into a :class:`~.tables.Source` (bounded in size).

PDF (:mod:`.read_pdf`), DOCX (python-docx), XLSX (openpyxl), CSV/TSV, and text: plain or OCR text,
Markdown, HTML (:mod:`.read_text`). A file that cannot be read raises :class:`~.tables.DraftError`
with a one-line reason.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import stat
import zipfile
from pathlib import Path

from drivemap.onboard.draft.read_text import read_text
from drivemap.onboard.draft.tables import DraftError, Row, Source, Table

MAX_BYTES = 200 * 1024 * 1024
MAX_SHEET_ROWS = 20000
MAX_SHEET_COLS = 60


def _bytes(path: Path) -> bytes:
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise DraftError("not a regular file")
        if info.st_size > MAX_BYTES:
            raise DraftError(f"file larger than {MAX_BYTES // (1024 * 1024)} MiB; refused")
        with open(path, "rb") as handle:
            return handle.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DraftError(f"cannot read file: {exc.strerror}") from None


def kind_of(path: Path, head: bytes) -> str:
    suffix = path.suffix.lower()
    if head.startswith(b"%PDF") or suffix == ".pdf":
        return "pdf"
    if head.startswith(b"PK") or suffix in (".xlsx", ".xlsm", ".docx"):
        try:
            with zipfile.ZipFile(io.BytesIO(head)) as z:
                names = set(z.namelist())
        except (zipfile.BadZipFile, OSError, ValueError):
            raise DraftError(f"not a readable {suffix.lstrip('.') or 'zip'} file (corrupt archive)") from None
        if "word/document.xml" in names:
            return "docx"
        if "xl/workbook.xml" in names:
            return "xlsx"
        raise DraftError("a zip archive that is neither a Word (.docx) nor an Excel (.xlsx) document")
    if suffix in (".xls", ".doc"):
        raise DraftError(f"the old binary {suffix} format is not supported: save it as {suffix}x")
    if suffix in (".csv", ".tsv"):
        return "csv"
    if suffix in (".html", ".htm"):
        return "html"
    return "text"


def _decode(data: bytes) -> str:
    if b"\x00" in data[:4096] and not data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise DraftError("a binary file, not a document drivemap reads (PDF, DOCX, XLSX, CSV, text)")
    for encoding in ("utf-8-sig", "utf-16"):
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    return data.decode("latin-1")


def read_csv(text: str) -> list[Table]:
    sample = text[:20000]
    try:
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(sample, delimiters=",;\t|")
    except csv.Error:
        dialect = csv.excel
    rows = [Row([c.strip() for c in r], None, i, table="CSV")
            for i, r in enumerate(csv.reader(io.StringIO(text), dialect), 1) if any(c.strip() for c in r)]
    return [Table(None, rows, None, 1, "", label="CSV")]


def _cell_text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value).strip()


def read_xlsx(path: Path) -> tuple[list[Table], str, list[str]]:
    import openpyxl

    try:
        book = openpyxl.load_workbook(path, data_only=True)
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        raise DraftError(f"cannot read the workbook: {type(exc).__name__}: {exc}") from None
    tables, texts, notes = [], [], []
    for sheet in book.worksheets:
        grid = [[_cell_text(c) for c in row[:MAX_SHEET_COLS]] for row in sheet.iter_rows(max_row=MAX_SHEET_ROWS, values_only=True)]
        merged = list(sheet.merged_cells.ranges)
        for rng in merged:
            top = grid[rng.min_row - 1][rng.min_col - 1] if rng.min_row - 1 < len(grid) and rng.min_col - 1 < len(grid[rng.min_row - 1]) else ""
            for r in range(rng.min_row - 1, min(rng.max_row, len(grid))):
                for c in range(rng.min_col - 1, min(rng.max_col, len(grid[r]))):
                    grid[r][c] = top
        if merged:
            notes.append(f"sheet {sheet.title}: {len(merged)} merged cell ranges: each cell reads the merged value")
        if sheet.max_row > MAX_SHEET_ROWS:
            notes.append(f"sheet {sheet.title}: only the first {MAX_SHEET_ROWS} rows read")
        rows = [Row(r, None, i, table=f"sheet {sheet.title}") for i, r in enumerate(grid, 1) if any(r)]
        tables.append(Table(None, rows, None, 1, sheet.title, label=f"sheet {sheet.title}"))
        texts.append("\n".join(" ".join(r.cells) for r in rows))
    return tables, "\n".join(texts), notes


def read_docx(path: Path) -> tuple[list[Table], str]:
    import docx
    from docx.table import Table as DocxTable
    from docx.text.paragraph import Paragraph

    try:
        document = docx.Document(str(path))
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        raise DraftError(f"cannot read the Word document: {type(exc).__name__}: {exc}") from None
    tables: list[Table] = []
    recent: list[str] = []
    texts: list[str] = []
    for child in document.element.body.iterchildren():
        tag = child.tag.rsplit("}", 1)[-1]
        if tag == "p":
            text = Paragraph(child, document).text.strip()
            if text:
                recent = (recent + [text])[-8:]
                texts.append(text)
        elif tag == "tbl":
            table = DocxTable(child, document)
            n = len(tables) + 1
            rows = [Row([cell.text.strip() for cell in row.cells], None, i, table=f"table {n}")
                    for i, row in enumerate(table.rows, 1)]
            headed = _continued(tables, rows, recent)
            if headed is not None:  # a table without a header right after one with it, as wide: it goes on
                headed.rows.extend(rows)
                tables.append(Table(None, [], None, None, "", label=f"table {n}"))
            else:
                tables.append(Table(None, rows, None, None, "\n".join(recent), label=f"table {n}"))
            texts.extend(" ".join(r.cells) for r in rows)
            recent = []
    return tables, "\n".join(texts)


def _continued(tables: list[Table], rows: list[Row], recent: list[str]) -> Table | None:
    """The table a headerless DOCX table goes on from: the last table with a header, when no text stands
    between them and its rows are as wide (a table broken where the document's pages break)."""
    from drivemap.onboard.draft.columns import find_layouts

    if recent or not rows or not tables or find_layouts([r.cells for r in rows]):
        return None
    for prev in reversed(tables):
        if not prev.rows:
            continue  # a table already joined to the one before it
        if find_layouts([r.cells for r in prev.rows]) and {len(r.cells) for r in rows} <= {len(r.cells) for r in prev.rows}:
            return prev
        return None
    return None


def read_document(path: Path, pages: tuple[int, int] | None = None, max_pages: int = 400,
                  seconds: float = 120.0) -> Source:
    """The tables and text of ``path``."""
    data = _bytes(path)
    sha = hashlib.sha256(data).hexdigest()
    kind = kind_of(path, data)
    notes: list[str] = []
    if kind == "pdf":
        from drivemap.onboard.draft.read_pdf import read_pdf

        tables, text, count, notes = read_pdf(path, pages, max_pages, seconds)
        return Source(path.name, sha, tables, text, count, notes)
    if kind == "xlsx":
        tables, text, notes = read_xlsx(path)
    elif kind == "docx":
        tables, text = read_docx(path)
    elif kind == "csv":
        text = _decode(data)
        tables = read_csv(text)
    else:
        text = _decode(data)
        tables = read_text(text, is_html=kind == "html")
    if pages is not None and kind != "pdf":
        notes.append("--pages applies to PDF documents only: the whole document was read")
    return Source(path.name, sha, tables, text, 0, notes)
