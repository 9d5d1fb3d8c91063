"""View of ``generated/<model>/client.py`` and ``generated/<model>/__init__.py``: the typed client.

Everything the templates need is computed here: class names (checked against keywords, each
other and the fixed names of the package), the Python value type of every register, the runtime
codec and accessor class for it, docstrings and the exact imports (so generated code stays
ruff-clean).
"""

from __future__ import annotations

import keyword
from dataclasses import dataclass
from typing import Any

from drivemap.backends.common import Options
from drivemap.backends.python.names import FIXED_NAMES, exception_classes
from drivemap.backends.python.names import bit_attribute as _attr
from drivemap.backends.views.common import header, provenance
from drivemap.model.nodes import Bit, Model, Register, camel
from drivemap.runtime.client.api.declare import REG_CLASSES, broadcast_kind_of, kind_of


def _num(value: float | None) -> str:
    if value is None:
        return "—"
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _value(value: float | str | None) -> str:
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, bool):
        return str(value)
    return _num(value)


def bits_kind(reg: Register) -> str | None:
    """``flags`` (IntFlag: single bits only), ``fields`` (frozen dataclass) or None."""
    if not reg.bits:
        return None
    if reg.multibit or any(b.enum for b in reg.bits):
        return "fields"
    return "flags"


def base_type(reg: Register) -> str:
    """The Python type of the register's value, not-available aside."""
    if reg.enum:
        return reg.enum
    if reg.bits:
        return reg.bits_class or camel(reg.name)
    if reg.type == "bool":
        return "bool"
    if reg.type == "string":
        return "str"
    return "int" if reg.is_integer else "float"


def value_type(reg: Register) -> str:
    """The accessor's type: :func:`base_type`, Optional only where the map lists not_available values."""
    return f"{base_type(reg)} | None" if reg.optional else base_type(reg)


def layout(reg: Register) -> str | None:
    """The byte layout of a multi-byte value on the wire: ``ABCD`` is the most significant byte first."""
    if reg.type in ("string", "bool") or reg.bit_table:
        return None
    letters = "ABCDEFGH"[: 2 * reg.words]
    words = [letters[i:i + 2] for i in range(0, len(letters), 2)]
    if reg.word_order == "low_first":
        words.reverse()
    if reg.byte_order == "low_first":
        words = [w[::-1] for w in words]
    return " ".join(words)


def _field_type(bit: Bit) -> str:
    if bit.enum:
        return bit.enum
    return "bool" if bit.width == 1 else "int"


@dataclass(frozen=True)
class AccessorView:
    name: str
    type: str
    base: str
    reg_class: str
    broadcast_class: str
    doc: list[str]
    broadcast: bool
    readable: bool
    is_array: bool


def _type_text(reg: Register) -> str:
    if reg.type == "string":
        return f"string of {reg.length} registers ({2 * reg.length} bytes, {reg.encoding})"
    shown = layout(reg)
    if shown and reg.words > 1 or (shown and reg.byte_order == "low_first"):
        return f"{reg.type} (bytes on the wire: {shown})"
    return reg.type


def _where(reg: Register) -> str:
    table = {"holding": "Address", "input": "Input register", "coil": "Coil", "discrete": "Discrete input"}[reg.table]
    where = f"{table} 0x{reg.address:04X} (Modicon {reg.modicon})"
    if reg.is_array:
        where += f", {reg.count} elements, stride {reg.stride}"
    if reg.param:
        where += f"; parameter {reg.param}"
    if reg.element_params and reg.is_array:
        where += f" ({', '.join(reg.element_params)})"
    elif reg.element_param_format and reg.is_array:
        where += f" (element i: {reg.element_param(0)} … {reg.element_param(reg.count - 1)})"
    return where + f"; {_type_text(reg)}, access {reg.access}."


def _units(reg: Register) -> str | None:
    """Engineering unit, scaling and range: only the parts the map states."""
    unit = f" {reg.unit}" if reg.unit else ""
    parts = [f"Unit:{unit}"] if unit else []
    if reg.scale != 1 or reg.offset or reg.scale_register:
        scale = f"scale {_num(reg.scale)}" if reg.scale != 1 or not reg.scale_register else "scale"
        if reg.scale_register:
            scale += f" x 10^{reg.scale_register} (read with it)"
        parts.append(scale + (f", offset {_num(reg.offset)}" if reg.offset else ""))
    if reg.min is not None or reg.max is not None:
        parts.append(f"range {_num(reg.min)} .. {_num(reg.max)}{unit}")
    text = "; ".join(parts)
    return text[:1].upper() + text[1:] + "." if text else None


def _state(reg: Register) -> str | None:
    """Default, reflect and storage: what the map states; when a write takes effect and whether it
    persists are said of writable registers even when unknown (never guessed)."""
    parts = []
    if any(d is not None for d in reg.defaults):
        parts.append("default: " + ", ".join(_value(d) for d in reg.defaults))
    if reg.reflect != "unknown" or reg.writable:
        parts.append(f"reflect: {reg.reflect}")
    if reg.storage != "unknown" or reg.writable:
        parts.append(f"storage: {reg.storage}")
    text = "; ".join(parts) + (f" (write delay {_num(reg.write_delay_ms)} ms)" if reg.write_delay_ms else "")
    return text[:1].upper() + text[1:] + "." if text else None


def _doc(model: Model, reg: Register) -> list[str]:
    """The register's docstring: what it is, where, unit and range, state, source (only lines that apply)."""
    lines = [reg.label or reg.description or reg.name]
    if reg.label and reg.description:
        lines.append(reg.description)
    lines.append(_where(reg))
    lines += [line for line in (_units(reg), _state(reg)) if line]
    if reg.values:
        lines.append("Allowed values: " + ", ".join(v.text() for v in reg.value_set)
                     + " (a write of any other raises NotAllowedValue before anything is sent).")
    if reg.not_available:
        shown = ", ".join(f"0x{v:X}" if v >= 0 else str(v) for v in reg.not_available)
        lines.append(f"Not available: raw {shown} reads as None.")
    if reg.page:
        lines.append(f"Page: valid while {reg.page.selector} = {reg.page.value}.")
    if reg.command_value is not None:
        lines.append(f"Command: writing {reg.command_value} executes it.")
    if reg.broadcast:
        lines.append("May be written by broadcast.")
    if reg.running_advice is not None:
        lines.append(f"While the drive runs the manual advises: {reg.running_advice}; "
                     "writing it then gives a RunningWriteWarning.")
    lines.append(f"Manual: {reg.source}.")
    return lines


def _check_names(model: Model, names: list[tuple[str, str]]) -> None:
    seen: dict[str, str] = {}
    for name, what in names:
        if name in FIXED_NAMES:
            raise ValueError(f"{model.path}: {what} {name!r} clashes with a name of the generated package")
        if keyword.iskeyword(name) or not name.isidentifier():
            raise ValueError(f"{model.path}: {what} {name!r} is not a usable class name")
        if name in seen and seen[name] != what:
            raise ValueError(f"{model.path}: {what} {name!r} clashes with {seen[name]} {name!r}")
        seen[name] = what


def _isort_key(name: str) -> tuple[int, str]:
    """ruff/isort order inside ``from x import (...)``: CONSTANTS, Classes, functions."""
    return (0 if name.isupper() else 1 if name[:1].isupper() else 2, name)


def _bit_classes(model: Model) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(IntFlag classes, dataclass records) of the map's bit fields."""
    flags: list[dict[str, Any]] = []
    records: list[dict[str, Any]] = []
    seen_bits: set[str] = set()
    for reg in model.registers:
        kind = bits_kind(reg)
        cls = base_type(reg)
        if kind is None or reg.enum or cls in seen_bits:
            continue
        seen_bits.add(cls)
        doc = f"Bits of {reg.name} (0x{reg.address:04X}, {reg.source})."
        if kind == "flags":
            flags.append({"name": cls, "doc": doc,
                          "members": [{"name": b.name, "value": f"0x{b.mask:04X}", "doc": b.label} for b in reg.bits]})
        else:
            records.append({"name": cls, "doc": doc, "fields": [
                {"name": _attr(b.name), "type": _field_type(b),
                 "doc": f"{b.label} (bit{'s' if b.width > 1 else ''} {b.offset}"
                        + (f"..{b.offset + b.width - 1}" if b.width > 1 else "") + ")"}
                for b in reg.bits]})
    for rec in records:
        names = [f["name"] for f in rec["fields"]]
        if len(set(names)) != len(names):
            raise ValueError(f"{model.path}: bit names of {rec['name']} collide once lower-cased")
    return flags, records


def _exceptions(model: Model) -> list[dict[str, str]]:
    exceptions = []
    classes = exception_classes([(ex.name, ex.code) for ex in model.protocol.exceptions])
    for ex, cls in zip(model.protocol.exceptions, classes, strict=True):
        exceptions.append({"name": cls, "code": f"0x{ex.code:02X}", "code_name": ex.name, "meaning": ex.meaning,
                           "source": ex.source})
    return exceptions


def _accessors(model: Model) -> list[AccessorView]:
    accessors: list[AccessorView] = []
    for reg in model.registers:
        accessors.append(AccessorView(
            name=reg.name, type=value_type(reg), base=base_type(reg),
            reg_class=REG_CLASSES[kind_of(reg)].__name__,
            broadcast_class={"w": "BroadcastReg", "cmd": "BroadcastCommandReg",
                             "w[]": "BroadcastArrayReg"}[broadcast_kind_of(reg)],
            doc=_doc(model, reg), broadcast=reg.broadcast and reg.writable, readable=reg.readable,
            is_array=reg.is_array,
        ))
    return accessors


#: Names every generated package exports besides its own classes.
PACKAGE_NAMES = frozenset({
    "SPEC", "Bus", "AsyncBus", "DriveError", "DeviceException", "DriveTimeout", "ValueOutOfRange",
    "ReadOnlyRegister", "WriteOnlyRegister", "WrongPage", "NotBroadcastable", "BroadcastRead",
    "InvalidValue", "UnknownRegister", "UnsupportedFunction", "TransportError", "PartialWrite",
    "ScaleUnavailable", "IndexOutOfRange", "InvalidArgument",
})


def context(model: Model, options: Options) -> dict[str, Any]:
    enums = [
        {"name": e.name, "doc": f"{e.name} ({e.source}).", "notes": e.notes,
         "values": [{"name": v.name, "value": v.value, "doc": v.label} for v in e.members]}
        for e in model.enums
    ]
    flags, records = _bit_classes(model)
    exceptions = _exceptions(model)
    _check_names(model, [(e["name"], "enum") for e in enums] + [(f["name"], "bit-field class") for f in flags]
                 + [(r["name"], "bit-field class") for r in records] + [(e["name"], "exception class") for e in exceptions])
    accessors = _accessors(model)

    # a broadcast client only where some register may be written by broadcast; else the runtime's
    # ClientBase.broadcast refuses with the map's reason (broadcast_refusal)
    has_broadcast = model.protocol.broadcast_address is not None and any(a.broadcast for a in accessors)
    broadcast = [a for a in accessors if a.broadcast] if has_broadcast else []
    declare_names = {a.reg_class for a in accessors} | {a.broadcast_class for a in broadcast} | {"codecs_for"}

    snapshot_fields = [
        {"name": a.name, "type": f"tuple[{a.base} | None, ...] | None" if a.is_array else f"{a.base} | None"}
        for a in accessors if a.readable
    ]
    all_names = (["AsyncBroadcastClient", "BroadcastClient"] if has_broadcast else []) + [
        "AsyncClient", "Client", "CODECS", "EXCEPTIONS", "Snapshot",
    ] + [e["name"] for e in enums] + [f["name"] for f in flags] + [r["name"] for r in records] + [
        e["name"] for e in exceptions]
    return {
        "header": header(model, options),
        "provenance": provenance(model),
        "package": options.package,
        "model": model,
        "title": model.device.title,
        "enums": enums,
        "flags": flags,
        "records": records,
        "exceptions": exceptions,
        "accessors": accessors,
        "value_classes": [e["name"] for e in enums] + [f["name"] for f in flags] + [r["name"] for r in records],
        "declare_imports": sorted(declare_names, key=_isort_key),
        "need_drive_enum": bool(enums),
        "need_enum": bool(flags),
        "has_broadcast": has_broadcast,
        "broadcast_address": model.protocol.broadcast_address,
        "broadcast": broadcast,
        "snapshot_fields": snapshot_fields,
        "client_all": sorted(all_names, key=lambda n: (n.lower(), n)),
        "package_all": sorted(set(all_names) | PACKAGE_NAMES, key=lambda n: (n.lower(), n)),
        "client_exports": sorted(all_names, key=_isort_key),
        "loopback": model.protocol.function(0x08) is not None,
    }
