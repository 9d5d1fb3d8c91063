"""``drivemap scan (--serial DEV | --tcp HOST | --rtu-over-tcp HOST:PORT)``: who answers, and which map fits.

For each line setting (on serial: each baud rate and parity the project's maps list, the maps'
defaults first) every unit id in ``--units`` gets one probe read; a unit that answers anything
(a reply or an exception) is there. On serial the scan stops at the first setting where a unit
answers (devices on one line share its settings) unless ``--all-settings``. Each unit found is
then read with every project map's planned requests (a read fingerprint: a map fits when every
request is answered and every value lies within its enum and min/max), except that a map naming
``identity`` registers is judged by them first: they are read, and the map fits exactly when each
holds the value the map states (such a fit ranks above every fingerprint); a value that reads 0 where
the map documents no power-up value is a note, "not set yet?", as in verify. When none of the project's
maps fits a unit, the maps drivemap ships (and its catalogue) that the project does not override are
weighed too, and those that fit are suggested by model id. The number of probes is known in advance (progress bar, ETA), each
probe waits at most ``--timeout``; Ctrl-C stops and prints what was found.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeRemainingColumn
from rich.table import Table

from drivemap.device.connection import (
    PARITIES,
    Link,
    add_connection_arguments,
    check_serial_device,
    open_bus,
    resolve_link,
)
from drivemap.device.errors import EXIT_INPUT, EXIT_INTERRUPTED, EXIT_NO_ANSWER, EXIT_OK, LiveError, epilog, verb
from drivemap.device.progress import shown
from drivemap.device.target import Target, load_target, project_of
from drivemap.diagnostics import CompileError
from drivemap.live.fingerprint import Fit, SharedReads, fingerprint, identify
from drivemap.live.fmt import console
from drivemap.live.session import read_words
from drivemap.runtime.client.api.sync_client import Core
from drivemap.runtime.client.protocol.planner import read_function
from drivemap.runtime.client.transport.bus import Bus
from drivemap.runtime.errors import DeviceException, DriveTimeout, TransportError
from drivemap.runtime.spec import DeviceSpec

STANDARD_BAUDRATES = (9600, 19200, 38400, 57600, 115200)


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("scan", help="find the unit ids (and serial settings) that answer; which maps fit",
                       description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
                       epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--units", "--unit", default=None, metavar="A-B[,C]", action=_Named,
                   help="unit ids to try (default: the project maps' unit range, at most 1-247)")
    p.add_argument("--baudrates", default=None, metavar="N,N", help="serial: baud rates to try (default: the maps')")
    p.add_argument("--parities", default=None, metavar="P,P", help="serial: parities to try (default: the maps')")
    p.add_argument("--all-settings", action="store_true", help="serial: try every setting, not only up to the first answer")
    p.add_argument("--json", action="store_true", help="print JSON")
    add_connection_arguments(p, unit=False)
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    p.set_defaults(func=cmd_scan, timeout=None)


class _Named(argparse.Action):
    """Stores the value and the option as typed (``--unit`` or ``--units``), for the error message."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_option", option_string or "--units")


@dataclass
class Found:
    unit: int
    link: Link
    answer: str
    fits: list[Fit] = field(default_factory=list)
    #: reads sent to judge the maps (each distinct read once for all of them)
    reads: int = 0
    #: when none of the project's maps fits: the shipped and catalogue maps that do (ids the project lacks)
    suggested: list[Fit] = field(default_factory=list)


@dataclass
class Scan:
    found: list[Found] = field(default_factory=list)
    garbled: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    probes: int = 0
    interrupted: bool = False
    #: whose maps were compared: "the project's", or "shipped" (a folder without maps)
    maps: str = "the project's"


@verb("scan")
def cmd_scan(args: argparse.Namespace) -> int:
    targets, whose = scan_targets(args.maps)
    if not targets:
        raise LiveError(EXIT_INPUT, "the project has no maps to compare with (pass --maps PATH)")
    link = resolve_link(with_defaults(args, targets), None, unit=0)
    link = replace(link, timeout=args.timeout or 0.1, retries=args.retries or 0)
    units = parse_units(args.units, targets, getattr(args, "units_option", "--units"))
    settings = list(line_settings(args, link, targets))
    result = Scan(maps=whose)
    err = Console(stderr=True)
    if whose == "shipped":
        err.print(f"the project has no maps: comparing with the {len(targets)} maps shipped with drivemap")
    total = len(settings) * len(units)
    err.print(f"scanning {len(units)} unit ids x {len(settings)} line setting{'s' if len(settings) != 1 else ''}: "
              f"at most {total} probes of {link.timeout:g} s (~{eta(total, link)})")
    try:
        probe_all(result, settings, units, targets, args.all_settings, err)
        for found in result.found:
            found.fits = fits_of(found, targets)
        suggest(result, targets, whose, err)
    except KeyboardInterrupt:
        result.interrupted = True
    show(result, args.json)
    if result.interrupted:
        return EXIT_INTERRUPTED
    return EXIT_OK if result.found else EXIT_NO_ANSWER


def with_defaults(args: argparse.Namespace, targets: list[Target]) -> argparse.Namespace:
    """Serial options the scan tries itself are not required up front."""
    ns = argparse.Namespace(**vars(args))
    ns.baudrate = ns.baudrate or 9600
    ns.parity = ns.parity or "none"
    return ns


def scan_targets(maps: list[str] | None) -> tuple[list[Target], str]:
    """The project's maps; in a folder without maps (and no ``--maps``), the maps drivemap ships (and its
    catalogue, when installed under the package's ``data/maps/catalogue``)."""
    targets = project_targets(maps)
    if targets or maps:
        return targets, "the project's"
    return project_targets(None, shipped_maps()), "shipped"


def suggest(result: Scan, targets: list[Target], whose: str, err: Console) -> None:
    """For each unit none of the project's maps fits: weigh the shipped and catalogue maps whose ids
    the project does not have, and keep those that fit (a map to verify, usable by its id)."""
    lost = [f for f in result.found if not any(fit.fits for fit in f.fits)]
    if whose != "the project's" or not lost:
        return
    have = {t.model.name for t in targets}
    others = [p for p in shipped_maps() if p.stem not in have]
    err.print(f"none of the project's maps fits unit{'s' if len(lost) > 1 else ''} "
              f"{', '.join(str(f.unit) for f in lost)}: weighing the {len(others)} maps shipped with drivemap")
    more = [t for t in project_targets(None, others) if t.model.name not in have]
    for found in lost:
        found.suggested = [fit for fit in fits_of(found, more) if fit.fits]


def shipped_maps() -> list[Path]:
    """The seed maps drivemap ships, then its catalogue."""
    from drivemap.frontend.project import catalogue_maps
    from drivemap.frontend.project import shipped_maps as seed_maps

    return [*seed_maps(), *catalogue_maps()]


def project_targets(maps: list[str] | None, files: list[Path] | None = None) -> list[Target]:
    project = project_of(maps)
    targets = []
    for path in project.map_files() if files is None else files:
        try:
            targets.append(load_target(str(path), project))
        except CompileError as exc:
            print(f"drivemap scan: skipping {path}: {exc.diagnostics[0].format()}", file=sys.stderr)
    return targets


def parse_units(text: str | None, targets: list[Target], option: str = "--units") -> list[int]:
    if text is None:
        low = min((t.spec.protocol.unit_min for t in targets), default=1)
        high = min(max((t.spec.protocol.unit_max for t in targets), default=247), 247)
        return list(range(low, high + 1))
    units: list[int] = []
    try:
        for part in text.split(","):
            first, _, last = part.partition("-")
            units.extend(range(int(first), int(last or first) + 1))
    except ValueError:
        raise LiveError(EXIT_INPUT, f"{option} wants unit ids or ranges like 1-16,20, not {text!r}") from None
    if not units or any(not 0 <= u <= 255 for u in units):
        raise LiveError(EXIT_INPUT, f"{option}: unit ids are 0..255, not {text!r}")
    return sorted(set(units))


def line_settings(args: argparse.Namespace, link: Link, targets: list[Target]) -> Iterator[Link]:
    if not link.serial:
        yield link
        return
    for baud in _baudrates(args, targets):
        for parity in _parities(args, targets):
            yield replace(link, baudrate=baud, parity=parity)


def _baudrates(args: argparse.Namespace, targets: list[Target]) -> list[int]:
    text = args.baudrates or (str(args.baudrate) if args.baudrate else None)
    if text:
        try:
            return [int(b) for b in text.split(",")]
        except ValueError:
            raise LiveError(EXIT_INPUT, f"--baudrates wants numbers like 9600,19200, not {text!r}") from None
    defaults = [t.spec.protocol.serial.baudrate for t in targets if t.spec.protocol.serial.baudrate]
    listed = sorted({b for t in targets for port in t.model.protocol.ports for b in port.baudrates})
    return list(dict.fromkeys([*defaults, *(listed or STANDARD_BAUDRATES)]))


def _parities(args: argparse.Namespace, targets: list[Target]) -> list[str]:
    text = args.parities or args.parity
    if text:
        chosen = [PARITIES.get(p.strip().lower()) for p in text.split(",")]
        if None in chosen:
            raise LiveError(EXIT_INPUT, f"--parities wants none, even, odd, not {text!r}")
        return [p for p in chosen if p]
    defaults = [t.spec.protocol.serial.parity for t in targets if t.spec.protocol.serial.parity]
    listed = [p for t in targets for port in t.model.protocol.ports for p in port.parity]
    ordered = [PARITIES.get(p, "") for p in [*defaults, *listed, "none", "even", "odd"]]
    return [p for p in dict.fromkeys(ordered) if p]


def eta(probes: int, link: Link) -> str:
    seconds = probes * (link.timeout or 0.1) * 1.1
    return f"{seconds / 60:.0f} min" if seconds >= 120 else f"{seconds:.0f} s"


def probe_all(result: Scan, settings: list[Link], units: list[int], targets: list[Target],
              all_settings: bool, err: Console) -> None:
    columns = (TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(), TimeRemainingColumn())
    with shown(Progress(*columns, console=err, transient=True, disable=not err.is_terminal)) as progress:
        task = progress.add_task("probing", total=len(settings) * len(units))
        if settings and settings[0].serial:
            check_serial_device(settings[0].device)
        for setting in settings:
            progress.update(task, description=f"{setting.line()}")
            try:
                bus = open_bus(setting)
            except LiveError as exc:
                if not setting.serial:
                    raise
                result.refused.append(f"{setting.line()}: {exc.message} (the port refuses these settings)")
                progress.advance(task, len(units))
                continue
            try:
                found_here = probe_setting(result, bus, setting, units, targets, lambda: progress.advance(task))
            finally:
                bus.close()
            if found_here and not all_settings:
                return


def probe_setting(result: Scan, bus: Bus, setting: Link, units: list[int], targets: list[Target],
                  advance: object) -> bool:
    found_here = False
    garbled_before = bus.stats.bytes_garbled
    for unit in units:
        answer = probe(bus, unit, targets)
        result.probes += 1
        if answer is not None:
            result.found.append(Found(unit, replace(setting, unit=unit), answer))
            found_here = True
        advance()  # type: ignore[operator]
    if bus.stats.bytes_garbled > garbled_before and not found_here:
        result.garbled.append(setting.line())
    return found_here


def probe(bus: Bus, unit: int, targets: list[Target]) -> str | None:
    """What ``unit`` answers to the probe reads (None: silence)."""
    for address, code, spec in probes(targets):
        core = Core(spec, unit, {}, "raise", False)
        try:
            read_words(bus, core, address, 1, code)
        except DeviceException as exc:
            return f"exception {exc.code:02X}h to a read of 0x{address:04X}"
        except (DriveTimeout, TransportError):
            continue
        return f"read of 0x{address:04X} answered"
    return None


def probes(targets: list[Target]) -> list[tuple[int, int, DeviceSpec]]:
    """One probe read (first readable register) per map; later maps only if a wrong address goes unanswered."""
    out: list[tuple[int, int, DeviceSpec]] = []
    for target in targets:
        first = next((r for r in target.model.registers if r.readable and r.page is None), None)
        if first is None:
            continue
        quiet = target.spec.protocol.policy("illegal_address") is None and any(
            p.case == "illegal_address" for p in target.spec.protocol.exception_policy)
        if not out or quiet:
            out.append((first.address, read_function(target.spec) or 0x03, target.spec))
    return out or [(0, 0x03, targets[0].spec)]


def fits_of(found: Found, targets: list[Target]) -> list[Fit]:
    fits = []
    bus = open_bus(replace(found.link, timeout=max(found.link.timeout or 0.1, 0.3)))
    reads = SharedReads(bus)  # each distinct read once for all the candidates
    try:
        for target in targets:
            if found.link.serial and found.link.mode not in target.spec.protocol.modes:
                continue
            fits.append(identify(bus, target, found.unit, reads) or fingerprint(bus, target, found.unit, reads))
    finally:
        bus.close()
    found.reads = reads.sent
    # equal scores: the map that explains more of the device first (more reads answered, more values in range)
    return sorted(fits, key=lambda f: (-f.score, -f.answered, -f.values, f.model))


def show(result: Scan, as_json: bool) -> None:
    if as_json:
        doc = {"interrupted": result.interrupted, "probes": result.probes, "garbled": result.garbled,
               "refused": result.refused,
               "maps": result.maps,
               "units": [{"unit": f.unit, "link": f.link.line(), "answer": f.answer, "reads": f.reads,
                          "fits": [fit.json() for fit in f.fits],
                          "suggested": [fit.json() for fit in f.suggested]} for f in result.found]}
        print(json.dumps(doc, indent=2))
        return
    out = console()
    for line in result.refused:
        out.print(f"not tried: {line}")
    for line in result.garbled:
        out.print(f"garbled replies on {line}: a device seems to be there with other settings (parity?)")
    if result.interrupted:
        out.print(f"interrupted after {result.probes} probes; found so far:")
    if not result.found:
        out.print("no unit answered")
        return
    table = Table(title="units that answer", title_justify="left", header_style="bold")
    for column in ("unit", "line", "answer", "maps that fit", "maps that do not"):
        table.add_column(column)
    for f in result.found:
        good = "; ".join(fit.summary() for fit in f.fits if fit.fits) or "none of the project's maps"
        bad = ", ".join(f"{fit.model} ({fit.answered}/{fit.requests} reads)" for fit in f.fits if not fit.fits)
        table.add_row(str(f.unit), f.link.line(), f.answer, good, bad or "-")
    out.print(table)
    for f in result.found:  # why each map does not fit (the same reasons --json gives)
        for fit in f.fits:
            if not fit.fits:
                out.print(f"unit {f.unit}: {fit.model} does not fit{fit.why() or ': no read answered'}", soft_wrap=True)
    for f in result.found:
        if f.suggested:
            shown = "; ".join(fit.summary() for fit in f.suggested[:5])
            more = f" (+{len(f.suggested) - 5} more: --json lists them)" if len(f.suggested) > 5 else ""
            out.print(f"unit {f.unit}: maps shipped with drivemap that fit: {shown}{more}; verify one by its id: "
                      f"drivemap verify {f.suggested[0].model} ...", soft_wrap=True)
