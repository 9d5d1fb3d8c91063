"""Facts of the register types and of identity values that the runtime and the compiler's model both
state: one leaf module below both, so the model needs nothing of the client to say them."""

from __future__ import annotations

#: Raw bounds of the integer register types (signed for s16/s32/s64).
TYPE_BOUNDS: dict[str, tuple[int, int]] = {
    "u16": (0, 0xFFFF),
    "s16": (-0x8000, 0x7FFF),
    "u32": (0, 0xFFFFFFFF),
    "s32": (-0x80000000, 0x7FFFFFFF),
    "u64": (0, 0xFFFFFFFFFFFFFFFF),
    "s64": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF),
}


def show_value(value: int | str) -> str:
    """A value as messages show it: text quoted, small integers in decimal, wide ones in hex (with the
    ASCII they spell, as SunSpec's 0x53756E53 'SunS')."""
    if isinstance(value, str):
        return repr(value)
    if 0 <= value <= 0xFFFF or value < 0:
        return str(value)
    raw = value.to_bytes((value.bit_length() + 7) // 8, "big")
    text = raw.decode("ascii") if all(32 <= b < 127 for b in raw) else None
    return f"0x{value:X}" + (f" ({text!r})" if text else "")


def expected_text(kind: str, values: tuple[int | str, ...]) -> str:
    """What an identity check expects, in words."""
    shown = [show_value(v) for v in values]
    if kind == "one_of":
        return "one of " + ", ".join(shown)
    if kind == "prefix":
        return f"text starting with {shown[0]}"
    if kind == "pattern":
        return f"text matching {shown[0]}"
    return shown[0]


__all__ = ["TYPE_BOUNDS", "expected_text", "show_value"]
