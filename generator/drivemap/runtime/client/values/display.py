"""What people see of a value, and the value sets a write must keep to.

:func:`display_text` formats a value as people read it (``read``, ``watch``, MQTT state, exports):
the map's ``precision`` when it gives one, else the shortest decimal text that reads back as the
same value - for an f32 the same f32 (``230.2``, not ``230.1999969482422``). :func:`check_values`
refuses a value outside a register's value set (``values:`` in the map) with
:class:`~drivemap.runtime.errors.NotAllowedValue`, which names the allowed values; every codec's
range check calls it, so the client, the CLI and the gateway refuse such a value before the wire.
"""

from __future__ import annotations

import math

from drivemap.runtime.client.values.steps import short_value, shortest_f32_text, unit_suffix
from drivemap.runtime.errors import NotAllowedValue
from drivemap.runtime.spec import RegisterSpec

__all__ = ["allowed_text", "check_values", "display_text", "is_allowed", "register_text"]

#: Relative tolerance when comparing a number with a value of the set (binary floats such as 0.1).
_EPS = 1e-9


def _same(value: object, allowed: float | str) -> bool:
    if isinstance(allowed, str) or isinstance(value, str):
        return value == allowed
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isclose(float(value), float(allowed), rel_tol=_EPS, abs_tol=1e-12)
    except OverflowError:
        return False


def allowed_text(spec: RegisterSpec) -> str:
    """The value set of ``spec`` for a message: ``0, 5 (5 min), 8 (8 min)``."""
    return ", ".join(display_text(_plain(v), spec.precision) + (f" ({label})" if label else "") for v, label in spec.values)


def _plain(value: float | str) -> float | str:
    """A whole float as an int (``5`` rather than ``5.0`` in a list of allowed values)."""
    return int(value) if isinstance(value, float) and value.is_integer() else value


def is_allowed(spec: RegisterSpec, value: object) -> bool:
    """Whether ``value`` is in the register's value set (always, for a register without one)."""
    return not spec.values or any(_same(value, allowed) for allowed, _ in spec.values)


def check_values(spec: RegisterSpec, value: object) -> None:
    """Refuse a value outside the register's value set (a register without one takes any value)."""
    if is_allowed(spec, value):
        return
    shown = repr(value) if isinstance(value, str) else short_value(_plain(value) if isinstance(value, float) else value)
    raise NotAllowedValue(f"{spec.name}: {shown}{unit_suffix(spec)} is not one of the allowed values {allowed_text(spec)}",
                          tuple(v for v, _ in spec.values))


def display_text(value: object, precision: int | None = None, *, single: bool = False) -> str:
    """A value as people read it: ``precision`` decimals when the map gives them, else the shortest
    text that reads back as the same value (as an f32 when ``single``: ``230.2``, not
    ``230.1999969482422``). Whole numbers, text, enums, None and NaN print as they are."""
    if isinstance(value, bool) or not isinstance(value, float) or not math.isfinite(value):
        if isinstance(value, int) and not isinstance(value, bool) and precision:
            return f"{value:.{precision}f}"
        return str(value)
    if precision is not None:
        return f"{value:.{precision}f}"
    return shortest_f32_text(value) if single else repr(value)


def register_text(spec: RegisterSpec, value: object) -> str:
    """:func:`display_text` with the register's precision; the f32 rule for an unscaled f32."""
    return display_text(value, spec.precision, single=spec.type == "f32" and spec.scale == 1 and spec.offset == 0)
