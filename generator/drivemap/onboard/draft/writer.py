"""The map text, checked in memory by the real compiler until it validates as written.

Every diagnostic of the compiler on a register is answered the same way: a refused name is
renamed, a refused field is dropped (and listed), a register the compiler refuses as a whole (an
address that overlaps another) is dropped and listed as a skipped row. Nothing is written to disk
here.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from drivemap.diagnostics import CompileError, Diagnostic
from drivemap.frontend import checks, schema
from drivemap.frontend.load import load_text
from drivemap.model.build import build_model
from drivemap.model.nodes import Model
from drivemap.onboard.draft.assemble import Draft
from drivemap.onboard.draft.fields import REVIEWED
from drivemap.onboard.draft.tables import Drafted, Skipped
from drivemap.vocab import namecheck

_KEY_ORDER = ("name", "label", "param", "table", "address", "count", "stride", "element_params", "group", "type",
              "length", "encoding", "word_order", "access", "scale", "unit", "min", "max", "default", "enum", "bits", "source",
              "notes")
_DROPPABLE = {"label", "param", "element_params", "type", "length", "encoding", "word_order", "access", "scale", "unit", "min",
              "max", "default", "enum", "bits", "notes"}
MAX_ROUNDS = 12


class _Hex(int):
    pass


class _Dumper(yaml.SafeDumper):
    pass


_Dumper.add_representer(_Hex, lambda d, v: d.represent_scalar("tag:yaml.org,2002:int", f"0x{int(v):04X}"))


def _ordered(entry: dict[str, Any]) -> dict[str, Any]:
    out = {k: entry[k] for k in _KEY_ORDER if k in entry}
    out.update({k: v for k, v in entry.items() if k not in out})
    if "address" in out:
        out["address"] = _Hex(int(out["address"]))
    return out


def render(draft: Draft, header: str) -> str:
    data = dict(draft.data)
    data["registers"] = [_ordered(d.entry) for d in draft.registers]
    body = yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=110, default_flow_style=False)
    return header + body


def _register_lines(text: str) -> list[int]:
    """The first line (1-based) of every register entry in the rendered text."""
    lines = text.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("registers:"))
    firsts = []
    for i in range(start + 1, len(lines)):
        if lines[i] and not lines[i].startswith((" ", "-")):
            break
        if lines[i].startswith("- name:"):
            firsts.append(i + 1)
    return firsts


def _key_at(text: str, line: int) -> str | None:
    lines = text.splitlines()
    for i in range(min(line, len(lines)) - 1, -1, -1):
        m = re.match(r"^\s*(?:-\s+)?([a-z_]+):", lines[i])
        if m and (len(lines[i]) - len(lines[i].lstrip(" -")) <= 4 or i == line - 1):
            indent = len(lines[i]) - len(lines[i].lstrip(" "))
            if indent <= 4:
                return m.group(1)
    return None


def _exporter_problems(doc: Any, model: Model) -> list[Diagnostic]:
    """The name checks of the outputs ``drivemap build`` writes (generated names, docs anchors: the naming
    policy in :mod:`drivemap.vocab.namecheck`), so that a draft builds as written, not only validates."""
    return [Diagnostic(doc.positions.at(where), message)
            for where, message, _options in (*namecheck.python_problems(model), *namecheck.docs_problems(model))]


def compile_text(text: str, path: str) -> list[Diagnostic]:
    """Every error of the map text, as `drivemap validate` would report it (nothing is written)."""
    try:
        doc = load_text(text, path)
        errors = schema.validate(doc)
        if errors:
            return errors
        problems, statuses = checks.check(doc)
        if problems:
            return problems
        lines = {r["name"]: doc.positions.at(("registers", i)).line for i, r in enumerate(doc.data["registers"])}
        model = build_model(path, doc.data, statuses, lines, doc.positions.at)  # type: ignore[arg-type]
        return _exporter_problems(doc, model)
    except CompileError as exc:
        return list(exc.diagnostics)
    return []


def _fix(draft: Draft, text: str, firsts: list[int], diag: Diagnostic, drop: set[int],
         done: set[tuple[int, str]]) -> bool:
    """Change the draft so that ``diag`` goes away; False when it is not about a register."""
    index = max((i for i, first in enumerate(firsts) if first <= diag.location.line), default=None)
    if index is None:
        return _fix_enum(draft, text, diag)
    reg = draft.registers[index]
    key = _key_at(text, diag.location.line) or ""
    if (index, key) in done and key != "name":
        key = ""
    done.add((index, key))
    if key == "name":
        reg.entry["name"] = f"{str(reg.entry['name'])[:52].rstrip('_')}_reg"
        reg.notes.append(f"renamed: {diag.message}")
    elif key in _DROPPABLE:
        reg.entry.pop(key, None)
        if key == "type":
            reg.entry.pop("word_order", None)
            reg.entry.pop("length", None)
        reg.missing.append(key)
        reg.notes.append(f"{key} left out: the compiler refused it ({diag.message})")
        if key in REVIEWED:  # the schema's default would now stand in for what the document stated
            listed = reg.entry.get("review")
            items = list(listed) if isinstance(listed, list) else []
            reg.entry["review"] = items if key in items else [*items, key]
    elif index not in drop:
        drop.add(index)
        other = _two_meanings(draft, firsts, diag, index)
        if other is not None and other not in drop:
            drop.add(other)
            them = draft.registers[other]
            for one, other_one in ((them, reg), (reg, them)):
                draft.skipped.append(Skipped(one.where, _at(one), f"not drafted: the document gives its address "
                                             f"another meaning at {other_one.where} ({_label(other_one)!r}); which "
                                             "one the device has is for a person to say"))
        else:
            draft.skipped.append(Skipped(reg.where, _label(reg), f"not drafted: {diag.message}"))
    return True


def _label(reg: Drafted) -> str:
    return str(reg.entry.get("label") or reg.entry.get("name"))


def _at(reg: Drafted) -> str:
    address = int(reg.entry["address"])  # type: ignore[call-overload]
    return f"address {address} (0x{address:04X}): {_label(reg)}"


def _two_meanings(draft: Draft, firsts: list[int], diag: Diagnostic, index: int) -> int | None:
    """The register that ``diag`` says the one at ``index`` overlaps, when both are rows of drawn tables
    (PDF, DOCX, spreadsheet) that start at the same address of a table both state and name two things
    (neither label holds the other: "limitation" is "Power limitation" cut short): the document gives one
    address two meanings (one model's register beside another's),
    and neither is drafted as the device's. For spans that overlap in part, for one register printed
    twice, or for lines of a text (where a sentence may be read as a row), the first is kept, as before."""
    if " overlaps " not in diag.message or not diag.related:
        return None
    line = diag.related[0][0].line
    other = max((i for i, first in enumerate(firsts) if first <= line), default=None)
    if other is None or other == index:
        return None
    mine, theirs = draft.registers[index], draft.registers[other]
    if mine.entry.get("address") != theirs.entry.get("address") or mine.entry.get("table") != theirs.entry.get("table"):
        return None  # spans that overlap in part: a length misread as likely as two meanings
    if any("table" in r.missing or "table" not in r.entry for r in (mine, theirs)):
        return None  # the table left open: the two may be registers of two tables
    if not all(re.search(r"\brow \d+$", r.where) for r in (mine, theirs)):
        return None  # a line of text may be a sentence read as a row; a drawn table's row is the table's own
    a, b = (re.sub(r"\W+", "", str(r.entry.get("label") or "")).lower() for r in (mine, theirs))
    if not a or not b or a in b or b in a:
        return None
    return other


def _fix_enum(draft: Draft, text: str, diag: Diagnostic) -> bool:
    lines = text.splitlines()
    for i in range(diag.location.line - 1, -1, -1):
        m = re.match(r"^  ([A-Z][A-Za-z0-9]*):\s*$", lines[i])
        if m:
            name = m.group(1)
            draft.data["enums"].pop(name, None)
            for reg in draft.registers:
                if reg.entry.get("enum") == name:
                    reg.entry.pop("enum")
                    reg.notes.append(f"value list left out: {diag.message}")
            return True
        if re.match(r"^\S", lines[i]):
            break
    return False


def settle(draft: Draft, header: str, path: str) -> tuple[str, list[Diagnostic]]:
    """Render and compile until the text validates; the remaining errors if it never does."""
    errors: list[Diagnostic] = []
    done: set[tuple[int, str]] = set()
    for _ in range(MAX_ROUNDS):
        _sync_notes(draft)
        text = render(draft, header)
        errors = compile_text(text, path)
        if not errors:
            return text, []
        firsts = _register_lines(text)
        drop: set[int] = set()
        fixed = False
        for diag in errors:
            fixed = _fix(draft, text, firsts, diag, drop, done) or fixed
        for index in sorted(drop, reverse=True):
            draft.registers.pop(index)
        if not fixed:
            break
    return render(draft, header), errors


def _sync_notes(draft: Draft) -> None:
    """Each register's notes: what the draft found out, then what the document does not state."""
    for reg in draft.registers:
        parts = list(dict.fromkeys(reg.notes))
        if reg.missing:
            parts.append("left out, to fill from the document: " + ", ".join(dict.fromkeys(reg.missing)))
        if parts:
            reg.entry["notes"] = "; ".join(parts)


def drafted_names(registers: list[Drafted]) -> list[str]:
    return [str(r.entry["name"]) for r in registers]
