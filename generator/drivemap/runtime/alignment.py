"""Alignment rules (``protocol.alignment``): which request start addresses and quantities a device takes.

A manual may say that every request must start at an even address and carry an even number of
registers, or that a read starting inside a float (or covering half of one) is refused. The map
says so per table or per block of addresses (:class:`~drivemap.runtime.spec.AlignmentSpec`);
:func:`violation` tells whether one request breaks such a rule. The client calls it before anything
is sent (raw reads, planned reads, writes), the simulator answers the rule's exception code, and
the planner never plans a read that breaks it.
"""

from __future__ import annotations

import math

from drivemap.runtime.errors import MisalignedRequest
from drivemap.runtime.spec import AlignmentSpec, DeviceSpec

__all__ = ["Violation", "aligned_limit", "refuse_misaligned", "rules_for", "violation"]

Violation = tuple[AlignmentSpec, str]
"""The rule a request breaks and why (a sentence naming the address, the quantity or the register)."""

#: id(spec) -> (spec, {table: {word: (element start, end, element name)}}) for whole-value checks
_LAYOUTS: dict[int, tuple[DeviceSpec, dict[str, dict[int, list[tuple[int, int, str]]]]]] = {}


def _layout(spec: DeviceSpec) -> dict[str, dict[int, list[tuple[int, int, str]]]]:
    cached = _LAYOUTS.get(id(spec))
    if cached is not None and cached[0] is spec:
        return cached[1]
    out: dict[str, dict[int, list[tuple[int, int, str]]]] = {}
    for reg in spec.registers:
        if reg.words < 2 or reg.bit_table:
            continue
        words = out.setdefault(reg.table, {})
        for i in range(reg.count):
            start = reg.element_address(i)
            for a in range(start, start + reg.words):
                words.setdefault(a, []).append((start, start + reg.words, reg.element_name(i)))
    _LAYOUTS[id(spec)] = (spec, out)
    return out


def rules_for(spec: DeviceSpec, table: str, operation: str) -> tuple[AlignmentSpec, ...]:
    """The rules of ``table`` that apply to ``operation`` ("read" or "write")."""
    return tuple(r for r in spec.protocol.alignment if r.table == table and operation in r.operations)


def _cut(spec: DeviceSpec, table: str, address: int, end: int) -> str | None:
    """The multi-word element a request of words ``address``..``end - 1`` covers only in part."""
    words = _layout(spec).get(table, {})
    for start, stop, name in words.get(address, ()):
        if start < address:
            return f"starts inside {name} (0x{start:04X}..0x{stop - 1:04X})"
    for start, stop, name in words.get(end - 1, ()):
        if stop > end:
            return f"ends inside {name} (0x{start:04X}..0x{stop - 1:04X})"
    return None


def violation(spec: DeviceSpec, table: str, address: int, count: int, operation: str) -> Violation | None:
    """The first rule a request of ``count`` words at ``address`` of ``table`` breaks, or None."""
    end = address + count
    for rule in rules_for(spec, table, operation):
        if end <= rule.start or address > rule.end:
            continue
        where = f"{operation} {table} 0x{address:04X} x{count}"
        if address % rule.start_multiple:
            return rule, f"{where}: the start address must be a multiple of {rule.start_multiple}"
        if count % rule.quantity_multiple:
            return rule, f"{where}: the quantity must be a multiple of {rule.quantity_multiple}"
        if count < rule.min_quantity:
            return rule, f"{where}: the quantity must be at least {rule.min_quantity}"
        if rule.whole_values:
            cut = _cut(spec, table, address, end)
            if cut is not None:
                return rule, f"{where} {cut}: multi-word values are read and written whole"
    return None


def refuse_misaligned(spec: DeviceSpec, table: str, address: int, count: int, operation: str) -> None:
    """Raise :class:`MisalignedRequest` (naming the rule's source) for a request that breaks a rule."""
    if spec.protocol.alignment:
        broken = violation(spec, table, address, count, operation)
        if broken is not None:
            raise MisalignedRequest(f"{broken[1]} (the map's alignment rule, {broken[0].source})")


def aligned_limit(spec: DeviceSpec, table: str, limit: int, operation: str = "read") -> int:
    """The largest quantity up to ``limit`` that every rule of ``table`` takes (a multiple of each
    rule's quantity_multiple), so that the planner never plans a request a rule refuses."""
    step = 1
    for rule in rules_for(spec, table, operation):
        step = math.lcm(step, rule.quantity_multiple)
    return max(step, limit - limit % step)
