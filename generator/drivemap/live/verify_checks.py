"""The checks of ``drivemap verify``: the map against the device in front of you.

Each check adds :class:`Finding` s: ``disagree`` (the map and the device do not agree: a
line of the map is probably wrong for this firmware) or ``note`` (worth knowing, not a
contradiction). Every finding names the map line it concerns.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from drivemap.live.fingerprint import unset_zero, value_problem
from drivemap.live.session import Session
from drivemap.model.nodes import Register
from drivemap.runtime.client.protocol.planner import Key, ReadRequest
from drivemap.runtime.errors import DeviceException, DriveError, DriveTimeout

Cell = tuple[Register, int]
#: How far around an address that fails verify looks for a register the map does not list.
SHIFT_PROBE = 2


@dataclass
class Finding:
    check: str
    severity: str  # "disagree" | "note"
    subject: str
    address: int | None
    line: int
    map_says: str
    device_says: str
    hint: str = ""

    def json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Results:
    """Everything a verify run found, plus what each check covered."""

    findings: list[Finding] = field(default_factory=list)
    alone: dict[Key, int] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)

    def add(self, finding: Finding) -> None:
        self.findings.append(finding)

    def count(self, check: str, n: int = 1) -> None:
        self.counts[check] = self.counts.get(check, 0) + n

    @property
    def disagreements(self) -> list[Finding]:
        return [f for f in self.findings if f.severity == "disagree"]


def failure_text(session: Session, exc: DriveError) -> str:
    if isinstance(exc, DeviceException):
        return f"exception {exc.code:02X}h {exc.name}"
    if isinstance(exc, DriveTimeout):
        return "no answer"
    return str(exc)


# ---------------------------------------------------------------- every readable register alone


def check_alone(session: Session, cells: list[Cell], results: Results, tick: Callable[[], None]) -> None:
    for reg, index in cells:
        key = (reg.name, index)
        name = reg.element_name(index)
        address = reg.element_address(index)
        try:
            raw = session.read_keys([key])[key]
        except (DeviceException, DriveTimeout) as exc:
            results.add(Finding("read alone", "disagree", name, address, reg.line,
                                f"readable {reg.type} at 0x{address:04X}", failure_text(session, exc),
                                shift_hint(session, reg, index)))
        else:
            results.alone[key] = raw
            check_value(session, reg, index, raw, results)
        results.count("read alone")
        tick()


def check_value(session: Session, reg: Register, index: int, raw: int, results: Results) -> None:
    problem = value_problem(session.target, reg, raw)
    name = reg.element_name(index)
    if problem is None:
        ratio_note(session, reg, index, raw, results)
        return
    unset = unset_zero(reg, index, raw)
    results.add(Finding("value", "note" if unset else "disagree", name, reg.element_address(index), reg.line,
                        _range_text(reg), problem,
                        "0 with no documented power-up value: not set yet?" if unset else
                        "a wrong scale, address or enum for this firmware?"))
    results.count("value")


def _range_text(reg: Register) -> str:
    if reg.enum is not None:
        return f"one of enum {reg.enum}"
    if reg.bits:
        return "bits " + "|".join(b.name for b in reg.bits)
    unit = f" {reg.unit}" if reg.unit else ""
    return f"{reg.min if reg.min is not None else '-inf':g}..{reg.max if reg.max is not None else 'inf'}{unit}".replace(
        "-inf..inf", "any value")


def ratio_note(session: Session, reg: Register, index: int, raw: int, results: Results) -> None:
    """A value that is the map's default times a power of ten hints at a wrong scale."""
    default = reg.default_at(index)
    value = raw * reg.scale + reg.offset
    if not isinstance(default, (int, float)) or isinstance(default, bool) or default == 0 or value == 0:
        return
    if reg.enum or reg.bits:
        return
    exponent = math.log10(abs(value / default))
    if abs(exponent) >= 1 and abs(exponent - round(exponent)) < 1e-9:
        results.add(Finding("value", "note", reg.element_name(index), reg.element_address(index), reg.line,
                            f"default {default:g}", f"{value:g} (x{10 ** round(exponent):g} the default)",
                            "a scale off by a power of ten, or a changed setting?"))


def shift_hint(session: Session, reg: Register, index: int) -> str:
    """Look around a register that does not answer for addresses the map does not list that do."""
    address = reg.element_address(index)
    answering = []
    for delta in range(-SHIFT_PROBE, SHIFT_PROBE + 1):
        probe = address + delta
        if delta == 0 or not 0 <= probe <= 0xFFFF or session.target.register_at(probe, reg.table) is not None:
            continue
        try:
            session.read_words(probe, reg.words, reg.table)
        except DriveError:
            continue
        answering.append(f"0x{probe:04X} ({delta:+d})")
    if not answering:
        return "the register is not there: another firmware, or a map error?"
    return f"answers at {', '.join(answering)}, which the map does not list: address shifted?"


# ---------------------------------------------------------------- the planner's batches


def check_batches(session: Session, plan: tuple[ReadRequest, ...], results: Results,
                  tick: Callable[[], None]) -> None:
    target = session.target
    for req in plan:
        keys = [key for key, _ in req.cells]
        names = [target.model.register(n).element_name(i) for n, i in keys]
        first = target.model.register(keys[0][0])
        try:
            raws = session.read_request(req)
        except (DeviceException, DriveTimeout) as exc:
            alone_ok = all(k in results.alone for k in keys)
            results.add(Finding("batch", "disagree" if alone_ok else "note", f"{names[0]} .. {names[-1]}",
                                req.address, first.line, f"one read of 0x{req.address:04X}+{req.count} "
                                f"({len(keys)} elements)", failure_text(session, exc),
                                "each element reads alone: the device refuses this span (a gap or reserved "
                                "range the map calls readable?)" if alone_ok else "see the read-alone findings"))
        else:
            changed = [target.model.register(n).element_name(i) for (n, i) in keys
                       if (n, i) in results.alone and results.alone[(n, i)] != raws[(n, i)]]
            if changed:
                results.add(Finding("batch", "note", ", ".join(changed[:4]), req.address, first.line,
                                    "same value alone and in a batch", "values changed between the reads",
                                    "live values, or the device answers a batch differently"))
        results.count("batch")
        tick()


# ---------------------------------------------------------------- reserved ranges


def check_reserved(session: Session, results: Results, pages: dict[str, int], tick: Callable[[], None]) -> None:
    """Every reserved range: does the device answer reads there as the map says (readable true/false/null)?"""
    target = session.target
    limit = read_limit(session)
    for number, item in enumerate(target.model.reserved):
        line = target.line_of("reserved", number)
        subject = f"reserved 0x{item.start:04X}" + (f"..0x{item.end:04X}" if item.end != item.start else "")
        if item.page is not None and pages.get(item.page.selector) != item.page.value:
            results.skipped.append(f"{subject}: on page {item.page.value} of {item.page.selector}")
            continue
        failure = None
        for start in range(item.start, item.end + 1, limit):
            try:
                session.read_words(start, min(limit, item.end + 1 - start), item.table)
            except (DeviceException, DriveTimeout) as exc:
                failure = failure_text(session, exc)
                break
        results.count("reserved")
        tick()
        said = {True: "readable", False: "not readable", None: "readable: null (the manual does not say)"}[item.readable]
        answered = "answers reads" if failure is None else f"refuses reads ({failure})"
        if item.readable is None:
            results.add(Finding("reserved", "note", subject, item.start, line, said, answered,
                                f"the map could say readable: {str(failure is None).lower()}"))
        elif item.readable != (failure is None):
            hint = ("the planner spans it; set readable: false" if item.readable else
                    "set readable: true to let the planner span it")
            results.add(Finding("reserved", "disagree", subject, item.start, line, said, answered, hint))


def read_limit(session: Session) -> int:
    from drivemap.runtime.client.protocol.planner import read_function

    code = read_function(session.target.spec) or 0x03
    fc = session.target.spec.protocol.function(code)
    return fc.max_quantity if fc is not None and fc.max_quantity else 125
