"""View of ``generated/<model>/spec.py``: the DeviceSpec literal."""

from __future__ import annotations

from typing import Any

from drivemap.backends.exporters.base import Options
from drivemap.backends.views.common import header
from drivemap.model.nodes import Model, Register


def _num(value: float | None) -> int | float | None:
    if value is None:
        return None
    return int(value) if float(value).is_integer() else float(value)


def _default(value: float | str | None) -> int | float | str | bool | None:
    """A default as a literal: text and true/false as they are, numbers as :func:`_num`."""
    if isinstance(value, (str, bool)):
        return value
    return _num(value)


def register_args(model: Model, reg: Register) -> list[tuple[str, str]]:
    """(keyword, python literal) pairs for RegisterSpec, omitting defaults."""
    args: list[tuple[str, str]] = [("name", repr(reg.name)), ("address", f"0x{reg.address:04X}")]

    def add(key: str, value: Any, default: Any) -> None:
        if value != default:
            args.append((key, repr(value)))

    add("type", reg.type, "u16")
    add("table", reg.table, "holding")
    add("access", reg.access, "rw")
    add("count", reg.count, 1)
    add("stride", reg.stride, 1)
    add("word_order", reg.word_order, None)
    add("scale", _num(reg.scale), 1)
    add("offset", _num(reg.offset), 0)
    add("unit", reg.unit, None)
    add("min", _num(reg.min), None)
    add("max", _num(reg.max), None)
    add("defaults", tuple(_default(d) for d in reg.defaults), (None,))
    add("reflect", reg.reflect, "unknown")
    add("storage", reg.storage, "unknown")
    add("write_delay_ms", _num(reg.write_delay_ms), None)
    if reg.enum:
        args.append(("enum", repr(reg.enum)))
        args.append(("enum_values", repr(tuple(v.value for v in model.enum(reg.enum).values))))
    if reg.bits:
        bits = ", ".join(
            f"BitSpec({b.name!r}, {b.offset}, {b.width}, {b.label!r}, {b.enum!r})" for b in reg.bits
        )
        args.append(("bits", f"({bits},)"))
    if reg.page:
        args.append(("page", f"PageSpec({reg.page.selector!r}, {reg.page.value})"))
    add("command_value", reg.command_value, None)
    add("broadcast", reg.broadcast, False)
    add("refuse_while_running", reg.refuse_while_running, False)
    add("param", reg.param, None)
    args.append(("source", repr(reg.source)))
    add("running_advice", reg.running_advice.text() if reg.running_advice else None, None)
    add("byte_order", reg.byte_order, "high_first")
    add("length", reg.length, 1)
    if reg.type == "string":
        add("encoding", reg.encoding, "ascii")
    add("scale_register", reg.scale_register, None)
    if reg.not_available:
        args.append(("not_available", "(" + ", ".join(_raw_literal(reg, v) for v in reg.not_available) + ",)"))
    add("min_read", reg.min_read, None)
    if reg.values:
        args.append(("values", repr(tuple((v.value, v.label) for v in reg.values))))
    add("precision", reg.precision, None)
    add("first_index", reg.first_index, 0)
    return args


def alignment_literals(model: Model) -> list[str]:
    """``AlignmentSpec(...)`` literals of the map's alignment rules."""
    out = []
    for a in model.protocol.alignment:
        out.append(f"AlignmentSpec({a.table!r}, start=0x{a.start:04X}, end=0x{a.end:04X}, "
                   f"start_multiple={a.start_multiple}, quantity_multiple={a.quantity_multiple}, "
                   f"min_quantity={a.min_quantity}, whole_values={a.whole_values!r}, operations={a.operations!r}, "
                   f"exception=0x{a.exception:02X}, source={a.source!r})")
    return out


def _raw_literal(reg: Register, value: int) -> str:
    """A raw value as the map writes it: hex for unsigned patterns, decimal for negative values."""
    return str(value) if value < 0 else f"0x{value:0{4 * reg.words}X}"


def context(model: Model, options: Options) -> dict[str, Any]:
    p = model.protocol
    port = p.ports[0]
    t = p.timing
    return {
        "header": header(model, options),
        "package": options.package,
        "model": model,
        "serial": {
            "mode": port.default_mode or port.modes[0],
            "baudrate": port.default_baudrate,
            "parity": port.default_parity,
            "stop_bits": port.default_stop_bits,
            "data_bits": 8 if 8 in port.data_bits or not port.data_bits else port.data_bits[0],
        },
        "timing": [
            ("silent_interval_chars", _num(t.silent_interval_chars)),
            ("silent_interval_floor_ms", _num(t.silent_interval_floor_ms)),
            ("silent_interval_floor_above_bps", t.silent_interval_floor_above_bps),
            ("processing_ms", tuple(_num(x) for x in t.processing_ms) if t.processing_ms else None),
            ("inter_frame_gap_ms", _num(t.inter_frame_gap_ms)),
            ("broadcast_gap_ms", _num(t.broadcast_gap_ms)),
            ("response_timeout_ms", _num(t.response_timeout_ms)),
            ("retries", t.retries),
        ],
        "registers": [register_args(model, r) for r in model.registers],
        "configuration": (p.configuration.register, p.configuration.value) if p.configuration else None,
        "fixed_units": tuple(sorted({x.fixed_unit for x in p.ports if x.fixed_unit is not None
                                     and not p.unit_min <= x.fixed_unit <= p.unit_max})),
        "max_gap": p.max_gap,
        "imports": _imports(model),
        "running_state": ((p.running_state.register, p.running_state.values) if p.running_state else None),
        "reply_quirks": tuple(q.quirk for q in p.reply_quirks),
        "alignment": alignment_literals(model),
    }


def _imports(model: Model) -> list[str]:
    """Only the spec classes this model uses (generated code stays ruff-clean)."""
    names = {"DeviceSpec", "FunctionSpec", "RegisterSpec", "SerialSpec", "TimingSpec"}
    if model.protocol.exceptions:
        names.add("ExceptionSpec")
    if any(r.bits for r in model.registers):
        names.add("BitSpec")
    if any(r.page for r in model.registers) or any(r.page for r in model.reserved):
        names.add("PageSpec")
    if model.protocol.comm_errors:
        names.add("CommErrorSpec")
    if model.protocol.exception_policy or model.protocol.comm_error_policy:
        names.add("PolicySpec")
    if model.reserved:
        names.add("ReservedSpec")
    if model.protocol.alignment:
        names.add("AlignmentSpec")
    return sorted(names)
