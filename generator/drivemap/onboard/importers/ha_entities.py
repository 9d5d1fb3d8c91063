"""Home Assistant modbus entities -> registers (see :mod:`.homeassistant`)."""

from __future__ import annotations

from typing import Any

from drivemap.onboard.importers.ha_context import LEGACY, SIZED, TABLES, Ctx
from drivemap.onboard.importers.yamlsrc import Node, Tagged, here, located, renamed

__all__ = ["arrays", "binary_sensor", "climate", "sensor", "switches"]

DEFAULT_SCAN_S = 15


def _int(ctx: Ctx, entry: Node, key: str) -> int:
    value = entry.get(key)
    if isinstance(value, str) and not isinstance(value, Tagged):
        try:
            value = int(value, 0)
        except ValueError:
            pass
    if not isinstance(value, int) or isinstance(value, bool):
        raise located(ctx.path, entry, f"{entry.get('name', 'entity')}: {key} {value!r} is not an integer")
    return value


def _group(ctx: Ctx, entry: Node) -> str:
    seconds = entry.get("scan_interval", DEFAULT_SCAN_S)
    seconds = seconds if isinstance(seconds, int) and not isinstance(seconds, bool) else DEFAULT_SCAN_S
    name = ctx.doc.group(f"scan_{seconds}s", f"Polled every {seconds} s")
    ctx.intervals[name] = seconds
    return name


def _address(ctx: Ctx, entry: Node, key: str = "address") -> int:
    address = _int(ctx, entry, key)
    if not 0 <= address <= 0xFFFF:
        raise located(ctx.path, entry, f"{entry.get('name')}: {key} {address} is not 0..65535")
    return address


def data_type(ctx: Ctx, entry: Node, default: str = "int16") -> tuple[str, int | None]:
    """(drivemap type, string length) of an entity's data_type (+ count)."""
    kind = str(entry.get("data_type", default))
    count = entry.get("count")
    if kind in SIZED:
        return SIZED[kind], None
    if kind == "string":
        if not isinstance(count, int) or not 1 <= count <= 123:
            raise located(ctx.path, entry, f"{entry.get('name')}: a string needs count (its registers)")
        return "string", count
    legacy = LEGACY.get((kind, count if isinstance(count, int) else 1))
    if legacy is None:
        raise _Skip(f"data_type {kind!r}" + (f" with count {count}" if count else "") + " has no register type")
    return legacy, None


class _Skip(Exception):
    """An entity that does not become a register (listed in the review)."""


def _skip(ctx: Ctx, entry: Node, why: str) -> None:
    ctx.doc.review.skipped.append(f"{here(entry, ctx.path)}: {entry.get('name')!r}: {why}")


def _swap(reg: dict[str, Any], swap: Any) -> None:
    words = reg["type"] in ("u32", "s32", "f32", "u64", "s64", "f64")
    if words:
        reg["word_order"] = "low_first" if swap in ("word", "word_byte") else "high_first"
    if swap in ("byte", "word_byte"):
        reg["byte_order"] = "low_first"


def sensor(ctx: Ctx, entry: Node) -> None:
    table = {"holding": "holding", "input": "input"}.get(str(entry.get("input_type", "holding")))
    if table is None:
        return _skip(ctx, entry, f"a sensor of input_type {entry.get('input_type')!r} (import it as a binary_sensor)")
    try:
        dtype, length = data_type(ctx, entry)
    except _Skip as exc:
        return _skip(ctx, entry, str(exc))
    reg: dict[str, Any] = {"table": table, "address": _address(ctx, entry), "type": dtype}
    if length:
        reg["length"] = length
    _swap(reg, entry.get("swap"))
    for key in ("scale", "offset"):
        value = entry.get(key)
        if isinstance(value, int | float) and not isinstance(value, bool) and value != (1 if key == "scale" else 0):
            reg[key] = value
    nan = entry.get("nan_value")
    if nan is not None:
        try:
            reg["not_available"] = [int(nan, 0) if isinstance(nan, str) else int(nan)]
        except (TypeError, ValueError):
            raise located(ctx.path, entry, f"{entry.get('name')}: nan_value {nan!r} is not an integer") from None
    if entry.get("unit_of_measurement") and not isinstance(entry["unit_of_measurement"], Tagged):
        reg["unit"] = str(entry["unit_of_measurement"])
    virtual = entry.get("virtual_count", entry.get("slave_count"))
    if isinstance(virtual, int) and virtual > 0:
        reg["count"] = virtual + 1
    reg.update(access="r", group=_group(ctx, entry))
    ctx.put(entry, reg)
    for key in ("min_value", "max_value", "zero_suppress", "structure"):
        if key in entry:
            ctx.doc.review.notes.append(f"{entry.get('name')}: {key} is Home Assistant's display rule, not imported")
    return None


def binary_sensor(ctx: Ctx, entry: Node) -> None:
    table = TABLES.get(str(entry.get("input_type", "coil")))
    if table in ("coil", "discrete"):
        reg = {"table": table, "address": _address(ctx, entry), "type": "bool", "access": "r"}
    elif table is not None:
        reg = {"table": table, "address": _address(ctx, entry), "type": "u16", "access": "r",
               "description": "Home Assistant reads it as a binary sensor (on when not 0)."}
    else:
        return _skip(ctx, entry, f"input_type {entry.get('input_type')!r}")
    virtual = entry.get("virtual_count", entry.get("slave_count"))
    if isinstance(virtual, int) and virtual > 0:
        reg["count"] = virtual + 1
    reg["group"] = _group(ctx, entry)
    ctx.put(entry, reg, "binary_sensor")
    return None


#: a switch's write_type -> the function code Home Assistant writes it with
WRITE_TYPE_CODES = {"coil": 5, "coils": 15, "holding": 6, "holdings": 16}


def switches(ctx: Ctx, entries: list[Node]) -> None:
    """Coil switches; holding switches grouped by address (several at one address: a write-only enum)."""
    by_address: dict[int, list[Node]] = {}
    for entry in entries:
        kind = str(entry.get("write_type", "holding"))
        if kind in WRITE_TYPE_CODES:  # the function code the integration sends for it
            ctx.doc.max_quantity.setdefault(WRITE_TYPE_CODES[kind], None)
        if kind in ("coil", "coils"):
            verify = "verify" in entry
            reg = {"table": "coil", "address": _address(ctx, entry), "type": "bool", "access": "rw" if verify else "w",
                   "group": _group(ctx, entry), "_switch": (entry, [])}
            ctx.put(entry, reg, "switch")
        elif kind in ("holding", "holdings"):
            by_address.setdefault(_address(ctx, entry), []).append(entry)
        else:
            _skip(ctx, entry, f"write_type {kind!r}")
    for address, group in by_address.items():
        _holding_switches(ctx, address, group)


def _holding_switches(ctx: Ctx, address: int, group: list[Node]) -> None:
    values = [(_int(ctx, e, "command_on"), _int(ctx, e, "command_off") if "command_off" in e else None) for e in group]
    reg: dict[str, Any] = {"table": "holding", "address": address, "type": "u16", "access": "w",
                           "group": _group(ctx, group[0])}
    first = group[0]
    if len(group) == 1 and values[0][0] == values[0][1]:
        reg["command"] = {"value": values[0][0]}
        reg["_switch"] = (first, [(values[0][0], str(first.get("name")))])
        ctx.put(first, reg, "switch")
        return
    if len(group) > 1 and all(on == off for on, off in values):
        base, _, _ = str(first.get("name", "")).rpartition(" ")
        items = [(on, str(e.get("name", "")).rpartition(" ")[2]) for (on, _), e in zip(values, group, strict=True)]
        name, _, _ = ctx.split(base)
        reg["enum"] = ctx.doc.enum(name, items)
        reg["_switch"] = (first, items)
        ctx.put(renamed(first, base), reg, "switch")
        ctx.doc.review.miss(name, "enum labels (the switches name the values only)")
        return
    for entry, (on, off) in zip(group, values, strict=True):
        one = dict(reg, access="rw" if "verify" in entry else "w")
        pairs = [(on, "on")] + ([(off, "off")] if off is not None and off != on else [])
        name, _, _ = ctx.split(str(entry.get("name", "")))
        one["enum"] = ctx.doc.enum(f"{name}_state", pairs)
        one["_switch"] = (entry, pairs)
        ctx.put(entry, one, "switch")


def climate(ctx: Ctx, entry: Node) -> None:
    name, _, _ = ctx.split(str(entry.get("name", "")))
    try:
        dtype, _ = data_type(ctx, entry, "int16")
    except _Skip as exc:
        return _skip(ctx, entry, str(exc))
    unit = {"C": "°C", "F": "°F"}.get(str(entry.get("temperature_unit", "")))
    common: dict[str, Any] = {"type": dtype}
    _swap(common, entry.get("swap"))
    for key in ("scale", "offset"):
        if isinstance(entry.get(key), int | float) and entry[key] != (1 if key == "scale" else 0):
            common[key] = entry[key]
    if unit:
        common["unit"] = unit
    table = {"holding": "holding", "input": "input"}.get(str(entry.get("input_type", "holding")), "holding")
    current = {"table": table, "address": _address(ctx, entry), **common, "access": "r", "group": _group(ctx, entry)}
    ctx.put(renamed(entry, f"{name} current_temperature"), current, "climate")
    target = {"table": "holding", "address": _address(ctx, entry, "target_temp_register"), **common, "access": "rw",
              "group": _group(ctx, entry)}
    for key, out in (("min_temp", "min"), ("max_temp", "max")):
        if isinstance(entry.get(key), int | float):
            target[out] = entry[key]
    ctx.put(renamed(entry, f"{name} target_temperature"), target, "climate")
    _hvac_mode(ctx, entry, name)
    return None


def _hvac_mode(ctx: Ctx, entry: Node, name: str) -> None:
    mode = entry.get("hvac_mode_register")
    if not isinstance(mode, Node):
        return
    pairs = [(int(v), k.removeprefix("state_")) for k, v in (mode.get("values") or {}).items()
             if isinstance(v, int) and not isinstance(v, bool)]
    reg: dict[str, Any] = {"table": "holding", "address": _address(ctx, mode), "type": "u16", "access": "rw",
                           "group": _group(ctx, entry)}
    if pairs:
        reg["enum"] = ctx.doc.enum(f"{name}_hvac_mode", sorted(pairs))
    ctx.put(renamed(entry, f"{name} hvac_mode"), reg, "climate")


def arrays(ctx: Ctx, name: str, elements: dict[int, dict[str, Any]]) -> dict[str, Any]:
    """One register from its entities: a single one, or elements i..i+n-1 at a fixed stride."""
    first = elements[min(elements)]
    reg: dict[str, Any] = {"name": name, **{k: v for k, v in first.items() if k not in ("group", "_file", "_node")}}
    if len(elements) > 1:
        indexes = sorted(elements)
        addresses = [elements[i]["address"] for i in indexes]
        stride = addresses[1] - addresses[0]
        if indexes != list(range(indexes[0], indexes[0] + len(indexes))) or stride <= 0 or any(
                b - a != stride for a, b in zip(addresses, addresses[1:], strict=False)):
            raise located(ctx.path, None, f"{name}: elements {indexes} are not a numbered series at one stride")
        reg["count"] = len(indexes)
        if indexes[0] != 0:  # the elements are named by the manual's numbers
            reg["first_index"] = indexes[0]
        if stride != 1:
            reg["stride"] = stride
    reg["group"] = first["group"]
    reg["source"] = f"{first.get('_file', ctx.path.name)} ({ctx.prefix})"
    return reg


def merge_switches(ctx: Ctx) -> None:
    """A switch at the register a sensor reads is that register's command: one register, readable and
    writable, whose value set is what the switch writes (its labels: on, off or the switch names)."""
    read: dict[tuple[str, int], tuple[str, int]] = {}
    for name, elements in ctx.regs.items():
        for index, reg in elements.items():
            if "_switch" not in reg and "count" not in reg:
                read.setdefault((reg["table"], reg["address"]), (name, index))
    for name, elements in list(ctx.regs.items()):
        for index, reg in list(elements.items()):
            switch = reg.pop("_switch", None)
            owner = read.get((reg["table"], reg["address"])) if switch is not None else None
            if switch is None or owner is None:
                continue
            entry, pairs = switch
            target = ctx.regs[owner[0]][owner[1]]
            target["access"] = "rw"
            if pairs and target["type"] != "bool":
                scale, offset = target.get("scale", 1), target.get("offset", 0)
                target["values"] = [{"value": v * scale + offset if (scale, offset) != (1, 0) else v, "label": label}
                                    for v, label in pairs]
            del elements[index]
            if not elements:
                del ctx.regs[name]
            for entity, place in ctx.entities.items():
                if place == (name, index):
                    ctx.entities[entity] = owner
            what = ", ".join(f"{label}={v}" for v, label in pairs) or "on/off"
            ctx.doc.review.notes.append(f"{here(entry, ctx.path)}: switch {entry.get('name')!r} writes the register of "
                                        f"{owner[0]} (one register: readable, and writes {what})")
            if reg.get("enum") and not any(r.get("enum") == reg["enum"] for els in ctx.regs.values()
                                           for r in els.values()):
                ctx.doc.enums.pop(reg["enum"], None)
