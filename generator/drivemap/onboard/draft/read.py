"""Read a document of any supported format into a :class:`~.tables.Source` (bounded in size).

PDF (:mod:`.read_pdf`), DOCX (python-docx), XLSX (openpyxl, read-only streaming mode), CSV/TSV, and
text: plain or OCR text, Markdown, HTML (:mod:`.read_text`). A file that cannot be read raises
:class:`~.tables.DraftError` with a one-line reason (:class:`DocumentError` when it has a place).

Bounds (docs/limits.md): the file (:data:`MAX_BYTES`); a DOCX or XLSX archive's members, checked
before a parser sees them - their number, each member's inflated size and the sum, both as the
central directory declares them and as they really inflate (:func:`check_archive`), so a deflate bomb
or a lying header is refused; the rows of a sheet or CSV table (:data:`MAX_ROWS`, counted while
reading); the columns of a sheet.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import re
import stat
import unittest.mock
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from drivemap.onboard.draft.read_text import read_text
from drivemap.onboard.draft.tables import DraftError, Row, Source, Table

MAX_BYTES = 200 * 1024 * 1024
#: Rows of a sheet or of a CSV table (a register list has fewer; counted while reading).
MAX_ROWS = 20000
MAX_SHEET_ROWS = MAX_ROWS
MAX_SHEET_COLS = 60
#: Members of a DOCX/XLSX archive; the inflated size of one XML part (what the parsers build trees of;
#: the largest of the corpus is 3.5 MB); of another member (media: at most ten times its compressed size,
#: or the XML bound); and of all members together.
MAX_MEMBERS = 2000
MAX_MEMBER_BYTES = 32 * 1024 * 1024
MAX_INFLATED_BYTES = 256 * 1024 * 1024
_XML_PARTS = (".xml", ".rels", ".vml")
_CHUNK = 1 << 20
_MIB = 1024 * 1024


class DocumentError(DraftError):
    """A :class:`DraftError` at a place of the document: printed as ``file:line:column: error: message``."""

    def __init__(self, message: str, line: int, column: int = 1) -> None:
        super().__init__(message)
        self.line = line
        self.column = column


class TimeLimit(BaseException):
    """The run took longer than ``--timeout``: raised by the alarm, a BaseException so that no library's
    ``except Exception`` swallows or wraps it (pdfplumber wraps what its page walk raises)."""


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


def check_archive(z: zipfile.ZipFile) -> None:
    """Refuse an archive whose members would inflate past the bounds: first as its central directory
    declares them, then as they really inflate (read in chunks and dropped: a header that lies about a
    member's size does not beat the bound)."""
    infos = z.infolist()
    if len(infos) > MAX_MEMBERS:
        raise DraftError(f"an archive of {len(infos):,} members (at most {MAX_MEMBERS:,}); refused")
    declared = 0
    for info in infos:
        declared += info.file_size
        if info.file_size > _member_cap(info):
            raise DraftError(f"archive member {info.filename} inflates to {info.file_size / _MIB:,.0f} MiB (at most "
                             f"{_member_cap(info) // _MIB} MiB a member): refused{_bomb(info)}")
    if declared > MAX_INFLATED_BYTES:
        raise DraftError(f"the archive inflates to {declared / _MIB:,.0f} MiB (at most {MAX_INFLATED_BYTES // _MIB} "
                         "MiB); refused")
    total = 0
    for info in infos:
        size = 0
        try:
            with z.open(info) as member:
                while chunk := member.read(_CHUNK):
                    size += len(chunk)
                    total += len(chunk)
                    if size > _member_cap(info) or total > MAX_INFLATED_BYTES:
                        raise DraftError(f"archive member {info.filename} inflates past "
                                         f"{min(size, total) // _MIB} MiB though its header says "
                                         f"{info.file_size:,} bytes; refused: a deflate bomb?")
        except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError, OSError, ValueError) as exc:
            raise DraftError(f"not a readable archive: member {info.filename}: {exc}") from None
        except RuntimeError as exc:  # an encrypted member
            raise DraftError(f"archive member {info.filename}: {exc}") from None


def _member_cap(info: zipfile.ZipInfo) -> int:
    if info.filename.lower().endswith(_XML_PARTS):
        return MAX_MEMBER_BYTES
    return max(MAX_MEMBER_BYTES, 10 * info.compress_size)


def _bomb(info: zipfile.ZipInfo) -> str:
    ratio = info.file_size / max(info.compress_size, 1)
    return f" (from {info.compress_size:,} bytes: a deflate bomb?)" if ratio > 100 else ""


def kind_of(path: Path, head: bytes) -> str:
    suffix = path.suffix.lower()
    if head.startswith(b"%PDF") or suffix == ".pdf":
        return "pdf"
    if head.startswith(b"PK") or suffix in (".xlsx", ".xlsm", ".docx"):
        try:
            with zipfile.ZipFile(io.BytesIO(head)) as z:
                names = set(z.namelist())
                if "word/document.xml" in names or "xl/workbook.xml" in names:
                    check_archive(z)
        except (zipfile.BadZipFile, OSError, ValueError, EOFError):
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
    """The rows of a CSV/TSV text, at most :data:`MAX_ROWS` (a longer table is refused at the row past it);
    a cell longer than the csv module's field limit (131,072 characters) is refused at its line."""
    sample = text[:20000]
    try:
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(sample, delimiters=",;\t|")
    except csv.Error:
        dialect = csv.excel
    reader = csv.reader(io.StringIO(text), dialect)
    rows: list[Row] = []
    try:
        for i, r in enumerate(reader, 1):
            if any(c.strip() for c in r):
                if len(rows) == MAX_ROWS:
                    raise DocumentError(f"more than {MAX_ROWS:,} rows: refused (a register table has fewer; "
                                        "keep the register rows)", reader.line_num)
                rows.append(Row([c.strip() for c in r], None, i, table="CSV"))
    except csv.Error as exc:
        limit = csv.field_size_limit()
        reason = f"a cell longer than {limit:,} characters" if "field larger" in str(exc) else f"not CSV ({exc})"
        raise DocumentError(f"{reason}: refused", reader.line_num) from None
    return [Table(None, rows, None, 1, "", label="CSV")]


def _cell_text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value).strip()


_MERGE = re.compile(rb'<(?:[\w.-]+:)?mergeCell\b[^>]*?\bref="([A-Z]{1,3}[0-9]{1,7}(?::[A-Z]{1,3}[0-9]{1,7})?)"')


def _merged_refs(source: IO[bytes]) -> Iterator[str]:
    """The ``ref`` of every ``mergeCell`` of a worksheet part, read in chunks (the part is never whole in memory)."""
    tail = b""
    while chunk := source.read(_CHUNK):
        buf = tail + chunk
        end = 0
        for m in _MERGE.finditer(buf):
            end = m.end()
            yield m.group(1).decode("ascii")
        tail = buf[max(end, len(buf) - 512):]


def _sheet_grid(sheet: Any) -> tuple[list[list[str]], bool]:
    """The first :data:`MAX_SHEET_ROWS` rows of a read-only sheet (reading stops there), and whether a
    row past them holds something."""
    grid: list[list[str]] = []
    for k, row in enumerate(sheet.iter_rows(max_row=MAX_SHEET_ROWS + 1, max_col=MAX_SHEET_COLS, values_only=True), 1):
        cells = [_cell_text(c) for c in row]
        if k > MAX_SHEET_ROWS:
            return grid, any(cells)
        grid.append(cells)
    return grid, False


def _fill_merged(sheet: Any, grid: list[list[str]]) -> int:
    """Each cell of a merged range reads the range's value; the number of ranges."""
    from openpyxl.utils.cell import range_boundaries

    count = 0
    with sheet._get_source() as source:  # the worksheet part (read-only sheets keep no merged ranges)
        for ref in _merged_refs(source):
            count += 1
            min_col, min_row, max_col, max_row = range_boundaries(ref)
            if min_row - 1 >= len(grid):
                continue
            first = grid[min_row - 1]
            top = first[min_col - 1] if min_col - 1 < len(first) else ""
            for r in range(min_row - 1, min(max_row, len(grid))):
                for c in range(min_col - 1, min(max_col, len(grid[r]))):
                    grid[r][c] = top
    return count


def _unsized(_sheet: Any) -> None:
    """openpyxl sizes a read-only sheet without ``<dimension>`` by parsing all of it; the rows are read
    with max_row/max_col given, so the size is never needed."""


def read_xlsx(path: Path, sheet_name: str | None = None) -> tuple[list[Table], str, list[str]]:
    """Every sheet of a workbook as a table (``sheet_name``: that sheet only; a name the workbook does not
    have is refused, naming the sheets it has)."""
    import openpyxl
    from openpyxl.worksheet._read_only import ReadOnlyWorksheet

    try:
        with unittest.mock.patch.object(ReadOnlyWorksheet, "_get_size", _unsized):
            book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # noqa: BLE001 - any failure of the parser on a bad file is the file's
        raise DraftError(f"cannot read the workbook: {type(exc).__name__}: {exc}") from None
    tables, texts, notes = [], [], []
    try:
        sheets = book.worksheets
        if sheet_name is not None:
            sheets = [s for s in sheets if s.title == sheet_name]
            if not sheets:
                names = ", ".join(repr(s.title) for s in book.worksheets)
                raise DraftError(f"--sheet {sheet_name!r}: the workbook has no such sheet (its sheets: {names})")
            notes.append(f"--sheet {sheet_name!r}: only that sheet was read "
                         f"({len(book.worksheets) - 1} other sheet{'s' if len(book.worksheets) != 2 else ''} left out)")
        for sheet in sheets:
            try:
                grid, more = _sheet_grid(sheet)
                merged = _fill_merged(sheet, grid)
            except DocumentError:
                raise
            except Exception as exc:  # noqa: BLE001 - a broken sheet part is the file's
                raise DraftError(f"sheet {sheet.title}: cannot read it: {type(exc).__name__}: {exc}") from None
            if more:
                raise DocumentError(f"sheet {sheet.title}: more than {MAX_SHEET_ROWS:,} rows: refused (a register "
                                    "table has fewer; keep the register rows)", MAX_SHEET_ROWS + 1)
            if merged:
                notes.append(f"sheet {sheet.title}: {merged} merged cell ranges: each cell reads the merged value")
            rows = [Row(r, None, i, table=f"sheet {sheet.title}") for i, r in enumerate(grid, 1) if any(r)]
            tables.append(Table(None, rows, None, 1, sheet.title, label=f"sheet {sheet.title}"))
            texts.append("\n".join(" ".join(r.cells) for r in rows))
    finally:
        book.close()
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
                  seconds: float = 120.0, progress: Callable[[str], None] | None = None,
                  sheet: str | None = None) -> Source:
    """The tables and text of ``path`` (``progress`` is told what is being read: a PDF's pages;
    ``sheet``: a workbook's sheet to read alone)."""
    data = _bytes(path)
    sha = hashlib.sha256(data).hexdigest()
    kind = kind_of(path, data)
    notes: list[str] = []
    if kind == "pdf":
        from drivemap.onboard.draft.read_pdf import read_pdf

        tables, text, count, notes = read_pdf(path, pages, max_pages, seconds, progress)
        if sheet is not None:
            notes.append("--sheet applies to workbooks (XLSX) only: the whole document was read")
        return Source(path.name, sha, tables, text, count, notes)
    if kind == "xlsx":
        tables, text, notes = read_xlsx(path, sheet)
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
    if sheet is not None and kind != "xlsx":
        notes.append("--sheet applies to workbooks (XLSX) only: the whole document was read")
    return Source(path.name, sha, tables, text, 0, notes)
