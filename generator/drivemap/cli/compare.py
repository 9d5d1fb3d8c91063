"""``drivemap compare A B``: for two maps of one device, the registers whose address, table, type, word
order, scale, unit or value set disagree (one line each; exit 0 either way, 1 for a map that does not
compile). A and B are map files or model ids of the project."""

from __future__ import annotations

import argparse
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location

__all__ = ["add_parser"]


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("compare", help="where two maps of one device disagree (address, table, type, word "
                                       "order, scale, unit, value set)", description=__doc__)
    p.add_argument("a", metavar="A", help="a map file or model id")
    p.add_argument("b", metavar="B", help="another map of the same device")
    p.set_defaults(func=cmd_compare)


def _path(token: str) -> Path:
    path = Path(token)
    if path.is_file():
        return path
    from drivemap.frontend.project import load_project

    found = load_project().find_map(token)
    if found is not None:
        return found
    raise CompileError([Diagnostic(Location(token, 1, 1), "no such map file or model id of the project")])


def cmd_compare(args: argparse.Namespace) -> int:
    from drivemap.compiler import compile_map
    from drivemap.onboard.compare import compare_models

    ma, mb = compile_map(_path(args.a)), compile_map(_path(args.b))
    diffs = compare_models(ma, mb)
    for diff in diffs:
        print(diff.line())
    print(f"{len(diffs)} disagreement{'' if len(diffs) == 1 else 's'} between {ma.name} ({len(ma.registers)} "
          f"registers) and {mb.name} ({len(mb.registers)} registers)")
    return 0
