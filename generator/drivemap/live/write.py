"""``drivemap write MODEL NAME=VALUE...``: engineering values, checked before anything is sent.

Says when each value takes effect (the map's reflect timing: now, after the Configuration command,
after a power cycle), ``--apply`` sends the Configuration command where the map has one, and
``--dry-run`` prints the frames (built by pymodbus's framers) without opening the port.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from pymodbus.framer import FramerAscii, FramerRTU, FramerSocket
from pymodbus.pdu import DecodePDU, ModbusPDU
from rich.table import Table

from drivemap.device.connection import Link, add_connection_arguments, resolve_link
from drivemap.device.errors import EXIT_INPUT, EXIT_OK, LiveError, epilog, verb
from drivemap.device.target import Target, load_target, locate_error, project_of
from drivemap.diagnostics import CompileError, Diagnostic
from drivemap.live.fmt import console, rows_of
from drivemap.live.selection import positionals
from drivemap.live.session import Session, check_unit, session_for
from drivemap.live.values import Assignment, lookup, parse_assignments, to_text
from drivemap.model.nodes import Register
from drivemap.runtime.client.protocol.sansio import Core, Deferred, Op
from drivemap.runtime.client.transport.bus import Exchange
from drivemap.runtime.errors import DriveError, OpenForReview

REFLECT = {
    "immediate": "now",
    "configuration": "after the Configuration command",
    "power_cycle": "after a power cycle (drive off and on)",
    "unknown": "unknown (the map does not say)",
}
STORAGE = {"eeprom": "EEPROM (kept at power-off)", "ram": "RAM (lost at power-off)",
           "volatile": "volatile", "unknown": "unknown"}
FUNCTION_NAMES = {0x01: "read coils", 0x02: "read discrete inputs", 0x03: "read holding registers",
                  0x04: "read input registers", 0x05: "write single coil", 0x06: "write single register",
                  0x0F: "write multiple coils", 0x10: "write multiple registers"}
#: The table a request's addresses are in, by function code.
FUNCTION_TABLES = {0x01: "coil", 0x02: "discrete", 0x03: "holding", 0x04: "input", 0x05: "coil", 0x06: "holding",
                   0x0F: "coil", 0x10: "holding"}


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("write", help="write engineering values to a live device by name",
                       description="Write registers by name: NAME=VALUE (digital_speed[0]=1500, "
                                   "operation_mode=REMOTE, net_in=X0|X2). Every value is checked first.",
                       epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", metavar="MODEL|PATH")
    p.add_argument("assignments", nargs="*", metavar="NAME=VALUE")
    p.add_argument("--apply", action="store_true", help="send the map's Configuration command after the writes")
    p.add_argument("--dry-run", action="store_true", help="print the frames, in the order they go out; send nothing")
    p.add_argument("--round", action="store_true",
                   help="round a value between two steps of the register's resolution to the nearer step "
                        "(default: refuse it and name the nearest values); says what it sends")
    p.add_argument("--no-read-back", action="store_true", help="do not read written registers back")
    p.add_argument("--switch-pages", action="store_true", help="write page selectors as needed")
    add_connection_arguments(p)
    p.add_argument("--maps", action="append", default=None, metavar="PATH", help="map file or folder (repeatable)")
    p.set_defaults(func=cmd_write, takes_rest=True)


@verb("write")
def cmd_write(args: argparse.Namespace) -> int:
    target = load_target(args.model, project_of(args.maps))
    texts = positionals(args, "assignments")
    if not texts:
        raise LiveError(EXIT_INPUT, "give at least one NAME=VALUE")
    refuse_open(target, texts)
    assignments = parse_assignments(target, texts, args.round)
    for a in assignments:
        for note in a.rounded:
            print(f"drivemap write: note: {note}", file=sys.stderr)
    if args.round and any(isinstance(raw, Deferred) for a in assignments for _, _, raw, _ in a.items):
        print("drivemap write: note: --round: values scaled by a factor register are rounded to the factor read "
              "at the write; the read back shows what was sent", file=sys.stderr)
    if args.apply and target.model.protocol.configuration is None:
        raise LiveError(EXIT_INPUT, f"--apply: {target.model.name}'s map has no Configuration command")
    items = [((a.register.name, index), raw) for a in assignments for _, index, raw, _ in a.items]
    if args.dry_run:
        return dry_run(target, resolve_link(args, target), items, args.apply, args.switch_pages)
    with session_for(args, target, identity="refuse") as session:
        session.call(f"writing {', '.join(a.text for a in assignments)}", session.client._drivemap.write_raw_items, items)
        if args.apply:
            session.call("sending the Configuration command", session.client.apply_configuration)
        back = {} if args.no_read_back else read_back(session, assignments)
        show(session, assignments, back, applied=args.apply)
    return EXIT_OK


def refuse_open(target: Target, texts: Sequence[str]) -> None:
    """A located error for every ``NAME=VALUE`` whose register's map leaves a field that decides the
    written words open (``review:``), before any value is looked at; nothing is sent."""
    errors: list[Diagnostic] = []
    for text in texts:
        name, sep, _ = text.partition("=")
        try:
            reg, _ = lookup(target, name.strip(), text)
        except CompileError:
            continue  # parse_assignments says what is wrong with it
        if sep and reg.writable and reg.open_for_writes:
            errors += locate_error(text, str(OpenForReview(reg.name, reg.open_for_writes)), target, reg).diagnostics
    if errors:
        raise CompileError(errors)


def read_back(session: Session, assignments: Sequence[Assignment]) -> dict[tuple[str, int], int]:
    keys = [(a.register.name, index) for a in assignments if a.register.readable for _, index, _, _ in a.items]
    return session.call("reading back", session.read_keys, keys) if keys else {}


def effect(reg: Register, applied: bool, has_configuration: bool) -> str:
    if reg.reflect == "configuration":
        if applied:
            return "now (Configuration sent)"
        return REFLECT["configuration"] + (" (--apply sends it)" if has_configuration else "")
    return REFLECT.get(reg.reflect, reg.reflect)


def show(session: Session, assignments: Sequence[Assignment], back: dict[tuple[str, int], int], *,
         applied: bool) -> None:
    target = session.target
    has_config = target.model.protocol.configuration is not None
    out = Table(title=f"{target.model.name} {session.link.describe()}: written", title_justify="left",
                header_style="bold")
    for column in ("name", "written", "raw", "read back", "takes effect", "stored in"):
        out.add_column(column)
    for a in assignments:
        reg = a.register
        for name, index, raw, value in a.items:
            rows = rows_of(target, [(reg, index)], back)
            shown = f"{rows[0].value_text()} {reg.unit or ''}".strip() if (reg.name, index) in back else "-"
            raw_text = f"x 10^{reg.scale_register}" if not isinstance(raw, int) else \
                rows_of(target, [(reg, index)], {(reg.name, index): raw})[0].raw_text()
            out.add_row(name, f"{to_text(value)} {reg.unit or ''}".strip(), raw_text, shown, effect(reg, applied, has_config),
                        STORAGE.get(reg.storage, reg.storage))
    console().print(out)


# ---------------------------------------------------------------- --dry-run


def dry_run(target: Target, link: Link, items: list[tuple[tuple[str, int], int | Deferred]], apply: bool,
            switch_pages: bool) -> int:
    """Print the frames the write would send, built by pymodbus's framer for the link."""
    check_unit(target, link.unit)
    scaled = [key[0] for key, raw in items if not isinstance(raw, int)]
    if scaled:
        raise LiveError(EXIT_INPUT, f"--dry-run: {', '.join(scaled)} scale by a factor register read from the "
                                    "device at the write; a dry run reads nothing, so it cannot show the frame")
    core = Core(target.spec, link.unit, {}, "switch" if switch_pages else "raise", False)
    try:
        exchanges = record(core.write_raw(items))
        if apply:
            exchanges += record(core.apply_configuration())
    except DriveError as exc:
        raise LiveError(EXIT_INPUT, f"--dry-run: {exc}") from None
    framer = framer_for(link)
    out = console()
    out.print(f"dry run for {link.describe()}: {len(exchanges)} request{'s' if len(exchanges) != 1 else ''}, "
              "nothing sent")
    for number, ex in enumerate(exchanges, 1):
        pdu = ex.pdu
        pdu.dev_id, pdu.transaction_id = link.unit, number
        frame = framer.buildFrame(pdu)
        out.print(f"{number}. {describe_request(target, pdu)}")
        out.print(f"   {link.mode.upper() if link.serial else link.kind.upper()}: {frame_text(frame, link)}")
    return EXIT_OK


def record(op: Op[Any]) -> list[Exchange]:
    """The exchanges of an operation, answered as a device that accepts everything would."""
    sent: list[Exchange] = []
    try:
        ex = next(op)
        while True:
            sent.append(ex)
            ex = op.send(ex.pdu)  # a write's reply echoes it; only its error flag is looked at
    except StopIteration:
        return sent


def framer_for(link: Link) -> FramerRTU | FramerAscii | FramerSocket:
    decoder = DecodePDU(is_server=False)
    if link.kind == "tcp":
        return FramerSocket(decoder)
    if link.serial and link.mode == "ascii":
        return FramerAscii(decoder)
    return FramerRTU(decoder)


def frame_text(frame: bytes, link: Link) -> str:
    if link.serial and link.mode == "ascii":
        return repr(frame.decode("ascii"))[1:-1]
    return frame.hex(" ").upper()


def describe_request(target: Target, pdu: ModbusPDU) -> str:
    """``write multiple registers (10h) at 0x0002, 2 words: demand_period``: the names resolved in the
    table the function code addresses."""
    code = pdu.function_code
    address = getattr(pdu, "address", 0)
    table = FUNCTION_TABLES.get(code, "holding")
    bits = table in ("coil", "discrete")
    items = list(getattr(pdu, "bits", []) or []) if bits else list(getattr(pdu, "registers", []) or [])
    count = len(items) or getattr(pdu, "count", 0)
    names = []
    for offset in range(count):
        hit = target.register_at(address + offset, table)
        if hit is not None and hit[0].element_address(hit[1]) == address + offset:
            names.append(hit[0].element_name(hit[1]))
    what = FUNCTION_NAMES.get(code, "request")
    unit = "coil" if bits else "word"
    return f"{what} ({code:02X}h) at 0x{address:04X}, {count} {unit}{'s' if count != 1 else ''}: {', '.join(names)}"
