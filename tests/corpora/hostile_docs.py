"""Hostile documents for ``drivemap draft``, made on the spot (small on disk, huge when read).

* :func:`docx_bomb` / :func:`xlsx_bomb`: a Word or Excel archive one of whose members inflates to
  ``inflated`` bytes (a deflate stream of a repeated, fully flushed chunk: a few hundred KB on disk);
  ``lie=True`` writes a small size in the headers (the bound must hold while inflating too);
* :func:`xlsx_rows`: a workbook of ``rows`` rows (the sheet part streamed the same way);
* :func:`pdf_pages`: a PDF of ``pages`` pages, a ruled register table each (``broken=True``: a page
  tree without pages); :func:`pdf_content_bomb`: a page whose content stream inflates to 1 GiB;
* :func:`csv_rows`: a CSV register list of ``rows`` rows; :func:`csv_long_cell`: one cell past the csv
  module's field limit.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

_DOCX_TYPES = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
               b'<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
               b'<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
               b'<Default Extension="xml" ContentType="application/xml"/>'
               b'<Override PartName="/word/document.xml" ContentType="application/vnd.openxmlformats-officedocument.'
               b'wordprocessingml.document.main+xml"/></Types>')
_DOCX_RELS = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
              b'<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
              b'<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/'
              b'officeDocument" Target="word/document.xml"/></Relationships>')
_W = b'xmlns:w="http://schemas.openxmlformats.org/wordprocessingml/2006/main"'
_XLSX_TYPES = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
               b'<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
               b'<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
               b'<Default Extension="xml" ContentType="application/xml"/>'
               b'<Override PartName="/xl/workbook.xml" ContentType="application/vnd.openxmlformats-officedocument.'
               b'spreadsheetml.sheet.main+xml"/>'
               b'<Override PartName="/xl/worksheets/sheet1.xml" ContentType="application/vnd.openxmlformats-'
               b'officedocument.spreadsheetml.worksheet+xml"/></Types>')
_XLSX_RELS = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
              b'<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
              b'<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/'
              b'officeDocument" Target="xl/workbook.xml"/></Relationships>')
_S = b'xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"'
_R = b'xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"'
_WORKBOOK = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?><workbook ' + _S + b' ' + _R
             + b'><sheets><sheet name="Registers" sheetId="1" r:id="rId1"/></sheets></workbook>')
_WORKBOOK_RELS = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
                  b'<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
                  b'<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/'
                  b'relationships/worksheet" Target="worksheets/sheet1.xml"/></Relationships>')


class _Member:
    """A zip member: raw deflate bytes, its CRC and sizes (the sizes as the headers state them)."""

    def __init__(self, name: str, head: bytes, chunk: bytes, repeat: int, tail: bytes, *, lie: bool = False) -> None:
        co = zlib.compressobj(9, zlib.DEFLATED, -15)
        first = co.compress(head) + co.flush(zlib.Z_FULL_FLUSH)
        body = co.compress(chunk) + co.flush(zlib.Z_FULL_FLUSH)  # after a full flush: the same bytes each time
        last = co.compress(tail) + co.flush()
        self.name = name.encode()
        self.data = first + body * repeat + last
        crc = zlib.crc32(head)
        for _ in range(repeat):
            crc = zlib.crc32(chunk, crc)
        self.crc = zlib.crc32(tail, crc)
        size = len(head) + len(chunk) * repeat + len(tail)
        self.size = min(size, 4096) if lie else size


def _plain(name: str, data: bytes) -> _Member:
    return _Member(name, data, b"", 0, b"")


def _zip(path: Path, members: list[_Member]) -> Path:
    out = bytearray()
    central = bytearray()
    for m in members:
        offset = len(out)
        out += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0x21, m.crc, len(m.data), m.size, len(m.name), 0)
        out += m.name + m.data
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0x21, m.crc, len(m.data), m.size,
                               len(m.name), 0, 0, 0, 0, 0, offset)
        central += m.name
    start = len(out)
    out += central
    out += struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(members), len(members), len(central), start, 0)
    path.write_bytes(bytes(out))
    return path


def docx_bomb(path: Path, inflated: int = 1 << 30, *, lie: bool = False) -> Path:
    """A DOCX whose ``word/document.xml`` inflates to about ``inflated`` bytes (a paragraph repeated)."""
    chunk = b"<w:p><w:r><w:t>" + b"x" * 65000 + b"</w:t></w:r></w:p>"
    head = b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?><w:document ' + _W + b"><w:body>"
    body = _Member("word/document.xml", head, chunk, max(1, inflated // len(chunk)), b"</w:body></w:document>", lie=lie)
    return _zip(path, [_plain("[Content_Types].xml", _DOCX_TYPES), _plain("_rels/.rels", _DOCX_RELS), body])


def _xlsx(path: Path, sheet: _Member) -> Path:
    return _zip(path, [_plain("[Content_Types].xml", _XLSX_TYPES), _plain("_rels/.rels", _XLSX_RELS),
                       _plain("xl/workbook.xml", _WORKBOOK), _plain("xl/_rels/workbook.xml.rels", _WORKBOOK_RELS), sheet])


def xlsx_rows(path: Path, rows: int, *, lie: bool = False) -> Path:
    """A workbook whose one sheet holds ``rows`` register rows (a header, then the same row again)."""
    head = (b'<?xml version="1.0" encoding="UTF-8" standalone="yes"?><worksheet ' + _S + b"><sheetData>"
            b'<row><c t="inlineStr"><is><t>Address</t></is></c><c t="inlineStr"><is><t>Name</t></is></c></row>')
    row = b'<row><c><v>40001</v></c><c t="inlineStr"><is><t>Voltage</t></is></c></row>'
    per = 1000
    sheet = _Member("xl/worksheets/sheet1.xml", head, row * per, max(1, rows // per), b"</sheetData></worksheet>",
                    lie=lie)
    return _xlsx(path, sheet)


def xlsx_bomb(path: Path, inflated: int = 1 << 30, *, lie: bool = False) -> Path:
    """A workbook whose sheet part inflates to about ``inflated`` bytes."""
    return xlsx_rows(path, inflated // 75, lie=lie)


def _ruled_table(page: int, rows: int) -> bytes:
    """A page's content: a title and a ruled register table of ``rows`` rows under a header."""
    xs = [60, 140, 330, 420, 540]
    top, height = 700, 20
    ops = [f"BT /F1 12 Tf 60 740 Td (Register map, page {page}) Tj ET", "0.5 w"]
    for k in range(rows + 2):
        ops.append(f"{xs[0]} {top - k * height} m {xs[-1]} {top - k * height} l S")
    for x in xs:
        ops.append(f"{x} {top} m {x} {top - (rows + 1) * height} l S")
    cells = [("Address", "Name", "Unit", "Scale")] + [
        (f"{40001 + (page * rows + k) % 9000}", f"Value {page}.{k}", "V", "0.1") for k in range(rows)]
    for k, row in enumerate(cells):
        y = top - k * height - 14
        for x, text in zip(xs, row, strict=False):
            ops.append(f"BT /F1 10 Tf {x + 4} {y} Td ({text}) Tj ET")
    return "\n".join(ops).encode()


def pdf_pages(path: Path, pages: int, *, rows: int = 25, broken: bool = False) -> Path:
    """A PDF of ``pages`` pages, each a ruled register table (``broken``: a page tree without pages)."""
    objects: list[bytes] = [b"", b""]  # 1: catalog, 2: pages (filled in below)
    objects.append(b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica >>")  # 3
    kids = []
    for n in range(1, pages + 1):
        text = _ruled_table(n, rows)
        objects.append(b"<< /Length %d >>\nstream\n" % len(text) + text + b"\nendstream")
        objects.append(b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 612 792] /Contents %d 0 R "
                       b"/Resources << /Font << /F1 3 0 R >> >> >>" % (len(objects)))
        kids.append(b"%d 0 R" % len(objects))
    objects[0] = b"<< /Type /Catalog /Pages 2 0 R >>"
    objects[1] = (b"<< /Type /Pages /Count 0 /Kids [] >>" if broken
                  else b"<< /Type /Pages /Count %d /Kids [%s] >>" % (pages, b" ".join(kids)))
    if broken:  # no object says /Type /Page either: nothing to fall back on
        objects = [o.replace(b"/Type /Page ", b"/Type /Leaf ") for o in objects]
    return _pdf(path, objects)


def pdf_content_bomb(path: Path, inflated: int = 1 << 30) -> Path:
    """A one-page PDF whose content stream (FlateDecode) inflates to about ``inflated`` bytes."""
    co = zlib.compressobj(9, zlib.DEFLATED, 15)
    chunk = b" " * 65536
    first = co.compress(b"BT /F1 11 Tf 72 720 Td (40001 Voltage V) Tj ET\n") + co.flush(zlib.Z_FULL_FLUSH)
    body = co.compress(chunk) + co.flush(zlib.Z_FULL_FLUSH)
    data = first + body * (inflated // len(chunk)) + co.flush()
    objects = [b"<< /Type /Catalog /Pages 2 0 R >>", b"<< /Type /Pages /Count 1 /Kids [4 0 R] >>",
               b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica >>",
               b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 612 792] /Contents 5 0 R "
               b"/Resources << /Font << /F1 3 0 R >> >> >>",
               b"<< /Length %d /Filter /FlateDecode >>\nstream\n" % len(data) + data + b"\nendstream"]
    return _pdf(path, objects)


def _pdf(path: Path, objects: list[bytes]) -> Path:
    out = bytearray(b"%PDF-1.4\n")
    offsets = []
    for k, body in enumerate(objects, 1):
        offsets.append(len(out))
        out += b"%d 0 obj\n" % k + body + b"\nendobj\n"
    xref = len(out)
    out += b"xref\n0 %d\n0000000000 65535 f \n" % (len(objects) + 1)
    out += b"".join(b"%010d 00000 n \n" % o for o in offsets)
    out += b"trailer\n<< /Size %d /Root 1 0 R >>\nstartxref\n%d\n%%%%EOF\n" % (len(objects) + 1, xref)
    path.write_bytes(bytes(out))
    return path


def csv_rows(path: Path, rows: int) -> Path:
    """A CSV register list of ``rows`` rows."""
    lines = ["Address,Name,Type,Unit,Scale"] + [f"{40001 + k % 60000},reg_{k},uint16,V,0.1" for k in range(rows)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def csv_long_cell(path: Path, length: int = 131_073) -> Path:
    """A CSV whose third line holds a cell longer than the csv module's field limit (131,072)."""
    path.write_text("Address,Name\n40001,Voltage\n40002,\"" + "x" * length + "\"\n", encoding="utf-8")
    return path
