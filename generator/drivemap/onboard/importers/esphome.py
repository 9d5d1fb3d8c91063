"""``drivemap import esphome``: an ESPHome device's ``modbus_controller`` entities as a map.

Reads ``sensor``, ``binary_sensor``, ``number``, ``select``, ``switch`` and ``text_sensor`` entries
of ``platform: modbus_controller`` (exported by drivemap or written by hand): ``register_type``,
``address`` (+ ``offset`` bytes), ``value_type``, ``bitmask`` (bit fields, command switches),
``register_count`` of strings, filters (``multiply``, ``offset``, ``filter_out``, drivemap's 10^factor
``lambda``), ``min_value``/``max_value``/``step`` of numbers, ``optionsmap`` of selects, the ``map``
of enum label text sensors, the line settings of ``uart:`` and the timing of ``modbus:`` and
``modbus_controller:``. ``skip_updates`` is polling, not a device fact: entities are grouped by
their interval so a re-export can repeat it. Anything else (lambdas, custom commands) is listed.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.es_context import PARITY, PLATFORMS, RAW_ITEM, RAW_NOTE, Ctx
from drivemap.onboard.importers.es_entities import entity, finish
from drivemap.onboard.importers.es_packages import expand
from drivemap.onboard.importers.mapdoc import MapDoc, snake
from drivemap.onboard.importers.yamlinclude import load_config
from drivemap.onboard.importers.yamlsrc import Node, Tagged, here, left_out, located

__all__ = ["import_esphome"]

def import_esphome(doc: MapDoc, paths: list[Path]) -> str | None:
    path = paths[0]
    if len(paths) > 1:
        doc.review.skipped.extend(f"{p.name}: one ESPHome device per map (import it on its own)" for p in paths[1:])
    data, read = load_config(path)
    doc.review.skipped.extend(left_out(path))
    doc.review.notes.extend(read.secrets)
    data = expand(data, path, doc.review)
    if not isinstance(data, dict):
        raise located(path, None, "not an ESPHome configuration (a mapping with esphome:, modbus_controller:, ...)")
    node = str((data.get("esphome") or {}).get("name") or path.stem.split(".")[0])
    model = snake(node.replace("-", "_"), "device")
    controller = _controller(path, data)
    base = _seconds(controller.get("update_interval", "60s"))
    ctx = Ctx(doc, path, model, base)
    ctx.controllers = _controllers(data)
    _line(ctx, data, controller)
    ctx.raw_types = _raw_types(path)
    found = 0
    for platform in PLATFORMS:
        items = data.get(platform) or []
        for item in items if isinstance(items, list) else []:
            if isinstance(item, Node) and item.get("platform") == "modbus_controller":
                found += 1
                entity(ctx, platform, item)
            elif isinstance(item, Node):
                doc.review.skipped.append(f"{here(item, path)}: {platform} {item.get('name') or item.get('id')!r} "
                                          f"(platform {item.get('platform')}: not a Modbus register)")
    if not found:
        raise located(path, None, "no modbus_controller entities here")
    _unread(doc, data)
    finish(ctx)
    return model


def _controller(path: Path, data: dict[str, Any]) -> Node:
    controllers = data.get("modbus_controller")
    if isinstance(controllers, Node):
        controllers = [controllers]
    if not isinstance(controllers, list) or not controllers or not isinstance(controllers[0], Node):
        raise located(path, data, "no modbus_controller: (the device's address and polling)")
    return controllers[0]


def _controllers(data: dict[str, Any]) -> dict[str, tuple[object, int]]:
    """Each controller's id -> (device address, update_interval in s)."""
    items = data.get("modbus_controller")
    items = [items] if isinstance(items, Node) else items if isinstance(items, list) else []
    return {str(c.get("id")): (c.get("address"), _seconds(c.get("update_interval", "60s")))
            for c in items if isinstance(c, Node) and c.get("id") is not None}


def _seconds(text: Any) -> int:
    match = re.fullmatch(r"(\d+)\s*(ms|s|min|h)?", str(text).strip())
    if not match:
        return 60
    value, unit = int(match.group(1)), match.group(2) or "s"
    return max(1, {"ms": value // 1000, "s": value, "min": value * 60, "h": value * 3600}[unit])


def _ms(text: Any) -> float | None:
    match = re.fullmatch(r"(\d+(?:\.\d+)?)\s*(ms|s)?", str(text).strip())
    if not match:
        return None
    value = float(match.group(1))
    return value * 1000 if match.group(2) == "s" else value


def _line(ctx: Ctx, data: dict[str, Any], controller: Node) -> None:
    """The serial line (uart:), timing (modbus:, modbus_controller:) and the unit id."""
    doc = ctx.doc
    uart = data.get("uart")
    uart = uart[0] if isinstance(uart, list) and uart else uart
    doc.modes = ["rtu"]
    if isinstance(uart, dict):
        baud, parity = uart.get("baud_rate"), PARITY.get(str(uart.get("parity", "")))
        data_bits, stop_bits = uart.get("data_bits"), uart.get("stop_bits")
        doc.port = {"name": "serial", "modes": ["rtu"], "default_mode": "rtu",
                    "baudrates": [baud] if isinstance(baud, int) else [],
                    "default_baudrate": baud if isinstance(baud, int) else None,
                    "parity": [parity] if parity else [], "default_parity": parity,
                    "data_bits": [data_bits] if data_bits in (7, 8) else [],
                    "stop_bits": [stop_bits] if stop_bits in (1, 2) else [],
                    "default_stop_bits": stop_bits if stop_bits in (1, 2) else None,
                    "set_by": "unknown", "source": doc.source,
                    "notes": "The uart: settings of the ESPHome device (what one installation uses)."}
    bus = data.get("modbus")
    bus = bus[0] if isinstance(bus, list) and bus else bus
    if isinstance(bus, dict):
        for key, fact in (("send_wait_time", "response_timeout_ms"), ("turnaround_time", "inter_frame_gap_ms")):
            if key in bus and _ms(bus[key]) is not None:
                doc.timing[fact] = _ms(bus[key])
        if bus.get("flow_control_pin") and not isinstance(bus["flow_control_pin"], Tagged):
            doc.review.notes.append(f"export again with --flow-control-pin {bus['flow_control_pin']}")
    if isinstance(controller.get("max_cmd_retries"), int):
        doc.timing["retries"] = controller["max_cmd_retries"]
    if "command_throttle" in controller and _ms(controller["command_throttle"]) != doc.timing.get("inter_frame_gap_ms"):
        doc.review.notes.append(f"command_throttle {controller['command_throttle']}: the pause the device needs "
                                "between commands (a write delay?) is not imported")
    unit = controller.get("address")
    if isinstance(unit, int) and unit != 1:
        doc.review.notes.append(f"export again with --unit {unit} (the controller's device address)")


def _raw_types(path: Path) -> dict[str, tuple[str, str | None, str]]:
    """drivemap's header note naming the type of each HEXBYTES text sensor (f64, low byte first)."""
    out: dict[str, tuple[str, str | None, str]] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        match = RAW_NOTE.search(line)
        if match:
            for item in match.group(1).split("; "):
                found = RAW_ITEM.match(item.strip())
                if found:
                    name, rtype, word, byte = found.groups()
                    out[name] = (rtype, None if word == "-" else word, byte)
    return out


#: the entity keys the import reads (or that only route an entity: id, platform, controller id)
ENTITY_KEYS = {"platform", "name", "id", "modbus_controller_id", "register_type", "address", "offset", "value_type",
               "bitmask", "register_count", "filters", "unit_of_measurement", "min_value", "max_value", "step",
               "multiply", "optionsmap", "skip_updates", "force_new_range", "reuse_previous_range", "use_write_multiple", "internal",
               "raw_encode", "write_lambda", "assumed_state"}


def _unread(doc: MapDoc, data: dict[str, Any]) -> None:
    """One review line naming the entity keys that are not register facts (how many entities have each)."""
    counts: dict[str, int] = {}
    for platform in PLATFORMS:
        items = data.get(platform) or []
        for item in items if isinstance(items, list) else []:
            if isinstance(item, dict) and item.get("platform") == "modbus_controller":
                for key in set(item) - ENTITY_KEYS:
                    counts[key] = counts.get(key, 0) + 1
    if counts:
        listed = ", ".join(f"{k} ({n} entit{'y' if n == 1 else 'ies'})" for k, n in sorted(counts.items()))
        doc.review.notes.append(f"entity keys not imported (ESPHome's presentation, not register facts): {listed}")
