"""Presets of a simulator: ``drivemap simulate ... --set NAME=VALUE`` and ``--values FILE``.

A preset is the device's state at power-up (what its memory holds), given in engineering values
and checked against the map before the simulator starts: the cell must exist, a number must lie in
the map's ``min``..``max``, be a whole number of steps of the register's resolution and fit its
type, an enum register takes one of its values, a bool ``true``/``false`` (``on``/``off``,
``1``/``0`` on the command line), a string register text that fits, ``null`` (``--set name=null``)
a register with a not-available value. Every problem is a located error
(``<command line>:1:COL: error: ...`` or ``FILE:LINE:COL: error: ...``); nothing is served then.

``--values FILE`` is a mapping of cell names to values: JSON for a generated simulator
(:func:`read_json`), YAML or JSON for ``drivemap simulate`` (which passes its YAML reader)::

    phase_1_voltage: 230.1
    digital_speed[0]: 1500
    manufacturer: Fronius
"""

from __future__ import annotations

import difflib
import json
import math
import re
import shlex
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from drivemap.runtime.client.values.steps import STEP_TOLERANCE, number_text
from drivemap.runtime.client.values.words import raw_bounds
from drivemap.runtime.sim.unit import SimulatorError, SimValue, from_value, to_value
from drivemap.runtime.spec import DeviceSpec, RegisterSpec

__all__ = ["Entries", "EnumNames", "Preset", "PresetError", "Reader", "check", "from_command_line", "from_file", "read_json"]

#: (cell name, engineering value)
Preset = tuple[str, SimValue]
_BOOLS = {"true": True, "on": True, "1": True, "false": False, "off": False, "0": False}


class PresetError(SimulatorError):
    """A preset that does not fit the map; ``str()`` is ``where:line:col: error: message``."""


def _cells(spec: DeviceSpec) -> dict[str, RegisterSpec]:
    return {reg.element_name(i): reg for reg in spec.registers for i in range(reg.count)}


#: register name -> enum member name (upper case) -> value: lets a preset name an enum member
EnumNames = Mapping[str, Mapping[str, int]]


def check(spec: DeviceSpec, name: str, value: Any, factors: Mapping[str, SimValue] | None = None,
          enums: EnumNames | None = None) -> SimValue:
    """The value of cell ``name`` checked against the map (ValueError with the reason); an enum
    register takes a member name (any case) when ``enums`` gives the names."""
    cells = _cells(spec)
    reg = cells.get(name)
    if reg is None:
        close = difflib.get_close_matches(name, list(cells), n=3)
        raise ValueError(f"{spec.name} has no register {name!r}" + (f" (did you mean {', '.join(close)}?)" if close else ""))
    members = (enums or {}).get(reg.name)
    if isinstance(value, str) and reg.enum_values and reg.type != "string":
        if not members or value.strip().upper() not in members:
            known = ", ".join(members) if members else ", ".join(str(v) for v in reg.enum_values)
            raise ValueError(f"{name}: {value!r} is not a value of {reg.enum} ({known})")
        value = members[value.strip().upper()]
    if value is None:
        if not reg.not_available:
            raise ValueError(f"{name}: null, but the map lists no not-available value for it")
        return None
    if reg.type == "bool":
        if not isinstance(value, bool):
            raise ValueError(f"{name}: a bool register takes true or false, not {value!r}")
        return value
    if reg.type == "string":
        if not isinstance(value, str):
            raise ValueError(f"{name}: a string register takes text, not {value!r}")
        try:
            from_value(reg, value)
        except (SimulatorError, UnicodeEncodeError) as exc:
            raise ValueError(str(exc)) from None
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name}: a {reg.type} register takes a number, not {value!r}")
    return _number(spec, reg, name, value, factors or {})


def _number(spec: DeviceSpec, reg: RegisterSpec, name: str, value: float, factors: Mapping[str, SimValue]) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{name}: {value} is not finite")
    unit = f" {reg.unit}" if reg.unit else ""
    tol = 1e-9 * max(1.0, abs(value))
    if reg.min is not None and value < reg.min - tol:
        raise ValueError(f"{name}: {number_text(value)}{unit} is below the map's min {number_text(reg.min)}{unit}")
    if reg.max is not None and value > reg.max + tol:
        raise ValueError(f"{name}: {number_text(value)}{unit} is above the map's max {number_text(reg.max)}{unit}")
    factor = factors.get(reg.scale_register) if reg.scale_register else None
    if reg.scale_register and not isinstance(factor, int):  # not preset: the factor register's default
        default = spec.register(reg.scale_register).default_at(0)
        factor = int(default) if isinstance(default, (int, float)) else 0
    try:
        raw = from_value(reg, value, factor if isinstance(factor, int) else None)
    except SimulatorError as exc:
        raise ValueError(str(exc)) from None
    if reg.type not in ("f32", "f64"):
        step = reg.scale * 10.0 ** (factor if isinstance(factor, int) else 0)
        back = to_value(reg, raw, factor if isinstance(factor, int) else None)
        if not isinstance(back, (int, float)) or abs(float(back) - value) > STEP_TOLERANCE * abs(step):
            raise ValueError(f"{name}: {number_text(value)}{unit} is not a whole number of steps of "
                             f"{number_text(step)}{unit}")
        lo, hi = raw_bounds(reg)
        if not lo <= raw <= hi:
            raise ValueError(f"{name}: {number_text(value)}{unit} does not fit {reg.type}")
    if reg.enum_values and int(raw) not in reg.enum_values:
        raise ValueError(f"{name}: {number_text(value)} is not a value of {reg.enum} "
                         f"({', '.join(str(v) for v in reg.enum_values)})")
    return value


def _column(argv: Sequence[str], index: int, prog: str) -> int:
    shown = [prog, *(shlex.quote(a) for a in argv)]
    return 1 + sum(len(s) + 1 for s in shown[: index + 1])


def _text_value(reg: RegisterSpec | None, text: str) -> Any:
    """A command-line value: by the register's type (bool words, text, null, ASCII numbers)."""
    if text.strip().lower() == "null":
        return None
    if reg is None or reg.type == "string":
        return text
    if reg.type == "bool":
        value = _BOOLS.get(text.strip().lower())
        if value is None:
            raise ValueError(f"{text!r} is not a bool (write true/false, on/off or 1/0)")
        return value
    if not text.isascii():
        raise ValueError(f"{text!r} is not a number (write ASCII digits)")
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        if reg.enum_values:
            return text  # a member name: check() looks it up
        raise ValueError(f"{text!r} is not a number") from None


def from_command_line(spec: DeviceSpec, texts: Sequence[str], argv: Sequence[str], prog: str = "drivemap",
                      factors: Mapping[str, SimValue] | None = None, enums: EnumNames | None = None) -> list[Preset]:
    """``--set NAME=VALUE`` options, checked; errors located in the command line ``argv``."""
    out: list[Preset] = []
    errors: list[str] = []
    cells = _cells(spec)
    known = dict(factors or {})
    for text in texts:
        name, sep, raw = text.partition("=")
        name = name.strip()
        try:
            if not sep:
                raise ValueError(f"{text!r}: write --set NAME=VALUE (e.g. --set digital_speed[0]=1500)")
            value = check(spec, name, _text_value(cells.get(name), raw), known, enums)
        except ValueError as exc:
            index = list(argv).index(text) if text in argv else len(argv)
            errors.append(f"<command line>:1:{_column(argv, index, prog)}: error: {exc}")
            continue
        known[name] = value
        out.append((name, value))
    if errors:
        raise PresetError("\n".join(errors))
    return out


#: A file's entries: (cell name, value, line, column), in file order.
Entries = list[tuple[str, Any, int, int]]
#: Reads a values file into entries; raises :class:`PresetError` (located) when it cannot.
Reader = Callable[[Path], Entries]


def read_json(path: Path) -> Entries:
    """A JSON object of cell names to values (what a generated simulator reads; ``drivemap simulate``
    reads YAML too): each entry located at its key."""
    where = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise PresetError(f"{where}:1:1: error: cannot read values: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise PresetError(f"{where}:1:1: error: cannot read values: not UTF-8 text") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PresetError(f"{where}:{exc.lineno}:{exc.colno}: error: not JSON: {exc.msg}") from None
    if not isinstance(data, dict):
        raise PresetError(f"{where}:1:1: error: expected an object of register names to values")
    out: Entries = []
    offset = 0
    for name, value in data.items():
        match = re.compile(re.escape(json.dumps(name)) + r"\s*:").search(text, offset)
        at = match.start() if match else 0
        offset = match.end() if match else offset
        line = text.count("\n", 0, at) + 1
        out.append((name, value, line, at - (text.rfind("\n", 0, at) + 1) + 1))
    return out


def from_file(spec: DeviceSpec, path: str | Path, reader: Reader | None = None,
              enums: EnumNames | None = None) -> list[Preset]:
    """``--values FILE``: cell names to engineering values, checked; every problem a located error.

    Scale-factor registers are taken first, so a scaled value is checked (and set) with the factor
    the same file gives."""
    where = str(path)
    items = (reader or read_json)(Path(path))
    factor_names = {reg.scale_register for reg in spec.registers if reg.scale_register}
    items.sort(key=lambda item: str(item[0]) not in factor_names)
    out: list[Preset] = []
    errors: list[tuple[int, str]] = []
    known: dict[str, SimValue] = {}
    for name, value, line, col in items:
        try:
            checked = check(spec, str(name), value, known, enums)
        except ValueError as exc:
            errors.append((line, f"{where}:{line}:{col}: error: {exc}"))
            continue
        known[str(name)] = checked
        out.append((str(name), checked))
    if errors:
        raise PresetError("\n".join(text for _, text in sorted(errors)))
    return out
