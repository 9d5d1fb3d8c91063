"""Semantic checks of a map's ``identity``: each check names a readable, unpaged register of the map and
gives exactly one way to compare, with values the register can hold."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from drivemap.frontend.load import PathT
from drivemap.model.family import IDENTITY_KINDS
from drivemap.model.nodes import default_type, normalize_raw

Problem = tuple[PathT, str]


def problems(data: dict[str, Any], tables: dict[str, str]) -> Iterator[Problem]:
    """Every problem of ``data['identity']`` (``tables``: register name -> its table)."""
    registers = {r["name"]: r for r in data.get("registers", ()) if isinstance(r, dict) and "name" in r}
    for i, check in enumerate(data.get("identity", ())):
        name = check["register"]
        reg = registers.get(name)
        if reg is None:
            yield ("identity", i, "register"), f"identity register {name!r} is not a register of this map"
            continue
        kinds = [k for k in IDENTITY_KINDS if k in check]
        if len(kinds) != 1:
            yield ("identity", i), (f"identity check of {name!r} gives {' and '.join(kinds)}: give exactly one of "
                                    if kinds else f"identity check of {name!r} gives no value: give one of ") + \
                ", ".join(IDENTITY_KINDS)
            continue
        if reg.get("access", "rw") == "w" or reg.get("page"):
            yield ("identity", i, "register"), f"identity register {name!r} must be readable without a page switch"
            continue
        yield from _values(i, kinds[0], check[kinds[0]], reg, tables.get(name, "holding"))


def _values(i: int, kind: str, given: Any, reg: dict[str, Any], table: str) -> Iterator[Problem]:
    rtype = reg.get("type", default_type(table))
    name = reg["name"]
    values = given if kind == "one_of" else [given]
    where: PathT = ("identity", i, kind)
    if kind in ("prefix", "pattern") and rtype != "string":
        yield where, f"{kind} compares text: {name!r} is a {rtype} register (use equals or one_of)"
        return
    if kind == "pattern":
        try:
            re.compile(given)
        except re.error as exc:
            yield where, f"pattern {given!r} is not a regular expression: {exc}"
        return
    for j, value in enumerate(values):
        at = (*where, j) if kind == "one_of" else where
        if rtype == "string":
            if not isinstance(value, str):
                yield at, f"{name!r} is a string register: its identity value must be text, not {value!r}"
            elif len(value.encode("utf-8")) > 2 * reg.get("length", 1):
                yield at, f"{value!r} is longer than {name!r} ({reg.get('length', 1)} registers)"
        elif not isinstance(value, int):
            yield at, f"{name!r} is a {rtype} register: its identity value must be an integer (raw), not {value!r}"
        elif rtype in ("f32", "f64"):
            yield at, f"{name!r} is a float register: identity compares integers or text, not float bit patterns"
        elif normalize_raw(rtype, table, reg.get("length", 1), value) is None:
            yield at, f"{value} does not fit {name!r} ({rtype})"
