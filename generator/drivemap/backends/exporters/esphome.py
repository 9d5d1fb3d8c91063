"""The ``esphome`` exporter: a complete ESPHome device YAML (ESP32, UART, modbus, modbus_controller).

Entities per register element (``platform: modbus_controller``): ``sensor`` for values (scale and
offset as filters), ``number`` for writable values with a range (min/max/step in engineering
units, ``multiply`` for the scale), ``select`` for writable enums and writable registers with a value
set (``values:``; the option texts are its labels), ``text_sensor`` with the enum's
labels (HEXBYTES + ``map``) for read-only enums, ``binary_sensor`` with ``bitmask`` per one-bit
field of a one-word register (a multi-bit field, or any field of a multi-word register: a sensor with
``bitmask`` and the register's value_type, 0/1 for one bit: ESPHome's binary_sensor reads one word and
would split the register's read), ``switch`` per command (assumed state, never
polled). Every table and type of the map language: input registers are ``register_type: read``; a coil or discrete input is a
``binary_sensor`` (``coil``/``discrete_input``), a writable coil a ``switch`` that polls it (write-only:
assumed state); f32 -> FP32(_R), u64/s64 -> U_QWORD/S_QWORD(_R); strings are a ``text_sensor``
(``raw_encode: ANSI``); what ESPHome has no value_type for (f64, low byte first) is a ``text_sensor``
with the wire bytes as hex (HEXBYTES), listed in the header for the reader to decode;
``not_available`` values are a ``filter_out`` before scaling (integers; a NaN float is NaN anyway);
a scale register is the id of its sensor, and each scaled sensor multiplies by 10^its last value in a
``lambda`` filter. Range batching follows drivemap's read plan (:mod:`drivemap.backends.views.esphome`); timing comes
from the map (``command_throttle``, ``turnaround_time``, ``send_wait_time``, ``max_cmd_retries``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from drivemap.backends.exporters.base import Exporter, OptionError, Options, option
from drivemap.backends.options import SERIAL_GROUP, SelectionOptions, SerialOptions
from drivemap.backends.views import integrations as iv
from drivemap.backends.views.common import header as generated_header
from drivemap.backends.views.common import provenance, review_lines
from drivemap.backends.views.esphome import Item, align
from drivemap.backends.yamltext import Hex, Literal, LiteralMap, Secret, dump, header
from drivemap.model.nodes import Model, Register
from drivemap.model.spec import spec_from_model
from drivemap.runtime.client.protocol.planner import plan_reads

__all__ = ["REGISTER_TYPES", "VALUE_TYPES", "EsphomeExporter"]

#: (drivemap type, word order) -> value_type (high byte first: ESPHome has no byte-swapped types).
VALUE_TYPES: dict[tuple[str, str | None], str] = {
    ("u16", None): "U_WORD",
    ("s16", None): "S_WORD",
    ("bool", None): "U_WORD",
    ("u32", "high_first"): "U_DWORD",
    ("u32", "low_first"): "U_DWORD_R",
    ("s32", "high_first"): "S_DWORD",
    ("s32", "low_first"): "S_DWORD_R",
    ("f32", "high_first"): "FP32",
    ("f32", "low_first"): "FP32_R",
    ("u64", "high_first"): "U_QWORD",
    ("u64", "low_first"): "U_QWORD_R",
    ("s64", "high_first"): "S_QWORD",
    ("s64", "low_first"): "S_QWORD_R",
}
#: The ESPHome releases --esphome-version knows: the newest (the default) and the oldest the export supports.
NEWEST = (2026, 10)
OLDEST = (2026, 6)
#: From this release on, register_count is refused unless it is the width ESPHome derives, force_new_range
#: and skip_updates are replaced (reuse_previous_range; a controller per interval) and command_throttle
#: does nothing (the modbus hub's turnaround_time spaces commands): esphome/esphome#18085, #18652.
REUSE_RANGES = (2026, 9)

#: drivemap register table -> register_type.
REGISTER_TYPES = {"holding": "holding", "input": "read", "coil": "coil", "discrete": "discrete_input"}


def value_type(reg: Register) -> str | None:
    """ESPHome's value_type of a register, None where it has none (f64, strings, low byte first)."""
    if reg.byte_order == "low_first":
        return None
    return VALUE_TYPES.get((reg.type, reg.word_order if reg.words > 1 else None))


NUMBER_LIMIT = 16777215  # ESPHome's number range (24 bits of a float)
_PARITY = {"none": "NONE", "even": "EVEN", "odd": "ODD"}
_PLATFORMS = ("sensor", "binary_sensor", "text_sensor", "number", "select", "switch")


def text(value: str) -> str:
    """Map text for ESPHome: ``!literal`` when ESPHome's substitution pass would read it."""
    return Literal(value) if "$" in value else value


@dataclass(frozen=True)
class EsphomeOptions(SelectionOptions, SerialOptions):
    name: str | None = option(help="ESPHome node name (default: the model id)")
    board: str = option("esp32dev", help="ESP32 board (default esp32dev)")
    tx_pin: str = option("GPIO17", help="UART TX pin (default GPIO17)")
    rx_pin: str = option("GPIO16", help="UART RX pin (default GPIO16)")
    flow_control_pin: str | None = option(metavar="PIN", help="RS-485 DE/RE pin")
    no_network: bool = option(False, help="leave out wifi:, api: and ota: (which read !secret wifi_ssid / wifi_password)")
    esphome_version: str | None = option(
        metavar="YYYY.M", help=f"write only what this ESPHome release accepts (default: {NEWEST[0]}.{NEWEST[1]}, "
                               f"the newest known; oldest supported: {OLDEST[0]}.{OLDEST[1]})")
    method: str | None = option(choices=("rtu",), group=SERIAL_GROUP, help="framing")


class EsphomeExporter(Exporter):
    name = "esphome"
    help = "ESPHome device YAML: uart, modbus, modbus_controller and its entities, batched as drivemap plans"
    suffix = ".yaml"

    options_class = EsphomeOptions

    def render(self, model: Model, options: Options) -> dict[str, str]:
        own = EsphomeOptions.from_values(options.values)
        node = own.name or model.name.replace("_", "-")
        if not re.fullmatch(r"[a-z0-9][a-z0-9-]{0,30}", str(node)):
            raise OptionError(f"--name: {node!r} must be lower-case letters, digits and '-' (at most 31)")
        values = own.values()
        sel = iv.select(model, values)
        line = iv.serial_settings(model, values, modes=("rtu",))
        version = esphome_version(own.esphome_version)
        build = _Build(model, sel, version >= REUSE_RANGES)
        doc: dict[str, Any] = {
            "esphome": {"name": node},
            "esp32": {"board": own.board or "esp32dev", "framework": {"type": "esp-idf"}},
            "logger": {},
        }
        if not own.no_network:
            doc.update({"wifi": {"ssid": Secret("wifi_ssid"), "password": Secret("wifi_password")},
                        "api": {}, "ota": [{"platform": "esphome"}]})
        doc["uart"] = [{"id": "modbus_uart", "tx_pin": own.tx_pin or "GPIO17",
                        "rx_pin": own.rx_pin or "GPIO16", "baud_rate": line.baudrate,
                        "data_bits": line.data_bits, "parity": _PARITY[line.parity], "stop_bits": line.stop_bits}]
        doc["modbus"] = [self._modbus(model, own, build)]
        doc["modbus_controller"] = build.controllers()
        for platform in _PLATFORMS:
            entries = [i.config for i in build.items if i.platform == platform]
            if entries:
                doc[platform] = entries
        lines = [generated_header(model, options),
                 f"{model.device.title} - ESPHome {version[0]}.{version[1]} (esphome config FILE)",
                 *provenance(model), *review_lines(model),
                 f"reads per update: drivemap plans {len(build.layout.requests)}, "
                 f"this file makes ESPHome send {build.layout.esphome_requests}", *build.notes, *build.layout.notes]
        return {f"{model.name}.esphome.yaml": header(lines) + dump(doc)}

    @staticmethod
    def _modbus(model: Model, own: EsphomeOptions, build: _Build) -> dict[str, Any]:
        t = model.protocol.timing
        bus: dict[str, Any] = {"id": "modbus_bus", "uart_id": "modbus_uart"}
        if own.flow_control_pin:
            bus["flow_control_pin"] = own.flow_control_pin
        if t.response_timeout_ms is not None:
            bus["send_wait_time"] = f"{iv.timing_ms(t.response_timeout_ms)}ms"
        gap = build.throttle() if build.reuse else t.inter_frame_gap_ms
        if gap is not None:
            bus["turnaround_time"] = f"{iv.timing_ms(gap)}ms"
        return bus


def esphome_version(text: Any) -> tuple[int, int]:
    """``--esphome-version`` as (year, month): NEWEST when not given; OptionError if older than OLDEST."""
    if text is None:
        return NEWEST
    match = re.fullmatch(r"(\d{4})\.(\d{1,2})(?:\.\d+)?", str(text).strip())
    if not match:
        raise OptionError(f"--esphome-version: {text!r} is not a release (YYYY.M, e.g. {NEWEST[0]}.{NEWEST[1]})")
    version = (int(match.group(1)), int(match.group(2)))
    if version < OLDEST:
        raise OptionError(f"--esphome-version: {text} is older than the oldest supported release "
                          f"({OLDEST[0]}.{OLDEST[1]})")
    return version


class _Build:
    def __init__(self, model: Model, sel: iv.Selection, reuse: bool = True) -> None:
        self.model, self.sel, self.reuse = model, sel, reuse
        self.items: list[Item] = []
        self.notes: list[str] = sel.omitted_lines()
        self.raw: list[str] = []
        #: scale-factor registers -> the id of their entity (read by the scaled entities' lambda)
        exported = {p.reg.name for p in sel.points if p.readable and not p.reg.is_array}
        self.factors = {p.reg.scale_register: f"sf_{p.reg.scale_register}" for p in sel.points
                        if p.reg.scale_register and p.reg.scale_register in exported}
        readable = [p for p in sel.points if p.readable]
        self.base = min((p.interval for p in readable), default=iv.DEFAULT_SCAN_S)
        for point in sel.points:
            self._point(point)
        keys = sorted({(p.reg.name, p.index) for p in readable
                       if any(i.polled and i.address == p.address and i.table == p.reg.table for i in self.items)})
        plan = plan_reads(spec_from_model(model), keys) if keys else ()
        skips: dict[tuple[str, int], int] = {(p.reg.table, p.address): max(0, round(p.interval / self.base) - 1) for p in readable}
        if self.raw:
            self.notes.append("text_sensor with the wire bytes as hex (ESPHome has no value_type for them): "
                              + "; ".join(self.raw))
        if self.factors:
            self.notes.append("scale registers: each scaled sensor multiplies by 10^(the last value of its factor "
                              "sensor, id sf_<register>) in a lambda filter")
        self.layout = align(self.items, plan, skips, self._filler, reuse=self.reuse)
        if self.reuse and self.layout.skips:
            self.notes.append("slower polling intervals: a controller each (device_<n>x polls every n-th "
                              f"{self.base}s; ESPHome 2026.9 and later have no skip_updates)")

    def throttle(self) -> float | None:
        """The spacing of commands: the map's inter-frame gap or its longest write delay."""
        t = self.model.protocol.timing
        delays = [p.reg.write_delay_ms for p in self.sel.points if p.writable and p.reg.write_delay_ms is not None]
        return max([v for v in (t.inter_frame_gap_ms, *delays) if v is not None], default=None)

    def controllers(self) -> list[dict[str, Any]]:
        t = self.model.protocol.timing
        ctl: dict[str, Any] = {"id": "device", "modbus_id": "modbus_bus", "address": Hex(self.sel.unit),
                               "update_interval": f"{self.base}s"}
        throttle = self.throttle()
        if throttle is not None and not self.reuse:
            ctl["command_throttle"] = f"{iv.timing_ms(throttle)}ms"
        if t.retries is not None:
            ctl["max_cmd_retries"] = t.retries
        slow = [{**ctl, "id": f"device_{skip + 1}x", "update_interval": f"{self.base * (skip + 1)}s"}
                for skip in sorted(self.layout.skips)]
        return [ctl, *slow]

    # ---------------------------------------------------------------- items of one element

    def _base(self, point: iv.Point, name: str) -> dict[str, Any]:
        return {"platform": "modbus_controller", "modbus_controller_id": "device", "name": name,
                "register_type": REGISTER_TYPES[point.reg.table], "address": Hex(point.address)}

    def _add(self, platform: str, point: iv.Point, config: dict[str, Any], polled: bool = True) -> None:
        if platform in ("switch", "number", "select") and needs_write_multiple(self.model, point.reg):
            config["use_write_multiple"] = True  # the map lists no single write (06h / 05h) for it
        self.items.append(Item(platform, config, point.address, point.reg.words, polled, table=point.reg.table))

    def _point(self, point: iv.Point) -> None:
        reg, name = point.reg, f"{self.sel.prefix} {point.key}"
        if reg.bit_table:
            self._bit(point, name)
            return
        vtype = value_type(reg)
        if vtype is None:
            self._text(point, name)
            return
        self._typed(point, name, vtype)

    def _bit(self, point: iv.Point, name: str) -> None:
        """A coil or discrete input: a binary_sensor; a writable coil: a switch that polls it."""
        if point.writable:
            readable = point.reg.readable  # a write-only coil: assumed state, never polled
            self._add("switch", point, {**self._base(point, name), **({} if readable else {"assumed_state": True})},
                      polled=readable)
        elif point.reg.readable:
            self._add("binary_sensor", point, self._base(point, name))

    def _text(self, point: iv.Point, name: str) -> None:
        """Strings (ANSI text) and what ESPHome has no value_type for (f64, low byte first): a
        text_sensor with the wire bytes as hex (HEXBYTES), decoded by the reader."""
        reg = point.reg
        if not reg.readable:
            self.notes.append(f"not exported: {point.cell.name} is write-only")
            return
        text_string = reg.type == "string" and reg.byte_order == "high_first"
        self._add("text_sensor", point, {**self._base(point, name), **self._count(reg.words),
                                         "response_size": 2 * reg.words,
                                         "raw_encode": "ANSI" if text_string else "HEXBYTES"})
        if not text_string:
            self.raw.append(f"{point.cell.name} ({reg.type}, word order {reg.word_order or 'open for review'}, "
                            f"byte order {reg.byte_order})")
        if point.writable:
            self.notes.append(f"{point.cell.name} is writable; this export reads it only")

    def _typed(self, point: iv.Point, name: str, value_type: str) -> None:
        reg = point.reg
        if point.is_command or (reg.enum and not reg.readable and point.writable):
            self._switches(point, name)
            return
        if not reg.readable:
            self.notes.append(f"not exported: {point.cell.name} is write-only")
            return
        if reg.values and point.writable and not reg.scale_register and reg.type != "string":
            self._value_select(point, name, value_type)
            return
        if reg.enum and point.writable:
            options = _options(self.sel.enum_labels(point))
            config = {k: v for k, v in self._base(point, name).items() if k != "register_type"}  # holding only
            self._add("select", point, {**config, "value_type": value_type, "optionsmap": options})
            return
        if point.writable and not reg.bits and self._number(point, name, value_type):
            return
        self._add("sensor", point, self._sensor(point, name, value_type))
        if reg.enum:
            self._add("text_sensor", point, {**self._base(point, f"{name} label"), **self._count(reg.words),
                                             "response_size": 2 * reg.words, "raw_encode": "HEXBYTES",
                                             "filters": [{"map": _hex_map(reg, self.sel.enum_labels(point))}]})
        for bit in reg.bits:
            config = {**self._base(point, f"{name} {bit.name}"), "bitmask": Hex(bit.mask)}
            if bit.width == 1 and reg.words == 1:
                self._add("binary_sensor", point, config)
            else:
                self._add("sensor", point, {**config, "value_type": value_type, "accuracy_decimals": 0})
        if point.selector:
            self.notes.append(f"{point.key} is a page selector: exported read-only")

    def _value_select(self, point: iv.Point, name: str, value_type: str) -> None:
        """A writable register with a value set: a select whose options map to the raw values (a float
        by its bit pattern, read and written as the unsigned integer of the same words, since ESPHome's
        select has no float type), so a value outside the set is never written."""
        reg = point.reg
        if reg.is_float:
            value_type = value_type.replace("FP32", "U_DWORD") if reg.type == "f32" else \
                ("U_QWORD_R" if reg.word_order == "low_first" else "U_QWORD")
        options = {text: iv.wire_raw(reg, item.value)[1] for item, text in iv.options(reg)}
        config = {k: v for k, v in self._base(point, name).items() if k != "register_type"}  # holding only
        config.update({"value_type": value_type, "optionsmap": LiteralMap(options) if any("$" in k for k in options)
                       else options})
        if reg.words == 1 and self.model.protocol.function(0x06) is None:
            config["use_write_multiple"] = True
        self._add("select", point, config)

    def _sensor(self, point: iv.Point, name: str, value_type: str) -> dict[str, Any]:
        reg = point.reg
        places = iv.decimals(reg.scale, reg.offset) + (2 if reg.is_float or reg.scale_register else 0)
        places = reg.precision if reg.precision is not None else places
        config = {**self._base(point, name), "value_type": value_type, "accuracy_decimals": places}
        if reg.name in self.factors:
            config["id"] = self.factors[reg.name]
        if reg.unit and not reg.enum and not reg.bits:
            config["unit_of_measurement"] = text(iv.unit_for(reg.unit))
            device_class, state_class = iv.DEVICE_CLASSES.get(iv.unit_for(reg.unit), (None, None))
            if device_class:
                config["device_class"] = device_class
            if state_class:
                config["state_class"] = state_class
        filters: list[dict[str, Any]] = []
        if reg.not_available and not reg.is_float:
            # before any scaling: the decoded value (signed for s16/s32/s64) as ESPHome sees it
            filters.append({"filter_out": [v for v in reg.not_available]})
        if reg.scale_register and reg.scale_register not in self.factors:
            self.notes.append(f"{point.cell.name}: its scale register {reg.scale_register} is not exported; "
                              "the sensor is the unscaled value")
        elif reg.scale_register:
            filters.append({"lambda": f"return x * powf(10.0f, id({self.factors[reg.scale_register]}).state);"})
        if reg.scale != 1:
            filters.append({"multiply": _number(reg.scale)})
        if reg.offset:
            filters.append({"offset": _number(reg.offset)})
        if filters:
            config["filters"] = filters
        return config

    def _number(self, point: iv.Point, name: str, value_type: str) -> bool:
        reg = point.reg
        low, high = reg.raw_bounds()
        lo = reg.min if reg.min is not None else low * reg.scale + reg.offset
        hi = reg.max if reg.max is not None else high * reg.scale + reg.offset
        if reg.offset or reg.scale_register or reg.not_available or not -NUMBER_LIMIT <= lo < hi <= NUMBER_LIMIT:
            return False
        config = {**self._base(point, name), "value_type": value_type, "min_value": _number(lo),
                  "max_value": _number(hi), "step": _number(reg.scale)}
        if reg.scale != 1:
            config["multiply"] = _number(1 / reg.scale)
        if reg.name in self.factors:
            config["id"] = self.factors[reg.name]
        if reg.unit:
            config["unit_of_measurement"] = text(iv.unit_for(reg.unit))
        self._add("number", point, config)
        return True

    def _switches(self, point: iv.Point, name: str) -> None:
        reg = point.reg
        if reg.words > 1:  # an ESPHome switch writes one register; the device takes this one only whole
            self.notes.append(f"not exported: {point.cell.name} is a {reg.words}-register command "
                              "(an ESPHome switch writes one register)")
            return
        commands = [(name, reg.command_value or 0)] if point.is_command else \
            [(f"{name} {v.name}", v.value) for v in self.model.enum(reg.enum or "").members]
        for label, value in commands:
            # assumed state: never polled; both on and off write the command value (never an undocumented 0)
            self._add("switch", point, {**self._base(point, label), "assumed_state": True, "bitmask": Hex(value),
                                        "write_lambda": "return true;"}, polled=False)

    def _count(self, words: int) -> dict[str, int]:
        """A text_sensor's register_count: before 2026.9 only (since then derived from response_size)."""
        return {} if self.reuse else {"register_count": words}

    def _filler(self, table: str, address: int, words: int) -> Item:
        prefix = "" if table == "holding" else f"{table}_"
        config = {"platform": "modbus_controller", "modbus_controller_id": "device",
                  "id": f"gap_{prefix}{address:04x}", "internal": True, "register_type": REGISTER_TYPES[table],
                  "address": Hex(address), "value_type": "U_WORD", "register_count": words}
        return Item("sensor", config, address, words, True, filler=True, table=table)


def needs_write_multiple(model: Model, reg: Register) -> bool:
    """True when the map lists no single write for ``reg`` (06h for a one-word register, 05h for a
    coil) but the multiple one (10h / 0Fh): ESPHome then needs ``use_write_multiple: true``."""
    has = model.protocol.function
    if reg.table == "coil":
        return has(0x05) is None and has(0x0F) is not None
    return reg.table == "holding" and reg.words == 1 and has(0x06) is None and has(0x10) is not None


def _options(labels: tuple[tuple[int, str], ...]) -> dict[str, int]:
    out: dict[str, int] = {}
    for value, label in labels:
        out[label if label not in out else f"{label} ({value})"] = value
    # a key is substituted too: a map with '$' in a label goes in whole as !literal
    return LiteralMap(out) if any("$" in key for key in out) else out


def _hex_map(reg: Any, labels: tuple[tuple[int, str], ...]) -> list[dict[str, str]]:
    out = []
    for value, label in labels:
        raw = value & ((1 << (16 * reg.words)) - 1)
        words = [(raw >> (16 * i)) & 0xFFFF for i in reversed(range(reg.words))]
        if reg.word_order == "low_first":
            words.reverse()
        out.append({"from": "".join(f"{w:04x}" for w in words), "to": text(label)})
    return out


def _number(value: float) -> int | float:
    return int(value) if float(value).is_integer() else round(float(value), 12)
