"""The register part of the docs pages: one table per group and Modbus table, reserved ranges, addressing.

Each row shows the protocol address (hex and decimal) beside the Modicon number, because an
off-by-one between the two notations is the most common transcription error; types show their
layout on the wire (``AB CD``: most significant byte first), strings their size and encoding,
and not-available values what the client returns for them.
"""

from __future__ import annotations

from typing import Any

from drivemap.backends.views.client import layout
from drivemap.backends.views.format import RESERVED_KIND, bits_anchor, enum_anchor, hex4, num, with_unit
from drivemap.model import modicon
from drivemap.model.nodes import Group, Model, Register, Value

#: How each table is read and written.
TABLE_TITLES = {
    "holding": ("Holding registers", "read 03h, written 06h/10h", "4xxxx"),
    "input": ("Input registers", "read 04h, read-only", "3xxxx"),
    "coil": ("Coils", "read 01h, written 05h/0Fh; one bit each", "0xxxx"),
    "discrete": ("Discrete inputs", "read 02h, read-only; one bit each", "1xxxx"),
}
TYPE_NOTES = {
    "f32": "IEEE-754 binary32",
    "f64": "IEEE-754 binary64",
}



def _range(reg: Register) -> str | None:
    if reg.min is None and reg.max is None:
        return None
    lo = num(reg.min) if reg.min is not None else "?"
    hi = num(reg.max) if reg.max is not None else "?"
    return with_unit(f"{lo} … {hi}", reg.unit)


def shown_value(value: Value) -> str:
    """An engineering value as the docs show it: numbers plainly, text quoted, None as not available."""
    if value is None:
        return "not available (None)"
    if isinstance(value, str):
        return f'"{value}"'
    return num(value) or ""


def _default(reg: Register) -> str | None:
    if all(d is None for d in reg.defaults):
        return None
    shown = [shown_value(d) if d is not None else "?" for d in reg.defaults]
    return with_unit(", ".join(shown), reg.unit if reg.type not in ("string", "bool") else None)


def _scale(reg: Register) -> str:
    text = "1" if reg.scale == 1 else num(reg.scale) or "1"
    if reg.scale_register:
        text += f" × 10^{reg.scale_register}"
    if reg.offset:
        text += f" + {num(reg.offset)}"
    return text


def _type(reg: Register) -> str:
    return f"string[{reg.length}]" if reg.type == "string" else reg.type


def _raw(reg: Register, value: int) -> str:
    return str(value) if value < 0 else f"0x{value:0{4 * min(reg.words, 4)}X}"


def _type_notes(reg: Register) -> list[str]:
    """Layout, text, scale-factor and not-available notes of a row."""
    notes: list[str] = []
    shown = layout(reg)
    if shown is not None and (reg.words > 1 or reg.byte_order == "low_first"):
        what = TYPE_NOTES.get(reg.type, reg.type)
        order = (f"word order {reg.word_order.replace('_', ' ')}" if reg.word_order else
                 "word order open for review (read high word first meanwhile)")
        order += f", byte order {reg.byte_order.replace('_', ' ')}"
        notes.append(f"{what} in {reg.words} registers, {order}: bytes on the wire {shown} (A = most significant)")
    if reg.type == "string":
        notes.append(f"text of {reg.length} registers ({2 * reg.length} bytes, {reg.encoding}"
                     + (", bytes of each word swapped" if reg.byte_order == "low_first" else "")
                     + "); trailing NUL and spaces stripped on read, NUL-padded on write")
    if reg.type == "bool" and not reg.bit_table:
        notes.append("a register read as true/false (0 is false)")
    if reg.scale_register:
        notes.append(f"scaled by 10^{reg.scale_register} (SunSpec scale factor), read in the same request "
                     "where possible, never remembered")
    if reg.not_available:
        raw = ", ".join(_raw(reg, v) for v in reg.not_available)
        notes.append(f"not available: raw {raw} (the client reads None)")
    if reg.min_read:
        notes.append(f"the device only reads the {reg.min_read}-{'bit' if reg.bit_table else 'word'} block from "
                     f"{hex4(reg.address)} whole: every read of it reads the block")
    return notes


def _advice_text(reg: Register) -> str:
    """The manual's advice for writes while running (the device is not known to refuse them)."""
    advice = reg.advice
    assert advice is not None
    instead = f"; write {advice.instead} instead" if advice.instead else ""
    return (f"while the drive runs the manual advises: {advice.advice}{instead} ({advice.source}; advice only: "
            "the client warns with RunningWriteWarning, nothing is refused)")



def _modicon(reg: Register, last: int) -> str:
    first = modicon.number(reg.table, reg.address)
    return first if last == reg.address else f"{first}-{modicon.number(reg.table, last)}"


def _elements(reg: Register) -> str | None:
    """Arrays compactly: ``No.0 0x0308 (03-09), No.1 0x0309 ...`` or the rule for long arrays."""
    if not reg.is_array:
        return None
    if reg.count > 16:
        last = reg.element_address(reg.count - 1)
        fmt = reg.element_param_format
        ids = ""
        if fmt:
            ids = f"; No.i is parameter {fmt.replace('{index}', 'i').replace('{address}', 'n')}"
            ids += ", n = its address in decimal" if "{address}" in fmt else ""
        first = reg.first_index
        at = f"{hex4(reg.address)} + {reg.stride}·i" if not first else f"{hex4(reg.address)} + {reg.stride}·(i - {first})"
        return (f"No.{first}-No.{reg.count - 1 + first}: No.i at {at} "
                f"({hex4(reg.address)} … {hex4(last)}){ids}")
    parts = []
    for i in range(reg.count):
        param = reg.element_param(i)
        parts.append(f"No.{i + reg.first_index} {hex4(reg.element_address(i))}"
                     + (f" ({param})" if param and (reg.element_params or reg.element_param_format) else ""))
    return ", ".join(parts)


def _display_notes(reg: Register) -> list[str]:
    """The value set, the display precision and the manual's numbering of an array."""
    notes = []
    if reg.values:
        notes.append("values: " + ", ".join(v.text() for v in reg.value_set) + " (a write of any other value is refused)")
    if reg.precision is not None:
        notes.append(f"shown with {reg.precision} decimal{'s' if reg.precision != 1 else ''}")
    if reg.first_index:
        notes.append(f"the manual numbers the elements from {reg.first_index}: No.{reg.first_index} is "
                     f"{reg.name}[0] in Python and on the command line")
    return notes


def _param_text(reg: Register) -> str | None:
    """The parameter id; for an array whose ids follow a rule, the first … last id."""
    if reg.is_array and reg.element_param_format:
        return f"{reg.element_param(0)} … {reg.element_param(reg.count - 1)}"
    return reg.param


def _register_row(model: Model, reg: Register) -> dict[str, Any]:
    last = reg.element_address(reg.count - 1) + reg.words - 1
    address = hex4(reg.address) if last == reg.address else f"{hex4(reg.address)}-{hex4(last)}"
    decimal = str(reg.address) if last == reg.address else f"{reg.address}-{last}"
    extras: list[str] = []
    if reg.page is not None:
        sel = model.register(reg.page.selector)
        extras.append(f"page {reg.page.value}: shown when {reg.page.selector} ({hex4(sel.address)}) = {reg.page.value}")
    if reg.command_value is not None:
        extras.append(f"command: writing {reg.command_value} executes it")
    if reg.broadcast:
        extras.append("may be written by broadcast")
    if reg.refuse_while_running:
        extras.append("writes refused while running")
    if reg.running_advice is not None:
        extras.append(_advice_text(reg))
    if reg.word_order and reg.type in ("u32", "s32") and reg.byte_order == "high_first":
        extras.append(f"word order: {reg.word_order.replace('_', ' ')}")
    else:
        extras.extend(_type_notes(reg))
    if reg.modicon_given is not None:
        extras.append(f"the manual gives Modicon {reg.modicon_given}")
    extras.extend(_display_notes(reg))
    storage = reg.storage
    if reg.write_delay_ms is not None:
        storage += f" (write takes {num(reg.write_delay_ms)} ms)"
    return {
        "name": f"{reg.name}[0..{reg.count - 1}]" if reg.is_array else reg.name,
        "register": reg.name,
        "address": address,
        "decimal": decimal,
        "modicon": _modicon(reg, last),
        "param": _param_text(reg),
        "label": reg.label,
        "type": _type(reg),
        "scale": _scale(reg),
        "unit": reg.unit,
        "range": _range(reg),
        "default": _default(reg),
        "access": {"r": "read", "w": "write", "rw": "read/write"}[reg.access],
        "reflect": reg.reflect.replace("_", " "),
        "storage": storage,
        "enum": reg.enum,
        "enum_anchor": enum_anchor(reg.enum) if reg.enum else None,
        "bits_anchor": bits_anchor(reg) if reg.bits else None,
        "elements": _elements(reg),
        "extras": "; ".join(extras) if extras else None,
        "description": reg.description,
        "notes": reg.notes,
        "param_rule": reg.param_rule,
        "source": reg.source,
    }


def groups(model: Model) -> list[dict[str, Any]]:
    out = []
    known = {g.name for g in model.groups}
    listed = list(model.groups)
    for reg in model.registers:  # a register whose group has no title still appears
        if reg.group not in known:
            listed.append(Group(reg.group, reg.group, reg.source, None))
            known.add(reg.group)
    for group in listed:
        regs = sorted(model.group_registers(group.name),
                      key=lambda r: (modicon.TABLES.index(r.table), r.address, r.page.value if r.page else -1))
        if not regs:
            continue
        pages: dict[str, dict[int, list[str]]] = {}
        for reg in regs:
            if reg.page is not None:
                pages.setdefault(reg.page.selector, {}).setdefault(reg.page.value, []).append(reg.name)
        paging = []
        for selector, by_value in pages.items():
            sel = model.register(selector)
            labels = {}
            if sel.enum:
                labels = {v.value: v.label for v in model.enum(sel.enum).members}
            paging.append({
                "selector": selector,
                "address": hex4(sel.address),
                "pages": [
                    {"value": value, "label": labels.get(value), "registers": ", ".join(names)}
                    for value, names in sorted(by_value.items())
                ],
            })
        out.append({
            "name": group.name,
            "title": group.title,
            "source": group.source,
            "notes": group.notes,
            "rows": [_register_row(model, r) for r in regs],
            "tables": [
                {"table": table, "title": TABLE_TITLES[table][0], "how": TABLE_TITLES[table][1],
                 "rows": [_register_row(model, r) for r in regs if r.table == table]}
                for table in modicon.TABLES if any(r.table == table for r in regs)
            ],
            "paging": paging,
        })
    return out


def reserved_rows(model: Model) -> list[dict[str, str | None]]:
    out = []
    for r in model.reserved:
        readable = {True: "yes", False: "no", None: "not stated"}[r.readable]
        out.append({
            "kind": RESERVED_KIND[r.kind],
            "range": hex4(r.start) if r.start == r.end else f"{hex4(r.start)}-{hex4(r.end)}",
            "decimal": str(r.start) if r.start == r.end else f"{r.start}-{r.end}",
            "readable": readable,
            "writable": "yes" if r.writable else "no",
            "page": f"{r.page.selector} = {r.page.value}" if r.page else None,
            "table": TABLE_TITLES[r.table][0],
            "source": r.source,
            "notes": r.notes,
        })
    return out


def addressing(model: Model) -> dict[str, Any]:
    """The tables the map uses, how they are read and written, and the Modicon rule."""
    rows = []
    for table in modicon.TABLES:
        regs = [r for r in model.registers if r.table == table]
        if not regs:
            continue
        title, how, digits = TABLE_TITLES[table]
        first = modicon.number(table, 0)
        rows.append({"title": title, "how": how, "count": str(len(regs)), "cells": str(sum(r.count for r in regs)),
                     "modicon": f"{digits}: {first} = {table} address 0x0000"})
    return {"rows": rows, "max_gap": model.protocol.max_gap}
