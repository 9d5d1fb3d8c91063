"""``drivemap verify MODEL ...``: a conformance run of the map against the device in front of you.

Reads every readable register alone and in the planner's batches, reads every reserved range
(the map says readable: true / false / null), checks each value against its enum and min/max,
and with ``--write-safe`` writes RAM registers and reads them back, restoring each (EEPROM
registers only with ``--eeprom``). Writes a Markdown and a JSON report "map vs device": each
disagreement with the map line it concerns. Exit 0 when they agree, 6 when they disagree.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeRemainingColumn
from rich.table import Table

from drivemap.device.connection import add_connection_arguments, explain
from drivemap.device.errors import EXIT_DISAGREE, EXIT_INPUT, EXIT_OK, LiveError, epilog, verb
from drivemap.device.progress import shown
from drivemap.device.target import load_target, project_of
from drivemap.live.fmt import console
from drivemap.live.pages import Cell, current_pages, on_shown_page, restore, selectors
from drivemap.live.session import Session, session_for
from drivemap.live.verify_checks import Finding, Results, check_alone, check_batches, check_reserved
from drivemap.live.verify_report import Header, report_paths, write_report
from drivemap.live.verify_write import candidates, check_writes
from drivemap.runtime.errors import DeviceException, TransportError


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("verify", help="run the map against the device; a Markdown and JSON report 'map vs device'",
                       description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
                       epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", metavar="MODEL|PATH")
    p.add_argument("--write-safe", action="store_true",
                   help="write/read-back round trips of RAM registers, each restored afterwards")
    p.add_argument("--eeprom", action="store_true", help="with --write-safe: EEPROM registers too (wears them)")
    p.add_argument("--switch-pages", action="store_true", help="write page selectors to reach every page (restored)")
    p.add_argument("--report", default=None, metavar="STEM",
                   help="write STEM.md and STEM.json (default: verify-MODEL-unitN)")
    p.add_argument("--force", action="store_true", help="overwrite report files drivemap did not write")
    add_connection_arguments(p)
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    p.set_defaults(func=cmd_verify)


@verb("verify")
def cmd_verify(args: argparse.Namespace) -> int:
    if args.eeprom and not args.write_safe:
        raise LiveError(EXIT_INPUT, "--eeprom only goes with --write-safe")
    target = load_target(args.model, project_of(args.maps))
    stem = args.report or f"verify-{target.model.name}-unit{args.unit if args.unit is not None else 1}"
    report_paths(stem, args.force)  # refuse a foreign file before talking to the device
    started = time.strftime("%Y-%m-%d %H:%M:%S")
    checks = "read alone, batches, reserved, values" + (", write-safe" + (" (EEPROM too)" if args.eeprom else "")
                                                        if args.write_safe else "")
    with session_for(args, target, identity="refuse" if args.write_safe else "warn") as session:
        try:
            results = run_checks(session, args.write_safe, args.eeprom)
        except TransportError as exc:
            raise explain(exc, session.link, target, "verify", garbled=False) from None
        header = Header(target.model.name, target.model.path, session.link.describe(), started, checks)
    md, js = write_report(stem, header, results, args.force)
    summary(results, md, js)
    return EXIT_DISAGREE if results.disagreements else EXIT_OK


def reach(session: Session, cells: list[Cell]) -> None:
    """Stop early (one line, its exit code) when the unit does not answer at all."""
    reg, index = cells[0]
    try:
        session.read_keys([(reg.name, index)])
    except DeviceException:
        pass  # it answers: that register's problem is a finding
    except TransportError as exc:
        raise explain(exc, session.link, session.target, "verify", garbled=session.bus is not None
                      and session.bus.stats.bytes_garbled > 0) from None


def check_identity_findings(session: Session, results: Results) -> None:
    """The identity registers the session read on connecting: each that does not match disagrees."""
    checks = session.target.model.identity
    if not checks or session.identity_mode == "off":
        return
    results.count("identity", len(checks))
    for m in session.identity:
        index = next(i for i, c in enumerate(checks) if c.register == m.register)
        results.add(Finding("identity", "disagree", m.register, m.address, session.target.line_of("identity", index),
                            m.expected, m.actual, "another device answers, or the map's identity is wrong"))


def run_checks(session: Session, write_safe: bool, eeprom: bool) -> Results:
    model = session.target.model
    cells: list[Cell] = [(r, i) for r in model.registers if r.readable for i in range(r.count)]
    if not cells:
        raise LiveError(EXIT_INPUT, f"{model.name}'s map has no readable register to verify")
    reach(session, cells)
    saved = current_pages(session, selectors(cells) + selectors([(r, 0) for r in model.registers]))
    results = Results()
    check_identity_findings(session, results)
    if session.page_policy == "raise":
        cells, other = on_shown_page(cells, saved)
        results.skipped += [f"{r.element_name(i)}: on page {r.page.value} of {r.page.selector}"
                            for r, i in other if r.page is not None]
    plan = session.client.plan([(r.name, i) for r, i in cells])
    writes_total = len(cells) if write_safe else 0
    with progress_bar(len(cells) + len(plan) + len(model.reserved) + writes_total) as tick:
        check_alone(session, cells, results, tick)
        check_batches(session, plan, results, tick)
        check_reserved(session, results, saved, tick)
        if write_safe:
            check_writes(session, candidates(session, cells, eeprom, results), results, tick)
    restore(session, saved)
    return results


class progress_bar:  # noqa: N801 (a context manager used like a function)
    """A transient progress bar on stderr; entering gives ``tick()``."""

    def __init__(self, total: int) -> None:
        columns = (TextColumn("verifying"), BarColumn(), TaskProgressColumn(), TimeRemainingColumn())
        err = Console(stderr=True)
        self.progress = Progress(*columns, console=err, transient=True, disable=not err.is_terminal)
        self.task = self.progress.add_task("verify", total=total)
        self._shown = shown(self.progress)

    def __enter__(self) -> Callable[[], None]:
        self._shown.__enter__()
        return lambda: self.progress.advance(self.task)

    def __exit__(self, *exc: object) -> None:
        self._shown.__exit__(None, None, None)


def summary(results: Results, md: object, js: object) -> None:
    out = console()
    bad = results.disagreements
    if bad:
        table = Table(title=f"{len(bad)} disagreement{'s' if len(bad) != 1 else ''} (map vs device)",
                      title_justify="left", header_style="bold")
        for column in ("map line", "check", "what", "the map says", "the device says"):
            table.add_column(column)
        for f in bad:
            table.add_row(f":{f.line}", f.check, f.subject, f.map_says, f.device_says)
        out.print(table)
    covered = ", ".join(f"{name} {count}" for name, count in results.counts.items())
    notes = len(results.findings) - len(bad)
    verdict = "map and device agree" if not bad else f"{len(bad)} disagreements"
    out.print(f"{verdict}; {notes} notes; checked: {covered}")
    not_written: dict[str, list[str]] = {}
    for text in results.skipped:
        name, sep, why = text.partition(": not written by --write-safe: ")
        if sep:
            not_written.setdefault(why, []).append(name)
    for why, names in not_written.items():
        shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
        out.print(f"--write-safe did not write {len(names)}: {why}: {shown}")
    out.print(f"report: {md} and {js}")
