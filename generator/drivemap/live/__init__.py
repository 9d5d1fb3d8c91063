"""At the drive: ``read``, ``write``, ``watch``, ``scan`` and ``verify`` against a live device, by name.

Each verb is one module; :mod:`.connection` holds the shared connection options (defaults from
the map) and turns failures into one actionable line with a documented exit code
(:mod:`.errors`); :mod:`.fmt` shows values; :mod:`.values` parses engineering values.
"""

from __future__ import annotations

import argparse


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register the live verbs on the ``drivemap`` command's sub-parsers."""
    from drivemap.live import read, scan, verify, watch, write

    for module in (read, write, watch, scan, verify):
        module.add_parser(sub)
