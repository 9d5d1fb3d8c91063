"""``drivemap draft DOC --review review.html``: one static page to check a draft against its document.

Each table the draft read is shown beside the region of the page it came from (PDF: the page drawn as
an image, the rows it used outlined on it; other documents: the table's cells as read), every drafted
register links to its row, and every field left open and every skipped row is listed with its reason.
The page is self-contained (images inlined), so it can be mailed or attached to a review.

Geometry is found again on the page, by the row's text, rather than carried through the draft: a row
that cannot be found is still listed and linked, only without an outline (and the page says so).
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.onboard.draft.assemble import Draft
from drivemap.onboard.draft.tables import Row, Source

#: Pages drawn at most (a review of a 400-page manual lists the rest without images).
MAX_IMAGES = 60
RESOLUTION = 96
MARGIN = 24.0


@dataclass
class _Row:
    """One source row and what the draft made of it."""

    key: str
    row: Row
    registers: list[str] = field(default_factory=list)
    skipped: str | None = None
    box: tuple[float, float, float, float] | None = None
    """x0, top, x1, bottom in PDF points on ``row.page``."""

    @property
    def state(self) -> str:
        return "used" if self.registers else "skipped" if self.skipped is not None else "unused"


@dataclass
class _Table:
    label: str
    index: int
    header: list[str] | None
    rows: list[_Row]


def _norm(text: str) -> str:
    return re.sub(r"\s+", " ", text).strip().lower()


def _anchor(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-") or "x"


def _tables(source: Source, draft: Draft) -> tuple[list[_Table], dict[str, _Row]]:
    """The source's tables, their rows keyed by the place a draft names (``Row.where()``)."""
    tables: list[_Table] = []
    by_where: dict[str, _Row] = {}
    for k, t in enumerate(source.tables):
        rows = []
        for source_row in t.rows:
            where = source_row.where()
            entry = _Row(f"t{k}-{_anchor(where)}", source_row)
            rows.append(entry)
            by_where.setdefault(where, entry)
        tables.append(_Table(t.label or (f"p.{t.page}" if t.page else f"table {k + 1}"), k, t.header, rows))
    order = {id(r): (t.index, i) for t in tables for i, r in enumerate(t.rows)}

    def span(where: str) -> list[_Row]:
        first, _, last = where.partition(" .. ")
        a, b = by_where.get(first.strip()), by_where.get(last.strip()) if last else None
        if a is None:
            return []
        if b is None or order[id(a)][0] != order[id(b)][0]:
            return [a] if b is None else [a, b]
        t = tables[order[id(a)][0]]
        return t.rows[order[id(a)][1]:order[id(b)][1] + 1]

    for d in draft.registers:
        for r in span(d.where):
            r.registers.append(str(d.entry["name"]))
    for s in draft.skipped:
        for r in span(s.where):
            if r.skipped is None:
                r.skipped = s.reason
    return tables, by_where


def _locate(pdf: Any, rows: list[_Row]) -> None:
    """Find each PDF row on its page: a ruled table's row whose cells read the same, else a text line
    that holds the row's first cells."""
    pages: dict[int, list[_Row]] = defaultdict(list)
    for r in rows:
        if r.row.page is not None and 1 <= r.row.page <= len(pdf.pages):
            pages[r.row.page].append(r)
    for number, wanted in pages.items():
        page = pdf.pages[number - 1]
        cells: dict[str, tuple[float, float, float, float]] = {}
        for found in page.find_tables():
            for texts, row in zip(found.extract(), found.rows, strict=False):
                key = _norm(" ".join(c or "" for c in texts))
                cells.setdefault(key, tuple(row.bbox))
        lines = page.extract_text_lines() if hasattr(page, "extract_text_lines") else []
        for r in wanted:
            key = _norm(" ".join(r.row.cells))
            if key in cells:
                r.box = cells[key]
                continue
            parts = [_norm(c) for c in r.row.cells if c.strip()][:2]
            for line in lines:
                text = _norm(line["text"])
                if parts and all(p in text for p in parts):
                    r.box = (line["x0"], line["top"], line["x1"], line["bottom"])
                    break


def _figure(pdf: Any, number: int, rows: list[_Row]) -> str:
    """The region of page ``number`` that holds ``rows``, as an inlined image with the rows outlined."""
    page = pdf.pages[number - 1]
    boxes = [r.box for r in rows if r.box is not None]
    top = max(0.0, min(b[1] for b in boxes) - MARGIN * 3) if boxes else 0.0
    bottom = min(float(page.height), max(b[3] for b in boxes) + MARGIN) if boxes else float(page.height)
    region = page.crop((0, top, float(page.width), max(bottom, top + 1)))
    image = region.to_image(resolution=RESOLUTION).original
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    width, height = float(page.width), bottom - top
    marks = []
    for r in rows:
        if r.box is None:
            continue
        x0, t, x1, b = r.box
        style = (f"left:{100 * x0 / width:.3f}%;top:{100 * (t - top) / height:.3f}%;"
                 f"width:{100 * (x1 - x0) / width:.3f}%;height:{100 * (b - t) / height:.3f}%")
        title = html.escape(", ".join(r.registers) or (r.skipped or "not drafted"), quote=True)
        marks.append(f'<a class="mark {r.state}" id="mark-{r.key}" href="#row-{r.key}" style="{style}" '
                     f'title="{title}"></a>')
    return (f'<figure class="page"><div class="shot"><img alt="page {number}" '
            f'src="data:image/png;base64,{data}">{"".join(marks)}</div>'
            f"<figcaption>page {number}</figcaption></figure>")


def _cells_table(t: _Table) -> str:
    head = ""
    if t.header:
        head = "<thead><tr><th></th>" + "".join(f"<th>{html.escape(c)}</th>" for c in t.header) + "</tr></thead>"
    body = []
    for r in t.rows:
        what = ", ".join(f'<a href="#reg-{_anchor(n)}">{html.escape(n)}</a>' for n in r.registers)
        what = what or html.escape(r.skipped or "")
        cells = "".join(f"<td>{html.escape(c)}</td>" for c in r.row.cells)
        body.append(f'<tr class="{r.state}" id="row-{r.key}"><th>{html.escape(r.row.where())}</th>{cells}'
                    f'<td class="made">{what}</td></tr>')
    return f'<table class="cells">{head}<tbody>{"".join(body)}</tbody></table>'


CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;color:#222}
h1{font-size:1.4em}h2{font-size:1.15em;margin-top:2em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}
.pair{display:flex;gap:1.5em;align-items:flex-start;flex-wrap:wrap}.pair>*{flex:1 1 480px;min-width:0}
.shot{position:relative;display:inline-block;width:100%}.shot img{width:100%;display:block;border:1px solid #999}
.mark{position:absolute;box-sizing:border-box;border:2px solid}
.mark.used{border-color:#1a7f37;background:rgba(26,127,55,.12)}
.mark.skipped{border-color:#cf222e;background:rgba(207,34,46,.10)}.mark.unused{border-color:#9a6700}
tr.used{background:#e6f4ea}tr.skipped{background:#fde8e8}tr:target,.mark:target{outline:3px solid #0969da}
.open{color:#9a3412;font-weight:600}.note{color:#555}
"""


def render(document: Path, source: Source, draft: Draft, map_name: str) -> str:
    """The review page of ``draft`` (of ``document``, read as ``source``) written to ``map_name``."""
    tables, by_where = _tables(source, draft)
    drawn: dict[int, str] = {}
    unplaced = 0
    if _is_pdf(document):
        import pdfplumber

        with pdfplumber.open(str(document)) as pdf:
            shown = [r for t in tables for r in t.rows if r.state != "unused"]
            _locate(pdf, shown)
            unplaced = sum(1 for r in shown if r.box is None)
            pages = sorted({r.row.page for r in shown if r.row.page is not None})
            for number in pages[:MAX_IMAGES]:
                rows = [r for t in tables for r in t.rows if r.row.page == number]
                drawn[number] = _figure(pdf, number, rows)
    out = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Review: "
           f"{html.escape(map_name)}</title><style>{CSS}</style></head><body>",
           f"<h1>Review of the draft {html.escape(map_name)}</h1>",
           f"<p>Document <b>{html.escape(source.name)}</b> (sha256 <code>{source.sha256}</code>). "
           f"{len(draft.registers)} registers drafted from {len(draft.tables)} tables; "
           f"{len(draft.skipped)} rows skipped; "
           f"{sum(len(_open(d)) for d in draft.registers)} fields left open.</p>"]
    if unplaced:
        out.append(f"<p class='note'>{unplaced} rows could not be found again on their page: they are listed "
                   "below without an outline on the image.</p>")
    if len(drawn) < len({r.row.page for t in tables for r in t.rows if r.state != 'unused' and r.row.page}):
        out.append(f"<p class='note'>Only the first {MAX_IMAGES} pages are drawn.</p>")
    for note in source.notes:
        out.append(f"<p class='note'>note: {html.escape(note)}</p>")
    if draft.review:
        out.append("<h2 id='map-review'>To review in the whole map</h2><ul>"
                   + "".join(f"<li>{html.escape(x)}</li>" for x in draft.review) + "</ul>")
    out.append(_registers(draft, by_where))
    out.append(_skipped(draft, by_where))
    out.append("<h2 id='tables'>Tables and the pages they came from</h2>")
    for t in tables:
        if all(r.state == "unused" for r in t.rows):
            continue
        pages = sorted({r.row.page for r in t.rows if r.row.page in drawn})
        figures = "".join(drawn.pop(p) for p in pages if p in drawn)
        out.append(f"<section id='table-{t.index}'><h3>{html.escape(t.label)}</h3>"
                   f"<div class='pair'><div>{_cells_table(t)}</div>"
                   f"{f'<div>{figures}</div>' if figures else ''}</div></section>")
    out.append("</body></html>\n")
    return "\n".join(out)


def _is_pdf(path: Path) -> bool:
    try:
        with path.open("rb") as handle:
            return handle.read(5) == b"%PDF-"
    except OSError:
        return False


def _open(d: Any) -> list[str]:
    review = d.entry.get("review")
    listed = [str(x) for x in review] if isinstance(review, list) else []
    return list(dict.fromkeys([*listed, *d.missing]))


def _link(where: str, by_where: dict[str, _Row]) -> str:
    first = where.partition(" .. ")[0].strip()
    row = by_where.get(first)
    text = html.escape(where)
    return f'<a href="#row-{row.key}">{text}</a>' if row else text


def _registers(draft: Draft, by_where: dict[str, _Row]) -> str:
    rows = []
    for d in draft.registers:
        e = d.entry
        name = str(e["name"])
        address = e.get("address")
        shown = f"0x{int(str(address)):04X}" if isinstance(address, int) else html.escape(str(address))
        opened = _open(d)
        rows.append(
            f'<tr id="reg-{_anchor(name)}"><td>{html.escape(name)}</td><td>{html.escape(str(e.get("table", "")))}'
            f'</td><td>{shown}</td><td>{html.escape(str(e.get("type", "")))}</td>'
            f'<td>{html.escape(str(e.get("scale", "")))}</td><td>{html.escape(str(e.get("unit", "") or ""))}</td>'
            f'<td class="open">{html.escape(", ".join(opened))}</td><td>{_link(d.where, by_where)}</td></tr>')
    return ("<h2 id='registers'>Registers drafted</h2><table class='registers'><thead><tr><th>register</th>"
            "<th>table</th><th>address</th><th>type</th><th>scale</th><th>unit</th><th>open fields</th>"
            f"<th>source</th></tr></thead><tbody>{''.join(rows)}</tbody></table>")


def _skipped(draft: Draft, by_where: dict[str, _Row]) -> str:
    if not draft.skipped:
        return "<h2 id='skipped'>Rows skipped</h2><p>None.</p>"
    rows = [f"<tr class='skip'><td>{_link(s.where, by_where)}</td><td>{html.escape(s.reason)}</td>"
            f"<td>{html.escape(s.text[:200])}</td></tr>" for s in draft.skipped]
    return (f"<h2 id='skipped'>Rows skipped: {len(draft.skipped)}</h2><table><thead><tr><th>where</th>"
            f"<th>reason</th><th>row</th></tr></thead><tbody>{''.join(rows)}</tbody></table>")
