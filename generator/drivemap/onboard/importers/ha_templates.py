"""The ``template:`` entities drivemap's Home Assistant export writes, read back as register facts.

* ``{% set labels = {...} %}...`` over ``states('sensor.X')``: X's enum (values and labels);
* ``((states('sensor.X') | int(0)) // 2^o) % 2^w``: a bit field of X (offset o, width w), its name
  from the entity name; with a labels mapping: the field's enum;
* ``{% set sf = states('sensor.F') | int %}{% set v = states('sensor.X_raw') | float %}``: X's scale
  factor register F, and X's unit from the template entity.
* ``{{ states('sensor.X_raw') }}`` (and a string's ``| regex_replace(...)`` that drops its NUL/space
  padding): X's unit from the template entity; an availability ``(states('sensor.X_raw') | float(0)) != N``
  says the raw value 0 means not available.
* a ``select`` whose state maps ``[[value, option], ...]`` over ``states('sensor.X')`` and whose
  option writes ``modbus.write_register``: X's value set (an option that is not the value and unit is
  its label), writable with 06h (one word) or 10h (a list of words).

Any other template is the user's own logic: listed, not imported.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.ha_context import Ctx
from drivemap.onboard.importers.ha_labels import entities_of, label_map, open_fields
from drivemap.onboard.importers.mapdoc import upper
from drivemap.onboard.importers.yamlsrc import here

__all__ = ["apply_templates"]

_LABELS = re.compile(r"^\{% set labels = (\{.*\}) %\}\{% set v = (.*) %\}\{\{ labels\.get\(v, v\) \}\}$", re.S)
_STATE = re.compile(r"^states\('(sensor\.[a-z0-9_]+)'\)$")
_FIELD = re.compile(r"^\(\(\(states\('(sensor\.[a-z0-9_]+)'\) \| int\(0\)\) // (\d+)\) % (\d+)\) \| string$")
_BIT = re.compile(r"^\{\{ \(\(states\('(sensor\.[a-z0-9_]+)'\) \| int\(0\)\) // (\d+)\) % (\d+)( == 1)? \}\}$")
_PLAIN = re.compile(r"^\{\{ states\('(sensor\.[a-z0-9_]+)'\)( \| regex_replace\('\[\\x00 \]\+\$', ''\))? \}\}$")
_UNAVAILABLE_0 = re.compile(r"\(states\('(sensor\.[a-z0-9_]+)'\) \| float\(0\)\) != ")
_OPTIONS = re.compile(r"^\{% set opts = (\[.*\]) %\}\{% set v = states\('(sensor\.[a-z0-9_]+)'\)( \| float\(none\))? %\}"
                      r"\{% for o in opts if o\[0\] == v %\}\{\{ o\[1\] \}\}\{% endfor %\}$", re.S)
_WRITE = re.compile(r"^\{\{ (\{.*\})\[option\] \}\}$", re.S)
_SCALED = re.compile(r"^\{% set sf = states\('(sensor\.[a-z0-9_]+)'\) \| int %\}"
                     r"\{% set v = states\('(sensor\.[a-z0-9_]+)'\) \| float %\}")


def apply_templates(ctx: Ctx, path: Path, block: Any) -> None:
    if not isinstance(block, dict):
        return
    for kind in ("sensor", "binary_sensor", "select"):
        for entry in block.get(kind) or []:
            if not isinstance(entry, dict):
                continue
            if _select(ctx, entry) if kind == "select" else (_apply(ctx, entry) or _label_map(ctx, path, entry)):
                continue
            _user_logic(ctx, path, kind, entry)
    for kind, entries in block.items():
        if kind not in ("sensor", "binary_sensor", "select", "trigger", "unique_id") and isinstance(entries, list):
            for entry in entries:
                ctx.doc.review.skipped.append(f"{here(entry, path)}: template {kind} "
                                              f"{entry.get('name') if isinstance(entry, dict) else entry!r} "
                                              "(not a register fact)")


def _label_map(ctx: Ctx, path: Path, entry: dict[str, Any]) -> bool:
    """A template that only maps a register's values to text: that register's enum."""
    found = label_map(str(entry.get("state", "")))
    if found is None:
        return False
    reg = _register(ctx, found[0])
    name = str(entry.get("name", ""))
    if reg is None or reg.get("enum") or reg.get("type") in ("f32", "f64", "string", "bool") or "scale" in reg:
        return False
    owner = ctx.entities[found[0]][0]
    reg["enum"] = ctx.doc.enum(name or owner, sorted(found[1].items()))
    ctx.doc.review.notes.append(f"{here(entry, path)}: template sensor {name!r}: the labels of {owner} "
                                f"(enum {reg['enum']}, {len(found[1])} values)")
    return True


def _user_logic(ctx: Ctx, path: Path, kind: str, entry: dict[str, Any]) -> None:
    """Listed; a register it reads gets the fields it seems to compute in its ``review``."""
    state = str(entry.get("state", ""))
    regs = [(e, _register(ctx, e)) for e in entities_of(state)]
    named = [ctx.entities[e][0] for e, reg in regs if reg is not None]
    fields = open_fields(state) if len(named) == 1 else []
    for _, reg in regs:
        if reg is not None and fields:
            reg["review"] = list(dict.fromkeys([*reg.get("review", []), *fields]))
    reads = f" over {', '.join(named)}" if named else ""
    review = f"; review: {', '.join(fields)} of {named[0]}" if fields else ""
    ctx.doc.review.skipped.append(f"{here(entry, path)}: template {kind} {entry.get('name')!r}{reads} (the user's own "
                                  f"logic, not a register fact{review})")


def _register(ctx: Ctx, entity: str) -> dict[str, Any] | None:
    found = ctx.entities.get(entity)
    return ctx.regs[found[0]][found[1]] if found else None


def _log2(value: int) -> int | None:
    exponent = int(math.log2(value)) if value > 0 else -1
    return exponent if exponent >= 0 and 1 << exponent == value else None


def _apply(ctx: Ctx, entry: dict[str, Any]) -> bool:
    state = str(entry.get("state", ""))
    name = str(entry.get("name", ""))
    match = _LABELS.match(state)
    if match:
        try:
            labels = {int(k): str(v) for k, v in json.loads(match.group(1)).items()}
        except (ValueError, AttributeError):
            return False
        source = _STATE.match(match.group(2)) or _FIELD.match(match.group(2))
        if source is None:
            return False
        if source.re is _STATE:
            return _enum(ctx, name, source.group(1), labels)
        return _bit(ctx, name, source.group(1), int(source.group(2)), int(source.group(3)), labels)
    match = _BIT.match(state)
    if match:
        return _bit(ctx, name, match.group(1), int(match.group(2)), int(match.group(3)), None)
    match = _SCALED.match(state)
    if match:
        return _scaled(ctx, entry, match.group(1), match.group(2)) and _available(ctx, entry, match.group(2))
    match = _PLAIN.match(state)
    if match:
        reg = _register(ctx, match.group(1))
        if reg is None:
            return False
        if entry.get("unit_of_measurement") and reg.get("type") != "string":
            reg["unit"] = str(entry["unit_of_measurement"])
        return _available(ctx, entry, match.group(1))
    return False


def _available(ctx: Ctx, entry: dict[str, Any], raw: str) -> bool:
    """An availability that is false while the raw value is 0: 0 means not available."""
    reg = _register(ctx, raw)
    if reg is None:
        return False
    found = _UNAVAILABLE_0.search(str(entry.get("availability", "")))
    if found and found.group(1) == raw and 0 not in reg.get("not_available", []):
        reg["not_available"] = [0, *reg.get("not_available", [])]
    return True


def _select(ctx: Ctx, entry: dict[str, Any]) -> bool:
    """drivemap's template select: the register's value set and its write function code."""
    match = _OPTIONS.match(str(entry.get("state", "")))
    actions = entry.get("select_option")
    action = actions[0] if isinstance(actions, list) and len(actions) == 1 and isinstance(actions[0], dict) else {}
    data: dict[str, Any] = action["data"] if isinstance(action.get("data"), dict) else {}
    write = _WRITE.match(str(data.get("value", "")))
    reg = _register(ctx, match.group(2)) if match else None
    if match is None or write is None or reg is None:
        return False
    try:
        pairs, words = json.loads(match.group(1)), json.loads(write.group(1))
    except ValueError:
        return False
    values = []
    for value, text in pairs:
        shown = str(int(value)) if isinstance(value, float) and value.is_integer() else str(value)
        plain = f"{shown} {reg['unit']}" if reg.get("unit") and not isinstance(value, str) else shown
        values.append({"value": value, **({} if text == plain else {"label": text})})
    reg.update(access="rw", values=values)
    multiple = any(isinstance(w, list) for w in words.values())
    ctx.doc.max_quantity.setdefault(16 if multiple else 6, None)
    return True


def _enum(ctx: Ctx, name: str, entity: str, labels: dict[int, str]) -> bool:
    reg = _register(ctx, entity)
    if reg is None:
        return False
    owner = ctx.entities[entity][0]
    reg["enum"] = ctx.doc.enum(owner, sorted(labels.items()))
    return True


def _bit(ctx: Ctx, name: str, entity: str, divisor: int, modulus: int, labels: dict[int, str] | None) -> bool:
    reg = _register(ctx, entity)
    offset, width = _log2(divisor), _log2(modulus)
    if reg is None or offset is None or width is None or width == 0:
        return False
    bit_name = upper(name.rpartition(" ")[2], f"bit_{offset}")
    if any(b["name"] == bit_name for b in reg.get("bits", [])):
        return True  # the same field of another element of the array
    bit: dict[str, Any] = {"name": bit_name, "offset": offset}
    if width != 1:
        bit["width"] = width
    bit["label"] = bit_name
    if labels:
        bit["enum"] = ctx.doc.enum(f"{ctx.entities[entity][0]}_{bit_name}", sorted(labels.items()))
    reg.setdefault("bits", []).append(bit)
    ctx.doc.review.miss(ctx.entities[entity][0], f"label of bit {bit_name} (the export names it only)")
    return True


def _scaled(ctx: Ctx, entry: dict[str, Any], factor: str, raw: str) -> bool:
    reg, scale = _register(ctx, raw), ctx.entities.get(factor)
    if reg is None or scale is None:
        return False
    reg["scale_register"] = scale[0]
    unit = entry.get("unit_of_measurement")
    if unit:
        reg["unit"] = str(unit)
    return True
