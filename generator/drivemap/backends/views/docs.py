"""View of ``generated/docs/<model>.md`` and ``generated/docs/index.md``: the reference pages.

Everything a page shows is computed here: register rows, bit diagrams, the byte-by-byte annotation
of every printed example frame, the usage snippet. Values that come from a map stay plain text; the
templates pass each of them through the ``md`` filter, so no map text can break a table or inject
HTML. Identifiers (register, enum, bit and example names) are validated by the schema and may
appear in code blocks as they are.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drivemap.backends.common import Options
from drivemap.backends.views.annotate import FrameView, annotate, describe_value, exception_short
from drivemap.backends.views.common import header, provenance, review_text
from drivemap.backends.views.format import enum_anchor, example_anchor, hex2, hex4, num, with_unit
from drivemap.backends.views.registers import addressing, groups, reserved_rows, shown_value
from drivemap.backends.views.usage import SNIPPET_HOST, SNIPPET_PORT, usage
from drivemap.frontend.formats import CURRENT
from drivemap.model.nodes import Example, FunctionCode, Model, Register, Value
from drivemap.vocab.escape import slug

MODE_NAMES = {"rtu": "Modbus RTU", "ascii": "Modbus ASCII", "tcp": "Modbus TCP"}
OPERATIONS = {
    "read": "read",
    "write": "write one register",
    "write_multiple": "write several registers",
    "loopback": "loopback test",
}

__all__ = ["FrameView", "SNIPPET_HOST", "SNIPPET_PORT", "annotate", "bit_diagram", "context", "describe_value",
           "index_context", "num", "slug", "usage"]

# ---------------------------------------------------------------- device, connection, protocol


def _manual_rows(model: Model) -> list[tuple[str, str | None]]:
    man = model.device.manual
    rows: list[tuple[str, str | None]] = [
        ("Document", man.document),
        ("Revision", man.revision),
        ("Date", man.date),
        ("Source file", man.file),
        ("Language", man.language),
    ]
    if man.cross_check:
        rows.append(("Cross-checked against", ", ".join(man.cross_check)))
    rows.append(("Vendor", model.device.vendor))
    rows.append(("Cited as", model.device.source))
    return rows


def _port(model: Model, index: int) -> dict[str, Any]:
    port = model.protocol.ports[index]

    def listing(values: tuple[Any, ...], default: Any) -> str:
        shown = [f"{v} (default)" if default is not None and v == default else str(v) for v in values]
        return ", ".join(shown) if shown else "not stated"

    rows: list[tuple[str, str | None]] = [
        ("Modes", listing(tuple(MODE_NAMES.get(m, m) for m in port.modes),
                          MODE_NAMES.get(port.default_mode, port.default_mode) if port.default_mode else None)),
        ("Baud rates (bit/s)", listing(port.baudrates, port.default_baudrate)),
        ("Parity", listing(port.parity, port.default_parity)),
        ("Data bits", listing(port.data_bits, None)),
        ("Stop bits", listing(port.stop_bits, port.default_stop_bits)),
        ("Unit id", f"fixed at {port.fixed_unit}" if port.fixed_unit is not None else "settable"),
        ("Set by", port.set_by.replace("_", " ")),
        ("Source", port.source),
    ]
    return {
        "name": port.name,
        "rows": rows,
        "settings": [
            {"what": s.what, "how": s.how, "when": (s.when or "not stated").replace("_", " "),
             "source": s.source, "notes": s.notes}
            for s in port.settings
        ],
        "notes": port.notes,
    }


def _function_codes(model: Model) -> list[dict[str, str | None]]:
    out = []
    for fc in model.protocol.function_codes:
        out.append({
            "code": hex2(fc.code),
            "name": fc.name,
            "max_quantity": num(fc.max_quantity) if fc.max_quantity is not None else "not stated",
            "broadcast": _broadcast_text(fc),
            "request_bytes": f"{fc.request_bytes.min}-{fc.request_bytes.max}" if fc.request_bytes else "not stated",
            "response_bytes": f"{fc.response_bytes.min}-{fc.response_bytes.max}" if fc.response_bytes else "not stated",
            "source": fc.source,
            "notes": fc.notes,
        })
    return out


def _broadcast_text(fc: FunctionCode) -> str:
    """yes / no / not stated, with the map's reason where broadcast is null or a map choice."""
    text = {True: "yes", False: "no", None: "not stated"}[fc.broadcast]
    return f"{text} — {fc.broadcast_reason}" if fc.broadcast_reason else text


def _policies(model: Model) -> list[dict[str, str | None]]:
    p = model.protocol
    names = {e.code: e.name for e in p.exceptions}
    comm = {e.code: e.name for e in p.comm_errors}
    out = []
    for kind, items, table in (("exception", p.exception_policy, names), ("communication error", p.comm_error_policy, comm)):
        for item in items:
            if item.code is None:
                answer = "no code" if kind == "communication error" else "no reply"
            else:
                answer = f"{hex2(item.code)} {table.get(item.code, '')}".strip()
            out.append({"kind": kind, "case": item.case.replace("_", " "), "answer": answer,
                        "source": item.source, "reason": item.reason})
    return out


def _timing(model: Model) -> list[tuple[str, str]]:
    t = model.protocol.timing
    rows: list[tuple[str, str]] = []

    def add(label: str, value: str | None) -> None:
        rows.append((label, value if value is not None else "not stated"))

    silent = None
    if t.silent_interval_chars is not None:
        silent = f"{num(t.silent_interval_chars)} characters"
        if t.silent_interval_floor_ms is not None:
            above = f" above {t.silent_interval_floor_above_bps} bit/s" if t.silent_interval_floor_above_bps else ""
            silent += f", at least {num(t.silent_interval_floor_ms)} ms{above}"
    add("Silent interval (frame end)", silent)
    add("Device processing (turnaround)",
        f"{num(t.processing_ms[0])}-{num(t.processing_ms[1])} ms" if t.processing_ms else None)
    add("Gap between frames", with_unit(num(t.inter_frame_gap_ms), "ms"))
    add("Gap after a broadcast", with_unit(num(t.broadcast_gap_ms), "ms"))
    add("Response timeout", with_unit(num(t.response_timeout_ms), "ms"))
    add("Retries", num(t.retries))
    add("Longest frame", with_unit(num(model.protocol.max_frame_bytes), "bytes"))
    return rows


_QUIRK_TEXT = {
    "two_byte_byte_count": "03h/04h replies may carry a two-byte (high, low) byte count instead of one byte",
}



def _running_state(model: Model) -> dict[str, str] | None:
    state = model.protocol.running_state
    if state is None:
        return None
    return {"register": state.register, "address": hex4(model.register(state.register).address),
            "shows": ", ".join(str(v) for v in state.values), "source": state.source, "notes": state.notes or ""}



# ---------------------------------------------------------------- enums and bit fields


def _enums(model: Model) -> list[dict[str, Any]]:
    out = []
    for enum in model.enums:
        used = [r.name for r in model.registers if r.enum == enum.name]
        used += [f"{r.name}.{b.name}" for r in model.registers for b in r.bits if b.enum == enum.name]
        out.append({
            "heading": f"Enum {enum.name}",
            "name": enum.name,
            "members": [
                {"value": num(v.value), "hex": hex2(v.value) if v.value >= 0 else None, "name": v.name,
                 "label": v.label, "notes": v.notes}
                for v in enum.members
            ],
            "used_by": ", ".join(used) if used else None,
            "source": enum.source,
            "notes": enum.notes,
        })
    return out


def bit_diagram(reg: Register) -> str:
    """A text diagram of a bit field: bit positions, the bits in use, a ladder to each field's name."""
    width = 16 * reg.words
    col = {b: 4 * (width - 1 - b) + 3 for b in range(width)}  # character column of bit b's marker
    total = col[0] + 1
    numbers = "".join(f"{b:>4}" for b in range(width - 1, -1, -1))
    marks = [" "] * total
    for b in range(width):
        marks[col[b]] = "."
    fields = sorted(reg.bits, key=lambda b: b.offset)
    for f in fields:
        hi, lo = f.offset + f.width - 1, f.offset
        if f.width == 1:
            marks[col[lo]] = "x"
        else:
            for c in range(col[hi], col[lo] + 1):
                marks[c] = "="
            marks[col[hi]] = "["
            marks[col[lo]] = "]"
    lines = [numbers, "".join(marks).rstrip()]
    for i, f in enumerate(fields):
        row = [" "] * total
        for later in fields[i + 1:]:
            row[col[later.offset]] = "|"
        anchor = col[f.offset]
        row[anchor] = "+"
        for c in range(anchor + 1, total):
            row[c] = "-"
        bits = str(f.offset) if f.width == 1 else f"{f.offset + f.width - 1}-{f.offset}"
        lines.append("".join(row) + f"-- {bits:<5} {f.name}")
    unused = [b for b in range(width) if not any(f.offset <= b < f.offset + f.width for f in fields)]
    lines.append("")
    lines.append("x = bit in use, [==] = multi-bit field, . = unused")
    if unused:
        lines[-1] += f" ({_ranges(unused)})"
    return "\n".join(lines)


def _ranges(bits: list[int]) -> str:
    runs: list[list[int]] = []
    for b in bits:
        if runs and b == runs[-1][-1] + 1:
            runs[-1].append(b)
        else:
            runs.append([b])
    return "bits " + ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


def _bitfields(model: Model) -> list[dict[str, Any]]:
    out = []
    for reg in model.registers:
        if not reg.bits:
            continue
        out.append({
            "heading": f"Bits of {reg.name}",
            "register": reg.name,
            "address": hex4(reg.address) if not reg.is_array else f"{hex4(reg.address)} (each of No.0-No.{reg.count - 1})",
            "class_name": reg.bits_class,
            "diagram": bit_diagram(reg),
            "bits": [
                {"bits": str(b.offset) if b.width == 1 else f"{b.offset + b.width - 1}-{b.offset}",
                 "mask": f"0x{b.mask:0{4 * reg.words}X}", "name": b.name, "label": b.label,
                 "enum": b.enum, "enum_anchor": enum_anchor(b.enum) if b.enum else None, "notes": b.notes}
                for b in sorted(reg.bits, key=lambda b: b.offset)
            ],
        })
    return out


def _meaning_summary(model: Model, ex: Example) -> str:
    m = ex.meaning
    who = f"unit {m.unit}" + (" (broadcast)" if m.broadcast else "")
    parts = [f"{who}: {OPERATIONS.get(m.operation, m.operation)}"]
    if m.address is not None:
        if m.quantity is not None and m.quantity != 1:
            parts.append(f"{m.quantity} registers from {hex4(m.address)}")
        else:
            parts.append(f"register {hex4(m.address)}" + (f" ({m.quantity} register)" if m.quantity else ""))
    elif m.quantity is not None:
        parts.append(f"{m.quantity} register(s)")
    if m.raw:
        parts.append("raw data " + ", ".join(hex4(v) for v in m.raw))
    if m.loopback:
        parts.append("sub-function " + hex4(m.loopback[0]) + (
            ", data " + ", ".join(hex4(v) for v in m.loopback[1:]) if len(m.loopback) > 1 else ""))
    text = ", ".join(parts)
    if m.exception is not None:
        text += f"; the reply is exception {exception_short(model, m.exception)}"
    elif m.broadcast or ex.response is None:
        text += "; no reply"
    else:
        text += "; normal reply"
    return text


def _value_rows(model: Model, pairs: tuple[tuple[str, Value], ...]) -> list[dict[str, str | None]]:
    rows = []
    for ref, value in pairs:
        try:
            cell = model.cell(ref)
        except KeyError:
            rows.append({"register": ref, "address": None, "value": shown_value(value)})
            continue
        reg = cell.register
        where = hex4(cell.address) if reg.table == "holding" else f"{reg.table} {hex4(cell.address)}"
        if value is None or isinstance(value, (str, bool)) or reg.type == "bool":
            rows.append({"register": ref, "address": where, "value": shown_value(value)})
            continue
        shown = with_unit(num(value), reg.unit)
        if reg.enum and float(value).is_integer():
            names = {v.value: v.name for v in model.enum(reg.enum).members}
            if int(value) in names:
                shown = f"{num(value)} ({names[int(value)]})"
        elif reg.bits and float(value).is_integer():
            shown = f"{num(value)} ({describe_value(model, reg, int(value))})"
        rows.append({"register": ref, "address": where, "value": shown})
    return rows


def _examples(model: Model) -> list[dict[str, Any]]:
    out = []
    for ex in model.examples:
        frames_: list[FrameView] = []
        for part in ("request", "response"):
            printed = getattr(ex, part)
            corrected = getattr(ex, f"corrected_{part}")
            if printed is None:
                continue
            label = "as printed" if corrected is None else "as printed (wrong, see erratum)"
            frames_.append(annotate(model, ex, printed, part, f"{part.capitalize()}, {label}"))
            if corrected is not None:
                frames_.append(annotate(model, ex, corrected, part, f"{part.capitalize()}, corrected"))
        if ex.response is None:
            no_reply = "No reply is printed" + (" (broadcast: the devices do not answer)." if ex.meaning.broadcast else ".")
        else:
            no_reply = None
        if ex.request is None:
            no_request = "No request is printed; only the reply."
        else:
            no_request = None
        status_text = {
            "verified": "every printed frame checks",
            "erratum": "a printed frame is wrong; the corrected frame is shown and verified",
            "illegible": "bytes were lost in the manual's text; checksums cannot be checked",
        }[ex.status]
        out.append({
            "heading": f"Example {ex.name}",
            "anchor": example_anchor(ex.name),
            "name": ex.name,
            "title": ex.title,
            "status": ex.status,
            "status_text": status_text,
            "source": ex.source,
            "mode": MODE_NAMES[ex.mode],
            "summary": _meaning_summary(model, ex),
            "decoded": _value_rows(model, ex.meaning.values),
            "preset": _value_rows(model, ex.preset),
            "inject": exception_short(model, ex.inject_exception) if ex.inject_exception is not None else None,
            "frames": frames_,
            "no_reply": no_reply,
            "no_request": no_request,
            "erratum": ex.erratum,
            "illegible": ex.illegible,
            "notes": ex.notes,
        })
    return out


def _known_issues(model: Model) -> list[dict[str, Any]]:
    examples = {ex.name for ex in model.examples}
    out = []
    for issue in model.known_issues:
        affects = []
        for name in issue.affects:
            affects.append({"name": name, "anchor": example_anchor(name) if name in examples else None})
        out.append({
            "title": issue.title,
            "source": issue.source,
            "printed": issue.printed,
            "corrected": issue.corrected,
            "chosen": issue.chosen,
            "reason": issue.reason,
            "affects": affects,
        })
    return out


# ---------------------------------------------------------------- page contexts


def _relative_link(target: Path, docs: Path) -> str | None:
    try:
        return Path(os.path.relpath(target, docs)).as_posix()
    except ValueError:
        return None


def _links(model: Model, options: Options) -> list[tuple[str, str]]:
    """Links from the docs page to the map and the generated modules (when they are in the project)."""
    links = [("All models", "index.md")]
    root = options.root.resolve()
    docs = options.docs.resolve()
    source = Path(model.path).resolve()
    if source.is_relative_to(root) and (rel := _relative_link(source, docs)):
        links.append(("Map source", rel))
    out = options.out.resolve()
    if out.is_relative_to(root):
        for module, label in (("spec", "Generated spec"), ("client", "Generated client"), ("simulator", "Generated simulator")):
            if rel := _relative_link(out / model.name / f"{module}.py", docs):
                links.append((label, rel))
    return links


def context(model: Model, options: Options) -> dict[str, Any]:
    p = model.protocol
    counts = model.status_counts()
    return {
        "header": header(model, options),
        "model": model,
        "title": model.device.title,
        "links": _links(model, options),
        "manual_rows": _manual_rows(model),
        "coverage": model.device.coverage,
        "device_notes": model.device.notes,
        "modes": ", ".join(MODE_NAMES.get(m, m) for m in p.modes),
        "unit_range": f"{p.unit_min}-{p.unit_max}",
        "unit_source": p.unit_source,
        "broadcast": str(p.broadcast_address) if p.broadcast_address is not None else "none",
        "ports": [_port(model, i) for i in range(len(p.ports))],
        "function_codes": _function_codes(model),
        "exceptions": [
            {"code": hex2(e.code), "name": e.name, "meaning": e.meaning,
             "comm_errors": ", ".join(hex2(c) for c in e.comm_errors) or None, "source": e.source, "notes": e.notes,
             "documented": "yes" if e.documented else "no: assumed by the map"}
            for e in p.exceptions
        ],
        "comm_errors": [
            {"code": hex2(e.code), "decimal": str(e.code), "name": e.name, "meaning": e.meaning, "source": e.source}
            for e in p.comm_errors
        ],
        "comm_error_history": p.comm_error_history,
        "policies": _policies(model),
        "alignment": p.alignment,
        "timing": _timing(model),
        "timing_source": p.timing.source,
        "timing_notes": p.timing.notes,
        "checksum": p.checksum,
        "configuration": (
            {"register": p.configuration.register, "value": p.configuration.value,
             "address": hex4(model.register(p.configuration.register).address)}
            if p.configuration else None
        ),
        "running_state": _running_state(model),
        "reply_quirks": [{"quirk": q.quirk, "text": _QUIRK_TEXT.get(q.quirk, q.quirk), "source": q.source,
                          "reason": q.reason} for q in p.reply_quirks],
        "protocol_source": p.source,
        "protocol_notes": p.notes,
        "register_count": len(model.registers),
        "cell_count": sum(r.count for r in model.registers),
        "groups": groups(model),
        "addressing": addressing(model),
        "reserved": reserved_rows(model),
        "enums": _enums(model),
        "bitfields": _bitfields(model),
        "examples": _examples(model),
        "counts": counts,
        "known_issues": _known_issues(model),
        "provenance": provenance(model),
        "review": [review_text(r) for r in model.registers if r.review],
        "usage": usage(model, options.package),
        **_family(model),
    }


def _family(model: Model) -> dict[str, Any]:
    """The identity table, what a variant changes, and the map's format (docs)."""
    variant = model.variant
    return {
        "identity": [{"register": c.register, "address": f"{model.register(c.register).table} "
                      f"{hex4(model.register(c.register).address)}", "expected": c.expected(), "source": c.source}
                     for c in model.identity],
        "variant": ({"base": Path(variant.extends[0]).name, "chain": [Path(p).name for p in variant.extends],
                     "changes": variant.changes}
                    if variant else None),
        "format_version": model.format_version,
        "current_format": CURRENT,
    }


def index_context(models: Sequence[Model], options: Options) -> dict[str, Any]:
    rows = []
    for m in sorted(models, key=lambda m: m.name):
        man = m.device.manual
        manual = ", ".join(x for x in (man.document, man.revision, man.date) if x) or "not stated"
        counts = m.status_counts()
        rows.append({
            "name": m.name,
            "page": f"{m.name}.md",
            "title": m.device.title,
            "manual": manual,
            "file": man.file,
            "modes": ", ".join(MODE_NAMES.get(x, x) for x in m.protocol.modes),
            "registers": len(m.registers),
            "cells": sum(r.count for r in m.registers),
            "examples": len(m.examples),
            "verified": counts["verified"],
            "erratum": counts["erratum"],
            "illegible": counts["illegible"],
            "evidence": m.device.evidence or "not stated",
            "origin": (f"{m.device.origin.project} ({m.device.origin.licence})" if m.device.origin else "the map's manual"),
            "review": sum(len(r.review) for r in m.registers),
            "links": [(label, href) for label, href in _links(m, options) if href != "index.md"],
        })
    return {"rows": rows}
