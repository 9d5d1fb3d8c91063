"""An example's stated values against its frames: ``meaning.values`` and ``preset`` must be what the
printed (or corrected) frames carry.

* a read example: the normal reply's data words, from the address the example reads, are the
  values of ``meaning.values``, and the ``preset`` of the cells it covers (the simulator serves
  the preset to give the printed reply);
* a write example (06h / 10h, broadcast too): the request's words are the values of
  ``meaning.values``.

Only numeric registers of the holding and input tables (u16, s16, u32, s32, standard byte order)
with a protocol ``address`` are compared here, each against the frame of its own table's function; floats, 64-bit
values, strings, coils, scale-factor registers and Modicon-numbered registers are proven by the
round-trip tests, which decode every example's frames through the generated client.

Frames that cannot be read (syntax, illegible bytes, a wrong checksum without an erratum, a layout
that is not Modbus) are reported by the frame checks and skipped here. :func:`problems` yields
(where, message, options of :meth:`Checker.error`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from drivemap.frontend import frames
from drivemap.frontend.load import PathT

__all__ = ["problems"]

Problem = tuple[PathT, str, dict[str, Any]]
_SIGNED = {"s16", "s32"}


def _frame(ex: dict[str, Any], part: str) -> frames.Frame | None:
    text = (ex.get("erratum") or {}).get(part) or ex.get(part)
    if text is None:
        return None
    try:
        frame = frames.parse(text, ex["mode"])
    except frames.FrameSyntaxError:
        return None
    if frame.illegible or not frame.check_ok or frames.structure_problem(frame, part) is not None:
        return None
    return frame


_TABLE_OF = {0x03: "holding", 0x04: "input", 0x06: "holding", 0x10: "holding"}
_COMPARED_TYPES = {"u16", "s16", "u32", "s32"}


def _words(ex: dict[str, Any]) -> tuple[str, int | None, list[int], str] | None:
    """(which frame, start address or None, data words, table) the example's values are in."""
    meaning = ex["meaning"]
    request = _frame(ex, "request")
    req_address = int.from_bytes(request.body[2:4], "big") if request is not None and len(request.body) >= 4 else None
    if meaning["operation"] == "read":
        response = _frame(ex, "response")
        if response is None or len(response.body) < 3 or response.body[1] & 0x80 or response.body[1] not in (3, 4):
            return None
        data = response.body[3:]
        start = meaning.get("address") if meaning.get("address") is not None else req_address
        words = [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data) - 1, 2)]
        return "response", start, words, _TABLE_OF[response.body[1]]
    if request is None or meaning["operation"] not in ("write", "write_multiple"):
        return None
    pdu = request.body[1:]
    if pdu[0] == 0x06:
        return "request", req_address, [int.from_bytes(pdu[3:5], "big")], "holding"
    if pdu[0] == 0x10:
        data = pdu[6:]
        return "request", req_address, [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data) - 1, 2)], \
            "holding"
    return None


def _cell(registers: dict[str, dict[str, Any]], ref: str, table: str) -> tuple[dict[str, Any], int] | None:
    """The register and element of ``ref`` when this module compares it (see the module docstring)."""
    base, _, rest = ref.partition("[")
    reg = registers.get(base)
    if (reg is None or reg.get("type", "u16") not in _COMPARED_TYPES or "address" not in reg
            or reg.get("table", "holding") != table or reg.get("scale_register")
            or reg.get("byte_order", "high_first") != "high_first"):
        return None
    count = reg.get("count", 1)
    if not rest:
        return (reg, 0) if count == 1 else None
    try:
        index = int(rest.rstrip("]"))
    except ValueError:
        return None
    return (reg, index) if rest.endswith("]") and 0 <= index < count else None


def _raw_at(reg: dict[str, Any], index: int, start: int, words: list[int]) -> int | None:
    """The cell's raw value in ``words`` (read from ``start``), None when the frame does not cover it."""
    rtype = reg.get("type", "u16")
    size = 2 if rtype in ("u32", "s32") else 1
    at = reg["address"] + index * reg.get("stride", 1) - start
    if at < 0 or at + size > len(words):
        return None
    raw: int
    if size == 1:
        raw = words[at]
    else:
        first, second = words[at], words[at + 1]
        raw = (second << 16) | first if reg.get("word_order") == "low_first" else (first << 16) | second
    bits = 16 * size
    if rtype in _SIGNED and raw >= 1 << (bits - 1):
        raw -= 1 << bits
    return raw


def _engineering(reg: dict[str, Any], raw: int) -> float:
    return float(raw * reg.get("scale", 1) + reg.get("offset", 0))


def _same(reg: dict[str, Any], value: float, raw: int) -> bool:
    scale = reg.get("scale", 1)
    return math.isclose(_engineering(reg, raw), float(value), rel_tol=1e-9, abs_tol=abs(scale) * 1e-6)


def _shown(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def problems(data: dict[str, Any]) -> Iterator[Problem]:
    registers = {r["name"]: r for r in reversed(data["registers"])}
    for i, ex in enumerate(data["examples"]):
        found = _words(ex)
        if found is None:
            continue
        part, start, words, table = found
        if start is None:
            continue
        meaning = ex["meaning"]
        checks: list[tuple[tuple[str, ...], str, float, str]] = [
            (("meaning", "values"), ref, value, "meaning.values gives") for ref, value in
                  (meaning.get("values") or {}).items()]
        if part == "response":
            checks += [(("preset",), ref, value, "preset sets") for ref, value in (ex.get("preset") or {}).items()]
        for key, ref, value, says in checks:
            cell = _cell(registers, ref, table)
            if cell is None or isinstance(value, (bool, str)) or value is None:
                continue  # unknown names are reported by the example checks; other kinds by the round trips
            reg, index = cell
            if key == ("preset",) and reg.get("page"):
                continue  # shares its addresses with other pages: the frame shows the page selected
            raw = _raw_at(reg, index, start, words)
            where: PathT = ("examples", i, *key, ref)
            if raw is None:
                if key == ("meaning", "values"):
                    yield where, f"{says} {ref}, which the {part} does not carry (it holds {len(words)} word(s) " \
                                 f"from 0x{start:04X})", {"key": True}
                continue
            if not _same(reg, value, raw):
                yield where, f"{says} {ref} = {_shown(value)}, but the {part} carries raw {raw} there " \
                             f"({_shown(_engineering(reg, raw))})", {"key": True}
