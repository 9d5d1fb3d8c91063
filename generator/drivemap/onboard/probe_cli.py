"""``drivemap probe``: what a live device answers, as a skeleton map (and a snapshot), without a manual.

``drivemap probe --tcp HOST[:PORT] | --serial DEV --unit N [--tables holding,input,coil,discrete]
[--range A-B[,C-D]] [--max-quantity N] [--rate R] [--sunspec] [--snapshot FILE] [-o MAP] [--force]``
sweeps the ranges with bounded reads (splitting on refusal) and writes a map of the readable blocks
as raw u16 words (coils and discrete inputs as bools), each with ``source: probe <date>``; with
``--sunspec`` it walks the SunSpec model chain instead and writes the models found (named points
with ``drivemap[sunspec]``, else raw blocks per model). It sends read function codes only: it never
writes. ``drivemap probe --diff A.json B.json`` lists what changed between two snapshots.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
from dataclasses import replace
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display, load_project
from drivemap.live.connection import Link, add_connection_arguments, open_bus, resolve_link
from drivemap.live.errors import EXIT_INPUT, EXIT_NO_ANSWER, EXIT_OK, LiveError, epilog, verb
from drivemap.live.values import locate_error
from drivemap.onboard.importers.mapdoc import MapDoc, model_id, target_path, write_map
from drivemap.onboard.probe import STANDARD_MAX, Block, Prober, ProbeSilence, blocks_of
from drivemap.onboard.probe_snapshot import diff, load_snapshot, snapshot_text
from drivemap.onboard.probe_sunspec import Chain, walk
from drivemap.runtime.spec import READ_CODES, DeviceSpec

__all__ = ["add_parser"]

DEFAULT_RANGE = "0-9999"


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
        from drivemap.live.target import load_target

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
        values, chain = _sweep(prober, plan, args.sunspec)
    except ProbeSilence as exc:
        raise LiveError(EXIT_NO_ANSWER, f"no answer from {link.describe()}: {exc} (is the unit id right? list the "
                                        "units with: drivemap scan; nothing was written)") from None
    finally:
        bus.close()
    if prober.answered == 0:
        raise LiveError(EXIT_NO_ANSWER, f"no answer from {link.describe()} to {prober.requests} reads "
                                        f"(is the unit id right? list the units with: drivemap scan)")
    return _finish(args, plan, link, prober, values, chain)


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
    if not args.rate > 0 or args.rate != args.rate:
        raise locate_error(str(args.rate), "--rate: a positive number of requests per second")
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


def _sweep(prober: Prober, plan: _Plan, sunspec: bool) -> tuple[dict[str, dict[int, int]], Chain | None]:
    values: dict[str, dict[int, int]] = {t: {} for t in STANDARD_MAX}
    if sunspec:
        chain = walk(prober)
        if chain is not None:
            values["holding"].update(chain.values)
        return values, chain
    for table in plan.tables:
        for first, last in plan.ranges:
            prober.sweep(table, first, last, values[table])
    return values, None


def _finish(args: argparse.Namespace, plan: _Plan, link: Link, prober: Prober, values: dict[str, dict[int, int]],
            chain: Chain | None) -> int:
    if args.sunspec and chain is None:
        raise LiveError(EXIT_NO_ANSWER, f"no SunSpec marker 'SunS' at 40000, 50000 or 0 on {link.describe()}")
    source = f"probe {plan.date}"
    doc = MapDoc(plan.model, f"Device probed on {link.line()}, unit {link.unit}", source,
                 f"drivemap probe of unit {link.unit} on {link.line()}", modes=[_mode(link)])
    if chain is not None:
        from drivemap.onboard.probe_map import sunspec_registers

        sunspec_registers(doc, chain)
    else:
        raw_registers(doc, blocks_of(values))
    if args.snapshot:
        _write_snapshot(Path(args.snapshot), snapshot_text(values, date=plan.date, link=link.line(), unit=link.unit))
    write_map(doc, plan.target, force=args.force)
    _summary(doc, plan, prober, values, chain)
    return EXIT_OK


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
                       notes="Readable at probe time; meaning, type, scale and writability are not known.")
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
