"""Per-spec tables the client's per-call path needs (:class:`SpecTables`), computed once per spec."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from drivemap.runtime.client.protocol.planner import Key, max_write_words, units
from drivemap.runtime.spec import READ_CODES, DeviceSpec, FunctionSpec, RegisterSpec


@dataclasses.dataclass(frozen=True)
class SpecTables:
    """What the per-call path needs from a :class:`DeviceSpec`, computed once per spec."""

    readable: frozenset[str]
    """Names of the readable registers."""
    selectors: frozenset[str]
    """Names of the registers that select a page of some register."""
    read_codes: frozenset[int]
    """The read function codes the map lists."""
    all_keys: tuple[Key, ...]
    """Every readable element, in :func:`planner.units` order (what ``read_all`` reads)."""
    decode: Mapping[str, tuple[int, bool, bool, bool, RegisterSpec | None]]
    """Per readable register: (words, signed, low word first, is a page selector, the spec when the
    words need the general conversion: byte order, more than two words)."""
    fc05: FunctionSpec | None
    fc06: FunctionSpec | None
    fc0f: FunctionSpec | None
    fc10: FunctionSpec | None
    write_limits: Mapping[str, int]
    """:func:`max_write_words` per writable table."""
    under_review: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)
    """Per register whose ``review:`` leaves a field open that decides its words: those fields
    (:attr:`RegisterSpec.open_for_writes`); empty for most maps."""
    read_review: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)
    """Per register whose ``review:`` leaves a field open that decides the value read (those of
    ``under_review``): a read warns once (:func:`~.review.warn_review`). An open ``signedness``
    alone does not warn: the value read is the map's (unsigned) reading, and the docs and exports
    mark it."""


_TABLES: dict[int, tuple[DeviceSpec, SpecTables]] = {}


def _decode_entry(reg: RegisterSpec, selectors: frozenset[str]) -> tuple[int, bool, bool, bool, RegisterSpec | None]:
    general = not reg.bit_table and (reg.byte_order == "low_first" or reg.words > 2)
    return reg.words, reg.signed, reg.word_order == "low_first", reg.name in selectors, reg if general else None


def spec_tables(spec: DeviceSpec) -> SpecTables:
    """The tables of ``spec`` (cached by identity; specs are module-level constants)."""
    hit = _TABLES.get(id(spec))
    if hit is not None and hit[0] is spec:
        return hit[1]
    selectors = frozenset(r.page.selector for r in spec.registers if r.page is not None)
    tables = SpecTables(
        readable=frozenset(r.name for r in spec.registers if r.readable),
        selectors=selectors,
        read_codes=frozenset(c for c in READ_CODES.values() if spec.protocol.function(c) is not None),
        all_keys=tuple(k for u in units(spec) for k, _ in u.keys),
        decode={r.name: _decode_entry(r, selectors) for r in spec.registers if r.readable},
        fc05=spec.protocol.function(0x05),
        fc06=spec.protocol.function(0x06),
        fc0f=spec.protocol.function(0x0F),
        fc10=spec.protocol.function(0x10),
        write_limits={"holding": max_write_words(spec, "holding"), "coil": max_write_words(spec, "coil")},
        under_review={r.name: r.open_for_writes for r in spec.registers if r.open_for_writes},
        read_review={r.name: r.open_for_writes for r in spec.registers if r.open_for_writes},
    )
    _TABLES[id(spec)] = (spec, tables)
    return tables


__all__ = ["SpecTables", "spec_tables"]
