"""What a register map becomes in the tools users already run (Home Assistant, ESPHome, pymodbus).

Tool-neutral: which register elements are exported (``Point``), with which polling interval, on
which page, under which unit id, over which serial settings. Each exporter maps a ``Point`` to its
tool's entities with one table of its own. Map text never decides structure here: names come from
register identifiers, labels travel as plain values that the exporters hand to a YAML/JSON/CSV
library.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from drivemap.backends.common import OptionError
from drivemap.backends.options import DEFAULT_SCAN_S, DEFAULT_SETTINGS_S
from drivemap.model.nodes import AllowedValue, Cell, Model, Port, Register
from drivemap.runtime.client.values.codec import FloatCodec, IeeeCodec, IntCodec, StringCodec, raw_to_words
from drivemap.runtime.spec import RegisterSpec
from drivemap.vocab.escape import comment_safe
from drivemap.vocab.units import (
    DEVICE_CLASS_SINCE,
    DEVICE_CLASSES,
    UNIT_SPELLING,
    decimals,
    device_class_known,
    unit_for,
)

__all__ = [
    "DEFAULT_SCAN_S",
    "DEFAULT_SETTINGS_S",
    "device_class_known",
    "DEVICE_CLASSES",
    "DEVICE_CLASS_SINCE",
    "UNIT_SPELLING",
    "Point",
    "Selection",
    "SerialSettings",
    "comment_safe",
    "decimals",
    "int_option",
    "select",
    "serial_settings",
    "tcp_endpoint",
    "unit_for",
]


def display_decimals(reg: Register) -> int | None:
    """Decimals to show of ``reg``'s values: the map's ``precision``, else the decimals of its scale
    and offset for integer registers, else None (a float: the tool's own default)."""
    if reg.precision is not None:
        return reg.precision
    if reg.is_float:
        return None
    return decimals(reg.scale, reg.offset)


def options(reg: Register) -> list[tuple[AllowedValue, str]]:
    """Each value of ``reg``'s value set with the option text a select shows: the label, else the
    value and unit (``5 min``); the value and label when two texts would be the same."""
    def plain(item: AllowedValue) -> str:
        value = item.value
        text = str(int(value)) if isinstance(value, float) and value.is_integer() else str(value)
        return f"{text} {reg.unit}" if reg.unit and not isinstance(value, str) else text

    texts = [item.label or plain(item) for item in reg.value_set]
    if len(set(texts)) != len(texts):
        texts = [item.text() for item in reg.value_set]
    return list(zip(reg.value_set, texts, strict=True))


def wire_words(reg: Register, value: float | str) -> list[int]:
    """The words a write of ``value`` to ``reg`` puts on the wire (word and byte order applied), by
    the runtime's own codecs; for exports that write fixed values (a select's options)."""
    spec, raw = wire_raw(reg, value)
    return raw_to_words(spec, raw)


def wire_raw(reg: Register, value: float | str) -> tuple[RegisterSpec, int]:
    """The raw value of ``value`` in ``reg`` (an f32's bit pattern, a string's bytes), by the
    runtime's codecs, with the runtime description of the register."""
    spec = RegisterSpec(reg.name, reg.address, type=reg.type, table=reg.table, word_order=reg.word_order,
                        byte_order=reg.byte_order, length=reg.length, scale=reg.scale, offset=reg.offset,
                        encoding=reg.encoding)
    if isinstance(value, str):
        return spec, StringCodec(spec).encode(value)
    if reg.is_float:
        return spec, IeeeCodec(spec).encode(value)
    if reg.is_integer:
        return spec, IntCodec(spec).encode(int(value))
    return spec, FloatCodec(spec).encode(value)


@dataclass(frozen=True)
class Point:
    """One exported register element."""

    cell: Cell
    key: str                     # identifier: register name, ``name_<n>`` for array elements (n: the manual's number)
    interval: int                # polling interval, seconds
    selector: bool               # a page selector (exported read-only)

    @property
    def reg(self) -> Register:
        return self.cell.register

    @property
    def address(self) -> int:
        return self.cell.address

    @property
    def index(self) -> int:
        return self.cell.index

    @property
    def readable(self) -> bool:
        return self.reg.readable

    @property
    def writable(self) -> bool:
        """Offered as a control: writable, not a page selector, no write-deciding field open (``review:``)."""
        return self.reg.writable and not self.selector and not self.reg.open_for_writes

    @property
    def is_command(self) -> bool:
        return self.reg.command_value is not None


@dataclass(frozen=True)
class Selection:
    """What one export covers: the points, what was left out and why, the settings it used."""

    model: Model
    points: tuple[Point, ...]
    omitted: tuple[tuple[str, str], ...]     # (register element, reason)
    pages: tuple[tuple[str, int], ...]        # (selector, page shown)
    unit: int
    prefix: str

    def enum_labels(self, point: Point) -> tuple[tuple[int, str], ...]:
        if point.reg.enum is None:
            return ()
        return tuple((v.value, v.label) for v in self.model.enum(point.reg.enum).members)

    def enum_labels_of(self, name: str) -> tuple[tuple[int, str], ...]:
        return tuple((v.value, v.label) for v in self.model.enum(name).members)

    def omitted_lines(self) -> list[str]:
        """One comment line per reason: what was left out."""
        by_reason: dict[str, list[str]] = {}
        for name, reason in self.omitted:
            by_reason.setdefault(reason, []).append(name)
        return [f"not exported ({reason}): {', '.join(names)}" for reason, names in by_reason.items()]

    def intervals(self) -> list[int]:
        return sorted({p.interval for p in self.points if p.readable})


# ---------------------------------------------------------------- options shared by the tools


def int_option(values: Mapping[str, Any], key: str, default: int, low: int = 1, high: int = 86400) -> int:
    value = values.get(key)
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise OptionError(f"--{key.replace('_', '-')}: expected a whole number {low}..{high}, got {value!r}")
    return value


def _pairs(values: Mapping[str, Any], key: str) -> list[tuple[str, str]]:
    out = []
    for item in values.get(key) or ():
        name, sep, value = str(item).partition("=")
        if not sep or not name or not value:
            raise OptionError(f"--{key}: expected NAME=VALUE, got {item!r}")
        out.append((name, value))
    return out


def _unit(model: Model, values: Mapping[str, Any]) -> int:
    p = model.protocol
    fixed = {port.fixed_unit for port in p.ports if port.fixed_unit is not None}
    unit = values.get("unit")
    if unit is None:
        return 1 if p.unit_min <= 1 <= p.unit_max else p.unit_min
    if (not p.unit_min <= unit <= p.unit_max and unit not in fixed) or unit == p.broadcast_address:
        raise OptionError(f"--unit: {unit} is not a unit id of {model.name} ({p.unit_min}..{p.unit_max})")
    return int(unit)


def _pages(model: Model, values: Mapping[str, Any]) -> dict[str, int]:
    selectors = sorted({r.page.selector for r in model.registers if r.page is not None})
    chosen: dict[str, int] = {}
    for sel in selectors:
        reg = model.register(sel)
        shown = sorted({r.page.value for r in model.registers if r.page is not None and r.page.selector == sel})
        default = reg.default_at(0)
        chosen[sel] = int(default) if default is not None and int(default) in shown else shown[0]
    for name, value in _pairs(values, "page"):
        if name not in chosen:
            raise OptionError(f"--page: {name!r} is not a page selector of {model.name} "
                              f"(selectors: {', '.join(selectors) or 'none'})")
        try:
            chosen[name] = int(value, 0)
        except ValueError:
            raise OptionError(f"--page: {value!r} is not a number") from None
    return chosen


def _intervals(model: Model, values: Mapping[str, Any]) -> dict[str, int]:
    scan = int_option(values, "scan_interval", DEFAULT_SCAN_S)
    settings = int_option(values, "settings_interval", DEFAULT_SETTINGS_S)
    out: dict[str, int] = {}
    for group in model.groups:
        regs = [r for r in model.group_registers(group.name) if r.readable]
        out[group.name] = settings if regs and all(r.writable for r in regs) else scan
    known = {g.name for g in model.groups}
    for name, value in _pairs(values, "interval"):
        if name not in known:
            raise OptionError(f"--interval: {name!r} is not a group of {model.name} (groups: {', '.join(sorted(known))})")
        if not value.isdigit() or not 1 <= int(value) <= 86400:
            raise OptionError(f"--interval: {value!r} is not a number of seconds 1..86400")
        out[name] = int(value)
    return out


def _prefix(model: Model, values: Mapping[str, Any]) -> str:
    prefix = values.get("name_prefix")
    if prefix is None:
        return model.name
    if not isinstance(prefix, str) or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9 _-]{0,39}", prefix):
        raise OptionError(f"--name-prefix: {prefix!r} must be 1-40 letters, digits, spaces, '_' or '-'")
    return prefix


def select(model: Model, values: Mapping[str, Any]) -> Selection:
    """The register elements an integration export covers (every readable or writable element of
    the chosen groups, on the chosen pages); the rest goes to ``omitted`` with the reason."""
    groups = values.get("only")
    known = {g.name for g in model.groups}
    for g in groups or ():
        if g not in known:
            raise OptionError(f"--only: {g!r} is not a group of {model.name} (groups: {', '.join(sorted(known))})")
    pages = _pages(model, values)
    intervals = _intervals(model, values)
    selectors = set(pages)
    points: list[Point] = []
    omitted: list[tuple[str, str]] = []
    for reg in model.registers:
        if groups and reg.group not in groups:
            continue
        for cell in reg.cells():
            if reg.page is not None and pages[reg.page.selector] != reg.page.value:
                omitted.append((cell.name, f"page {reg.page.value} of {reg.page.selector} "
                                           f"(export it with --page {reg.page.selector}={reg.page.value})"))
                continue
            key = f"{reg.name}_{cell.index + reg.first_index}" if reg.is_array else reg.name  # the manual's number
            points.append(Point(cell, key, intervals.get(reg.group, DEFAULT_SCAN_S), reg.name in selectors))
    points.sort(key=lambda p: (p.address, p.key))
    return Selection(model, tuple(points), tuple(omitted), tuple(sorted(pages.items())), _unit(model, values),
                     _prefix(model, values))


# ---------------------------------------------------------------- transports


@dataclass(frozen=True)
class SerialSettings:
    port: str                 # the map's port name
    mode: str                 # rtu | ascii
    baudrate: int
    parity: str               # none | even | odd
    data_bits: int
    stop_bits: int


def _port(model: Model, name: str | None, modes: Sequence[str]) -> Port:
    ports = model.protocol.ports
    if name is not None:
        for port in ports:
            if port.name == name:
                return port
        raise OptionError(f"--port: {name!r} is not a port of {model.name} (ports: {', '.join(p.name for p in ports)})")
    for port in ports:
        if set(port.modes) & set(modes):
            return port
    raise OptionError(f"{model.name}: no port speaks {' or '.join(modes)}")


def serial_settings(model: Model, values: Mapping[str, Any], modes: Sequence[str] = ("rtu", "ascii")) -> SerialSettings:
    """The serial line: options first, then the map's port defaults; anything the map leaves open
    and no option gives is an error that lists the choices (nothing is guessed)."""
    port = _port(model, values.get("port"), modes)
    usable = [m for m in port.modes if m in modes]
    if not usable:
        raise OptionError(f"{model.name}: port {port.name} speaks {', '.join(port.modes)}; this tool speaks "
                          f"{' or '.join(modes)} only")
    missing: list[str] = []

    def pick(key: str, given: Any, default: Any, choices: Sequence[Any], what: str) -> Any:
        if given is not None:
            if choices and given not in choices:
                raise OptionError(f"--{key}: {given} is not among port {port.name}'s {what} ({', '.join(map(str, choices))})")
            return given
        if default is not None:
            return default
        if len(choices) == 1:
            return choices[0]
        missing.append(f"--{key} ({', '.join(map(str, choices)) or 'not listed'})")
        return None

    mode = pick("method", values.get("method"), port.default_mode if port.default_mode in usable else None, usable, "modes")
    baud = pick("baudrate", values.get("baudrate"), port.default_baudrate, port.baudrates, "baud rates")
    parity = pick("parity", values.get("parity"), port.default_parity, port.parity, "parities")
    data_bits = pick("bytesize", values.get("bytesize"), 8 if 8 in port.data_bits or not port.data_bits else None,
                     port.data_bits, "data bits")
    stop_bits = pick("stopbits", values.get("stopbits"), port.default_stop_bits, port.stop_bits, "stop bits")
    if missing:
        raise OptionError(f"{model.name}: the map leaves the serial line of port {port.name} open; give "
                          + ", ".join(missing))
    return SerialSettings(port.name, mode, int(baud), parity, int(data_bits), int(stop_bits))


def tcp_endpoint(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (IPv6 as ``[::1]:502``)."""
    host, sep, port = text.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536 or any(c.isspace() for c in host):
        raise OptionError(f"--tcp: expected HOST:PORT, got {text!r}")
    return host, int(port)


def timing_ms(value: float | None) -> int | None:
    return None if value is None else int(math.ceil(value))
