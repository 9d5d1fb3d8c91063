"""The comparison of a `drivemap draft` result with a finished map, shared by the draft benchmarks.

`make_draft` runs the verb's own code in memory (read, draft, settle, compile: nothing written) and
`compare` scores the drafted model against a compiled map, register by register:

* **registers exact**: a finished register whose every element address is drafted in the same table
  with the same type and scale (as compiled: a field the draft leaves out takes the schema default);
* **fields right**: table+address, type, scale, unit, access, min, max right as compiled (7 per register);
* **wrong stated**: fields the draft *writes* that differ from the finished map (a type of the same width
  is not wrong where the finished map leaves the signedness open, ``review: [signedness]``, or where every
  value its value list, value set or range holds reads alike signed and unsigned);
* **defaulted, differs**: fields the draft leaves out whose schema default differs from the finished map;
* **extra**: drafted registers at an address the finished map does not have.

`compare` can read the draft under a map choice applied to every drafted register (an address offset,
a table): the public documents' maps number registers from 1 or choose the table a page does not name.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

FIELDS = ("type", "scale", "unit", "access", "min", "max")


class NoTable(Exception):
    """The draft found no register table (the verb's "no register table found" error), after ``seconds``."""

    def __init__(self, message: str, seconds: float) -> None:
        super().__init__(message)
        self.seconds = seconds


@dataclass
class Drafted:
    """A draft made in memory: its YAML text, its document data, its model and the tool time."""

    text: str
    data: dict[str, Any]
    model: Any
    seconds: float
    skipped: int = 0
    """Rows the draft skipped (and listed in its summary)."""


@dataclass
class Score:
    model: str
    proven: int
    exact: int
    fields_right: int
    wrong_stated: list[str]
    defaulted: int
    extra: int
    seconds: float
    drafted: int

    @property
    def edits(self) -> int:
        return (self.proven - self.found) + self.field_edits + self.extra

    found: int = 0
    field_edits: int = 0
    not_found: list[str] = field(default_factory=list)
    lists_right: int = 0
    lists_total: int = 0
    lists_wrong: list[str] = field(default_factory=list)
    not_exact: list[str] = field(default_factory=list)
    exact_names: list[str] = field(default_factory=list)


def make_draft(document: Path, model_id: str, pages: tuple[int, int] | None = None, max_pages: int = 400,
               timeout: float = 300.0) -> Drafted:
    """`drivemap draft DOCUMENT` in memory, timed from reading the document to the compiled map."""
    from drivemap.frontend import checks
    from drivemap.frontend.load import load_text
    from drivemap.model.build import build_model
    from drivemap.onboard.draft.assemble import draft
    from drivemap.onboard.draft.read import read_document
    from drivemap.onboard.draft.writer import compile_text, settle

    started = time.perf_counter()
    source = read_document(document, pages, max_pages, timeout)
    result = draft(source, model_id)
    if not result.registers:
        why = f" ({len(result.skipped)} rows skipped: {result.skipped[0].reason})" if result.skipped else ""
        raise NoTable(f"no register table found: no table with an address column{why}", time.perf_counter() - started)
    text, errors = settle(result, "", f"{model_id}.yaml")
    if errors:
        raise RuntimeError(f"{model_id}: the draft does not validate: {errors[0].format()}")
    problems = compile_text(text, f"{model_id}.yaml")
    seconds = time.perf_counter() - started
    if problems:
        raise RuntimeError(f"{model_id}: the draft does not compile: {problems[0].format()}")
    doc = load_text(text, f"{model_id}.yaml")
    _, statuses = checks.check(doc)
    model = build_model(f"{model_id}.yaml", doc.data, statuses, {})  # type: ignore[arg-type]
    return Drafted(text, doc.data, model, seconds, len(result.skipped))


def _key(reg: Any, i: int, offset: int = 0, table: str | None = None) -> tuple[str, int]:
    return (table or reg.table, reg.address + offset + i * (reg.stride or 1))


def cells(model: Any, offset: int = 0, table: str | None = None) -> dict[tuple[str, int], Any]:
    """(table, element address) -> register, under an address offset and a table choice."""
    return {_key(r, i, offset, table): r for r in model.registers for i in range(r.count)}


def entries(data: dict[str, Any], model: Any) -> dict[str, dict[str, Any]]:
    """register name -> its entry as written (the stated fields)."""
    names = {r.name for r in model.registers}
    return {str(e["name"]): e for e in data["registers"] if e.get("name") in names}


def _value(reg: Any, key: str) -> Any:
    value = getattr(reg, key, None)
    return float(value) if key == "scale" and value is not None else value


def _comparable(registers: Any, mine: dict[tuple[str, int], Any]) -> list[Any]:
    """The finished registers to compare: where several pages share an address, the draft (which holds one
    register per address) is compared with the page whose register it matches best; the others count
    as not found."""
    by_key: dict[tuple[str, int], list[Any]] = {}
    for reg in registers:
        by_key.setdefault((reg.table, reg.address), []).append(reg)
    out = []
    for key, regs in by_key.items():
        drafted = mine.get(key)
        if len(regs) == 1 or drafted is None:
            out += regs
            continue
        out.append(max(regs, key=lambda r: sum(_value(drafted, f) == _value(r, f) for f in FIELDS)))
    return out


def _values(model: Any, reg: Any) -> set[int] | None:
    if reg.enum is None:
        return None
    return {v.value for e in model.enums if e.name == reg.enum for v in e.members}


def _compare_lists(s: Score, reg: Any, mine: Any, proven: Any, drafted: Any) -> None:
    """Enum values and bit offsets of a finished register that has them: right when the draft has the same
    set, wrong when the draft writes a different one, missing when it writes none."""
    for kind, theirs, ours in (("enum", _values(proven, reg), _values(drafted, mine)),
                               ("bits", {b.offset for b in reg.bits} or None, {b.offset for b in mine.bits} or None)):
        if theirs is None:
            continue
        s.lists_total += 1
        if ours == theirs:
            s.lists_right += 1
        elif ours is not None:
            s.lists_wrong.append(f"{reg.name}.{kind}: drafted {sorted(ours)}, proven {sorted(theirs)}")


def _sign_open(proven: Any, reg: Any, mine: Any) -> bool:
    """The draft states the finished register's width, signed where the map says unsigned or the other way,
    and the finished map leaves the signedness open (``review: [signedness]``: its type is the unsigned
    reading of a known width) or chose it because every value the register may hold (its value list,
    value set or range) reads alike either way (0..32767)."""
    if str(mine.type)[1:] != str(reg.type)[1:] or str(mine.type)[:1] not in "su" or str(reg.type)[:1] not in "su":
        return False
    if "signedness" in reg.review:
        return True
    held = _values(proven, reg) or {v for v, _ in reg.values if isinstance(v, (int, float))}
    lo, hi, scale = getattr(reg, "min", None), getattr(reg, "max", None), float(reg.scale or 1)
    if not held and lo is not None and hi is not None and scale > 0:
        held = {lo / scale, hi / scale}  # the raw span of a stated range
    return bool(held) and all(0 <= v <= 32767 for v in held)


def _compare_one(s: Score, reg: Any, mine: dict[tuple[str, int], Any], entry: dict[str, Any],
                 keys: list[tuple[str, int]], proven: Any) -> None:
    first = mine[keys[0]]
    s.found += 1
    s.fields_right += 1
    exact = True
    for key in FIELDS:
        same = _value(first, key) == _value(reg, key) or key == "type" and _sign_open(proven, reg, first)
        s.fields_right += same
        if not same:
            s.field_edits += 1
            if key in entry:
                s.wrong_stated.append(f"{reg.name}.{key}: drafted {_value(first, key)!r}, proven {_value(reg, key)!r}")
            else:
                s.defaulted += 1
            if key in ("type", "scale"):
                exact = False
    if exact and all((mine[k].type == reg.type or _sign_open(proven, reg, mine[k])) and float(mine[k].scale) == float(reg.scale)
                     for k in keys):
        s.exact += 1
        s.exact_names.append(reg.name)
    else:
        s.not_exact.append(f"{reg.name} ({first.type} x{first.scale} vs {reg.type} x{reg.scale})")


def compare(model_id: str, proven: Any, drafted: Drafted, offset: int = 0, table: str | None = None) -> Score:
    """Score ``drafted`` against the compiled map ``proven``; every drafted register read at its address +
    ``offset`` in ``table`` (its own table when None)."""
    mine = cells(drafted.model, offset, table)
    stated = entries(drafted.data, drafted.model)
    s = Score(model_id, len(proven.registers), 0, 0, [], 0, 0, drafted.seconds, len(drafted.model.registers))
    for reg in _comparable(proven.registers, mine):
        keys = [(reg.table, reg.address + i * (reg.stride or 1)) for i in range(reg.count)]
        if not all(k in mine for k in keys):
            s.not_found.append(reg.name)
            continue
        _compare_one(s, reg, mine, stated.get(mine[keys[0]].name, {}), keys, proven)
        _compare_lists(s, reg, mine[keys[0]], proven, drafted.model)
    proven_cells = cells(proven)
    s.extra = sum(1 for r in drafted.model.registers if _key(r, 0, offset, table) not in proven_cells)
    return s
