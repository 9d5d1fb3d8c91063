"""Small formatting helpers shared by the docs views: numbers as engineers write them, hex, anchors."""

from __future__ import annotations

from drivemap.model.nodes import Register
from drivemap.vocab.escape import slug


def num(value: float | int | None) -> str | None:
    """A number as an engineer writes it: ``60`` not ``60.0``, no float noise; None stays None."""
    if value is None:
        return None
    if isinstance(value, bool):
        return str(value).lower()
    if float(value).is_integer():
        return str(int(value))
    return f"{float(value):.12g}"


def hex4(value: int) -> str:
    return f"0x{value:04X}"


def hex2(value: int) -> str:
    return f"0x{value:02X}"


def with_unit(value: str | None, unit: str | None) -> str | None:
    if value is None:
        return None
    return f"{value} {unit}" if unit else value


def engineering(reg: Register, raw: int) -> float:
    if reg.signed and raw >= 1 << (16 * reg.words - 1):
        raw -= 1 << (16 * reg.words)
    return raw * reg.scale + reg.offset


def enum_anchor(name: str) -> str:
    return "#" + slug(f"Enum {name}")


def bits_anchor(reg: Register) -> str:
    return "#" + slug(f"Bits of {reg.name}")


def example_anchor(name: str) -> str:
    return "#" + slug(f"Example {name}")


#: What the manual shows at a reserved range (Reserved.kind), as the docs say it.
RESERVED_KIND = {
    "reserved": "marked reserved",
    "unlabeled": "listed without a name",
    "not_listed": "not listed in the manual",
}
