"""Paged registers at the drive: which page each selector shows, and putting it back afterwards."""

from __future__ import annotations

from collections.abc import Sequence

from drivemap.live.session import Session
from drivemap.model.nodes import Register

Cell = tuple[Register, int]


def selectors(cells: Sequence[Cell]) -> list[str]:
    return sorted({reg.page.selector for reg, _ in cells if reg.page is not None})


def current_pages(session: Session, names: Sequence[str]) -> dict[str, int]:
    """The raw value each selector shows now (one planned read)."""
    if not names:
        return {}
    keys = [(name, 0) for name in names if session.target.model.register(name).readable]
    raws = session.call("reading the page selectors", session.read_keys, keys) if keys else {}
    return {name: raws[(name, 0)] for name in names if (name, 0) in raws}


def on_shown_page(cells: Sequence[Cell], pages: dict[str, int]) -> tuple[list[Cell], list[Cell]]:
    """(cells readable without switching a page, cells on another page)."""
    here: list[Cell] = []
    elsewhere: list[Cell] = []
    for reg, index in cells:
        page = reg.page
        if page is None or pages.get(page.selector) == page.value:
            here.append((reg, index))
        else:
            elsewhere.append((reg, index))
    return here, elsewhere


def restore(session: Session, saved: dict[str, int]) -> None:
    """Write each selector back to the page it showed before (only those that changed)."""
    for name, raw in saved.items():
        if session.core.pages.get(name, raw) != raw:
            reg = session.target.model.register(name)
            session.call(f"restoring {name}", session.client._drivemap.write_raw_items, [((reg.name, 0), raw)])
