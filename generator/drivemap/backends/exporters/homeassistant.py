"""The ``homeassistant`` exporter: a Home Assistant package with a ``modbus:`` hub and its entities.

One entity per register element: a modbus ``sensor`` (data type, swap, scale, offset, precision,
unit, device/state class from the unit), a ``template`` sensor that turns an enum value into its
label, a ``template`` binary sensor per one-bit field (a multi-bit field: a template sensor), a
modbus ``switch`` per command (a write-only enum register: one switch per value). Arrays whose
elements fit one read are one sensor with ``virtual_count`` (one request for the whole array).
Read-only registers are never writable; writable settings are sensors too (the modbus integration
has no number entity; write them with the ``modbus.write_register`` action).

Types beyond 16 bits: f32/f64/u64/s64 -> float32/float64/uint64/int64, string -> string with ``count`` =
length; low-first words -> ``swap: word``, low-first bytes -> ``swap: byte`` (both: ``word_byte``);
input registers -> ``input_type: input``; a coil or discrete input -> a modbus ``binary_sensor``
(``input_type: coil``/``discrete_input``), a writable coil -> a ``switch`` with ``write_type: coil``
that reads its state back (``verify``); ``not_available`` -> ``nan_value`` (the integration takes one
value and compares it with the decoded integer; floats and strings have none, a NaN float reads as
unavailable anyway). A scale register (value x 10^factor) has no equivalent in the integration: the
modbus sensor is named ``<name> raw`` and a template sensor ``<name>`` multiplies it by 10^factor,
unavailable while either is (the header of the export lists them).

Key names follow the current Home Assistant release; ``--ha-version X.Y`` writes an older
release's names where they differ (``KEYS``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from drivemap.backends.exporters.base import Exporter, OptionError, Options, option
from drivemap.backends.options import SelectionOptions, SerialOptions
from drivemap.backends.views import integrations as iv
from drivemap.backends.views.common import header as generated_header
from drivemap.backends.views.common import provenance, review_lines
from drivemap.backends.yamltext import Hex, dump, header
from drivemap.model.nodes import READ_CODES, Model, Register
from drivemap.runtime.client.protocol.planner import MODBUS_MAX_READ
from drivemap.runtime.client.values.codec import raw_to_words

__all__ = ["DATA_TYPES", "KEYS", "HomeAssistantExporter", "render_line"]

#: Home Assistant's current release line (its key names are the default).
CURRENT = (2026, 11)
OLDEST = (2022, 1)

#: drivemap type -> the modbus integration's data_type (a string reads ``count`` = length registers).
DATA_TYPES: dict[str, str] = {
    "u16": "uint16", "s16": "int16", "bool": "uint16",
    "u32": "uint32", "s32": "int32",
    "u64": "uint64", "s64": "int64",
    "f32": "float32", "f64": "float64",
    "string": "string",
}
#: drivemap register table -> the entity's input_type.
INPUT_TYPES = {"holding": "holding", "input": "input", "coil": "coil", "discrete": "discrete_input"}


def swap_of(reg: Register) -> str | None:
    """The integration's ``swap``: ``word`` reverses the words (low word first), ``byte`` swaps the
    bytes of each word (low byte first), ``word_byte`` both; one-word types and strings only ``byte``."""
    words = reg.words > 1 and reg.type != "string" and reg.word_order == "low_first"
    byte = reg.byte_order == "low_first"
    if words and byte:
        return "word_byte"
    return "word" if words else "byte" if byte else None


#: Key names by release: the first release that reads a name -> {our key: its name}. 2023.10 added
#: ``device_address`` and ``virtual_count`` (home-assistant/core #100399, #100398); the current
#: release still reads ``slave``/``slave_count`` but documents the new names.
KEYS: tuple[tuple[tuple[int, int], dict[str, str]], ...] = (
    ((2024, 8), {"device_address": "device_address", "virtual_count": "virtual_count", "action": "action"}),
    ((2023, 10), {"device_address": "device_address", "virtual_count": "virtual_count", "action": "service"}),
    (OLDEST, {"device_address": "slave", "virtual_count": "slave_count", "action": "service"}),
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


@dataclass(frozen=True)
class HomeAssistantOptions(SelectionOptions, SerialOptions):
    hub_name: str | None = option(help="name of the modbus hub (default: the model id)")
    tcp: str | None = option(metavar="HOST:PORT", exclusive="where", help="Modbus TCP (a gateway or the device)")
    rtu_over_tcp: str | None = option(metavar="HOST:PORT", exclusive="where", help="RTU frames over TCP")
    serial: str | None = option(metavar="DEV", exclusive="where", help="serial device (default: /dev/ttyUSB0)")
    ha_version: str | None = option(
        metavar="X.Y", help=f"write the key names of this Home Assistant release (default: {CURRENT[0]}.{CURRENT[1]})")


class HomeAssistantExporter(Exporter):
    name = "homeassistant"
    help = "Home Assistant package: a modbus: hub (serial or TCP) with sensors and switches, template labels and bits"
    suffix = ".yaml"

    options_class = HomeAssistantOptions

    multi_device = True

    def render_line(self, devices: Sequence[tuple[Model, int | None]], options: Options) -> dict[str, str]:
        """Several devices on one line: one hub (:func:`render_line`)."""
        return render_line(devices, options)

    def render(self, model: Model, options: Options) -> dict[str, str]:
        own = HomeAssistantOptions.from_values(options.values)
        version = _version(own.ha_version)
        sel = iv.select(model, own.values())
        build = _Build(model, sel, keys_for(version), own)
        hub = build.hub()
        doc: dict[str, Any] = {"modbus": [hub]}
        if build.templates_sensor or build.templates_binary or build.templates_select:
            block: dict[str, Any] = {}
            if build.templates_select:
                block["select"] = build.templates_select
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
            *provenance(model),
            *review_lines(model),
            *build.notes,
        ]
        return {f"{model.name}.homeassistant.yaml": header(lines) + dump(doc)}


class _Build:
    """The entities of one export (kept apart from the exporter class so each step stays short)."""

    def __init__(self, model: Model, sel: iv.Selection, keys: Mapping[str, str], own: HomeAssistantOptions) -> None:
        self.model, self.sel, self.keys, self.own = model, sel, keys, own
        self.sensors: list[dict[str, Any]] = []
        self.switches: list[dict[str, Any]] = []
        self.binary_sensors: list[dict[str, Any]] = []
        self.templates_sensor: list[dict[str, Any]] = []
        self.templates_binary: list[dict[str, Any]] = []
        self.templates_select: list[dict[str, Any]] = []
        self.notes: list[str] = []
        self._entities()

    # ---------------------------------------------------------------- the hub

    def hub(self) -> dict[str, Any]:
        own = self.own
        hub: dict[str, Any] = {"name": own.hub_name or self.model.name}
        if own.tcp or own.rtu_over_tcp:
            host, port = iv.tcp_endpoint(own.tcp or own.rtu_over_tcp or "")
            hub.update({"type": "tcp" if own.tcp else "rtuovertcp", "host": host, "port": port})
        else:
            line = iv.serial_settings(self.model, own.values())
            hub.update({"type": "serial", "method": line.mode, "port": own.serial or "/dev/ttyUSB0",
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
        if self.binary_sensors:
            hub["binary_sensors"] = self.binary_sensors
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
            if reg.bit_table:
                self._bit(point)
                continue
            if point.is_command or (reg.enum and not reg.readable and point.writable):
                self._switches(point)
                continue
            if not reg.readable:
                self.notes.append(f"not exported: {point.cell.name} is write-only (use the modbus.write_register action)")
                continue
            group = [p for p in self.sel.points if p.reg.name == reg.name]
            if (reg.is_array and len(group) == reg.count and reg.stride == 1 and reg.type != "string"
                    and reg.first_index == 0 and reg.count * reg.words <= self._max_read(reg.table)):
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
        scaled = sorted({p.reg.name for p in self.sel.points if p.reg.scale_register and p.reg.readable})
        if scaled:
            self.notes.append("scale registers (value x 10^factor, SunSpec): the modbus integration has no such "
                              "option; each '<name> raw' modbus sensor is the unscaled value and a template sensor "
                              f"'<name>' multiplies it by 10^<its factor register>: {', '.join(scaled)}")

    def _max_read(self, table: str) -> int:
        fc = self.model.protocol.function(READ_CODES.get(table, 0x03))
        return fc.max_quantity if fc is not None and fc.max_quantity else MODBUS_MAX_READ

    def _bit(self, point: iv.Point) -> None:
        """A coil or discrete input: a binary_sensor, a writable coil a switch (which reads it back)."""
        reg = point.reg
        name = self.entity_name(point)
        entry: dict[str, Any] = {"name": name, "unique_id": slug(name), "address": Hex(point.address),
                                 self.keys["device_address"]: self.sel.unit}
        if point.writable:
            kind = write_type(self.model, reg)
            if kind is None:
                self.notes.append(f"not exported as a switch: {point.cell.name} (the map lists no coil write)")
                return
            entry.update({"write_type": kind, "command_on": 1, "command_off": 0})
            if reg.readable:
                entry["verify"] = {"input_type": "coil"}
            self.switches.append(entry)
        elif reg.readable:
            entry.update({"input_type": INPUT_TYPES[reg.table], "scan_interval": point.interval})
            self.binary_sensors.append(entry)

    def entity_name(self, point: iv.Point) -> str:
        """The name Home Assistant shows (element 0 of an array keeps the plain name, as virtual_count
        does; an array with the manual's own numbering (first_index) numbers every element so)."""
        base = f"{self.sel.prefix} {point.reg.name}"
        if point.reg.is_array and point.reg.first_index:
            return point.reg.display_name(point.index, base)
        return f"{base} {point.index}" if point.reg.is_array and point.index else base

    def entity_id(self, point: iv.Point) -> str:
        return f"sensor.{slug(self.entity_name(point))}"

    def _sensor(self, point: iv.Point, virtual: int) -> dict[str, Any]:
        reg = point.reg
        name = self.entity_name(point) + (" raw" if needs_template(reg) else "")
        entry: dict[str, Any] = {
            "name": name,
            "unique_id": slug(name),
            "address": Hex(point.address),
            self.keys["device_address"]: self.sel.unit,
            "input_type": INPUT_TYPES[reg.table],
            "data_type": DATA_TYPES[reg.type],
        }
        if reg.type == "string":
            entry["count"] = reg.length
        swap = swap_of(reg)
        if swap:
            entry["swap"] = swap
        if virtual:
            entry[self.keys["virtual_count"]] = virtual
        if reg.type == "string":
            entry["scan_interval"] = point.interval
            self._template(point, name, 0)
            return entry
        self._nan(point, entry)
        if reg.scale != 1:
            entry["scale"] = _number(reg.scale)
        if reg.offset:
            entry["offset"] = _number(reg.offset)
        shown = iv.display_decimals(reg)
        places = shown or 0
        if shown is not None and (places or reg.precision is not None):
            entry["precision"] = places
        if needs_template(reg):
            self._template(point, name, places)
        elif reg.unit and not reg.enum and not reg.bits:
            entry.update(_unit_keys(reg.unit, _version(self.own.ha_version)))
        entry["scan_interval"] = point.interval
        return entry

    def _nan(self, point: iv.Point, entry: dict[str, Any]) -> None:
        """``nan_value``: the integration ignores a falsy one (it tests ``if self._nan_value``), so 0
        is handled by the template sensor (:meth:`_template`) and the first other value goes here."""
        reg = point.reg
        if not reg.not_available or reg.is_float:
            return
        # the integration compares the decoded value (signed for s16/s32/s64) with one value
        others = [v for v in reg.not_available if v != 0]
        if others:
            entry["nan_value"] = others[0]
        if len(others) > 1:
            self.notes.append(f"{point.cell.name}: the integration takes one nan_value; not available as well: "
                              + ", ".join(hex(v) for v in others[1:]))

    def _template(self, point: iv.Point, raw_name: str, places: int) -> None:
        """The template sensor over a '<name> raw' modbus sensor: a string without its NUL/space
        padding; a scale register's raw x 10^factor; unavailable while the raw value is 0 when 0
        means not available (a nan_value of 0 is ignored by the integration)."""
        reg = point.reg
        raw_id = f"sensor.{slug(raw_name)}"
        available = [f"has_value('{raw_id}')"]
        if reg.type == "string":
            state = f"{{{{ states('{raw_id}') | regex_replace('[\\x00 ]+$', '') }}}}"
        elif reg.scale_register:
            factor = self.model.register(reg.scale_register)
            sf_id = f"sensor.{slug(f'{self.sel.prefix} {factor.name}')}"
            available.append(f"has_value('{sf_id}')")
            state = (f"{{% set sf = states('{sf_id}') | int %}}{{% set v = states('{raw_id}') | float %}}"
                     f"{{{{ (v * 10 ** sf) | round({places} - sf if sf < 0 else {places}) }}}}")
        else:
            state = f"{{{{ states('{raw_id}') }}}}"
        if 0 in reg.not_available and not reg.is_float:
            available.append(f"(states('{raw_id}') | float(0)) != {_number(reg.offset)}")
        entry: dict[str, Any] = {"name": self.entity_name(point), "unique_id": slug(self.entity_name(point)),
                                 "state": state, "availability": f"{{{{ {' and '.join(available)} }}}}"}
        if reg.unit and not reg.enum and not reg.bits and reg.type != "string":
            entry.update(_unit_keys(reg.unit, _version(self.own.ha_version)))
        self.templates_sensor.append(entry)

    def _switches(self, point: iv.Point) -> None:
        """A command: one switch; a write-only enum: one switch per value (written by the function the map allows)."""
        reg = point.reg
        kind = write_type(self.model, reg)
        if kind is None or reg.words > 1:
            how = "use the modbus.write_register action"
            if reg.words > 1 and point.is_command:
                spec, _ = iv.wire_raw(reg, 0)
                words = raw_to_words(spec, int(reg.command_value or 0) & ((1 << (16 * reg.words)) - 1))
                how += (f" with value: {words}, the {reg.words}-word list, sent as 10h; "
                        "a single number goes out as 06h to one register")
            self.notes.append(f"not exported as a switch: {point.cell.name} ("
                              + ("a switch writes one register" if reg.words > 1 else "the map lists no register write")
                              + f"; {how})")
            return
        if point.is_command:
            self.switches.append(self._switch(point, point.key, reg.command_value or 0, kind))
            return
        for item in self.model.enum(reg.enum or "").members:
            self.switches.append(self._switch(point, f"{point.key} {item.name}", item.value, kind))

    def _switch(self, point: iv.Point, key: str, value: int, kind: str) -> dict[str, Any]:
        # command_off repeats the command: turning the switch off never writes a value the map does not document
        return {
            "name": f"{self.sel.prefix} {key}",
            "unique_id": slug(f"{self.sel.prefix} {key}"),
            "address": Hex(point.address),
            self.keys["device_address"]: self.sel.unit,
            "write_type": kind,
            "command_on": value,
            "command_off": value,
        }

    def _select(self, point: iv.Point, source: str) -> None:
        """A template select over a writable register's sensor with a value set: its state is the
        option of the value read, choosing an option writes that value's words with the function code
        the map allows (a list of words is 10h, one word 06h)."""
        reg = point.reg
        pairs = iv.options(reg)
        states = [[item.value, text] for item, text in pairs]
        single = reg.words == 1 and self.model.protocol.function(0x06) is not None
        writes = {text: (iv.wire_words(reg, item.value)[0] if single else iv.wire_words(reg, item.value))
                  for item, text in pairs}
        name = self.entity_name(point) + " select"
        value = "states('" + source + "')" + (" | float(none)" if reg.type != "string" else "")
        self.templates_select.append({
            "name": name, "unique_id": slug(name),
            "state": (f"{{% set opts = {jinja_literal(states)} %}}{{% set v = {value} %}}"
                      "{% for o in opts if o[0] == v %}{{ o[1] }}{% endfor %}"),
            "options": f"{{{{ {jinja_literal([text for _, text in pairs])} }}}}",
            "availability": f"{{{{ has_value('{source}') }}}}",
            "select_option": [{self.keys["action"]: "modbus.write_register", "data": {
                "hub": self.own.hub_name or self.model.name, "slave": self.sel.unit,
                "address": point.address, "value": f"{{{{ {jinja_literal(writes)}[option] }}}}"}}],
        })

    def _derived(self, point: iv.Point) -> None:
        """Template entities over a register's sensor: the enum label, each bit field, a select."""
        source = self.entity_id(point)
        available = f"{{{{ has_value('{source}') }}}}"
        if point.reg.values and point.writable and not point.reg.scale_register:
            self._select(point, source)
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


def needs_template(reg: Register) -> bool:
    """A register the modbus sensor cannot show as drivemap reads it: a string (padded with NULs), a
    scale register (x 10^factor), 0 meaning not available (``nan_value: 0`` is ignored)."""
    return reg.type == "string" or bool(reg.scale_register) or (0 in reg.not_available and not reg.is_float)


def write_type(model: Model, reg: Register) -> str | None:
    """The switch's ``write_type``: the single write (05h ``coil``, 06h ``holding``) when the map lists
    it, else the multiple write (0Fh ``coils``, 10h ``holdings``), else None (the map lists neither)."""
    has = model.protocol.function
    if reg.table == "coil":
        return "coil" if has(0x05) else "coils" if has(0x0F) else None
    if reg.words == 1 and has(0x06):
        return "holding"
    return "holdings" if has(0x10) else None


def _unit_keys(unit: str, version: tuple[int, int] = CURRENT) -> dict[str, Any]:
    unit = iv.unit_for(unit)
    out: dict[str, Any] = {"unit_of_measurement": unit}
    device_class, state_class = iv.DEVICE_CLASSES.get(unit, (None, None))
    if device_class and not iv.device_class_known(device_class, version):
        device_class = None
    if device_class:
        out["device_class"] = device_class
    if state_class:
        out["state_class"] = state_class
    return out


def _label_template(source: str, value: str, labels: tuple[tuple[int, str], ...], expression: bool = False) -> str:
    mapping = jinja_literal({str(v): label for v, label in labels})
    raw = f"({value}) | string" if expression else f"states('{source}')"
    return f"{{% set labels = {mapping} %}}{{% set v = {raw} %}}{{{{ labels.get(v, v) }}}}"


def _number(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)


# ---- several devices on one line ------------------------------------------------------------
# Several devices on one line: one Home Assistant ``modbus:`` hub with all their entities.
#
# Home Assistant loads one hub per serial port (a second hub on the same port is dropped:
# "/dev/ttyUSB0 is duplicate, not loaded!"), so devices that share a line must share a hub:
# ``drivemap export ev:1 vfd1000:2 --format homeassistant --serial /dev/ttyUSB0`` writes one package
# whose hub holds both devices' entities, each with its own ``device_address``. The line settings
# (mode, baud rate, parity, stop bits) must be the same for every device (they share the wire);
# the hub's ``timeout`` and ``message_wait_milliseconds`` are the largest any map asks for. Entity
# names start with the model id (``model_unit`` when a model appears more than once).

#: Hub keys that describe the line: equal for every device, or the export is refused.
LINE_KEYS = ("type", "method", "port", "host", "baudrate", "bytesize", "parity", "stopbits")
ENTITY_KEYS = ("sensors", "binary_sensors", "switches")


def render_line(devices: Sequence[tuple[Model, int | None]], options: Options) -> dict[str, str]:
    """One package for several (model, unit id) devices on one line (see the module docstring)."""
    line = HomeAssistantOptions.from_values(options.values)
    if line.unit is not None:
        raise OptionError("--unit: give each device's unit as MODEL:UNIT (e.g. ev:1 vfd1000:2)")
    if line.name_prefix is not None:
        raise OptionError("--name-prefix: with several devices each entity name starts with its model id")
    version = _version(line.ha_version)
    names = [m.name for m, _ in devices]
    builds: list[tuple[Model, _Build, dict[str, Any]]] = []
    units: dict[int, str] = {}
    for model, unit in devices:
        own = replace(line, unit=unit, name_prefix=f"{model.name}_{unit}" if names.count(model.name) > 1 else None)
        build = _Build(model, iv.select(model, own.values()), keys_for(version), own)
        chosen = build.sel.unit
        if chosen in units:
            raise OptionError(f"unit {chosen} is given to both {units[chosen]} and {model.name}: every device "
                              "on one line needs its own unit id (write MODEL:UNIT)")
        units[chosen] = model.name
        builds.append((model, build, build.hub()))
    hub = _merged_hub(builds, line)
    templates: dict[str, list[Any]] = {"sensor": [], "binary_sensor": []}
    notes: list[str] = []
    for model, build, _ in builds:
        templates["sensor"] += build.templates_sensor
        templates["binary_sensor"] += build.templates_binary
        notes += [f"{model.name} (unit {build.sel.unit}): {note}" for note in build.notes]
    doc: dict[str, Any] = {"modbus": [hub]}
    block = {key: items for key, items in templates.items() if items}
    if block:
        doc["template"] = [block]
    first = devices[0][0]
    lines = [
        generated_header(first, options).replace(f"from {options.source(first)}",
                                                 "from " + ", ".join(options.source(m) for m, _ in devices)),
        f"One modbus hub for {len(devices)} devices on one line: "
        + ", ".join(f"{m.name} unit {b.sel.unit}" for m, b, _ in builds)
        + f" - Home Assistant {version[0]}.{version[1]} key names",
        "A package: put it in packages/ (homeassistant: packages: !include_dir_named packages)",
        "or paste its modbus: and template: keys into configuration.yaml.",
        *notes,
    ]
    return {f"{'+'.join(dict.fromkeys(names))}.homeassistant.yaml": header(lines) + dump(doc)}


def _merged_hub(builds: list[tuple[Model, _Build, dict[str, Any]]], line: HomeAssistantOptions) -> dict[str, Any]:
    first_model, _, first = builds[0]
    hub: dict[str, Any] = {key: value for key, value in first.items() if key not in ENTITY_KEYS}
    hub["name"] = line.hub_name or "_".join(dict.fromkeys(m.name for m, _, _ in builds))
    for model, _, other in builds[1:]:
        differ = [f"{key} {first.get(key)!r} ({first_model.name}) vs {other.get(key)!r} ({model.name})"
                  for key in LINE_KEYS if first.get(key) != other.get(key)]
        if differ:
            raise OptionError("devices on one line share its settings; the maps ask for different ones: "
                              + "; ".join(differ) + " (give --baudrate/--parity/--stopbits/--method for the line)")
    for key in ("timeout", "message_wait_milliseconds"):
        waits = [h[key] for _, _, h in builds if key in h]
        if waits:
            hub[key] = max(waits)
    for key in ENTITY_KEYS:
        items = [entity for _, _, h in builds for entity in h.get(key, [])]
        if items:
            hub[key] = items
    return hub
