"""Home Assistant MQTT discovery, generated from the map.

One Home Assistant device per drive (manufacturer, model, manual document and revision from the
map; what the map does not state is left out) and, per register: a ``sensor`` for readable values
(unit, ``device_class`` where the unit names one, ``state_class`` and ``suggested_display_precision``
for numbers: the map's ``precision`` when it gives one, else the decimals of its scale, ``enum``
options for enumerated values), a ``binary_sensor`` per single bit of a
bit-field register (wider fields are sensors) and per read-only coil or discrete input. Controls
only for registers in the device's ``writable`` list (none for a register whose map leaves open a
field that decides the written words: it takes no command, its reads are published): a ``select`` per enumerated register and per
register with a value set (``values:``; options are the labels, the value where a value has none), a
``number`` per numeric register (min/max: the map's range, or where the map gives none the range of
its type in engineering units, :func:`number_bounds`; step = the map's scale), a ``button`` per
command register, a ``switch`` per coil or bool register (payloads true/false). Strings are text
sensors (no unit or state class); a register with not-available values publishes null for them,
which the sensor shows as unknown (its value template turns null into HA's "None" payload). Array
elements are named as the manual numbers them (the map's ``first_index``: ``Alarm history 1`` is
element 0); their topics and object ids keep the gateway's numbering from 0.

Home Assistant refuses a state it was not announced: enum templates turn a value outside the options
(``UNKNOWN_<n>``) into "None" (unknown); number templates turn a reading outside min..max into "None",
and a ``<name> reading`` sensor shows the reading whole.

Every entity is available only while both the gateway and its device are online
(``availability_mode: all``). Topics: ``<discovery_prefix>/<component>/<node_id>/<object_id>/config``,
retained, with ``node_id = drivemap_<gateway>_<device>``.
"""

from __future__ import annotations

import json
import sys
from decimal import Decimal
from typing import Any

from drivemap import __version__
from drivemap.gateway.device import PRESS, Device
from drivemap.gateway.valuesets import value_options
from drivemap.model.nodes import Model, Register
from drivemap.runtime.types import TYPE_BOUNDS
from drivemap.vocab import units as iv
from drivemap.vocab.units import decimals


def precision(reg: Register) -> int | None:
    """Decimals to show of ``reg``'s values: the map's ``precision`` when it gives one, else the
    decimals of its scale and offset; None for unscaled floats and registers scaled by a scale
    register (the decimals change with the factor)."""
    if reg.precision is not None:
        return reg.precision
    if reg.type in ("f32", "f64") and reg.scale == 1 and not reg.offset:
        return None
    if reg.scale_register is not None:
        return None
    return decimals(reg.scale, reg.offset or 0)


#: The oldest Home Assistant release the gateway's discovery is written for (the release the project's
#: tools tier runs): without ``mqtt.ha_version`` discovery uses only device classes it accepts, so no
#: supported release drops an entity (HA before 2025.6 refuses ``reactive_energy``: kvarh sensors
#: get no device class). Device classes and the release that brought them:
#: :data:`drivemap.vocab.units.DEVICE_CLASS_SINCE` (read, shared with the HA export).
OLDEST_HA: tuple[int, int] = (2024, 3)


def ha_release(ha_version: tuple[int, int] | None) -> tuple[int, int]:
    """The Home Assistant release discovery is for: ``mqtt.ha_version``, else :data:`OLDEST_HA`."""
    return ha_version if ha_version is not None else OLDEST_HA


def unit_info(reg: Register, ha_version: tuple[int, int] | None = None) -> dict[str, Any]:
    """unit_of_measurement / device_class / state_class / suggested_display_precision of a number
    (device classes Home Assistant ``ha_version`` - default :data:`OLDEST_HA` - does not know are
    left out)."""
    out: dict[str, Any] = {"state_class": "measurement"}
    if reg.unit is not None:
        unit = iv.unit_for(reg.unit)
        device_class, state_class = iv.DEVICE_CLASSES.get(unit, (None, "measurement"))
        out = {"unit_of_measurement": unit, "state_class": state_class}
        if device_class and iv.device_class_known(device_class, ha_release(ha_version)):
            out["device_class"] = device_class
    digits = precision(reg)
    if digits is not None:
        out["suggested_display_precision"] = digits
    return out


def ha_device(gateway: str, device: Device) -> dict[str, Any]:
    """The Home Assistant device: what the map states (vendor, title, manual), nothing guessed."""
    m: Model = device.model
    manual = m.device.manual
    out: dict[str, Any] = {
        "identifiers": [f"drivemap_{gateway}_{device.name}"],
        "name": device.cfg.title,
        "model": m.device.title,
        "sw_version": f"drivemap {__version__}",
    }
    if m.device.vendor:
        out["manufacturer"] = m.device.vendor
    if manual.document:
        out["hw_version"] = " ".join(x for x in (f"manual {manual.document}",
                                                 f"rev {manual.revision}" if manual.revision else "") if x)
    return out


class _Builder:
    def __init__(self, gateway: str, device: Device, discovery_prefix: str, availability: str,
                 ha_version: tuple[int, int] | None = None) -> None:
        self.gateway = gateway
        self.ha_version = ha_version
        self.device = device
        self.prefix = discovery_prefix
        self.node = f"drivemap_{gateway}_{device.name}"
        self.common = {
            "device": ha_device(gateway, device),
            "availability": [{"topic": availability}, {"topic": f"{device.topic}/availability"}],
            "availability_mode": "all",
            "origin": {"name": "drivemap", "sw_version": __version__},
        }
        self.out: list[tuple[str, dict[str, Any]]] = []

    def add(self, component: str, object_id: str, name: str, fields: dict[str, Any]) -> None:
        payload = {"name": name, "unique_id": f"{self.node}_{object_id}", "object_id": f"{self.node}_{object_id}",
                   **fields, **self.common}
        self.out.append((f"{self.prefix}/{component}/{self.node}/{object_id}/config", payload))


def _title(name: str) -> str:
    return name.replace("_", " ").capitalize()


def entity_name(reg: Register, index: int | None) -> str:
    """The display name of a register's entity, or of one element of an array register.

    The one place that names entities: element ``index`` (0-based, as the gateway's topics number
    it) is named as the manual numbers it, by the map's ``first_index``
    (:meth:`~drivemap.model.nodes.Register.display_name`)."""
    return _title(reg.name) if index is None else reg.display_name(index, _title(reg.name))


def _enum_names(model: Model, enum: str) -> list[str]:
    return [v.name for v in model.enum(enum).members]


def _announced(field: str, options: list[str]) -> str:
    """A value template that passes an announced option and turns anything else (an undocumented
    ``UNKNOWN_<n>``, null) into Home Assistant's "None" (unknown)."""
    listed = json.dumps(options, ensure_ascii=True)
    return f"{{{{ {field} if {field} in {listed} else 'None' }}}}"


def _in_range(field: str, low: float, high: float) -> str:
    """A value template that passes a number inside [low, high] and turns anything else into "None"."""
    return (f"{{% set v = {field} | float(none) %}}{{{{ {field} if v is not none and {low!r} <= v <= {high!r} "
            "else 'None' }}")


def _element(reg: Register, index: int | None) -> tuple[str, str, str | None]:
    """(object id, name, value template) of a register or one array element."""
    if index is None:
        return reg.name, entity_name(reg, None), None
    return f"{reg.name}_{index}", entity_name(reg, index), f"{{{{ value_json[{index}] }}}}"


def _field(index: int | None) -> str:
    return "value" if index is None else f"value_json[{index}]"


def _register(b: _Builder, reg: Register, published: bool, control: bool) -> None:
    """The entities of one register: controls only when the gateway takes commands for it."""
    indices: list[int | None] = list(range(reg.count)) if reg.is_array else [None]
    for index in indices:
        object_id, name, template = _element(reg, index)
        state = f"{b.device.topic}/{reg.name}"
        command = f"{state}/{index}/set" if index is not None else f"{state}/set"
        st: dict[str, Any] = {"state_topic": state} if published else {}
        if template and published:
            st["value_template"] = template
        options = _enum_names(b.device.model, reg.enum) if reg.enum else []
        if reg.bit_table or reg.type == "bool":
            _bool(b, reg, object_id, name, st, command, published, control)
        elif reg.bits:
            if published:
                _bits(b, reg, object_id, name, state, index)
        elif reg.command_value is not None and control:
            b.add("button", object_id, name, {"command_topic": command, "payload_press": PRESS})
        elif reg.enum and control:
            if published:
                st["value_template"] = _announced(_field(index), options)
            b.add("select", object_id, name, {**st, "command_topic": command, "options": options})
        elif reg.values and control:
            _value_select(b, reg, object_id, name, st, command, index)
        elif control and number_bounds(reg) is not None:
            _number(b, reg, object_id, name, st, command, index)
        elif published and reg.enum:
            b.add("sensor", object_id, name, {**st, "value_template": _announced(_field(index), options),
                                              "device_class": "enum", "options": options})
        elif published and reg.type == "string":
            b.add("sensor", object_id, name, st)
        elif published:
            _sensor(b, reg, object_id, name, st, template)


def _sensor(b: _Builder, reg: Register, object_id: str, name: str, st: dict[str, Any], template: str | None) -> None:
    if reg.optional and not template:
        st = {**st, "value_template": "{{ 'None' if value == 'null' else value }}"}
    b.add("sensor", object_id, name, {**st, **unit_info(reg, b.ha_version)})


#: The largest finite values of the float types (a float register without a range is bounded by them).
_FLOAT_MAX = {"f32": float(Decimal("3.4028234663852886e38")), "f64": sys.float_info.max}


def _whole(value: Decimal) -> int | float:
    """An end of a range: an int when whole and within the integer types' reach, else a float."""
    return int(value) if value == value.to_integral_value() and abs(value) <= 2**64 else float(value)


def number_bounds(reg: Register) -> tuple[int | float, int | float] | None:
    """The (min, max) of a ``number`` control: the map's range where it gives one, else (either end)
    its type's raw range in engineering units (raw * scale + offset); None for what is no plain
    number (strings, bools, bit fields) and for a register scaled by a scale register (its factor,
    and so its range, is known only when read)."""
    if reg.type in ("string", "bool") or reg.bit_table or reg.bits or reg.enum:
        return None
    if reg.min is not None and reg.max is not None:
        return reg.min, reg.max
    if reg.scale_register is not None:
        return None
    scale, offset = Decimal(repr(reg.scale)), Decimal(repr(reg.offset or 0))
    if reg.type in _FLOAT_MAX:
        top = Decimal(repr(_FLOAT_MAX[reg.type]))
        ends = [-top * scale + offset, top * scale + offset]
        limit = Decimal(repr(sys.float_info.max))
        ends = [max(-limit, min(limit, e)) for e in ends]
    else:
        low, high = TYPE_BOUNDS[reg.type]
        if "signedness" in reg.review:  # signed or not, the map does not say: only what reads the same both ways
            low, high = 0, (1 << (16 * reg.words - 1)) - 1
        ends = [Decimal(low) * scale + offset, Decimal(high) * scale + offset]
    lo, hi = sorted(_whole(e) for e in ends)
    return (reg.min if reg.min is not None else lo), (reg.max if reg.max is not None else hi)


def _number(b: _Builder, reg: Register, object_id: str, name: str, st: dict[str, Any], command: str,
            index: int | None) -> None:
    """A number entity over the map's writable range (without one: the range of the register's type,
    scaled); Home Assistant refuses a state outside it, so a reading outside the range shows as
    unknown there and in full in a ``<name> reading`` sensor."""
    bounds = number_bounds(reg)
    assert bounds is not None
    low, high = bounds
    step = reg.scale if not float(reg.scale).is_integer() else int(reg.scale)
    info = {k: v for k, v in unit_info(reg, b.ha_version).items() if k != "state_class"}
    if st:
        st = {**st, "value_template": _in_range(_field(index), low, high)}
    b.add("number", object_id, name, {**st, **info, "command_topic": command, "min": low,
                                      "max": high, "step": abs(step), "mode": "box"})
    if st:
        reading = {"state_topic": st["state_topic"], **({"value_template": f"{{{{ {_field(index)} }}}}"}
                                                        if index is not None else {})}
        _sensor(b, reg, f"{object_id}_reading", f"{name} reading", reading, reading.get("value_template"))


def _chosen(field: str, pairs: list[tuple[float | str, str]]) -> str:
    """A value template that turns a published value into its option text and anything else (a
    value outside the set, null) into "None" (unknown); numbers compare with the value set's
    tolerance (a scaled reading is not always the exact binary float of the map's value)."""
    numeric = any(not isinstance(v, str) for v, _ in pairs)
    head = f"{{% set v = {field} | float(none) %}}" if numeric else f"{{% set v = {field} | string %}}"
    body = ""
    for value, text in pairs:
        if isinstance(value, str):
            test = f"v == {json.dumps(value, ensure_ascii=True)}"
        else:
            test = f"v is not none and (v - {float(value)!r}) | abs <= {1e-9 * max(1.0, abs(float(value)))!r}"
        body += f"{{% {'elif' if body else 'if'} {test} %}}{{{{ {json.dumps(text, ensure_ascii=True)} }}}}"
    return f"{head}{body}{{% else %}}None{{% endif %}}"


def _value_select(b: _Builder, reg: Register, object_id: str, name: str, st: dict[str, Any], command: str,
                  index: int | None) -> None:
    """A select over the register's value set: Home Assistant sends the option text, which the
    gateway takes (as it takes the label or the value) and refuses anything else."""
    pairs = value_options(reg)
    if st:
        st = {**st, "value_template": _chosen(_field(index), pairs)}
    b.add("select", object_id, name, {**st, "command_topic": command, "options": [text for _, text in pairs]})


def _bool(b: _Builder, reg: Register, object_id: str, name: str, st: dict[str, Any], command: str,
          published: bool, control: bool) -> None:
    """A coil (writable: a switch) or a discrete input / bool register: payloads true/false."""
    states = {"payload_on": "true", "payload_off": "false"}
    if "value_template" in st:  # an array element: Jinja writes True/False
        st = {**st, "value_template": st["value_template"].replace(" }}", " | string | lower }}")}
    if control:
        b.add("switch", object_id, name, {**st, **states, "state_on": "true", "state_off": "false",
                                          "command_topic": command, **({} if published else {"optimistic": True})})
    elif published:
        b.add("binary_sensor", object_id, name, {**st, **states})


def _bits(b: _Builder, reg: Register, object_id: str, name: str, state: str, index: int | None) -> None:
    base = "value_json" if index is None else f"value_json[{index}]"
    for bit in reg.bits:
        field = f"{base}['{bit.name}']"
        oid, label = f"{object_id}_{bit.name.lower()}", f"{name} {bit.label or bit.name}"
        fields = {"state_topic": state}
        if bit.width == 1 and bit.enum is None:
            b.add("binary_sensor", oid, label, {**fields, "value_template": f"{{{{ 'ON' if {field} else 'OFF' }}}}"})
        elif bit.enum is not None:
            options = _enum_names(b.device.model, bit.enum)
            b.add("sensor", oid, label, {**fields, "value_template": _announced(field, options), "device_class": "enum",
                                         "options": options})
        else:
            b.add("sensor", oid, label, {**fields, "value_template": f"{{{{ {field} }}}}"})


def discovery_messages(gateway: str, device: Device, discovery_prefix: str, availability: str,
                       ha_version: tuple[int, int] | None = None) -> list[tuple[str, dict[str, Any]]]:
    """(topic, payload) of every discovery message of one device, for Home Assistant ``ha_version``."""
    b = _Builder(gateway, device, discovery_prefix, availability, ha_version)
    published = set(device.cfg.publish)
    for reg in device.model.registers:
        control = device.commandable(reg)
        if reg.name in published or control:
            _register(b, reg, reg.name in published, control)
    return b.out
