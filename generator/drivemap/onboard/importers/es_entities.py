"""ESPHome ``modbus_controller`` entities -> registers (see :mod:`.esphome`)."""

from __future__ import annotations

import re
from typing import Any

from drivemap.onboard.importers.es_bits import add_masked, masked_registers
from drivemap.onboard.importers.es_context import VALUE_TYPES, Ctx
from drivemap.onboard.importers.overlaps import check_overlaps
from drivemap.onboard.importers.yamlsrc import Node, Tagged, here, located

__all__ = ["entity", "finish"]

_FACTOR = re.compile(r"^return x \* powf\(10\.0f, id\(sf_([a-z][a-z0-9_]*)\)\.state\);$")


def _skip(ctx: Ctx, item: Node, why: str) -> None:
    ctx.doc.review.skipped.append(f"{here(item, ctx.path)}: {item.get('name') or item.get('id')!r}: {why}")


def _group(ctx: Ctx, item: Node) -> str:
    skip = item.get("skip_updates", 0)
    owner = ctx.controllers.get(str(item.get("modbus_controller_id")))
    seconds = (owner[1] if owner is not None else ctx.base) * ((skip if isinstance(skip, int) else 0) + 1)
    name = ctx.doc.group(f"scan_{seconds}s", f"Polled every {seconds} s")
    ctx.intervals[name] = seconds
    return name


def _address(ctx: Ctx, item: Node) -> int:
    address, offset = item.get("address"), item.get("offset", 0)
    if not isinstance(address, int) or isinstance(address, bool) or not isinstance(offset, int) or offset % 2:
        raise located(ctx.path, item, f"{item.get('name')}: address {address!r} (offset {offset!r}) is not a "
                                      "register address")
    address += offset // 2
    if not 0 <= address <= 0xFFFF:
        raise located(ctx.path, item, f"{item.get('name')}: address {address} is not 0..65535")
    return address


def entity(ctx: Ctx, platform: str, item: Node) -> None:
    owner = ctx.controllers.get(str(item.get("modbus_controller_id")))
    first = next(iter(ctx.controllers.values()), None)
    if owner is not None and first is not None and owner[0] != first[0]:
        return _skip(ctx, item, f"another device (modbus_controller {item.get('modbus_controller_id')!r}, "
                                f"address {owner[0]}): import it on its own")
    _batch(ctx, platform, item)
    if item.get("internal") is True and str(item.get("id", "")).startswith("gap_"):
        return _gap(ctx, item)  # drivemap's filler of a batched read: words the device reads
    name, suffix = ctx.key(str(item.get("name") or item.get("id") or ""))
    table = "holding" if platform == "select" else {"holding": "holding", "read": "input", "coil": "coil",
                                                    "discrete_input": "discrete"}.get(str(item.get("register_type")))
    if table is None:
        return _skip(ctx, item, f"register_type {item.get('register_type')!r}")
    if suffix is not None and name in ctx.regs:
        return _part(ctx, platform, item, name, suffix)
    if add_masked(ctx, platform, item, table, _address(ctx, item)):
        return None
    if suffix is not None:
        return _part(ctx, platform, item, name, suffix)
    if name in ctx.regs or ctx.doc.taken(name):
        name = ctx.doc.name(name)  # a second entity of the same name: a register of its own
    ctx.doc.claim(name)
    if table in ("coil", "discrete"):
        reg: dict[str, Any] | None = _bit_table(ctx, platform, item, table)
    elif platform == "switch":
        reg = _command(ctx, item)
    else:
        reg = _value(ctx, platform, item, table, name)
    if reg is not None:
        _write_code(ctx, reg, item)
        reg.setdefault("group", _group(ctx, item))
        ctx.regs[name] = {"name": name, **reg, "source": here(item, ctx.path), "_node": item}
    return None


def _write_code(ctx: Ctx, reg: dict[str, Any], item: Node) -> None:
    """The write function code ESPHome sends for a writable entity: the single one (06h / 05h) unless
    ``use_write_multiple: true`` or the value spans several registers (10h / 0Fh)."""
    if "w" not in reg.get("access", "") or reg["table"] not in ("holding", "coil"):
        return
    words = {"u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4, "f64": 4}.get(reg.get("type", "u16"), 1)
    if reg.get("type") == "string":
        words = 2
    single, multiple = (5, 15) if reg["table"] == "coil" else (6, 16)
    code = multiple if item.get("use_write_multiple") is True or words > 1 else single
    ctx.doc.max_quantity.setdefault(code, None)


def _batch(ctx: Ctx, platform: str, item: Node) -> None:
    table = "holding" if platform == "select" else str(item.get("register_type"))
    if item.get("assumed_state") or not isinstance(item.get("address"), int):
        return
    found = VALUE_TYPES.get(str(item.get("value_type", "U_WORD")))
    words = {"u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4}.get(found[0], 1) if found else 1
    count = item.get("register_count")
    words = max(words, count if isinstance(count, int) else 1)
    key = (table, item["address"] + (item.get("offset", 0) if isinstance(item.get("offset"), int) else 0) // 2)
    before = ctx.batches.get(key, (0, False))
    new_read = item.get("force_new_range") is True or item.get("reuse_previous_range") is False  # before / from 2026.9
    ctx.batches[key] = (max(before[0], words), before[1] or new_read)
    ctx.batch_owner[key] = str(item.get("modbus_controller_id"))
    if item.get("reuse_previous_range") is True:
        ctx.joins.append((table, key[1], item))


def _holes_read(ctx: Ctx) -> None:
    """ESPHome 2026.9+ reads across a hole before an entity marked ``reuse_previous_range: true`` (the
    older form names the hole with an internal filler entity): the hole's words are readable."""
    tables = {"holding": "holding", "read": "input", "coil": "coil", "discrete_input": "discrete"}
    for kind, address, item in ctx.joins:
        ends = [a + words for (t, a), (words, _) in ctx.batches.items() if t == kind and a < address]
        start = max(ends, default=address)
        if kind in tables and start < address:
            ctx.doc.reserved.append({"table": tables[kind], "start": start, "end": address - 1, "readable": True,
                                     "kind": "unlabeled", "source": here(item, ctx.path),
                                     "notes": "Read as part of a batched request; nothing is named here."})


def max_reads(ctx: Ctx) -> None:
    """A read split where the next word follows on: the reads before it show what the device takes
    (at least that many words); the map keeps that many, so no request grows past what was proven."""
    from drivemap.onboard.importers.mapdoc import TABLE_CODES

    tables = {"holding": "holding", "read": "input", "coil": "coil", "discrete_input": "discrete"}
    for table in {t for t, _ in ctx.batches}:
        longest = 0
        for owner in sorted({ctx.batch_owner.get(k, "") for k in ctx.batches if k[0] == table}):
            run, end = 0, None  # one controller's reads (ESPHome 2026.9+ polls each interval on its own)
            for (_, address), (words, forced) in sorted(i for i in ctx.batches.items()
                                                        if i[0][0] == table and ctx.batch_owner.get(i[0], "") == owner):
                if forced and address == end:
                    longest = max(longest, run)
                run = words if forced or address != end else run + words
                end = address + words
        if longest and table in tables:
            code = TABLE_CODES[tables[table]]
            ctx.doc.max_quantity[code] = longest
            ctx.doc.review.notes.append(f"max_quantity {longest} for function {code:02X}h: the longest read before "
                                        "a split of the file's batched reads (the device takes at least that many)")


def _gap(ctx: Ctx, item: Node) -> None:
    table = {"holding": "holding", "read": "input", "coil": "coil", "discrete_input": "discrete"}.get(
        str(item.get("register_type")))
    count = item.get("register_count", 1)
    if table is None or not isinstance(count, int) or count < 1:
        return _skip(ctx, item, "an internal filler entity")
    start = _address(ctx, item)
    ctx.doc.reserved.append({"table": table, "start": start, "end": start + count - 1, "readable": True,
                             "kind": "unlabeled", "source": here(item, ctx.path),
                             "notes": "Read as part of a batched request; nothing is named here."})
    return None


def _bit_table(ctx: Ctx, platform: str, item: Node, table: str) -> dict[str, Any]:
    access = "r" if platform != "switch" else ("w" if item.get("assumed_state") else "rw")
    return {"table": table, "address": _address(ctx, item), "type": "bool", "access": access}


def _command(ctx: Ctx, item: Node) -> dict[str, Any] | None:
    mask = item.get("bitmask")
    if not isinstance(mask, int) or "write_lambda" not in item:
        _skip(ctx, item, "a holding-register switch without a command value (bitmask + write_lambda)")
        return None
    ctx.doc.review.miss(ctx.key(str(item.get("name")))[0], "type of the command register (u16 by default)")
    return {"table": "holding", "address": _address(ctx, item), "type": "u16", "access": "w",
            "command": {"value": mask}, "group": _group(ctx, item)}


def _text_words(item: Node) -> int | None:
    """A text entity's registers: ``register_count``, or (ESPHome 2026.9+, which refuses it) its
    ``response_size`` in bytes, two to a register."""
    count, size = item.get("register_count"), item.get("response_size")
    if isinstance(count, int) and not isinstance(count, bool):
        return count
    if isinstance(size, int) and not isinstance(size, bool) and size > 0 and size % 2 == 0:
        return size // 2
    return None


def _typed(ctx: Ctx, item: Node, name: str) -> dict[str, Any] | None:
    if "raw_encode" in item:
        if item.get("raw_encode") == "ANSI":
            count = _text_words(item)
            return {"type": "string", "length": count} if count is not None else None
        raw = ctx.raw_types.get(name)
        if raw is None:
            return None
        out: dict[str, Any] = {"type": raw[0]}
        if raw[1]:
            out["word_order"] = raw[1]
        if raw[2] == "low_first":
            out["byte_order"] = "low_first"
        if raw[0] == "string":
            out["length"] = _text_words(item)
        return out
    found = VALUE_TYPES.get(str(item.get("value_type", "U_WORD")))
    if found is None:
        return None
    return {"type": found[0], **({"word_order": found[1]} if found[1] else {})}


def _value(ctx: Ctx, platform: str, item: Node, table: str, name: str) -> dict[str, Any] | None:
    typed = _typed(ctx, item, name)
    if typed is None:
        _skip(ctx, item, f"value type {item.get('value_type') or item.get('raw_encode')!r} has no register type")
        return None
    reg: dict[str, Any] = {"table": table, "address": _address(ctx, item), **typed, "access": "r"}
    unit = item.get("unit_of_measurement")
    if unit and not isinstance(unit, Tagged):
        reg["unit"] = str(unit)
    if platform == "number":
        _number(reg, item)
    elif platform == "select":
        options = item.get("optionsmap") or {}
        reg.update(access="rw", enum=ctx.doc.enum(name, sorted((int(v), str(k)) for k, v in options.items())))
    elif platform == "sensor":
        _filters(ctx, reg, item)
    if str(item.get("id", "")).startswith("sf_"):
        ctx.factors[str(item["id"])[3:]] = name
    return reg


def _number(reg: dict[str, Any], item: Node) -> None:
    reg["access"] = "rw"
    step, multiply = item.get("step"), item.get("multiply")
    if isinstance(multiply, int | float) and multiply and isinstance(step, int | float) and step != 1:
        reg["scale"] = step
    for key, out in (("min_value", "min"), ("max_value", "max")):
        if isinstance(item.get(key), int | float):
            reg[out] = item[key]


def _filters(ctx: Ctx, reg: dict[str, Any], item: Node) -> None:
    for step in item.get("filters") or []:
        if not isinstance(step, dict) or len(step) != 1:
            continue
        (kind, value), = step.items()
        if kind == "filter_out":
            reg["not_available"] = [int(v) for v in (value if isinstance(value, list) else [value])]
        elif kind == "multiply" and isinstance(value, int | float):
            reg["scale"] = value
        elif kind == "offset" and isinstance(value, int | float):
            reg["offset"] = value
        elif kind == "lambda" and _FACTOR.match(str(value)):
            reg["scale_register"] = _FACTOR.match(str(value)).group(1)  # type: ignore[union-attr]
        else:
            opened = {"calibrate_linear": ["scale", "offset"], "calibrate_polynomial": ["scale", "offset"],
                      "lambda": ["scale"]}.get(str(kind), [])
            if opened:  # the source converts the value itself: the register's conversion is for review
                reg["review"] = list(dict.fromkeys([*reg.get("review", []), *opened]))
            ctx.doc.review.notes.append(f"{here(item, ctx.path)}: {item.get('name')!r}: filter {kind} is ESPHome's "
                                        "processing, not imported" + (f" (review: {', '.join(opened)})" if opened else ""))


def _part(ctx: Ctx, platform: str, item: Node, name: str, suffix: str) -> None:
    """A label text sensor, a bit field, or one value switch of a write-only enum."""
    reg = ctx.regs.get(name)
    if platform == "switch" and isinstance(item.get("bitmask"), int):
        if reg is None:
            reg = ctx.regs[name] = {"name": name, "table": "holding", "address": _address(ctx, item), "type": "u16",
                                    "access": "w", "group": _group(ctx, item), "source": here(item, ctx.path)}
            ctx.doc.review.miss(name, "enum labels (the switches name the values only)")
        reg.setdefault("_values", []).append((int(item["bitmask"]), suffix))
        return
    if reg is None:
        return _skip(ctx, item, f"a part of {name}, which is not imported")
    if suffix == "label":
        return _labels(ctx, reg, item)
    mask = item.get("bitmask")
    if not isinstance(mask, int) or mask <= 0:
        return _skip(ctx, item, "a bit field without a bitmask")
    offset = (mask & -mask).bit_length() - 1
    width = bin(mask).count("1")
    bit: dict[str, Any] = {"name": suffix, "offset": offset}
    if width != 1:
        bit["width"] = width
    bit["label"] = suffix
    reg.setdefault("bits", []).append(bit)
    ctx.doc.review.miss(name, f"label of bit {suffix} (ESPHome names it only)")
    return None


def _labels(ctx: Ctx, reg: dict[str, Any], item: Node) -> None:
    words = 4 if reg["type"] in ("u64", "s64") else 2 if reg["type"] in ("u32", "s32") else 1
    pairs = []
    for step in item.get("filters") or []:
        for entry in (step.get("map") or []) if isinstance(step, dict) else []:
            text = str(entry.get("from", "")) if isinstance(entry, dict) else ""
            parts = [text[i:i + 4] for i in range(0, len(text), 4)]
            if reg.get("word_order") == "low_first":
                parts.reverse()
            value = int("".join(parts), 16)
            if reg["type"].startswith("s") and value >= 1 << (16 * words - 1):
                value -= 1 << (16 * words)
            pairs.append((value, str(entry.get("to"))))
    if pairs:
        reg["enum"] = ctx.doc.enum(reg["name"], pairs)


def _free_reserved(ctx: Ctx) -> None:
    """Filler words minus the words of registers imported there (a command switch is not polled)."""
    from drivemap.runtime.spec import TYPE_WORDS

    used = {(r["table"], r["address"] + w): r for r in ctx.regs.values()
            for w in range(r.get("length", 1) if r["type"] == "string" else TYPE_WORDS[r["type"]])}
    for res in ctx.doc.reserved:
        for a in range(res["start"], res["end"] + 1):
            reg = used.get((res["table"], a))
            if reg is not None and reg["access"] == "w":
                reg["access"] = "rw"  # a batched read covers it: the device reads it
    out = []
    for res in ctx.doc.reserved:
        run: list[int] = []
        for a in [*range(res["start"], res["end"] + 1), -1]:
            if a >= 0 and (res["table"], a) not in used and (not run or a == run[-1] + 1):
                run.append(a)
                continue
            if run:
                out.append({**res, "start": run[0], "end": run[-1]})
            run = [a] if a >= 0 and (res["table"], a) not in used else []
    ctx.doc.reserved = out


def finish(ctx: Ctx) -> None:
    for reg, first in masked_registers(ctx):
        reg["group"] = _group(ctx, first)
        _write_code(ctx, reg, first)
        ctx.regs[reg["name"]] = reg
    check_overlaps(ctx.path, [(reg, reg.pop("_node", None)) for reg in ctx.regs.values()],
                   "one register, one entity: delete one, or read parts of one register with bitmask")
    _holes_read(ctx)
    _free_reserved(ctx)
    max_reads(ctx)
    for reg in ctx.regs.values():
        values = reg.pop("_values", None)
        if values:
            reg["enum"] = ctx.doc.enum(reg["name"], values)
        if reg.get("scale_register") in ctx.factors:
            reg["scale_register"] = ctx.factors[reg["scale_register"]]
        ctx.doc.add(reg)
    extra = " ".join(f"--interval {g}={n}" for g, n in sorted(ctx.intervals.items()))
    ctx.doc.review.notes.append(f"export again with --scan-interval {ctx.base} {extra} (the entities' polling)")
