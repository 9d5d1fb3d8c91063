"""``drivemap import homeassistant``: a Home Assistant ``modbus:`` configuration as a map.

Reads a package or ``configuration.yaml`` (``modbus:`` with one or more hubs) or a bare list of hubs
(a file included with ``modbus: !include``), exported by drivemap or written by hand:

* the hub: ``type`` serial (method, baudrate, bytesize, parity, stopbits -> the map's port), tcp,
  udp or rtuovertcp; ``timeout`` -> response timeout; ``message_wait_milliseconds`` -> inter-frame gap;
* ``sensors``: ``address``, ``input_type``, ``data_type`` (and the old int/uint/float with ``count``),
  ``count`` of strings, ``swap``, ``scale``, ``offset``, ``nan_value``, ``unit_of_measurement``,
  ``virtual_count``/``slave_count`` (an array), ``slave``/``device_address``;
* ``binary_sensors`` (coils, discrete inputs), ``switches`` (coils; holding registers: a command
  value, one value per switch of a write-only enum, or on/off values), ``climates`` (current and
  target temperature, min/max, the HVAC mode register's values);
* drivemap's own ``template:`` entities: enum labels, bit fields, scale-factor registers.

``precision`` is display, ``scan_interval`` polling: neither is a device fact (entities are grouped
by their interval, so a re-export can repeat it). Whatever does not map is listed in the review.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.importers.ha_context import PARITY, Ctx
from drivemap.onboard.importers.ha_entities import arrays, binary_sensor, climate, merge_switches, sensor, switches
from drivemap.onboard.importers.ha_templates import apply_templates
from drivemap.onboard.importers.mapdoc import MapDoc, snake
from drivemap.onboard.importers.overlaps import check_overlaps
from drivemap.onboard.importers.yamlinclude import load_config
from drivemap.onboard.importers.yamlsrc import Node, Tagged, here, left_out, located, renamed

__all__ = ["import_homeassistant"]

def import_homeassistant(doc: MapDoc, paths: list[Path]) -> str | None:
    """Fill ``doc`` from the files' first hub; the hub's name (the model id it suggests)."""
    hubs: list[tuple[Path, Node]] = []
    templates: list[tuple[Path, Any]] = []
    for path in paths:
        top, read = load_config(path)
        doc.review.skipped.extend(left_out(path))
        doc.review.notes.extend(read.secrets)
        for data in _documents(top, path, doc):
            hubs.extend((path, hub) for hub in _hubs(path, data))
            blocks = data.get("template") if isinstance(data, dict) else None
            if isinstance(blocks, list):
                templates.extend((path, block) for block in blocks)
            elif isinstance(blocks, dict):
                templates.append((path, blocks))
            templates.extend((path, block) for block in _legacy_templates(data))
    if not hubs:
        raise located(paths[0], None, "no modbus: hub here (a modbus: key with a list of hubs, or such a list; "
                                      "or homeassistant: packages: holding one)")
    path, hub = hubs[0]
    for other_path, other in hubs[1:]:
        doc.review.skipped.append(f"{here(other, other_path)}: hub {other.get('name')!r} (one map per device: "
                                  "import it on its own)")
    name = str(hub.get("name") or "modbus_hub")
    ctx = Ctx(doc, path, name)
    _hub(ctx, hub)
    _entities(ctx, hub)
    merge_switches(ctx)
    for tpath, block in templates:
        apply_templates(ctx, tpath, block)
    _finish(ctx)
    return snake(name, "device")


def _documents(data: Any, path: Path, doc: MapDoc) -> list[Any]:
    """The configuration and each package it holds (``homeassistant: packages:``, included or inline),
    as Home Assistant merges them: their ``modbus:`` hubs and ``template:`` blocks add up."""
    out = [data]
    core = data.get("homeassistant") if isinstance(data, dict) else None
    packages = core.get("packages") if isinstance(core, dict) else None
    if isinstance(packages, dict):
        for name, package in packages.items():
            if isinstance(package, dict):
                out.extend(_documents(package, path, doc))
            else:
                doc.review.skipped.append(f"{here(core, path)}: package {name!r} is not a configuration (a mapping)")
    return out


def _legacy_templates(data: Any) -> list[dict[str, Any]]:
    """``sensor: - platform: template`` / ``binary_sensor:`` (``sensors: {id: {value_template: ...}}``) as
    ``template:`` blocks (the entity id is the key; the name its friendly_name)."""
    out: list[dict[str, Any]] = []
    for kind in ("sensor", "binary_sensor"):
        items = data.get(kind) if isinstance(data, dict) else None
        for item in items if isinstance(items, list) else []:
            if not isinstance(item, dict) or item.get("platform") != "template" or not isinstance(item.get("sensors"), dict):
                continue
            entries = []
            for key, spec in item["sensors"].items():
                if isinstance(spec, Node):
                    entry = renamed(spec, str(spec.get("friendly_name") or key))
                    entry["state"] = spec.get("value_template", "")
                    entries.append(entry)
            out.append({kind: entries})
    return out


def _hubs(path: Path, data: Any) -> list[Node]:
    if isinstance(data, dict):
        data = data.get("modbus")
    if isinstance(data, Node):
        data = [data]
    if not isinstance(data, list):
        return []
    for hub in data:
        if not isinstance(hub, Node):
            raise located(path, None, "a modbus: hub is a mapping (name, type, ...)")
    return list(data)


def _hub(ctx: Ctx, hub: Node) -> None:
    kind = hub.get("type")
    doc = ctx.doc
    if kind == "serial":
        method = str(hub.get("method", "rtu"))
        if method not in ("rtu", "ascii"):
            raise located(ctx.path, hub, f"method {method!r}: rtu or ascii")
        doc.modes = [method]
        doc.port = _port(ctx, hub, method)
    elif kind in ("tcp", "udp", "rtuovertcp"):
        doc.modes = ["tcp"] if kind != "rtuovertcp" else ["rtu"]
        host, port = hub.get("host"), hub.get("port")
        if not isinstance(host, Tagged) and host is not None:
            option = "--tcp" if kind != "rtuovertcp" else "--rtu-over-tcp"
            doc.review.notes.append(f"export again with {option} {host}:{port} (the hub's address is not a map fact)")
    else:
        raise located(ctx.path, hub, f"hub type {kind!r}: serial, tcp, udp or rtuovertcp")
    if isinstance(hub.get("timeout"), int | float):
        doc.timing["response_timeout_ms"] = float(hub["timeout"]) * 1000
    if isinstance(hub.get("message_wait_milliseconds"), int | float):
        doc.timing["inter_frame_gap_ms"] = hub["message_wait_milliseconds"]


def _port(ctx: Ctx, hub: Node, method: str) -> dict[str, Any]:
    def given(key: str) -> Any:
        value = hub.get(key)
        return None if isinstance(value, Tagged) else value

    parity = PARITY.get(str(given("parity"))) if given("parity") is not None else None
    baud, data_bits, stop_bits = given("baudrate"), given("bytesize"), given("stopbits")
    return {"name": "serial", "modes": [method], "default_mode": method,
            "baudrates": [baud] if isinstance(baud, int) else [], "default_baudrate": baud if isinstance(baud, int) else None,
            "parity": [parity] if parity else [], "default_parity": parity,
            "data_bits": [data_bits] if data_bits in (7, 8) else [],
            "stop_bits": [stop_bits] if stop_bits in (1, 2) else [],
            "default_stop_bits": stop_bits if stop_bits in (1, 2) else None,
            "set_by": "unknown", "source": ctx.doc.source,
            "notes": f"The line settings of the Home Assistant hub {hub.get('name')!r} (what one installation uses)."}


def _entities(ctx: Ctx, hub: Node) -> None:
    for entry in _list(ctx, hub, "sensors"):
        sensor(ctx, entry)
    for entry in _list(ctx, hub, "binary_sensors"):
        binary_sensor(ctx, entry)
    switches(ctx, _list(ctx, hub, "switches"))
    for entry in _list(ctx, hub, "climates"):
        climate(ctx, entry)
    for key in ("covers", "fans", "lights"):
        for entry in _list(ctx, hub, key):
            ctx.doc.review.skipped.append(f"{here(entry, ctx.path)}: {key[:-1]} {entry.get('name')!r} "
                                          "(no register meaning to import)")
    _unread(ctx, hub)


#: the hub keys and entity keys the import reads (or reports itself); any other key is named in the review
HUB_KEYS = {"name", "type", "host", "port", "method", "baudrate", "bytesize", "parity", "stopbits", "timeout",
            "message_wait_milliseconds", "sensors", "binary_sensors", "switches", "climates", "covers", "fans",
            "lights"}
ENTITY_KEYS = {"name", "address", "input_type", "data_type", "count", "swap", "scale", "offset", "nan_value",
               "unit_of_measurement", "virtual_count", "slave_count", "slave", "device_address", "scan_interval",
               "min_value", "max_value", "zero_suppress", "structure", "write_type", "command_on", "command_off",
               "verify", "target_temp_register", "min_temp", "max_temp", "temperature_unit", "hvac_mode_register",
               "precision"}


def _unread(ctx: Ctx, hub: Node) -> None:
    """One review line per key the import does not read: the hub's (with its value), the entities' (how often)."""
    for key in sorted(set(hub) - HUB_KEYS):
        ctx.doc.review.notes.append(f"{here(hub, ctx.path)}: hub {key}: {hub[key]!r} not imported (a setting of Home "
                                    "Assistant's connection, not of the device)")
    counts: dict[str, int] = {}
    for kind in ("sensors", "binary_sensors", "switches", "climates"):
        for entry in hub.get(kind) or []:
            for key in set(entry) - ENTITY_KEYS if isinstance(entry, dict) else ():
                counts[key] = counts.get(key, 0) + 1
    if counts:
        listed = ", ".join(f"{k} ({n} entit{'y' if n == 1 else 'ies'})" for k, n in sorted(counts.items()))
        ctx.doc.review.notes.append(f"entity keys not imported (Home Assistant's presentation, not register facts): "
                                    f"{listed}")


def _list(ctx: Ctx, hub: Node, key: str) -> list[Node]:
    items = hub.get(key) or []
    if not isinstance(items, list) or not all(isinstance(e, Node) for e in items):
        raise located(ctx.path, hub, f"{key}: a list of entities")
    for entry in items:
        if id(entry) in ctx.seen:
            raise located(ctx.path, entry, f"{key}: the entity {entry.get('name')!r} is listed again by a YAML alias "
                                           "(*name): one entity per register, delete the repeat")
        ctx.seen.add(id(entry))
    return items


def _finish(ctx: Ctx) -> None:
    singles = [(reg, reg.get("_node")) for elements in ctx.regs.values() if len(elements) == 1
               for reg in elements.values()]
    check_overlaps(ctx.path, singles, "one register, one entity: delete one entity, or give the second the "
                                      "address of its own register")
    for name, elements in ctx.regs.items():
        ctx.doc.add(arrays(ctx, name, elements))
    if len(ctx.units) == 1 and ctx.units != {1}:
        ctx.doc.review.notes.append(f"export again with --unit {next(iter(ctx.units))} (the entities' device address)")
    elif len(ctx.units) > 1:
        ctx.doc.review.notes.append(f"the entities use device addresses {sorted(ctx.units)}: one map per device")
    extra = [f"--interval {g}={n}" for g, n in sorted(ctx.intervals.items()) if n != 15]
    if extra:
        ctx.doc.review.notes.append("export again with " + " ".join(extra) + " (the entities' scan intervals)")
