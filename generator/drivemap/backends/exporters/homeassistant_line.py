"""Several devices on one line: one Home Assistant ``modbus:`` hub with all their entities.

Home Assistant loads one hub per serial port (a second hub on the same port is dropped:
"/dev/ttyUSB0 is duplicate, not loaded!"), so devices that share a line must share a hub:
``drivemap export ev:1 vfd1000:2 --format homeassistant --serial /dev/ttyUSB0`` writes one package
whose hub holds both devices' entities, each with its own ``device_address``. The line settings
(mode, baud rate, parity, stop bits) must be the same for every device (they share the wire);
the hub's ``timeout`` and ``message_wait_milliseconds`` are the largest any map asks for. Entity
names start with the model id (``model_unit`` when a model appears more than once).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from drivemap.backends.exporters._yaml import dump, header
from drivemap.backends.exporters.base import OptionError, Options
from drivemap.backends.exporters.homeassistant import _Build, _version, keys_for
from drivemap.backends.views import integrations as iv
from drivemap.backends.views.common import header as generated_header
from drivemap.model.nodes import Model

__all__ = ["render_line"]

#: Hub keys that describe the line: equal for every device, or the export is refused.
LINE_KEYS = ("type", "method", "port", "host", "baudrate", "bytesize", "parity", "stopbits")
ENTITY_KEYS = ("sensors", "binary_sensors", "switches")


def render_line(devices: Sequence[tuple[Model, int | None]], options: Options) -> dict[str, str]:
    """One package for several (model, unit id) devices on one line (see the module docstring)."""
    if options.values.get("unit") is not None:
        raise OptionError("--unit: give each device's unit as MODEL:UNIT (e.g. ev:1 vfd1000:2)")
    if options.values.get("name_prefix") is not None:
        raise OptionError("--name-prefix: with several devices each entity name starts with its model id")
    version = _version(options.values.get("ha_version"))
    names = [m.name for m, _ in devices]
    builds: list[tuple[Model, _Build, dict[str, Any]]] = []
    units: dict[int, str] = {}
    for model, unit in devices:
        values = dict(options.values, unit=unit)
        if names.count(model.name) > 1:
            values["name_prefix"] = f"{model.name}_{unit}"
        build = _Build(model, iv.select(model, values), keys_for(version), values)
        chosen = build.sel.unit
        if chosen in units:
            raise OptionError(f"unit {chosen} is given to both {units[chosen]} and {model.name}: every device "
                              "on one line needs its own unit id (write MODEL:UNIT)")
        units[chosen] = model.name
        builds.append((model, build, build.hub()))
    hub = _merged_hub(builds, options)
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


def _merged_hub(builds: list[tuple[Model, _Build, dict[str, Any]]], options: Options) -> dict[str, Any]:
    first_model, _, first = builds[0]
    hub: dict[str, Any] = {key: value for key, value in first.items() if key not in ENTITY_KEYS}
    hub["name"] = str(options.values.get("hub_name") or "_".join(dict.fromkeys(m.name for m, _, _ in builds)))
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
