"""ESPHome entities that read a part of a register (``bitmask:``): one register, each entity a bit field.

Several ``sensor`` / ``binary_sensor`` / ``text_sensor`` entities with a ``bitmask`` at one address (and
``switch`` entities that set bits there: the register is then writable) are one register of the device: each mask becomes a bit field (one bit: a flag; several: a field of that
width), named after its entity. A single masked entity is such a register too, so its mask is never
lost (the whole word is not what it reads). A mask that is not one run of bits, or bits two entities
both read, are located errors saying what to change.
"""

from __future__ import annotations

from typing import Any

from drivemap.onboard.importers.es_context import VALUE_TYPES, Ctx
from drivemap.onboard.importers.mapdoc import safe, upper
from drivemap.onboard.importers.yamlsrc import Node, here, located

__all__ = ["add_masked", "masked_registers"]

_PLATFORMS = ("sensor", "binary_sensor", "text_sensor")


def add_masked(ctx: Ctx, platform: str, item: Node, table: str, address: int) -> bool:
    """Keep a masked entity for its register; False when it is not one (no bitmask, a writable platform)."""
    mask = item.get("bitmask")
    switch = platform == "switch" and table == "holding" and "write_lambda" not in item
    if (platform not in _PLATFORMS and not switch) or table not in ("holding", "input") or isinstance(mask, bool) \
            or not isinstance(mask, int):
        return False
    if mask <= 0:
        raise located(ctx.path, item, f"{item.get('name')}: bitmask {mask} selects no bit: give the bits it reads")
    ctx.masked.setdefault((table, address), []).append((platform, item))
    return True


def _field(ctx: Ctx, item: Node, bits: int) -> tuple[int, int]:
    mask = int(item["bitmask"])
    offset = (mask & -mask).bit_length() - 1
    width = mask.bit_count()
    if mask >> offset != (1 << width) - 1:
        raise located(ctx.path, item, f"{item.get('name')}: bitmask {mask:#x} is not one run of bits: split it into "
                                      "one entity per run")
    if offset + width > bits:
        raise located(ctx.path, item, f"{item.get('name')}: bitmask {mask:#x} is wider than its {bits}-bit value_type")
    return offset, width


def _common(items: list[tuple[str, Node]]) -> list[str]:
    """The words all the entities' names start with (their device's name, usually)."""
    words = [str(item.get("name") or item.get("id") or "").lower().split() for _, item in items]
    common: list[str] = []
    for group in zip(*words, strict=False):
        if len(set(group)) != 1 or len(common) + 1 >= min(len(w) for w in words):
            break
        common.append(group[0])
    return common


def _name(items: list[tuple[str, Node]], table: str, address: int) -> str:
    if len(items) == 1:
        return safe(str(items[0][1].get("name") or items[0][1].get("id") or f"{table} {address}"))
    common = _common(items)
    return safe(" ".join([*common, "status"]) if common else f"{table} word {address}")


def masked_registers(ctx: Ctx) -> list[tuple[dict[str, Any], Node]]:
    """One register per address of masked entities, with its first entity (for its polling group)."""
    out = []
    for (table, address), items in ctx.masked.items():
        kinds = {str(item.get("value_type", "U_WORD")) for _, item in items}
        if len(kinds) != 1 or next(iter(kinds)) not in VALUE_TYPES:
            raise located(ctx.path, items[0][1], f"the entities at {table} address {address} read it as "
                                                 f"{', '.join(sorted(kinds))}: give them one value_type")
        rtype, word_order = VALUE_TYPES[next(iter(kinds))]
        bits_of_type = {"u16": 16, "s16": 16, "u32": 32, "s32": 32}.get(rtype)
        if bits_of_type is None:
            raise located(ctx.path, items[0][1], f"bitmask on a {rtype} value: drivemap's bit fields are on 16- or "
                                                 "32-bit integers")
        name = ctx.doc.name(_name(items, table, address))
        reg: dict[str, Any] = {"name": name, "table": table, "address": address,
                               "type": "u16" if rtype == "s16" else "u32" if rtype == "s32" else rtype}
        if word_order:
            reg["word_order"] = word_order
        writes = [item for platform, item in items if platform == "switch"]
        reg["access"] = "rw" if writes else "r"  # a switch sets its bits: ESPHome reads, changes and writes the word
        if writes and len(writes) < len(items):
            reg["review"] = ["access"]  # the source writes the switches' bits only: the others' writability is open
            ctx.doc.review.notes.append(
                f"{here(writes[0], ctx.path)}: switch {', '.join(repr(str(w.get('name'))) for w in writes)} writes "
                f"bits of {name}: the register is writable (read, change, write); whether its other bits may be "
                "written is for review")
        used = 0
        taken: set[str] = set()
        bits = []
        skip = len(_common(items)) if len(items) > 1 else 0
        for _, item in items:
            offset, width = _field(ctx, item, bits_of_type)
            mask = ((1 << width) - 1) << offset
            if used & mask:
                raise located(ctx.path, item, f"{item.get('name')}: bitmask {mask:#x} reads bits another entity at "
                                              f"{table} address {address} reads: give each bit to one entity")
            used |= mask
            label = str(item.get("name") or item.get("id") or f"bits {offset}")
            short = " ".join(label.split()[skip:]) or label
            bit_name = upper(short, f"bit_{offset}")
            n = 2
            while bit_name in taken:
                bit_name, n = f"{upper(short, f'bit_{offset}')}_{n}", n + 1
            taken.add(bit_name)
            bit: dict[str, Any] = {"name": bit_name, "offset": offset}
            if width > 1:
                bit["width"] = width
            bit["label"] = label
            bits.append(bit)
            for key in ("filters", "unit_of_measurement", "device_class"):
                if key in item:
                    ctx.doc.review.notes.append(f"{here(item, ctx.path)}: {label!r}: {key} of a bit field is not "
                                                "imported (a field is the raw bits)")
        reg["bits"] = sorted(bits, key=lambda b: b["offset"])
        reg["source"] = ", ".join(dict.fromkeys(here(item, ctx.path) for _, item in items))
        out.append((reg, items[0][1]))
    return out
