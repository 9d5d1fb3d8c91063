"""The "How to use it" snippet of a docs page: a simulator command and a few lines of client code.

The snippet reads a plain register and writes a valid value, preferring the manual's own examples;
tests run it against the model's simulator over TCP.
"""

from __future__ import annotations

from typing import Any

from drivemap.backends.views.format import hex4, num, with_unit
from drivemap.model.nodes import Model, Register, Value

#: The TCP port the page's snippet uses (tests substitute a free one).
SNIPPET_PORT = 5020
SNIPPET_HOST = "127.0.0.1"

__all__ = ["SNIPPET_HOST", "SNIPPET_PORT", "usage"]


def _plain(reg: Register) -> bool:
    """A register a short snippet can use without explaining pages, commands, bit objects, text,
    scale factors or not-available values: a plain 16-bit number."""
    return (reg.page is None and reg.command_value is None and not reg.bits and reg.enum is None
            and reg.type in ("u16", "s16") and reg.byte_order == "high_first" and not reg.optional
            and reg.scale_register is None)


def _valid_value(reg: Register, value: Value) -> float | None:
    if value is None or isinstance(value, (str, bool)):
        return None
    if reg.min is not None and value < reg.min or reg.max is not None and value > reg.max:
        return None
    raw = (value - reg.offset) / reg.scale
    if abs(raw - round(raw)) > 1e-6:
        return None
    lo, hi = reg.raw_bounds()
    return value if lo <= round(raw) <= hi else None


def _example_values(model: Model, operations: tuple[str, ...]) -> list[tuple[str, Value]]:
    found: list[tuple[str, Value]] = []
    for ex in model.examples:
        if ex.meaning.operation in operations and not ex.meaning.broadcast:
            found.extend(ex.meaning.values)
    return found


def _pick_cells(model: Model) -> tuple[str | None, tuple[str, float] | None]:
    """A readable register to read and a (register, value) to write, preferring the manual's examples."""
    readable: str | None = None
    for ref, _ in _example_values(model, ("read",)):
        cell = model.cell(ref)
        if cell.register.readable and _plain(cell.register):
            readable = ref
            break
    if readable is None:
        for reg in model.registers:
            if reg.readable and _plain(reg):
                readable = reg.element_name(0)
                break
    writable: tuple[str, float] | None = None
    for ref, value in _example_values(model, ("write", "write_multiple")):
        reg = model.cell(ref).register
        chosen = _valid_value(reg, value)
        if reg.writable and _plain(reg) and not reg.refuse_while_running and chosen is not None:
            writable = (ref, chosen)
            break
    if writable is None:
        for reg in model.registers:
            if not (reg.writable and _plain(reg) and not reg.refuse_while_running):
                continue
            for candidate in (reg.default_at(0), reg.min, 0.0):
                chosen = _valid_value(reg, candidate)
                if chosen is not None:
                    writable = (reg.element_name(0), chosen)
                    break
            if writable:
                break
    return readable, writable


def _accessor(ref: str, owner: str = "drive") -> str:
    base, _, rest = ref.partition("[")
    return f"{owner}.{base}[{rest}" if rest else f"{owner}.{base}"


def _literal(reg: Register, value: float) -> str:
    if reg.is_integer and float(value).is_integer():
        return str(int(value))
    return repr(float(value))


def usage(model: Model, package: str, port: int = SNIPPET_PORT) -> dict[str, Any]:
    """The snippet of "How to use it": shell command for the simulator and Python for the client."""
    unit = 1 if model.protocol.unit_min <= 1 <= model.protocol.unit_max else model.protocol.unit_min
    readable, writable = _pick_cells(model)
    lines = [
        f"from {package}.{model.name} import Client",
        "",
        f"with Client.tcp({SNIPPET_HOST!r}, port={port}, unit={unit}) as drive:",
    ]
    notes: list[str] = []
    if readable is not None:
        reg = model.cell(readable).register
        lines.append(f"    print({_accessor(readable)}.read())")
        notes.append(f"reads {readable} ({hex4(model.cell(readable).address)}"
                     + (f", {reg.unit}" if reg.unit else "") + ")")
    if writable is not None:
        ref, value = writable
        reg = model.cell(ref).register
        lines.append(f"    {_accessor(ref)}.write({_literal(reg, value)})")
        notes.append(f"writes {with_unit(num(value), reg.unit)} to {ref} ({hex4(model.cell(ref).address)})")
        if readable is not None and reg.readable and ref != readable:
            lines.append(f"    snapshot = drive.read({_accessor(readable)}, {_accessor(ref)})")
            lines.append(f"    print({_accessor(readable, 'snapshot')}, {_accessor(ref, 'snapshot')})")
            notes.append("reads both in one call (the client plans as few requests as the protocol allows)")
    if readable is None and writable is None:
        lines.append("    pass")
    shell = f"drivemap simulate {model.name} --tcp {SNIPPET_HOST}:{port} --unit {unit}"
    port0 = model.protocol.ports[0]
    known: list[str] = []
    missing: list[str] = []
    settings: tuple[tuple[str, str, object], ...] = (
        ("baud rate", "baudrate", port0.default_baudrate),
        ("parity", "parity", port0.default_parity),
        ("stop bits", "stopbits", port0.default_stop_bits),
    )
    for label, key, default in settings:
        if default is None:
            missing.append(key)
        else:
            known.append(f"{label} {default}")
    mode = port0.default_mode or port0.modes[0]
    return {
        "python": "\n".join(lines),
        "shell": shell,
        "unit": unit,
        "notes": notes,
        "serial_call": f'Client.serial("/dev/ttyUSB0", unit={unit})',
        "serial_defaults": ", ".join([f"mode {mode}" + ("" if port0.default_mode else " (the first it lists)")] + known),
        "serial_missing": ", ".join(f"{k}=" for k in missing),
    }
