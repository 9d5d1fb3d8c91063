"""The ``homeassistant`` exporter: a Home Assistant package with a ``modbus:`` hub and its entities.

One entity per register element: a modbus ``sensor`` (data type, swap, scale, offset, precision,
unit, device/state class from the unit), a ``template`` sensor that turns an enum value into its
label, a ``template`` binary sensor per one-bit field (a multi-bit field: a template sensor), a
modbus ``switch`` per command (a write-only enum register: one switch per value). Arrays whose
elements fit one read are one sensor with ``virtual_count`` (one request for the whole array).
Read-only registers are never writable; writable settings are sensors too (the modbus integration
has no number entity; write them with the ``modbus.write_register`` action).

Key names follow the current Home Assistant release; ``--ha-version X.Y`` writes an older
release's names where they differ (``KEYS``).
"""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Mapping
from typing import Any

from ..model import Model
from ..runtime.planner import MODBUS_MAX_READ
from ..views import integrations as iv
from ..views.common import header as generated_header
from ._yaml import Hex, dump, header
from .base import Exporter, OptionError, Options

__all__ = ["DATA_TYPES", "KEYS", "HomeAssistantExporter"]

#: Home Assistant's current release line (its key names are the default).
CURRENT = (2026, 11)
OLDEST = (2022, 1)

#: (drivemap type, word order) -> (data_type, swap). Issue 14 adds f32/f64/u64/s64/string here.
DATA_TYPES: dict[tuple[str, str | None], tuple[str, str | None]] = {
    ("u16", None): ("uint16", None),
    ("s16", None): ("int16", None),
    ("u32", "high_first"): ("uint32", None),
    ("u32", "low_first"): ("uint32", "word"),
    ("s32", "high_first"): ("int32", None),
    ("s32", "low_first"): ("int32", "word"),
}
#: drivemap register table -> the sensor's input_type (issue 14 adds input -> "input").
INPUT_TYPES = {"holding": "holding"}

#: Key names by release: the first release that reads a name -> {our key: its name}. 2023.10 added
#: ``device_address`` and ``virtual_count`` (home-assistant/core #100399, #100398); the current
#: release still reads ``slave``/``slave_count`` but documents the new names.
KEYS: tuple[tuple[tuple[int, int], dict[str, str]], ...] = (
    ((2023, 10), {"device_address": "device_address", "virtual_count": "virtual_count"}),
    (OLDEST, {"device_address": "slave", "virtual_count": "slave_count"}),
)

_PARITY = {"none": "N", "even": "E", "odd": "O"}


def _version(text: str | None) -> tuple[int, int]:
    if text is None:
        return CURRENT
    match = re.fullmatch(r"(\d{4})\.(\d{1,2})(?:\.\d+)?", str(text))
    if not match:
        raise OptionError(f"--ha-version: expected YEAR.MONTH (e.g. 2024.3), got {text!r}")
    version = (int(match.group(1)), int(match.group(2)))
    if version < OLDEST:
        raise OptionError(f"--ha-version: releases before {OLDEST[0]}.{OLDEST[1]} used another modbus: layout")
    return version


def keys_for(version: tuple[int, int]) -> dict[str, str]:
    for first, names in KEYS:
        if version >= first:
            return names
    raise AssertionError("KEYS covers every accepted version")


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def jinja_literal(value: Any) -> str:
    """A value as a Jinja literal that no label can break out of: JSON with every non-ASCII
    character and every character Jinja or YAML treat specially written as a \\u escape."""
    text = json.dumps(value, ensure_ascii=True, sort_keys=True)
    out, in_string, escaped = [], False, False
    for ch in text:
        if in_string and not escaped and ch in "{}%#'":
            out.append(f"\\u{ord(ch):04x}")
            continue
        out.append(ch)
        if escaped:
            escaped = False
        elif ch == "\\":
            escaped = True
        elif ch == '"':
            in_string = not in_string
    return "".join(out)


class HomeAssistantExporter(Exporter):
    name = "homeassistant"
    help = "Home Assistant package: a modbus: hub (serial or TCP) with sensors and switches, template labels and bits"
    suffix = ".yaml"

    def add_arguments(self, parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
        parser.add_argument("--hub-name", default=None, help="name of the modbus hub (default: the model id)")
        where = parser.add_mutually_exclusive_group()
        where.add_argument("--tcp", default=None, metavar="HOST:PORT", help="Modbus TCP (a gateway or the device)")
        where.add_argument("--rtu-over-tcp", default=None, metavar="HOST:PORT", help="RTU frames over TCP")
        where.add_argument("--serial", default=None, metavar="DEV", help="serial device (default: /dev/ttyUSB0)")
        parser.add_argument("--ha-version", default=None, metavar="X.Y",
                            help=f"write the key names of this Home Assistant release (default: {CURRENT[0]}.{CURRENT[1]})")
        iv.add_selection_arguments(parser)
        iv.add_serial_arguments(parser)

    def render(self, model: Model, options: Options) -> dict[str, str]:
        values = options.values
        version = _version(values.get("ha_version"))
        sel = iv.select(model, values)
        build = _Build(model, sel, keys_for(version), values)
        hub = build.hub()
        doc: dict[str, Any] = {"modbus": [hub]}
        if build.templates_sensor or build.templates_binary:
            block: dict[str, Any] = {}
            if build.templates_sensor:
                block["sensor"] = build.templates_sensor
            if build.templates_binary:
                block["binary_sensor"] = build.templates_binary
            doc["template"] = [block]
        lines = [
            generated_header(model, options),
            f"{model.device.title} - Home Assistant {version[0]}.{version[1]} key names",
            "A package: put it in packages/ (homeassistant: packages: !include_dir_named packages)",
            "or paste its modbus: and template: keys into configuration.yaml.",
            *build.notes,
        ]
        return {f"{model.name}.homeassistant.yaml": header(lines) + dump(doc)}


class _Build:
    """The entities of one export (kept apart from the exporter class so each step stays short)."""

    def __init__(self, model: Model, sel: iv.Selection, keys: Mapping[str, str], values: Mapping[str, Any]) -> None:
        self.model, self.sel, self.keys, self.values = model, sel, keys, values
        self.sensors: list[dict[str, Any]] = []
        self.switches: list[dict[str, Any]] = []
        self.templates_sensor: list[dict[str, Any]] = []
        self.templates_binary: list[dict[str, Any]] = []
        self.notes: list[str] = []
        fc = model.protocol.function(0x03)
        self.max_read = fc.max_quantity if fc is not None and fc.max_quantity else MODBUS_MAX_READ
        self._entities()

    # ---------------------------------------------------------------- the hub

    def hub(self) -> dict[str, Any]:
        name = self.values.get("hub_name") or self.model.name
        hub: dict[str, Any] = {"name": str(name)}
        if self.values.get("tcp") or self.values.get("rtu_over_tcp"):
            host, port = iv.tcp_endpoint(self.values.get("tcp") or self.values["rtu_over_tcp"])
            hub.update({"type": "tcp" if self.values.get("tcp") else "rtuovertcp", "host": host, "port": port})
        else:
            line = iv.serial_settings(self.model, self.values)
            hub.update({"type": "serial", "method": line.mode, "port": self.values.get("serial") or "/dev/ttyUSB0",
                        "baudrate": line.baudrate, "bytesize": line.data_bits, "parity": _PARITY[line.parity],
                        "stopbits": line.stop_bits})
        t = self.model.protocol.timing
        if t.response_timeout_ms is not None:
            hub["timeout"] = _number((iv.timing_ms(t.response_timeout_ms) or 0) / 1000)
        wait = max([v for v in (t.inter_frame_gap_ms, *self._write_delays()) if v is not None], default=None)
        if wait is not None:
            hub["message_wait_milliseconds"] = iv.timing_ms(wait)
        if self.sensors:
            hub["sensors"] = self.sensors
        if self.switches:
            hub["switches"] = self.switches
        return hub

    def _write_delays(self) -> list[float]:
        return [p.reg.write_delay_ms for p in self.sel.points if p.writable and p.reg.write_delay_ms is not None]

    # ---------------------------------------------------------------- entities

    def _entities(self) -> None:
        done: set[str] = set()
        for point in self.sel.points:
            reg = point.reg
            if reg.name in done:
                continue
            if point.is_command:
                self.switches.append(self._switch(point, point.key, reg.command_value or 0))
                continue
            if reg.enum and not reg.readable and point.writable:
                for item in self.model.enum(reg.enum).values:
                    self.switches.append(self._switch(point, f"{point.key} {item.name}", item.value))
                continue
            if not reg.readable:
                self.notes.append(f"not exported: {point.cell.name} is write-only (use the modbus.write_register action)")
                continue
            group = [p for p in self.sel.points if p.reg.name == reg.name]
            if reg.is_array and len(group) == reg.count and reg.stride == 1 and reg.count * reg.words <= self.max_read:
                self.sensors.append(self._sensor(point, virtual=reg.count - 1))
                done.add(reg.name)
                targets = group
            else:
                self.sensors.append(self._sensor(point, virtual=0))
                targets = [point]
            for p in targets:
                self._derived(p)
        self.notes.extend(self.sel.omitted_lines())
        for p in self.sel.points:
            if p.selector:
                self.notes.append(f"{p.key} is a page selector: exported read-only (writing it changes what the "
                                  "paged entities read)")

    def entity_name(self, point: iv.Point) -> str:
        """The name Home Assistant shows (element 0 of an array keeps the plain name, as virtual_count does)."""
        base = f"{self.sel.prefix} {point.reg.name}"
        return f"{base} {point.index}" if point.reg.is_array and point.index else base

    def entity_id(self, point: iv.Point) -> str:
        return f"sensor.{slug(self.entity_name(point))}"

    def _sensor(self, point: iv.Point, virtual: int) -> dict[str, Any]:
        reg = point.reg
        data_type, swap = DATA_TYPES[(reg.type, reg.word_order)]
        entry: dict[str, Any] = {
            "name": self.entity_name(point),
            "unique_id": slug(self.entity_name(point)),
            "address": Hex(point.address),
            self.keys["device_address"]: self.sel.unit,
            "input_type": INPUT_TYPES["holding"],
            "data_type": data_type,
        }
        if swap:
            entry["swap"] = swap
        if virtual:
            entry[self.keys["virtual_count"]] = virtual
        if reg.scale != 1:
            entry["scale"] = _number(reg.scale)
        if reg.offset:
            entry["offset"] = _number(reg.offset)
        places = iv.decimals(reg.scale, reg.offset)
        if places:
            entry["precision"] = places
        if reg.unit and not reg.enum and not reg.bits:
            entry["unit_of_measurement"] = reg.unit
            device_class, state_class = iv.DEVICE_CLASSES.get(reg.unit, (None, None))
            if device_class:
                entry["device_class"] = device_class
            if state_class:
                entry["state_class"] = state_class
        entry["scan_interval"] = point.interval
        return entry

    def _switch(self, point: iv.Point, key: str, value: int) -> dict[str, Any]:
        # command_off repeats the command: turning the switch off never writes a value the map does not document
        return {
            "name": f"{self.sel.prefix} {key}",
            "unique_id": slug(f"{self.sel.prefix} {key}"),
            "address": Hex(point.address),
            self.keys["device_address"]: self.sel.unit,
            "write_type": "holding",
            "command_on": value,
            "command_off": value,
        }

    def _derived(self, point: iv.Point) -> None:
        """Template entities over a register's sensor: the enum label, each bit field."""
        source = self.entity_id(point)
        available = f"{{{{ has_value('{source}') }}}}"
        if point.reg.enum:
            self.templates_sensor.append({
                "name": f"{self.entity_name(point)} label",
                "unique_id": slug(f"{self.entity_name(point)} label"),
                "state": _label_template(source, "v", self.sel.enum_labels(point)),
                "availability": available,
            })
        for bit in point.reg.bits:
            name = f"{self.entity_name(point)} {bit.name}"
            uid = slug(name)
            value = f"((states('{source}') | int(0)) // {1 << bit.offset}) % {1 << bit.width}"
            if bit.width == 1:
                self.templates_binary.append({"name": name, "unique_id": uid, "state": f"{{{{ {value} == 1 }}}}",
                                              "availability": available})
            elif bit.enum:
                self.templates_sensor.append({"name": name, "unique_id": uid, "availability": available,
                                              "state": _label_template(source, value, self.sel.enum_labels_of(bit.enum),
                                                                       expression=True)})
            else:
                self.templates_sensor.append({"name": name, "unique_id": uid, "state": f"{{{{ {value} }}}}",
                                              "availability": available})


def _label_template(source: str, value: str, labels: tuple[tuple[int, str], ...], expression: bool = False) -> str:
    mapping = jinja_literal({str(v): label for v, label in labels})
    raw = f"({value}) | string" if expression else f"states('{source}')"
    return f"{{% set labels = {mapping} %}}{{% set v = {raw} %}}{{{{ labels.get(v, v) }}}}"


def _number(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)
