"""Does a map fit the device that answers? A read fingerprint, and the value checks verify shares.

Many candidate maps are judged against one unit through :class:`SharedReads`: every read is sent at
most once per unit for all candidates (a read inside the words of one that answered is answered from
it; the same read refused is refused again without asking), so the device sees each distinguishing
address once, not once per map. A map stops being read at its first refused or unanswered request:
it does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.register_message import ReadHoldingRegistersResponse, ReadInputRegistersResponse

from drivemap.device.target import Target
from drivemap.model.nodes import Register
from drivemap.runtime.client.api.identity import identity_keys, identity_mismatches
from drivemap.runtime.client.protocol.planner import plan_reads
from drivemap.runtime.client.protocol.sansio import Core, run
from drivemap.runtime.client.transport.bus import Bus
from drivemap.runtime.client.transport.exchange import Exchange
from drivemap.runtime.errors import DeviceException, DriveError, DriveTimeout, TransportError

#: Requests a fingerprint sends at most per map (the planner's first batches).
MAX_REQUESTS = 8


_RESPONSES = {0x03: ReadHoldingRegistersResponse, 0x04: ReadInputRegistersResponse}


class SharedReads:
    """A bus for many candidates' reads of one device: each distinct read sent once (see the module doc).

    Only read function codes pass (anything else is refused before it reaches the device)."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.sent = 0
        self.shared = 0
        self._answers: dict[tuple[int, int, int, int], ModbusPDU | DriveError | None] = {}
        #: (unit, code) -> answered register reads: (address, words)
        self._words: dict[tuple[int, int], list[tuple[int, list[int]]]] = {}

    def exchange(self, ex: Exchange) -> ModbusPDU | None:
        pdu = ex.pdu
        code = pdu.function_code
        if code not in (0x01, 0x02, 0x03, 0x04):
            raise AssertionError("identification sends reads only")
        key = (ex.unit, code, pdu.address, pdu.count)
        if key not in self._answers:
            covered = self._covered(ex.unit, code, pdu.address, pdu.count)
            if covered is not None:
                self.shared += 1
                return covered
            self.sent += 1
            try:
                reply = self.bus.exchange(ex)
            except DriveError as exc:
                self._answers[key] = exc
                raise
            self._answers[key] = reply
            if reply is not None and code in _RESPONSES and not reply.isError():
                self._words.setdefault((ex.unit, code), []).append((pdu.address, list(reply.registers)))
            return reply
        self.shared += 1
        answer = self._answers[key]
        if isinstance(answer, DriveError):
            raise answer
        return answer

    def _covered(self, unit: int, code: int, address: int, count: int) -> ModbusPDU | None:
        for start, words in self._words.get((unit, code), ()):
            if start <= address and address + count <= start + len(words):
                return _RESPONSES[code](registers=words[address - start:address - start + count], dev_id=unit)
        return None


def value_problem(target: Target, reg: Register, raw: int, raws: dict[tuple[str, int], int] | None = None) -> str | None:
    """Why a raw value read cannot be right for the map (None when it can). ``raws``: what was read
    with it (the scale factor of a scaled register)."""
    lo, hi = reg.raw_bounds()
    if not lo <= raw <= hi:
        return f"raw {raw} does not fit {reg.type}"
    if raw in reg.not_available:
        return None
    if reg.type in ("string", "bool") or reg.scale_register is not None or reg.is_float:
        return _decoded_problem(target, reg, raw, raws or {})
    if reg.enum is not None:
        values = {v.value for v in target.model.enum(reg.enum).members}
        if raw not in values:
            return f"{raw} is not a value of {reg.enum} ({', '.join(map(str, sorted(values)))})"
    if reg.bits:
        mask = 0
        for bit in reg.bits:
            mask |= bit.mask
            if bit.enum is not None:
                part = (raw & bit.mask) >> bit.offset
                if part not in {v.value for v in target.model.enum(bit.enum).members}:
                    return f"bits {bit.name} = {part} is not a value of {bit.enum}"
        if raw & ~mask & ((1 << (16 * reg.words)) - 1):
            return f"bits outside the map's bit fields are set (raw 0x{raw & 0xFFFFFFFF:04X})"
        return None
    value = raw * reg.scale + reg.offset
    tol = 1e-9 * max(1.0, abs(value))
    if reg.min is not None and value < reg.min - tol:
        return f"{value:g}{' ' + reg.unit if reg.unit else ''} is below the map's min {reg.min:g}"
    if reg.max is not None and value > reg.max + tol:
        return f"{value:g}{' ' + reg.unit if reg.unit else ''} is above the map's max {reg.max:g}"
    return None


def unset_zero(reg: Register, index: int, raw: int) -> bool:
    """A value outside the map's range that is 0 on a register with no documented power-up value:
    "not set yet", a note (verify and scan alike), never a disagreement."""
    return raw == 0 and reg.default_at(index) is None


def _decoded_problem(target: Target, reg: Register, raw: int, raws: dict[tuple[str, int], int]) -> str | None:
    """Strings and bools fit as read; floats and scaled values are checked against min/max decoded."""
    from drivemap.live.fmt import decode

    if reg.type in ("string", "bool"):
        return None
    value, why = decode(target, reg, raw, raws)
    if value is None:
        return None if why == "not available" or (reg.scale_register, 0) not in raws else why
    number = float(value)
    if number != number:  # NaN: a float register may read NaN
        return None
    if reg.min is not None and number < reg.min - 1e-9 * max(1.0, abs(number)):
        return f"{number:g}{' ' + reg.unit if reg.unit else ''} is below the map's min {reg.min:g}"
    if reg.max is not None and number > reg.max + 1e-9 * max(1.0, abs(number)):
        return f"{number:g}{' ' + reg.unit if reg.unit else ''} is above the map's max {reg.max:g}"
    return None


@dataclass
class Fit:
    """How well one map explains what a unit answers."""

    model: str
    requests: int = 0
    answered: int = 0
    values: int = 0
    problems: list[str] = field(default_factory=list)
    #: "identity" when the map's identity registers decided (they are read first), else "fingerprint"
    by: str = "fingerprint"
    #: values outside the map's range that read 0 with no documented power-up value (see :func:`unset_zero`)
    notes: list[str] = field(default_factory=list)

    @property
    def fits(self) -> bool:
        return self.requests > 0 and self.answered == self.requests and not self.problems

    @property
    def score(self) -> float:
        if not self.requests:
            return 0.0
        return self.answered / self.requests - 0.1 * len(self.problems) + (1.0 if self.by == "identity" and self.fits else 0.0)

    def summary(self) -> str:
        if self.fits and self.by == "identity":
            return f"{self.model} fits by identity ({self.values} identity registers match)"
        if self.fits:
            unset = f"; {len(self.notes)} read 0, not set yet?" if self.notes else ""
            return f"{self.model} fits ({self.answered}/{self.requests} reads, {self.values} values in range{unset})"
        return f"{self.model} does not ({self.answered}/{self.requests} reads answered{self.why()})"

    def why(self) -> str:
        """``: <the first problem> (+N more)``, or nothing."""
        if not self.problems:
            return ""
        more = f" (+{len(self.problems) - 1} more)" if len(self.problems) > 1 else ""
        return f": {self.problems[0]}{more}"

    def json(self) -> dict[str, Any]:
        return {"model": self.model, "fits": self.fits, "by": self.by, "requests": self.requests,
                "answered": self.answered, "values": self.values, "problems": self.problems, "notes": self.notes}


def identify(bus: Bus, target: Target, unit: int, reads: Bus | SharedReads | None = None) -> Fit | None:
    """Read the map's identity registers from ``unit`` and judge them (None: the map names none)."""
    spec = target.spec
    if not spec.identity:
        return None
    fit = Fit(target.model.name, by="identity")
    if not spec.protocol.valid_unit(unit):
        fit.problems.append(f"unit {unit} is outside the map's unit ids")
        return fit
    client = target.client_class(bus, unit)
    keys = identity_keys(spec)
    for req in client.plan(keys):
        fit.requests += 1
        try:
            raws = run(reads or bus, client._drivemap.core.read_raw([k for k, _ in req.cells], (req,), checked=True))  # type: ignore[arg-type]
        except DeviceException as exc:
            fit.problems.append(f"identity: exception {exc.code:02X}h to a read of 0x{req.address:04X}+{req.count}")
            continue
        except (DriveTimeout, TransportError):
            fit.problems.append(f"identity: no answer to a read of 0x{req.address:04X}+{req.count}")
            continue
        fit.answered += 1
        checks = tuple(c for c in spec.identity if (c.register, 0) in raws)
        fit.values += len(checks)
        found = identity_mismatches(replace(spec, identity=checks), raws, target.codecs)
        fit.problems.extend(f"identity: {m}" for m in found)
    return fit


def fingerprint(bus: Bus, target: Target, unit: int, reads: Bus | SharedReads | None = None) -> Fit:
    """Read the map's first planned batches (pages left alone) from ``unit`` and judge the values."""
    fit = Fit(target.model.name)
    if not target.spec.protocol.valid_unit(unit):
        fit.problems.append(f"unit {unit} is outside the map's unit ids")
        return fit
    core = Core(target.spec, unit, {}, "raise", False)  # raw reads only: no client package is built
    plan = [req for req in plan_reads(target.spec, core.tables.all_keys) if req.page is None][:MAX_REQUESTS]
    for req in plan:
        fit.requests += 1
        keys = [key for key, _ in req.cells]
        try:
            raws = run(reads or bus, core.read_raw(keys, (req,), checked=True))  # type: ignore[arg-type]
        except DeviceException as exc:
            fit.problems.append(f"exception {exc.code:02X}h to a read of 0x{req.address:04X}+{req.count}")
            if reads is not None:
                break  # among many candidates: this one does not fit; its other reads are not sent
            continue
        except (DriveTimeout, TransportError):
            fit.problems.append(f"no answer to a read of 0x{req.address:04X}+{req.count}")
            if reads is not None:
                break
            continue
        fit.answered += 1
        for (name, index), raw in raws.items():
            fit.values += 1
            reg = target.model.register(name)
            problem = value_problem(target, reg, raw, raws)
            if problem:
                (fit.notes if unset_zero(reg, index, raw) else fit.problems).append(
                    f"{reg.element_name(index)}: {problem}")
    return fit
