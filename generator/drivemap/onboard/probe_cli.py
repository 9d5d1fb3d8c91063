"""``drivemap probe``: what a live device answers, as a skeleton map (and a snapshot), without a manual.

``drivemap probe --tcp HOST[:PORT] | --serial DEV --unit N [--tables holding,input,coil,discrete]
[--range A-B[,C-D]] [--max-quantity N] [--rate R] [--budget N] [--time S] [--exhaustive] [--sunspec]
[--snapshot FILE] [-o MAP] [--force]`` sweeps the ranges in the largest blocks the device takes and
bisects refused blocks only while the budget lasts (default: 3 reads per block of the sweep, at least
1000), learning
the device's rules (largest read, reads in even pairs, a function refused); it reports what it proved
readable, what it proved unreadable and what it left unresolved. ``--exhaustive`` proves every word
(every refused block split down to single words: slow). It writes a map of the readable blocks
as raw u16 words (coils and discrete inputs as bools), each with ``source: probe <date>`` and
``review:`` naming every field a probe cannot know, ``device.evidence: probed``; with
``--sunspec`` it walks the SunSpec model chain instead and writes the models found (named points
with ``drivemap[sunspec]``, else raw blocks per model). It sends read function codes only: it never
writes. ``drivemap probe --diff A.json B.json`` lists what changed between two snapshots.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drivemap.device.connection import Link, add_connection_arguments, explain, open_bus, resolve_link
from drivemap.device.errors import EXIT_INPUT, EXIT_NO_ANSWER, EXIT_OK, LiveError, epilog, verb
from drivemap.device.progress import shown
from drivemap.device.target import locate_error
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display, load_project
from drivemap.onboard.importers.mapdoc import MapDoc, model_id, target_path, write_map
from drivemap.onboard.probe import STANDARD_MAX, Block, ProbeGarbled, Prober, ProbeSilence, blocks_of, line_seconds
from drivemap.onboard.probe_bisect import Bisector, Outcome
from drivemap.onboard.probe_hints import candidate_specs, candidates, hint_runs, known_specs
from drivemap.onboard.probe_snapshot import diff, load_snapshot, snapshot_text
from drivemap.onboard.probe_sunspec import Chain, walk
from drivemap.runtime.spec import READ_CODES, DeviceSpec

if TYPE_CHECKING:
    from drivemap.device.target import Target

__all__ = ["add_parser"]

DEFAULT_RANGE = "0-9999"
#: what a probe cannot know of a register it found readable (the map's per-register ``review:``)
WORD_REVIEW = ("type", "word_order", "byte_order", "access", "scale", "offset", "unit", "min", "max", "enum")
BIT_REVIEW = ("access",)
#: the default budget is 3 reads per block of the sweep, and never less than this (a small range is
#: proven word by word well within it)
MIN_BUDGET = 1000


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("probe", help="discover the readable registers of a live device (reads only) -> skeleton map",
                       description=__doc__.split("\n\n", 1)[1] if __doc__ else None, epilog=epilog(),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tables", default="holding,input", metavar="T,T",
                   help="tables to sweep: holding, input, coil, discrete (default: holding,input)")
    p.add_argument("--range", dest="ranges", default=DEFAULT_RANGE, metavar="A-B[,C-D]",
                   help=f"addresses to sweep, protocol addresses 0..65535 (default {DEFAULT_RANGE})")
    p.add_argument("--max-quantity", type=int, default=None, metavar="N",
                   help="largest read in words (bits for coils) (default: 125 words, 2000 bits)")
    p.add_argument("--map", dest="like", default=None, metavar="MODEL|PATH",
                   help="a map of the device (family) whose max quantities bound the reads and whose serial "
                        "defaults apply")
    p.add_argument("--rate", type=float, default=20.0, metavar="R", help="at most R requests per second (default 20)")
    p.add_argument("--budget", type=int, default=None, metavar="N",
                   help=f"at most N reads (default: 3 per block of the sweep, at least {MIN_BUDGET}); what is left is "
                        "reported unresolved")
    p.add_argument("--time", dest="seconds", type=float, default=None, metavar="S",
                   help="stop bisecting after S seconds; what is left is reported unresolved")
    p.add_argument("--exhaustive", action="store_true",
                   help="prove every word: split every refused block down to single words (no budget; slow)")
    p.add_argument("--no-hints", dest="hints", action="store_false",
                   help="do not read where the shipped maps (and --map) put registers inside refused blocks")
    p.add_argument("--sunspec", action="store_true",
                   help="find 'SunS' (40000, 50000, 0) and walk the model chain (instead of --tables/--range)")
    p.add_argument("--snapshot", default=None, metavar="FILE", help="save every value read (JSON)")
    p.add_argument("--diff", nargs=2, default=None, metavar=("A.json", "B.json"),
                   help="list the registers that changed between two snapshots (no device)")
    p.add_argument("-o", "--output", default=None, metavar="MAP.yaml",
                   help="the skeleton map (default: the project's maps folder/MODEL.yaml)")
    p.add_argument("--model", default=None, metavar="ID",
                   help="model id of the map (default: the -o file's name, else probed_device)")
    p.add_argument("--force", action="store_true", help="replace an existing map or snapshot file")
    add_connection_arguments(p)
    p._mutually_exclusive_groups[-1].required = False  # --diff needs no device
    p.set_defaults(func=cmd_probe)


@verb("probe")
def cmd_probe(args: argparse.Namespace) -> int:
    if args.diff:
        lines = diff(load_snapshot(Path(args.diff[0])), load_snapshot(Path(args.diff[1])))
        for line in lines:
            print(line)
        print(f"{len(lines)} register{'s' if len(lines) != 1 else ''} changed")
        return EXIT_OK
    if not (args.tcp or args.rtu_over_tcp or args.serial):
        raise LiveError(EXIT_INPUT, "give the device: --tcp HOST[:PORT], --rtu-over-tcp HOST:PORT or --serial DEV "
                                    "(or --diff A.json B.json)")
    plan = _plan(args)
    target = None
    if args.like:
        from drivemap.device.target import load_target

        target = load_target(args.like)
        plan.limits = map_limits(plan.limits, target.spec)
        plan.paired = map_pairs(target.spec)
        plan.limits.update({t: plan.limits[t] - plan.limits[t] % 2 for t in plan.paired if plan.limits[t] > 1})
    link = resolve_link(args, target)
    if link.retries is None:
        link = replace(link, retries=0)
    if link.timeout is None:
        link = replace(link, timeout=1.0)
    _check_outputs(args, plan.target)
    bus = open_bus(link)
    prober = Prober(bus, link.unit, dict(plan.limits), args.rate)
    prober.pairs_first.update(dict.fromkeys(plan.paired, 0))
    prober.pairs_only |= plan.paired
    try:
        values, chain, outcome = _sweep(prober, plan, args, target, link)
    except ProbeSilence as exc:
        raise LiveError(EXIT_NO_ANSWER, f"no answer from {link.describe()}: {exc} (is the unit id right? list the "
                                        "units with: drivemap scan; nothing was written)") from None
    except ProbeGarbled as exc:
        error = explain(exc.timeout, link, None, "probe", garbled=True, rejected=exc.rejected)
        raise LiveError(error.code, f"{error.message.removeprefix('probe: ')} (after {prober.requests} reads; nothing "
                                    "was written)") from None
    finally:
        bus.close()
    if prober.answered == 0:
        raise LiveError(EXIT_NO_ANSWER, f"no answer from {link.describe()} to {prober.requests} reads "
                                        f"(is the unit id right? list the units with: drivemap scan)")
    return _finish(args, plan, link, prober, values, chain, outcome)


class _Plan:
    def __init__(self, tables: list[str], ranges: list[tuple[int, int]], limits: dict[str, int], target: Path,
                 model: str) -> None:
        self.tables, self.ranges, self.limits, self.target, self.model = tables, ranges, limits, target, model
        #: tables the map's alignment rules say to read in pairs at even addresses (--map)
        self.paired: set[str] = set()
        self.date = datetime.date.today().isoformat()


def _plan(args: argparse.Namespace) -> _Plan:
    tables = [t.strip() for t in args.tables.split(",") if t.strip()]
    bad = [t for t in tables if t not in STANDARD_MAX]
    if bad or not tables:
        raise locate_error(args.tables, f"--tables: holding, input, coil or discrete, not {args.tables!r}")
    ranges = parse_ranges(args.ranges)
    if args.max_quantity is not None and not 1 <= args.max_quantity <= 2000:
        raise locate_error(str(args.max_quantity), "--max-quantity: 1..2000 (Modbus allows 125 words, 2000 bits)")
    if not 0.01 <= args.rate <= 1e6:  # also refuses nan
        raise locate_error(str(args.rate), "--rate: requests per second, 0.01..1000000")
    if args.unit is not None and not 1 <= args.unit <= 255:
        raise locate_error(str(args.unit), "--unit: a unit id 1..255 (0 is broadcast: no unit answers it)")
    if args.budget is not None and args.budget < 1:
        raise locate_error(str(args.budget), "--budget: a number of reads, at least 1")
    if args.seconds is not None and not 0 < args.seconds <= 1e7:
        raise locate_error(str(args.seconds), "--time: seconds, more than 0 (at most 10000000)")
    if args.exhaustive and (args.budget is not None or args.seconds is not None):
        raise locate_error("--exhaustive", "--exhaustive proves every word: it takes no --budget or --time")
    model = model_id(args.model, args.output, "probed_device")
    limits = {t: min(m, args.max_quantity or m) for t, m in STANDARD_MAX.items()}
    folder = load_project().maps_folder()
    return _Plan(tables, ranges, limits, target_path(args.output, model, folder), model)


def map_limits(limits: dict[str, int], spec: DeviceSpec) -> dict[str, int]:
    """The map's max_quantity of each read function bounds that table's reads too."""
    out = dict(limits)
    for table, code in READ_CODES.items():
        fc = spec.protocol.function(code)
        if fc is not None and fc.max_quantity:
            out[table] = min(out[table], fc.max_quantity)
    return out


def map_pairs(spec: DeviceSpec) -> set[str]:
    """The tables whose reads the map's alignment rules (``protocol.alignment``) want at even starts or
    in even quantities, over the whole table: the probe reads them in pairs at even addresses only (a
    rule on a block of the table leaves the probe to find out, as without --map)."""
    return {rule.table for rule in spec.protocol.alignment if "read" in rule.operations and (rule.start, rule.end) == (0, 0xFFFF)
            and 2 in (rule.start_multiple, rule.quantity_multiple)}


def parse_ranges(text: str) -> list[tuple[int, int]]:
    """``0-99,40000-40300`` (decimal or 0x hex) -> [(0, 99), (40000, 40300)]; a located error otherwise."""
    out: list[tuple[int, int]] = []
    for part in text.split(","):
        first, sep, last = part.strip().partition("-")
        try:
            a = int(first, 0)
            b = int(last, 0) if sep else a
        except ValueError:
            raise locate_error(text, f"--range wants A-B[,C-D] with addresses 0..65535, not {part.strip()!r}") from None
        if not 0 <= a <= b <= 0xFFFF:
            raise locate_error(text, f"--range {part.strip()}: addresses are 0..65535 and A <= B")
        out.append((a, b))
    return out


def _check_outputs(args: argparse.Namespace, target: Path) -> None:
    """Refuse an existing map or snapshot before anything is sent (``--force`` replaces them)."""
    for path in (target, Path(args.snapshot) if args.snapshot else None):
        if path is not None and os.path.lexists(path) and not args.force:
            raise CompileError([Diagnostic(Location(display(path), 1, 1), "file exists; not overwritten (pass --force)")])


def _sweep(prober: Prober, plan: _Plan, args: argparse.Namespace, target: Target | None,
           link: Link) -> tuple[dict[str, dict[int, int]], Chain | None, Outcome | None]:
    values: dict[str, dict[int, int]] = {t: {} for t in STANDARD_MAX}
    if args.sunspec:
        chain = walk(prober)
        if chain is not None:
            values["holding"].update(chain.values)
        return values, chain, None
    if args.exhaustive:
        for table in plan.tables:
            for first, last in plan.ranges:
                prober.sweep(table, first, last, values[table])
        return values, None, None
    budget = args.budget if args.budget is not None else max(MIN_BUDGET, 3 * sweep_reads(plan.tables, plan.ranges,
                                                                                         plan.limits))
    hints = {}
    if args.hints:
        specs = [*known_specs(), *([target.spec] if target is not None else [])]
        hints = hint_runs(specs, plan.tables)
    with ProbeProgress(budget, link) as progress:
        outcome = Bisector(prober, budget=budget, seconds=args.seconds, hints=hints,
                           progress=progress.update).run(plan.tables, plan.ranges, plan.paired)
    for table, cells in outcome.values.items():
        values[table].update(cells)
    return values, None, outcome


def sweep_reads(tables: list[str], ranges: list[tuple[int, int]], limits: dict[str, int]) -> int:
    """Reads of a sweep of ``ranges`` in blocks of the largest read: the lower bound of a probe."""
    return sum(-(-(last - first + 1) // limits[t]) for t in tables for first, last in ranges)


class ProbeProgress:
    """A rich progress bar on stderr: reads of the budget, islands found, the time left at the line's
    baud rate (serial: from the frames still to send; TCP: at the rate reads went so far)."""

    def __init__(self, budget: int, link: Link) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn

        self.budget, self.link = budget, link
        self.started = time.monotonic()
        err = Console(stderr=True)
        self.bar = Progress(TextColumn("probe"), BarColumn(), TextColumn("{task.completed}/{task.total} reads"),
                            TextColumn("{task.fields[islands]} islands"), TextColumn("{task.fields[left]}"),
                            console=err, transient=True, disable=not err.is_terminal)
        self.task = self.bar.add_task("probe", total=budget, islands=0, left="")
        self._shown = shown(self.bar)

    def __enter__(self) -> ProbeProgress:
        self._shown.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._shown.__exit__(None, None, None)

    def update(self, bisector: Bisector) -> None:
        prober = bisector.prober
        left = max(0, self.budget - prober.requests)
        if self.link.serial and prober.requests:
            per = line_seconds(prober.chars, prober.requests, prober.silent, self.link.baudrate or 9600,
                               self.link.timeout or 1.0) / prober.requests
            where = f"at {self.link.baudrate} Bd"
        else:
            per = (time.monotonic() - self.started) / max(1, prober.requests)
            where = "at this pace"
        self.bar.update(self.task, completed=prober.requests, islands=bisector.islands,
                        left=f"~{left * per:.0f} s left {where}")


def _finish(args: argparse.Namespace, plan: _Plan, link: Link, prober: Prober, values: dict[str, dict[int, int]],
            chain: Chain | None, outcome: Outcome | None) -> int:
    if args.sunspec and chain is None:
        raise LiveError(EXIT_NO_ANSWER, f"no SunSpec marker 'SunS' at 40000, 50000 or 0 on {link.describe()}")
    source = f"probe {plan.date}"
    doc = ProbedDoc(plan.model, f"Device probed on {link.line()}, unit {link.unit}", source,
                 f"drivemap probe of unit {link.unit} on {link.line()}", modes=[_mode(link)])
    if chain is not None:
        from drivemap.onboard.probe_map import sunspec_registers

        sunspec_registers(doc, chain)
    else:
        raw_registers(doc, blocks_of(values))
    if outcome is not None:
        for table, spans in outcome.unresolved.items():
            if spans:
                doc.review.notes.append(f"{table}: {sum(b - a + 1 for a, b in spans)} words left unresolved "
                                        f"(not proven either way): {_spans(spans)}")
    if args.snapshot:
        _write_snapshot(Path(args.snapshot), snapshot_text(values, date=plan.date, link=link.line(), unit=link.unit,
                                                           outcome=outcome))
    write_map(doc, plan.target, force=args.force)
    _summary(doc, plan, prober, values, chain)
    if outcome is not None:
        _proof(outcome, prober, link)
    if chain is None:
        _candidates(plan, values)
    return EXIT_OK


def _candidates(plan: _Plan, values: dict[str, dict[int, int]]) -> None:
    """The maps (the project's, shipped, catalogue) whose every register in the ranges answered, the
    map naming most of what was read first: a map to verify, not a proof."""
    weighed = candidate_specs(load_project())
    whose = {spec.name: who for who, spec in weighed}
    found = candidates([spec for _, spec in weighed], values, plan.tables, plan.ranges)
    for model, words, _ in found[:3]:
        print(f"  every register of {whose[model]} {model} in these ranges answered ({words} words): check it with "
              f"drivemap verify {model}", file=sys.stdout)
    if len(found) > 3:
        print(f"  ... and {len(found) - 3} more maps (of {len(weighed)} weighed) whose registers all answered",
              file=sys.stdout)


def _spans(spans: list[tuple[int, int]], most: int = 12) -> str:
    shown = ", ".join(f"{a}-{b}" if b > a else str(a) for a, b in spans[:most])
    return shown + (f", ... ({len(spans) - most} more ranges)" if len(spans) > most else "")


def _proof(outcome: Outcome, prober: Prober, link: Link) -> None:
    """What was proven readable, proven unreadable and left unresolved, and the time at 19200 Bd."""
    out = sys.stdout
    for rule in outcome.rules:
        print(f"  learned: {rule}", file=out)
    for table in outcome.values:
        readable = len(outcome.values[table])
        unreadable = sum(b - a + 1 for a, b in outcome.unreadable.get(table, []))
        unresolved = outcome.unresolved.get(table, [])
        left = sum(b - a + 1 for a, b in unresolved)
        print(f"  {table}: {readable} words proven readable, {unreadable} proven unreadable, {left} unresolved"
              + (f" ({_spans(unresolved)})" if unresolved else ""), file=out)
    if outcome.stopped:
        print(f"  stopped by the {'--time limit' if outcome.stopped == 'time' else 'read budget'}: the unresolved "
              "words are not known to be empty (--budget N, --time S, or --exhaustive to prove every word)", file=out)
    baud = link.baudrate if link.serial and link.baudrate else 19200
    seconds = line_seconds(prober.chars, prober.requests, prober.silent, baud, link.timeout or 1.0)
    print(f"  these {prober.requests} reads take ~{seconds:.0f} s on a serial line at {baud} Bd", file=out)


class ProbedDoc(MapDoc):
    """The skeleton map of a probe: ``device.evidence: probed``."""

    def data(self) -> dict[str, Any]:
        doc = super().data()
        doc["device"]["evidence"] = "probed"
        return doc


def _mode(link: Link) -> str:
    return "tcp" if link.kind == "tcp" else link.mode


def raw_registers(doc: MapDoc, blocks: list[Block]) -> None:
    """Each readable block as raw words (bits), in arrays of at most 256."""
    for block in blocks:
        group = doc.group(block.table, f"{block.table.capitalize()} {'bits' if block.table in ('coil', 'discrete') else 'registers'} found readable")
        for start in range(block.start, block.end + 1, 256):
            count = min(256, block.end + 1 - start)
            reg = {"name": doc.name(f"{block.table}_{start}"), "table": block.table, "address": start,
                   "type": "bool" if block.table in ("coil", "discrete") else "u16", "access": "r"}
            if count > 1:
                reg["count"] = count
            reg.update(group=group, source=doc.source,
                       notes="Readable at probe time; meaning, type, scale and writability are not known.",
                       review=list(BIT_REVIEW if block.table in ("coil", "discrete") else WORD_REVIEW))
            doc.add(reg)


def _write_snapshot(path: Path, text: str) -> None:
    import tempfile

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".drivemap-tmp-")
    with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
        handle.write(text)
    os.replace(tmp, path)


def _summary(doc: MapDoc, plan: _Plan, prober: Prober, values: dict[str, dict[int, int]], chain: Chain | None) -> None:
    out = sys.stdout
    refused = ", ".join(f"{code:02X}h x{n}" for code, n in sorted(prober.refusals.items())) or "none"
    print(f"probe: {prober.requests} reads ({prober.answered} answered; exceptions {refused}); "
          f"nothing was written to the device", file=out)
    if chain is not None:
        models = ", ".join(f"{mid} (L {length}) at {at}" for mid, at, length in chain.models)
        print(f"SunSpec at {chain.base}: models {models}{'' if chain.ended else '; the chain did not end'}", file=out)
        if chain.problem:
            print(f"  note: {chain.problem}", file=out)
    for block in blocks_of(values):
        print(f"  {block.table} {block.start}-{block.end} ({len(block.values)} {'bits' if block.table in ('coil', 'discrete') else 'words'})", file=out)
    for table, words in sorted(prober.pairs_first.items()):
        if table in plan.paired:
            print(f"  {table}: read in pairs at even addresses as the map's alignment rules ask ({words} words read in "
                  "pairs)", file=out)
        else:
            print(f"  {table}: single-word reads are refused where two words at an even address answer ({words} "
                  "words read in pairs): the device has alignment rules (protocol.alignment); review them", file=out)
    for table in plan.tables if chain is None else ():
        if table in prober.unsupported:
            print(f"  {table}: the device refuses the function (exception 01h)", file=out)
    for line in doc.review.lines():
        print(line, file=out)
    shown = display(plan.target)
    print(f"wrote {shown}: {len(doc.registers)} registers; names, types, scales and access are for you to fill in", file=out)
    print(f"next: drivemap validate {shown}; drivemap read {shown} --tcp HOST --all", file=out)
