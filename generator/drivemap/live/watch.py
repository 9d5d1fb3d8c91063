"""``drivemap watch MODEL [NAME...] [--interval S] [--log FILE.csv]``: a live table, refreshed in place.

Each cycle reads the selection in one planned set of requests. Values that changed are
highlighted; a cycle without an answer (timeout, lost connection, exception) keeps the last
values, marked stale, and is counted; watching goes on until Ctrl-C (or ``--count`` cycles).
The footer shows the requests, bytes and line utilisation of the last cycle: on a serial line
the share of the interval the bytes took on the wire at the baud rate, on every link the share
of the interval spent waiting for replies.
"""

from __future__ import annotations

import argparse
import csv
import os
import stat
import sys
import time
from dataclasses import dataclass, field
from typing import Any, TextIO

from rich.console import Group
from rich.live import Live
from rich.text import Text

from drivemap.device.connection import add_connection_arguments, explain, seconds
from drivemap.device.errors import EXIT_INPUT, EXIT_OK, LiveError, epilog, verb
from drivemap.device.target import load_target, project_of
from drivemap.live.fmt import Row, console, rows_of, table
from drivemap.live.pages import Cell, current_pages, on_shown_page, selectors
from drivemap.live.selection import add_selection_arguments, positionals, select_cells
from drivemap.live.session import Session, describe_keys, keys_of, session_for
from drivemap.runtime.errors import DeviceException, TransportError


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("watch", help="a live table of registers, refreshed in place (--log FILE.csv)",
                       description="Watch registers of a live device: a table refreshed every --interval "
                                   "seconds; changes highlighted, timeouts counted (values marked stale).",
                       epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", metavar="MODEL|PATH")
    add_selection_arguments(p)
    p.add_argument("--interval", type=seconds(0.0, 86400.0), default=1.0, metavar="S", help="seconds between cycles (default 1)")
    p.add_argument("--log", default=None, metavar="FILE.csv", help="append every cycle's values to a CSV file")
    p.add_argument("--count", type=int, default=None, metavar="N", help="stop after N cycles (default: until Ctrl-C)")
    add_connection_arguments(p)
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    p.set_defaults(func=cmd_watch)


@dataclass
class State:
    """What the watch has seen so far."""

    cells: list[Cell]
    rows: list[Row] = field(default_factory=list)
    changed: set[str] = field(default_factory=set)
    cycles: int = 0
    stale_cycles: int = 0
    stale: bool = False
    problem: str = ""
    requests: int = 0
    bytes: int = 0
    busy_s: float = 0.0
    wire_s: float | None = None
    at: str = ""


@verb("watch")
def cmd_watch(args: argparse.Namespace) -> int:
    if args.interval <= 0:
        raise LiveError(EXIT_INPUT, "--interval must be positive")
    target = load_target(args.model, project_of(args.maps))
    cells = select_cells(target, positionals(args, "names"), args.group, args.all)
    log = open_log(args.log, cells) if args.log else None
    try:
        with session_for(args, target) as session:
            shown, skipped = on_shown_page(cells, current_pages(session, selectors(cells)))
            if session.page_policy == "raise" and skipped:
                print(f"not watching {len(skipped)} registers on pages not shown now "
                      f"({describe_keys(target, keys_of(skipped))}); --switch-pages reads them", file=sys.stderr)
                cells = shown
            state = State(cells, rows=rows_of(target, cells, {}))
            loop(session, state, args, log)
    finally:
        if log is not None:
            log.close()
    print(f"watched {state.cycles} cycles, {state.stale_cycles} without an answer")
    return EXIT_OK


def loop(session: Session, state: State, args: argparse.Namespace, log: TextIO | None) -> None:
    out = console()
    live = Live(render(session, state, args.interval), console=out, auto_refresh=False,
                redirect_stdout=False, redirect_stderr=False) if out.is_terminal else None
    next_at = time.monotonic()
    try:
        if live is not None:
            live.start()
        while args.count is None or state.cycles < args.count:
            cycle(session, state)
            if log is not None:
                write_log(log, state)
            if live is not None:
                live.update(render(session, state, args.interval), refresh=True)
            else:
                out.print(plain_line(state), soft_wrap=True)
            next_at = max(next_at + args.interval, time.monotonic())
            if args.count is None or state.cycles < args.count:
                time.sleep(max(0.0, next_at - time.monotonic()))
    except KeyboardInterrupt:
        pass
    finally:
        if live is not None:
            live.stop()


def cycle(session: Session, state: State) -> None:
    """One read of the selection; a failure keeps the last values and marks them stale."""
    assert session.bus is not None
    stats = session.bus.stats
    before = (stats.transactions, stats.bytes_sent + stats.bytes_received, stats.bytes_garbled, stats.rejected)
    started = time.monotonic()
    try:
        raws = session.read_keys(keys_of(state.cells))
    except (DeviceException, TransportError) as exc:
        garbled = stats.bytes_garbled > before[2]
        rejected = session.bus.last_rejected if stats.rejected > before[3] else None
        state.stale, state.problem = True, explain(exc, session.link, session.target, "read", garbled=garbled,
                                                   rejected=rejected).message
        state.stale_cycles += 1
    else:
        rows = rows_of(session.target, state.cells, raws)
        old = {r.name: r.raw for r in state.rows}
        state.changed = {r.name for r in rows if state.cycles and old.get(r.name) != r.raw}
        state.rows, state.stale, state.problem = rows, False, ""
    state.cycles += 1
    state.busy_s = time.monotonic() - started
    state.requests = stats.transactions - before[0]
    state.bytes = stats.bytes_sent + stats.bytes_received - before[1]
    link = session.link
    state.wire_s = state.bytes * link.bits_per_char / link.baudrate if link.serial and link.baudrate else None
    state.at = time.strftime("%H:%M:%S")


def footer(state: State, interval: float) -> str:
    use = f"busy {100 * state.busy_s / interval:.1f}%"
    if state.wire_s is not None:
        use = f"line {100 * state.wire_s / interval:.1f}% on the wire, " + use
    stale = f" | STALE: {state.problem}" if state.stale else ""
    return (f"cycle {state.cycles} at {state.at} | {state.requests} request{'s' if state.requests != 1 else ''}, "
            f"{state.bytes} bytes | {use} of {interval:g} s | timeouts {state.stale_cycles}{stale}")


def render(session: Session, state: State, interval: float) -> Group:
    styles = {name: "bold reverse" for name in state.changed}
    if state.stale:
        styles = {row.name: "dim" for row in state.rows}
    title = f"{session.target.model.name} {session.link.describe()}" + (" (stale)" if state.stale else "")
    return Group(table(session.target, state.rows, title=title, styles=styles), Text(footer(state, interval)))


def plain_line(state: State) -> str:
    values = " ".join(f"{r.name}={r.value_text()}" for r in state.rows)
    return f"{state.at} {'STALE ' if state.stale else ''}{values} [{state.requests} req]"


# ---------------------------------------------------------------- --log


def open_log(path: str, cells: list[Cell]) -> TextIO:
    """The CSV log: appended to when it has this watch's header, never overwritten otherwise."""
    header = ["time", "cycle", "stale", *(reg.element_name(i) for reg, i in cells)]
    try:
        if os.path.exists(path):
            if not stat.S_ISREG(os.stat(path).st_mode):  # a folder, FIFO or device: never opened
                raise LiveError(EXIT_INPUT, f"--log {path}: not a regular file (a folder, FIFO or device)")
            with open(path, encoding="utf-8", newline="") as handle:
                first = next(csv.reader([handle.readline(1_000_000)]), None)  # bounded: one line at most
            if first != header:
                raise LiveError(EXIT_INPUT, f"--log {path}: the file exists with other columns; not overwritten")
            return open(path, "a", encoding="utf-8", newline="")
        handle = open(path, "x", encoding="utf-8", newline="")
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise LiveError(EXIT_INPUT, f"--log {path}: cannot use it as the CSV log: {reason}") from None
    csv.writer(handle).writerow(header)
    return handle


def write_log(handle: TextIO, state: State) -> None:
    values: list[Any] = [r.value_text() for r in state.rows]
    csv.writer(handle).writerow([time.strftime("%Y-%m-%dT%H:%M:%S"), state.cycles, int(state.stale), *values])
    handle.flush()
