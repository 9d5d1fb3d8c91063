"""Exact values: the register's resolution and the shortest text of a float.

:func:`exact_raw` turns an engineering value into its raw value only when it is a whole number of
steps of the register's resolution (scale, offset, scale factor); a value between two steps is
refused with :class:`~drivemap.runtime.errors.InexactValue` naming the nearest representable
values. Binary floats cannot hold most decimals (12.3 / 0.1 is 122.99999999999999), so a value
within :data:`STEP_TOLERANCE` steps of an integer raw value is that raw value (for raw values beyond
about 10**9 steps, within the float's own precision, a few parts in 10**15).

:func:`shortest_f32_text` prints an f32 reading as the shortest decimal that reads back as the same
f32 (``230.2``, not ``230.1999969482422``): the one helper every printer (``drivemap read``, ``watch``,
``--json``, ``--csv``, the gateway) uses.
"""

from __future__ import annotations

import math
import struct

from drivemap.runtime.client.values.words import raw_bounds
from drivemap.runtime.errors import InexactValue, ValueOutOfRange
from drivemap.runtime.spec import RegisterSpec

#: Relative tolerance when comparing a float against min/max (binary floats such as 0.1).
_EPS = 1e-9
#: A value whose raw value (in steps of the resolution) is within this many steps of an integer
#: is that integer: 12.3 at 0.1 per step is raw 123 although 12.3 / 0.1 == 122.99999999999999.
STEP_TOLERANCE = 1e-6


def _round_half_away(x: float) -> int:
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def unit_suffix(spec: RegisterSpec) -> str:
    return f" {spec.unit}" if spec.unit else ""


def short_value(value: object) -> str:
    """``value`` for a message: a huge int (``10**400``) is named by its size, never converted to text."""
    if isinstance(value, int) and value.bit_length() > 96:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)


def offset_text(offset: float) -> str:
    return f" from the offset {number_text(offset)}" if offset else ""


def fits_raw(spec: RegisterSpec, raw: int, value: float) -> int:
    """``raw`` when it lies in the register type's bounds, else :class:`ValueOutOfRange`."""
    lo, hi = raw_bounds(spec)
    if not lo <= raw <= hi:
        raise ValueOutOfRange(f"{spec.name}: {short_value(value)}{unit_suffix(spec)} is not representable ({spec.type} raw {short_value(raw)})")
    return raw


def number_text(value: float) -> str:
    """A number for a message: ``-1`` for -1.0, ``12.3``, the shortest repr otherwise."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e16:
        return str(int(value))
    return repr(value)


def _in_range(spec: RegisterSpec, value: float, raw: int) -> bool:
    lo, hi = raw_bounds(spec)
    tol = _EPS * max(1.0, abs(value))
    return (lo <= raw <= hi and (spec.min is None or value >= spec.min - tol)
            and (spec.max is None or value <= spec.max + tol))


def exact_raw(spec: RegisterSpec, value: float, step: float, offset: float, digits: int, why: str = "") -> int:
    """The raw value of ``value`` at ``step`` per raw unit plus ``offset``, when it is a whole
    number of steps (within :data:`STEP_TOLERANCE`); else :class:`InexactValue` naming the nearest
    representable values (``digits``: decimals that show them exactly; ``why``: how the step comes about)."""
    exact = (value - offset) / step
    raw = _round_half_away(exact)
    # a float holds ~16 digits: beyond ~10**9 steps its own rounding error outgrows STEP_TOLERANCE
    if abs(exact - raw) <= max(STEP_TOLERANCE, abs(exact) * 2.0 ** -50):
        return raw
    below = math.floor(exact)
    options = [(r, round(r * step + offset, digits)) for r in (below, below + 1)]
    allowed = [(r, v) for r, v in options if _in_range(spec, v, r)]
    pick = [(r, v) for r, v in allowed if r == raw] or allowed
    nearest = tuple(v for _, v in allowed)
    unit = unit_suffix(spec)
    shown = " or ".join(f"{number_text(v)}{unit}" for v in nearest) or "none within the register's range"
    raise InexactValue(
        f"{spec.name}: {number_text(value)}{unit} is not a whole number of steps of the register's resolution "
        f"{number_text(round(step, digits))}{unit}{why}; nearest representable: {shown} (refused, not rounded)",
        nearest, pick[0][1] if pick else None, pick[0][0] if pick else None)



def exact_f32(spec: RegisterSpec, value: float, number: float, raw: int, back: float) -> None:
    """Refuse ``value`` when the single nearest its raw number ``number`` (``value`` less the offset,
    over the scale) does not read as that number: the register would show another value.
    ``raw`` and ``back`` are that single's bits and the value it reads as. 30.2 is taken (its single
    prints as 30.2, and 30.200000762939453, the single itself, is taken too); 30.123456789 is refused
    (its single prints as 30.123457)."""
    if math.isnan(number) or math.isinf(number):
        return
    single = _f32(number)
    shown = shortest_f32(single)
    if number in (single, shown) or math.isclose(shown, number, rel_tol=1e-12, abs_tol=0.0):
        return  # the single itself (a value read back), or the decimal it prints as
    nearest = shortest_f32(back) if spec.scale == 1 and spec.offset == 0 else back
    raise InexactValue(
        f"{spec.name}: {number_text(value)}{unit_suffix(spec)} is not representable as f32 (a single holds about 7 "
        f"significant digits); nearest representable: {number_text(nearest)}{unit_suffix(spec)} (refused, not rounded)",
        (nearest,), nearest, raw)


def _f32(value: float) -> float:
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


def shortest_f32_text(value: float) -> str:
    """The shortest decimal text that reads back as the same f32 as ``value`` (``230.2`` for the f32
    nearest 230.2, which Python prints as 230.1999969482422); nan, inf and -inf as Python prints them;
    a value outside the f32 range as ``repr``."""
    if not math.isfinite(value):
        return repr(value)
    try:
        target = _f32(value)
    except (OverflowError, struct.error):
        return repr(value)
    if target != value:
        return repr(value)  # not an f32 (an f64 reading, or scaled): Python's own shortest repr
    for digits in range(1, 18):
        text = f"{value:.{digits}g}"
        if _f32(float(text)) == target:
            return repr(float(text))
    return repr(value)


def shortest_f32(value: float) -> float:
    """The float of :func:`shortest_f32_text` (``230.2``): for JSON and anything that prints floats itself."""
    return float(shortest_f32_text(value)) if math.isfinite(value) else value


__all__ = ["STEP_TOLERANCE", "exact_f32", "exact_raw", "number_text", "shortest_f32", "shortest_f32_text"]
