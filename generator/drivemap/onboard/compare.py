"""Two maps of one device compared: the registers whose address, table, type, word order, scale, unit
or value set disagree.

Registers are paired by table and address (the sources name them differently); a pair disagrees on
type, word order (multi-word registers only), scale (neither scaled by a scale-factor register), unit
(case and spaces ignored) or value set (enum values or ``values:``). A register of one map that the
other has (the same label or name) at the same address in another table is a table disagreement; at
another address, an address disagreement. A label or name pairs registers across places only where it
names one register in each map: a label two registers share ("Register", "Reserved", "Battery") says
nothing of which one is meant, so it pairs none. These are errata candidates: the
comparison says where the sources differ, never which one is right.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from drivemap.model.nodes import Model, Register

__all__ = ["Difference", "compare_models"]


@dataclass(frozen=True)
class Difference:
    """One disagreement: the field, each map's register (name, table, address) and value."""

    field: str
    a: str
    b: str
    a_value: str
    b_value: str

    def line(self) -> str:
        return f"{self.field}: {self.a} = {self.a_value} | {self.b} = {self.b_value}"


def _where(reg: Register) -> str:
    return f"{reg.name} ({reg.table} {reg.address})"


def _key(text: str | None) -> str:
    return re.sub(r"[^a-z0-9]+", "", (text or "").lower())


#: unit spellings that name the same unit
_UNIT_WORDS = {"amps": "a", "amp": "a", "ampere": "a", "volts": "v", "volt": "v", "watts": "w", "watt": "w",
               "degc": "c", "celsius": "c", "hertz": "hz", "percent": "%", "pct": "%", "voltamps": "va", "degrees": "°", "deg": "°", "var": "var",
               "voltampsreactive": "var", "kilowatthours": "kwh"}



def _unit(text: str) -> str:
    key = _key(text) or text.strip()
    return _UNIT_WORDS.get(key, key)


def _values(model: Model, reg: Register) -> tuple[str, ...]:
    if reg.enum_values:
        return tuple(str(v) for v in sorted(reg.enum_values))
    return tuple(sorted(str(v.value) for v in reg.value_set))


def _pair(ma: Model, a: Register, mb: Model, b: Register) -> list[Difference]:
    out: list[Difference] = []
    here, there = _where(a), _where(b)
    if a.type != b.type:
        out.append(Difference("type", here, there, a.type, b.type))
    elif a.type not in ("u16", "s16", "bool", "string") and (a.word_order or "") != (b.word_order or ""):
        out.append(Difference("word_order", here, there, str(a.word_order), str(b.word_order)))
    if not (a.scale_register or b.scale_register) and abs(float(a.scale) - float(b.scale)) > 1e-12 * max(
            abs(float(a.scale)), abs(float(b.scale))):
        out.append(Difference("scale", here, there, f"{a.scale:g}", f"{b.scale:g}"))
    if a.unit and b.unit and _unit(a.unit) != _unit(b.unit):
        out.append(Difference("unit", here, there, a.unit, b.unit))
    va, vb = _values(ma, a), _values(mb, b)
    if va and vb and va != vb:
        out.append(Difference("values", here, there, ", ".join(va), ", ".join(vb)))
    return out


def _unique_labels(model: Model) -> dict[str, Register]:
    """label or name key -> the one register of ``model`` it names (keys naming two registers left out)."""
    seen: dict[str, list[Register]] = {}
    for r in model.registers:
        for key in dict.fromkeys(k for k in (_key(r.label), _key(r.name)) if k):
            seen.setdefault(key, []).append(r)
    return {key: regs[0] for key, regs in seen.items() if len(regs) == 1}


def compare_models(ma: Model, mb: Model) -> list[Difference]:
    """The disagreements of ``ma`` and ``mb``, in ``ma``'s register order."""
    by_place = {(r.table, r.address): r for r in mb.registers}
    by_label = _unique_labels(mb)
    mine = _unique_labels(ma)
    out: list[Difference] = []
    for a in ma.registers:
        b = by_place.get((a.table, a.address))
        if b is not None:
            out.extend(_pair(ma, a, mb, b))
            continue
        keys = [k for k in (_key(a.label), _key(a.name)) if k and mine.get(k) is a]
        same = next((by_label[k] for k in keys if k in by_label), None)
        if same is None:
            continue
        if same.address == a.address:
            out.append(Difference("table", _where(a), _where(same), a.table, same.table))
        else:
            out.append(Difference("address", _where(a), _where(same), str(a.address), str(same.address)))
    return out
