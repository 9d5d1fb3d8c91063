"""Semantic checks of value sets, display precision, array numbering and alignment rules.

Value sets (``values:``) hold engineering values the register can carry exactly, inside its range;
``precision`` is for numbers, ``first_index`` for arrays. An alignment rule (``protocol.alignment``)
must be one every register in its block can keep: a register whose own read or write would break
the rule could never be read or written, so the map is refused where that register is defined.
"""

from __future__ import annotations

import math
import struct
from typing import Any

from drivemap.frontend.checks_registers import CheckerBase
from drivemap.frontend.load import PathT
from drivemap.model.nodes import FLOAT_TYPES, INTEGER_TYPES, TYPE_BOUNDS, type_words

__all__ = ["check_rules"]

_FLOAT_FORMATS = {"f32": ">f", "f64": ">d"}


def check_rules(checker: CheckerBase) -> None:
    """Every check of this module, on a document whose registers were located."""
    for i, reg in enumerate(checker.data["registers"]):
        where: PathT = ("registers", i)
        rtype = checker.type_of(i)
        if "values" in reg:
            _check_values(checker, reg, where, rtype)
        if "precision" in reg and rtype in ("bool", "string"):
            checker.error(where + ("precision",), f"precision does not apply to a {rtype} register", key=True)
        elif "precision" in reg and (reg.get("enum") or reg.get("bits")):
            checker.error(where + ("precision",), "precision does not apply to a register with an enum or bits",
                          key=True)
        if "first_index" in reg and reg.get("count", 1) < 2:
            checker.error(where + ("first_index",), "first_index is for arrays (count > 1)", key=True)
    for j, rule in enumerate(checker.data["protocol"].get("alignment", ())):
        _check_alignment(checker, rule, ("protocol", "alignment", j))


def _check_values(checker: CheckerBase, reg: dict[str, Any], where: PathT, rtype: str) -> None:
    vwhere = where + ("values",)
    if rtype == "bool":
        checker.error(vwhere, "values does not apply to a bool register (it holds true or false)", key=True)
        return
    for key in ("enum", "bits", "command"):
        if reg.get(key):
            checker.error(vwhere, f"a register has values or {key}, not both (an enum names integer codes; values "
                          "limit any type)", key=True)
            return
    seen: dict[Any, int] = {}
    for j, item in enumerate(reg["values"]):
        value = item["value"]
        iwhere = vwhere + (j, "value")
        problem = _value_problem(reg, rtype, value)
        if problem is not None:
            checker.error(iwhere, f"value {value!r}: {problem}")
            continue
        vkey = value if isinstance(value, str) else float(value)
        if vkey in seen:
            checker.error(iwhere, f"value {value!r} is listed twice", related=vwhere + (seen[vkey],))
        seen.setdefault(vkey, j)
    default = reg.get("default")
    for j, value in enumerate(default if isinstance(default, list) else [default]):
        if value is None or isinstance(value, bool):
            continue
        if (value if isinstance(value, str) else float(value)) not in seen:
            dwhere = where + (("default", j) if isinstance(default, list) else ("default",))
            checker.error(dwhere, f"default {value!r} is not one of the register's values", related=vwhere,
                          note="the values are listed here", related_key=True)


def _value_problem(reg: dict[str, Any], rtype: str, value: Any) -> str | None:
    """Why ``value`` cannot be in the value set of ``reg`` (None: it can)."""
    if rtype == "string":
        if not isinstance(value, str):
            return "a string register's values are text"
        size = 2 * reg.get("length", 1)
        if len(value.encode(reg.get("encoding", "ascii"), errors="replace")) > size:
            return f"longer than the field ({size} bytes)"
        if reg.get("encoding", "ascii") == "ascii" and not value.isascii():
            return "not ASCII"
        return None
    if isinstance(value, str):
        return f"{'an' if rtype[0] in 'fs' else 'a'} {rtype} register's values are numbers"
    lo, hi = reg.get("min"), reg.get("max")
    if (lo is not None and value < lo - 1e-9) or (hi is not None and value > hi + 1e-9):
        return f"outside the range {lo}..{hi}"
    raw = (value - reg.get("offset", 0)) / reg.get("scale", 1)
    if rtype in FLOAT_TYPES:
        try:
            back = struct.unpack(_FLOAT_FORMATS[rtype], struct.pack(_FLOAT_FORMATS[rtype], raw))[0]
        except (OverflowError, struct.error):
            return f"does not fit {rtype}"
        if back != raw:
            return f"{rtype} cannot hold it exactly (the nearest {rtype} is {back!r})"
        return None
    if rtype in INTEGER_TYPES and not reg.get("scale_register"):
        if not math.isclose(raw, round(raw), abs_tol=1e-6):
            return f"not a multiple of the scale {reg.get('scale', 1)}"
        low, high = TYPE_BOUNDS[rtype]
        if not low <= round(raw) <= high:
            return f"does not fit {rtype}"
    return None


def _check_alignment(checker: CheckerBase, rule: dict[str, Any], where: PathT) -> None:
    start, end = rule.get("start", 0), rule.get("end", 0xFFFF)
    if start > end:
        checker.error(where + ("start",), f"the block starts at 0x{start:04X}, after its end 0x{end:04X}")
        return
    code = rule.get("exception")
    listed = {e["code"] for e in checker.data["protocol"]["exceptions"]}
    if code is not None and code not in listed:
        checker.error(where + ("exception",), f"exception {code:02X}h is not in protocol.exceptions")
    operations = rule.get("operations", ["read", "write"])
    for i, reg in enumerate(checker.data["registers"]):
        table, address = checker.locations.get(i, (None, 0))
        if table != rule["table"]:
            continue
        words = type_words(checker.type_of(i), reg.get("length", 1))
        size = max(words, reg.get("min_read") or 0)
        for k in range(reg.get("count", 1)):
            at = address + k * reg.get("stride", 1)
            if at + words <= start or at > end:
                continue
            for op in operations:
                if ("r" if op == "read" else "w") not in reg.get("access", "r"):
                    continue
                why = _breaks(rule, at, size if op == "read" else words)
                if why is not None:
                    name = reg["name"] + (f"[{k}]" if reg.get("count", 1) > 1 else "")
                    checker.error(checker.where_address(i), f"{name} ({words} word(s) at 0x{at:04X}) cannot be "
                                  f"{'read' if op == 'read' else 'written'} under the map's alignment rule: {why}",
                                  related=where, note="the rule is given here")
                    return


def _breaks(rule: dict[str, Any], address: int, count: int) -> str | None:
    if address % rule.get("start_multiple", 1):
        return f"its address is not a multiple of {rule['start_multiple']}"
    if count % rule.get("quantity_multiple", 1):
        return f"its size is not a multiple of {rule['quantity_multiple']}"
    if count < rule.get("min_quantity", 1):
        return f"it is smaller than the minimum quantity {rule['min_quantity']}"
    return None
