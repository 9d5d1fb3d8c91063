"""The simulator's address book: which register cell each 16-bit word (or bit) of a table belongs to,
how a word sits in its cell, and the internal refusal a request handler raises."""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from drivemap.runtime.spec import DeviceSpec, RegisterSpec

__all__ = ["ReadPlan", "Refused", "Slot", "cell_names", "gap_words", "packer", "swapped", "word_shift"]

_PACKERS: dict[int, Callable[..., bytes]] = {}
#: (cells read, per word: (cell or None for a word read as 0, bit shift in the cell's raw value, swap bytes),
#: whether any word swaps its bytes)
ReadPlan = tuple[tuple[str, ...], tuple[tuple[str | None, int, bool], ...], bool]


def packer(count: int) -> Callable[..., bytes]:
    """``struct.Struct(">{count}H").pack``, made once per count."""
    pack = _PACKERS.get(count)
    if pack is None:
        pack = _PACKERS[count] = struct.Struct(f">{count}H").pack
    return pack


class Refused(Exception):
    """Internal: the request hits an error case; the dialect decides the answer."""

    def __init__(self, case: str, code: int | None = None) -> None:
        super().__init__(case)
        self.case = case
        self.code = code  # the code the map names for this refusal (an alignment rule's), else by case


@dataclass(frozen=True)
class Slot:
    """One 16-bit address (one bit in a bit table) of one register cell."""

    cell: str
    reg: RegisterSpec
    index: int
    word: int  # 0 = first word on the wire


def cell_names(reg: RegisterSpec) -> Iterator[tuple[str, int]]:
    for i in range(reg.count):
        yield reg.element_name(i), i


def word_shift(reg: RegisterSpec, word: int) -> int:
    """Bit shift in the raw value of the ``word``-th word on the wire."""
    n = reg.words
    if reg.bit_table or n == 1:
        return 0
    canonical = n - 1 - word if reg.word_order == "low_first" else word
    return 16 * (n - 1 - canonical)


def gap_words(spec: DeviceSpec, documented: frozenset[tuple[str, int]]) -> frozenset[tuple[str, int]]:
    """Undocumented words between two documented ones at most ``max_gap`` apart (the device reads them)."""
    if not spec.protocol.max_gap:
        return frozenset()
    out: set[tuple[str, int]] = set()
    for table in {t for t, _ in documented}:
        addresses = sorted(a for t, a in documented if t == table)
        for low, high in zip(addresses, addresses[1:], strict=False):
            if 1 < high - low <= spec.protocol.max_gap + 1:
                out.update((table, a) for a in range(low + 1, high))
    return frozenset(out)


def swapped(word: int, swap: bool) -> int:
    return ((word & 0xFF) << 8) | (word >> 8) if swap else word


