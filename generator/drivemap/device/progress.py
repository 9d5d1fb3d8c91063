"""A rich progress bar shown only where it can be drawn (the one place that knows rich's quirks)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from rich.progress import Progress

__all__ = ["shown"]


@contextlib.contextmanager
def shown(bar: Progress) -> Iterator[Progress]:
    """``bar`` started for the block when it is enabled (its console a terminal); a disabled bar is
    never started: rich 13.0 writes a newline when one stops, ahead of the verb's own output."""
    if bar.disable:
        yield bar
        return
    with bar:
        yield bar
