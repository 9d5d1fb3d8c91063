"""The cells of a ruled PDF table put under the header they stand under on the page.

pdfplumber makes a grid column of every vertical line it finds, so a header cell and the cells below
it need not share a grid column: ``VariableName`` spans two grid columns while the names sit in the
second one; ``Register`` spans three, the addresses sit in the middle one; a type cell spans the
narrow empty header cells beside ``Data format``. A cell under no header text is moved to the header
cell it overlaps most on the page, when that cell of its row is empty. A headerless table on the next
page in the same frame (the table going on, drawn on a grid of its own) is laid out under the header
of the table it continues. Cells under header text are never moved: a grid that agrees with its
header reads as before.
"""

from __future__ import annotations

from dataclasses import dataclass

from drivemap.onboard.draft.columns import header_index

Box = tuple[float, float]
"""A cell's left and right edge on the page."""

FRAME_TOLERANCE = 4.0
"""Points two tables' left and right edges may differ by and still be one table across a page break."""


@dataclass
class Grid:
    """The header of a table as it stands on the page."""

    cells: list[tuple[int, Box, bool]]
    """(grid column, edges, holds text) of each header cell."""
    width: int
    frame: Box
    header: int
    """Index of the header row among the table's rows."""


def _overlap(a: Box, b: Box) -> float:
    return max(0.0, min(a[1], b[1]) - max(a[0], b[0]))


def _target(grid: Grid, box: Box, texts_only: bool = True) -> int | None:
    """The grid column of the header cell ``box`` overlaps most (header cells with text first)."""
    cells = [c for c in grid.cells if c[2] or not texts_only]
    best = max(cells, key=lambda c: _overlap(c[1], box), default=None)
    if best is None or _overlap(best[1], box) <= 0:
        return None
    return best[0]


def grid_of(texts: list[list[str]], boxes: list[list[Box | None]], frame: Box) -> Grid | None:
    """The header geometry of a table whose header row the column recognition finds."""
    index = header_index(texts)
    if index is None:
        return None
    cells = [(col, box, bool(texts[index][col])) for col, box in enumerate(boxes[index]) if box is not None]
    return Grid(cells, len(texts[index]), frame, index)


def realign(texts: list[list[str]], boxes: list[list[Box | None]], grid: Grid) -> None:
    """Move, in place, each cell below the header that stands under no header text."""
    header = texts[grid.header]
    for row, row_boxes in zip(texts[grid.header + 1:], boxes[grid.header + 1:], strict=True):
        for col, box in enumerate(row_boxes):
            if box is None or not row[col] or (col < len(header) and header[col]):
                continue
            target = _target(grid, box)
            if target is not None and target < len(row) and not row[target]:
                row[target], row[col] = row[col], ""


def same_frame(grid: Grid, frame: Box) -> bool:
    return abs(grid.frame[0] - frame[0]) <= FRAME_TOLERANCE and abs(grid.frame[1] - frame[1]) <= FRAME_TOLERANCE


def relay(texts: list[list[str]], boxes: list[list[Box | None]], grid: Grid) -> list[list[str]]:
    """Rows of a table on a grid of its own, laid out under ``grid``'s header cells (texts that fall
    under one header cell are joined; a text under none goes to the nearest one)."""
    out = []
    for row, row_boxes in zip(texts, boxes, strict=True):
        cells = [""] * grid.width
        for text, box in zip(row, row_boxes, strict=True):
            if not text or box is None:
                continue
            col = _target(grid, box)
            if col is None:
                col = _target(grid, box, texts_only=False)
            if col is None:
                middle = (box[0] + box[1]) / 2
                col = min(grid.cells, key=lambda c: abs((c[1][0] + c[1][1]) / 2 - middle))[0]
            cells[col] = f"{cells[col]} {text}".strip()
        out.append(cells)
    return out


def order_grid(boxes: list[list[Box | None]], grid: Grid) -> Grid | None:
    """Where ``grid``'s headings lie on a table drawn apart from it: its rows drawn with as many cells as
    the header has headings give, in order from the left, each heading's column (the median edges).
    None when no row has as many cells."""
    heads = sorted((c for c in grid.cells if c[2]), key=lambda c: c[1][0])
    full = [[b for b in row if b is not None] for row in boxes]
    full = [row for row in full if len(row) == len(heads) and all(a[1] <= b[0] + 1 for a, b in zip(row, row[1:], strict=False))]
    if not full:
        return None
    cells = []
    for i, (col, _, _) in enumerate(heads):
        lefts, rights = sorted(r[i][0] for r in full), sorted(r[i][1] for r in full)
        cells.append((col, (lefts[len(lefts) // 2], rights[len(rights) // 2]), True))
    return Grid(cells, grid.width, (cells[0][1][0], cells[-1][1][1]), 0)

