"""``drivemap read MODEL [NAME...|--group G|--all]``: one planned set of requests, shown by name."""

from __future__ import annotations

import argparse
import sys

from drivemap.device.connection import add_connection_arguments
from drivemap.device.errors import EXIT_INPUT, EXIT_OK, LiveError, epilog, verb
from drivemap.device.target import load_target, project_of
from drivemap.live.fmt import Row, console, rows_of, table, to_csv, to_json
from drivemap.live.pages import Cell, current_pages, on_shown_page, restore, selectors
from drivemap.live.selection import add_selection_arguments, positionals, select_cells
from drivemap.live.session import Session, describe_keys, keys_of, session_for


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("read", help="read registers of a live device by name (table, --json, --csv)",
                       description="Read registers of a live device in the fewest requests the map allows.",
                       epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", metavar="MODEL|PATH")
    add_selection_arguments(p)
    out = p.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="print JSON")
    out.add_argument("--csv", action="store_true", help="print CSV")
    add_connection_arguments(p)
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    p.set_defaults(func=cmd_read)


@verb("read")
def cmd_read(args: argparse.Namespace) -> int:
    target = load_target(args.model, project_of(args.maps))
    names = positionals(args, "names")
    cells = select_cells(target, names, args.group, args.all)
    if not cells:
        raise LiveError(EXIT_INPUT, "nothing readable selected")
    with session_for(args, target) as session:
        rows, skipped = read_rows(session, cells, explicit=bool(names))
        stats = session.bus.stats if session.bus else None
    if args.json:
        extra = {"unit": session.link.unit, "link": session.link.line(),
                 "requests": stats.transactions if stats else 0}
        print(to_json(target, rows, extra))
    elif args.csv:
        sys.stdout.write(to_csv(target, rows))
    else:
        out = console()
        title = f"{target.model.name} {session.link.describe()}"
        out.print(table(target, rows, title=title))
        requests = stats.transactions if stats else 0
        out.print(f"{len(rows)} values in {requests} request{'s' if requests != 1 else ''}")
    if skipped:
        print(f"skipped {len(skipped)} registers on pages not shown now "
              f"({describe_keys(target, keys_of(skipped))}); --switch-pages reads them", file=sys.stderr)
    return EXIT_OK


def read_rows(session: Session, cells: list[Cell], *, explicit: bool) -> tuple[list[Row], list[Cell]]:
    """Read ``cells`` (one planned set); cells on pages not shown are skipped unless --switch-pages."""
    target = session.target
    names = selectors(cells)
    saved = current_pages(session, names)
    skipped: list[Cell] = []
    if session.page_policy == "raise":
        cells, skipped = on_shown_page(cells, saved)
        if skipped and explicit:
            reg, _ = skipped[0]
            assert reg.page is not None
            raise LiveError(EXIT_INPUT, f"{reg.name} is on page {reg.page.value} of {reg.page.selector}, which shows "
                                        f"{saved.get(reg.page.selector)} now; --switch-pages selects it")
    keys = keys_of(cells)
    raws = session.call(f"reading {describe_keys(target, keys)}", session.read_keys, keys) if keys else {}
    restore(session, saved)
    return rows_of(target, cells, raws), skipped
