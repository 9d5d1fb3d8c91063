"""Which register elements a read or watch asks for: names, ``--group``, ``--all`` (the default)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from drivemap.device.errors import EXIT_INPUT, LiveError
from drivemap.device.target import Target, locate_error
from drivemap.live.values import lookup
from drivemap.model.nodes import Register

Cell = tuple[Register, int]


def add_selection_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME", help="registers or elements (digital_speed[0]); default: all")
    parser.add_argument("--group", action="append", default=None, metavar="G", help="every register of a group (repeatable)")
    parser.add_argument("--all", action="store_true", help="every readable register (the default)")
    parser.add_argument("--switch-pages", action="store_true",
                        help="write page selectors as needed to reach paged registers (default: refuse)")
    parser.set_defaults(takes_rest=True)


def positionals(args: argparse.Namespace, attribute: str) -> list[str]:
    """Positional words given before and after the options (argparse leaves the later ones over)."""
    rest = list(getattr(args, "rest", []) or [])
    unknown = [word for word in rest if word.startswith("-") and not _negative_number(word)]
    if unknown:
        raise LiveError(EXIT_INPUT, f"unrecognized arguments: {' '.join(unknown)} (see --help)")
    return [*getattr(args, attribute), *rest]


def _negative_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def select_cells(target: Target, names: Sequence[str], groups: Sequence[str] | None, everything: bool) -> list[Cell]:
    """The readable cells asked for, in map order for groups/all, in the given order for names."""
    cells: list[Cell] = []
    for name in names:
        reg, index = lookup(target, name, name)
        if not reg.readable:
            raise locate_error(name, f"{reg.name} is write-only", target, reg)
        cells.extend((reg, i) for i in ([index] if index is not None else range(reg.count)))
    known = {g.name for g in target.model.groups}
    for group in groups or ():
        if group not in known:
            raise locate_error(group, f"{target.model.name} has no group {group!r} (groups: {', '.join(sorted(known))})")
        cells.extend((r, i) for r in target.model.group_registers(group) if r.readable for i in range(r.count))
    if everything or (not names and not groups):
        cells.extend((r, i) for r in target.model.registers if r.readable for i in range(r.count))
    seen: set[tuple[str, int]] = set()
    unique = []
    for reg, index in cells:
        if (reg.name, index) not in seen:
            seen.add((reg.name, index))
            unique.append((reg, index))
    return unique
