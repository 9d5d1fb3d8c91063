"""One simulated unit: its raw register values, and the conversions between raw and engineering values.

Raw values are ints for every type, as in the client (:mod:`drivemap.runtime.client.values.codec`): integers
(signed for s16/s32/s64), IEEE-754 bit patterns, string bytes as one unsigned number, 0/1 for
coils and discrete inputs. Engineering values are what a preset or a behaviour gives: numbers,
text, true/false, None for a not-available value.
"""

from __future__ import annotations

import math
import struct
from typing import TYPE_CHECKING, Any

from drivemap.runtime.client.values.codec import join_words, raw_bounds, split_words
from drivemap.runtime.sim.view import SimValue
from drivemap.runtime.spec import BitSpec, DeviceSpec, RegisterSpec

if TYPE_CHECKING:
    from drivemap.runtime.sim.view import SimHost

__all__ = ["SimValue", "SimulatorError", "Unit", "from_value", "to_value"]


class SimulatorError(ValueError):
    """A bad call of the simulator API (unknown register, value that does not fit, bad unit)."""


_FLOAT_FORMATS = {"f32": ">f", "f64": ">d"}


def to_value(reg: RegisterSpec, raw: int, factor: int | None = None) -> SimValue:
    """Engineering value of a raw value (``factor``: the raw value of its scale-factor register)."""
    if raw in reg.not_available:
        return None
    if reg.type == "bool":
        return raw != 0
    if reg.type == "string":
        return raw.to_bytes(2 * reg.words, "big").rstrip(b"\x00 ").decode(reg.encoding, errors="replace")
    if reg.type in _FLOAT_FORMATS:
        number: float = struct.unpack(_FLOAT_FORMATS[reg.type], raw.to_bytes(2 * reg.words, "big"))[0]
        return number * reg.scale + reg.offset if reg.scale != 1 or reg.offset != 0 else number
    if reg.scale_register is not None:
        exponent = factor if factor is not None else 0
        return round(raw * reg.scale * 10.0 ** exponent + reg.offset, max(0, -exponent) + 9)
    if float(reg.scale).is_integer() and float(reg.offset).is_integer():
        return int(raw * int(reg.scale) + int(reg.offset))
    return round(raw * reg.scale + reg.offset, 9)


def from_value(reg: RegisterSpec, value: SimValue, factor: int | None = None) -> int:
    """Raw value of an engineering value (no range checks: a preset is the device's own state)."""
    if value is None:
        if not reg.not_available:
            raise SimulatorError(f"{reg.name}: None, but the map lists no not_available value")
        return reg.not_available[0]
    if reg.type == "bool":
        return 1 if value else 0
    if reg.type == "string":
        if not isinstance(value, str):
            raise SimulatorError(f"{reg.name}: a string register holds text, not {value!r}")
        data = value.encode(reg.encoding, errors="strict")
        if len(data) > 2 * reg.words:
            raise SimulatorError(f"{reg.name}: {value!r} does not fit {reg.words} registers")
        return int.from_bytes(data.ljust(2 * reg.words, b"\x00"), "big")
    if isinstance(value, str):
        raise SimulatorError(f"{reg.name}: a {reg.type} register holds a number, not {value!r}")
    number = (float(value) - reg.offset) / reg.scale
    if reg.type in _FLOAT_FORMATS:
        try:
            return int.from_bytes(struct.pack(_FLOAT_FORMATS[reg.type], number), "big")
        except OverflowError as exc:
            raise SimulatorError(f"{reg.name}: {value} does not fit {reg.type}") from exc
    if reg.scale_register is not None:
        number /= 10.0 ** (factor if factor is not None else 0)
    if not math.isfinite(number):
        raise SimulatorError(f"{reg.name}: {value} is not finite")
    return int(round(number))


def wire_words(reg: RegisterSpec, raw: int) -> list[int]:
    """The words a read of ``reg`` returns for ``raw`` (word and byte order applied)."""
    words = split_words(raw & ((1 << (16 * reg.words)) - 1), reg.words)
    if reg.word_order == "low_first":
        words.reverse()
    if reg.byte_order == "low_first":
        words = [((w & 0xFF) << 8) | (w >> 8) for w in words]
    return words


def unwire_words(reg: RegisterSpec, words: list[int]) -> int:
    """The raw value of the words a write carries (inverse of :func:`wire_words`)."""
    if reg.byte_order == "low_first":
        words = [((w & 0xFF) << 8) | (w >> 8) for w in words]
    if reg.word_order == "low_first":
        words = list(reversed(words))
    raw = join_words(words)
    bits = 16 * reg.words
    if reg.signed and raw >> (bits - 1):
        raw -= 1 << bits
    return raw


def start_raw(reg: RegisterSpec, factor: int | None = None) -> int:
    """The raw value a register without a default starts at: 0 when its value lies in the map's
    min..max, else the lowest value the range allows (min, rounded up to a step), else max. A device
    does not report a value outside its own map's range at power-up. An enum register starts at 0
    even when 0 is not one of its values (an empty history slot reads 0; picking a member would invent
    a state the map does not give)."""
    if reg.type in ("bool", "string") or reg.bit_table or reg.bits or (reg.min is None and reg.max is None):
        return 0
    if _allowed(reg, 0, factor):
        return 0
    candidates: list[int] = []
    if reg.min is not None:
        raw = from_value(reg, reg.min, factor)
        candidates += [raw, raw + 1]
    if reg.max is not None:
        candidates.append(from_value(reg, reg.max, factor))
    return next((raw for raw in candidates if _allowed(reg, raw, factor)), 0)


def _allowed(reg: RegisterSpec, raw: int, factor: int | None) -> bool:
    value = to_value(reg, raw, factor)
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return value is None and not reg.min and not reg.max
    tol = 1e-9 * max(1.0, abs(value))
    return (reg.min is None or value >= reg.min - tol) and (reg.max is None or value <= reg.max + tol)


def _cell_names(reg: RegisterSpec) -> list[tuple[str, int]]:
    return [(reg.element_name(i), i) for i in range(reg.count)]


class Unit:
    """The state of one unit id: raw register values, pending configuration, behaviour scratch.

    Behaviours read and change a unit through these methods; names are cell names
    (``motor_speed``, ``digital_speed[3]``).
    """

    def __init__(self, sim: SimHost, unit_id: int) -> None:
        self.sim = sim
        self.id = unit_id
        self.values: dict[str, int] = {}
        #: Values in effect for registers that take effect at Configuration (reflect "configuration").
        self.applied: dict[str, int] = {}
        #: Free space for the behaviour (ramps, timers, edge detection).
        self.scratch: dict[str, Any] = {}
        self.injected: int | None = None
        #: Cells that start without a map default, a saved or a preset value (at :func:`start_raw`): a
        #: behaviour's power-up may fill them (ev: RAM copies loaded from EEPROM).
        self.unset: set[str] = set()
        regs = sorted(sim.spec.registers, key=lambda r: r.scale_register is not None)  # factors first
        for reg in regs:
            for name, index in _cell_names(reg):
                default = reg.default_at(index)
                if default is None:
                    raw = start_raw(reg, self._factor(reg))
                    self.unset.add(name)
                else:
                    raw = from_value(reg, default, self._factor(reg))
                self.values[name] = raw
                if reg.reflect == "configuration":
                    self.applied[name] = raw
        self._identify()

    def _identify(self) -> None:
        """A register the map's identity names, without a default, holds the identifying value (the
        first of a list, a prefix's text; a pattern leaves it as it is): the simulator is the device."""
        for check in self.sim.spec.identity:
            reg = self.sim.spec.register(check.register)
            if reg.default_at(0) is not None or check.kind == "pattern" or not check.values:
                continue
            value = check.values[0]
            name = next(iter(_cell_names(reg)))[0]
            self.values[name] = from_value(reg, value, None) if isinstance(value, str) else value

    def _factor(self, reg: RegisterSpec) -> int | None:
        """The current raw value of ``reg``'s scale-factor register (None: it has none)."""
        if reg.scale_register is None:
            return None
        raw = self.values.get(reg.scale_register)
        factor = self.sim.spec.register(reg.scale_register)
        return None if raw is None or raw in factor.not_available else raw

    @property
    def spec(self) -> DeviceSpec:
        """The device's spec (what a behaviour looks registers up in)."""
        return self.sim.spec

    # ---- reading -------------------------------------------------------------------------
    def has(self, name: str) -> bool:
        return name in self.values

    def raw(self, name: str) -> int:
        """Raw value as a read would see it (signed for s16/s32/s64)."""
        return self.values[self.sim.check_cell(name)]

    def get(self, name: str) -> SimValue:
        """Engineering value (raw * scale + offset; text, true/false, None where the map says so)."""
        reg = self.sim.register_of(name)
        return to_value(reg, self.raw(name), self._factor(reg))

    def number(self, name: str) -> float:
        """The engineering value of a numeric register as a float (for behaviours)."""
        value = self.get(name)
        if value is None or isinstance(value, str):
            raise SimulatorError(f"{name} holds {value!r}, not a number")
        return float(value)

    def effective_raw(self, name: str) -> int:
        """The value in effect: for configuration-class registers the one applied at Configuration."""
        self.sim.check_cell(name)
        return self.applied.get(name, self.values[name])

    def bit(self, name: str, bit: str) -> int:
        spec = self.sim.bit_of(name, bit)
        return (self.raw(name) & spec.mask) >> spec.offset

    # ---- changing (no dialect checks: this is the device itself changing its state) --------
    def set_raw(self, name: str, raw: int) -> None:
        reg = self.sim.register_of(name)
        low, high = raw_bounds(reg)
        raw = int(raw)
        if not low <= raw <= high:
            raise SimulatorError(f"{name}: raw value {raw} does not fit {reg.type}")
        self.values[name] = raw
        if reg.storage == "eeprom":
            self.sim.mark_dirty()

    def set(self, name: str, value: SimValue) -> None:
        reg = self.sim.register_of(name)
        self.set_raw(name, from_value(reg, value, self._factor(reg)))

    def set_bit(self, name: str, bit: str, value: int) -> None:
        spec: BitSpec = self.sim.bit_of(name, bit)
        raw = self.raw(name) & 0xFFFF
        raw = (raw & ~spec.mask) | ((int(value) << spec.offset) & spec.mask)
        self.set_raw(name, raw)

    def apply_configuration(self) -> None:
        """Make every pending configuration-class value take effect."""
        for name in self.applied:
            self.applied[name] = self.values[name]

    def record_comm_error(self, code: int) -> None:
        """Push a communication error code into the history register (newest first)."""
        name = self.sim.spec.protocol.comm_error_history
        if name is None:
            return
        reg = self.sim.spec.register(name)
        for i in range(reg.count - 1, 0, -1):
            self.values[reg.element_name(i)] = self.values[reg.element_name(i - 1)]
        self.values[reg.element_name(0)] = code
