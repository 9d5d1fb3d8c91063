"""Wire words <-> raw values: word order, byte order, signedness and the raw bounds of every type.

The raw value of a register is an int for every type: the integer (signed for s16/s32/s64), the
IEEE-754 bit pattern of f32/f64, the bytes of a string as one unsigned number, 0/1 for a coil or
discrete input. :func:`words_to_raw` undoes the register's byte order (bytes inside each word) and
word order and joins the words, most significant first; :func:`raw_to_words` is its inverse.
"""

from __future__ import annotations

from collections.abc import Sequence

from drivemap.runtime.errors import InvalidValue, ValueOutOfRange
from drivemap.runtime.spec import RegisterSpec
from drivemap.runtime.types import TYPE_BOUNDS


def raw_bounds(spec: RegisterSpec) -> tuple[int, int]:
    """Bounds of the raw value: the integer types' ranges; 0/1 for a coil or discrete input; the
    unsigned bit pattern for floats, strings and a bool kept in a register."""
    bounds = TYPE_BOUNDS.get(spec.type)
    if bounds is not None:
        return bounds
    if spec.bit_table:
        return 0, 1
    return 0, (1 << (16 * spec.words)) - 1


def _swap(word: int) -> int:
    return ((word & 0xFF) << 8) | (word >> 8)


def words_to_raw(spec: RegisterSpec, words: Sequence[int]) -> int:
    """The register's raw value from its wire words (bits of a coil: 0/1)."""
    if spec.bit_table:
        return 1 if words[0] else 0
    if spec.byte_order == "low_first":
        words = [_swap(w) for w in words]
    if spec.word_order == "low_first":
        words = list(reversed(words))
    raw = 0
    for word in words:
        raw = (raw << 16) | word
    bits = 16 * len(words)
    if spec.signed and raw >> (bits - 1):
        raw -= 1 << bits
    return raw


def split_words(raw: int, count: int) -> list[int]:
    """An unsigned number as ``count`` words, most significant first."""
    return [(raw >> (16 * (count - 1 - i))) & 0xFFFF for i in range(count)]


def join_words(words: Sequence[int]) -> int:
    """Words, most significant first, as one unsigned number."""
    raw = 0
    for word in words:
        raw = (raw << 16) | word
    return raw


def raw_to_words(spec: RegisterSpec, raw: int) -> list[int]:
    """Wire words of a raw value (checked against the type's bounds); a coil's bit as [0] or [1]."""
    check_raw(spec, raw)
    if spec.bit_table:
        return [raw]
    count = spec.words
    if count == 1:
        words = [raw & 0xFFFF]
    else:
        words = split_words(raw & ((1 << (16 * count)) - 1), count)
        if spec.word_order == "low_first":
            words.reverse()
    if spec.byte_order == "low_first":
        words = [_swap(w) for w in words]
    return words


def check_raw(spec: RegisterSpec, raw: object) -> int:
    if not isinstance(raw, int) or isinstance(raw, bool):
        raise InvalidValue(f"{spec.name}: raw value must be int, not {type(raw).__name__}")
    lo, hi = raw_bounds(spec)
    if not lo <= raw <= hi:
        shown = str(raw) if raw.bit_length() <= 128 else f"an integer of {raw.bit_length()} bits"
        raise ValueOutOfRange(f"{spec.name}: raw value {shown} does not fit {spec.type} ({lo}..{hi})")
    return raw


__all__ = ["TYPE_BOUNDS", "check_raw", "join_words", "raw_bounds", "raw_to_words", "split_words", "words_to_raw"]
