"""View of ``generated/<model>/spec.py``: :func:`~drivemap.model.spec.spec_from_model`'s object, printed.

:func:`print_spec` writes a :class:`DeviceSpec` as the Python expression that builds it (fields
at their default are left out), so the generated module's ``SPEC`` equals the object the live
verbs, the gateway and the exporters use (a test compares them).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from drivemap.backends.common import Options
from drivemap.backends.views.common import header, provenance
from drivemap.model.nodes import Model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.spec import DeviceSpec, RegisterSpec, TimingSpec

__all__ = ["context", "print_spec"]

#: Classes printed with positional arguments on one line.
_POSITIONAL = frozenset({"BitSpec", "PageSpec", "PolicySpec", "EnumMemberSpec", "CommandSpec", "RunningStateSpec",
                         "ReplyQuirkSpec"})
#: Classes printed with keyword arguments on one line.
_ONE_LINE = frozenset({"ProductSpec", "SerialSpec", "FunctionSpec", "ExceptionSpec", "CommErrorSpec", "ReservedSpec"})
#: Fields printed even at their default.
_ALWAYS = {
    "DeviceSpec": frozenset({"device", "protocol", "registers"}),
    "ProtocolSpec": frozenset({"modes", "unit_min", "unit_max", "broadcast_address", "serial", "function_codes",
                               "exceptions", "timing"}),
    "RegisterSpec": frozenset({"name", "address", "source"}),
    "TimingSpec": frozenset(f.name for f in dataclasses.fields(TimingSpec)),
    "SerialSpec": frozenset({"mode", "baudrate", "parity", "stop_bits", "data_bits"}),
    "FunctionSpec": frozenset({"code", "max_quantity", "broadcast"}),
    "ReservedSpec": frozenset({"start", "end", "readable"}),
}
#: Tuple fields whose items stay on one line.
_INLINE_TUPLES = frozenset({"bits"})
#: Integer fields printed in hex, with their digits.
_HEX = {"address": 4, "start": 4, "end": 4, "code": 2}


def _is_default(f: dataclasses.Field[Any], value: Any) -> bool:
    if f.default is not dataclasses.MISSING:
        return bool(value == f.default)
    if f.default_factory is not dataclasses.MISSING:
        return bool(value == f.default_factory())
    return False


def _fields(obj: Any) -> list[tuple[str, Any]]:
    """(name, value) of the fields ``print_spec`` writes for ``obj``."""
    always = _ALWAYS.get(type(obj).__name__, frozenset())
    out = []
    for f in dataclasses.fields(obj):
        if not f.init:
            continue
        value = getattr(obj, f.name)
        if f.name in always or not _is_default(f, value):
            out.append((f.name, value))
    return out


def _raw(reg: RegisterSpec, value: int) -> str:
    """A raw value as the map writes it: hex for unsigned patterns, decimal for negative values."""
    return str(value) if value < 0 else f"0x{value:0{4 * reg.words}X}"


def _literal(name: str, value: Any, indent: str, owner: Any) -> str:
    if name in _HEX and isinstance(value, int) and not isinstance(value, bool):
        return f"0x{value:0{_HEX[name]}X}"
    if name == "not_available" and isinstance(owner, RegisterSpec):
        return "(" + ", ".join(_raw(owner, v) for v in value) + ",)"
    if dataclasses.is_dataclass(value):
        return _print(value, indent)
    if isinstance(value, tuple) and value and dataclasses.is_dataclass(value[0]):
        if name in _INLINE_TUPLES:
            return "(" + ", ".join(_print(v, indent) for v in value) + ",)"
        inner = indent + "    "
        return "(\n" + "".join(f"{inner}{_print(v, inner)},\n" for v in value) + f"{indent})"
    return repr(value)


def _print(obj: Any, indent: str) -> str:
    cls = type(obj).__name__
    fields = _fields(obj)
    if cls in _POSITIONAL:
        return f"{cls}(" + ", ".join(_literal(k, v, indent, obj) for k, v in fields) + ")"
    if cls in _ONE_LINE:
        return f"{cls}(" + ", ".join(f"{k}={_literal(k, v, indent, obj)}" for k, v in fields) + ")"
    inner = indent + "    "
    body = "".join(f"{inner}{k}={_literal(k, v, inner, obj)},\n" for k, v in fields)
    return f"{cls}(\n{body}{indent})"


def print_spec(spec: DeviceSpec) -> str:
    """``spec`` as the Python expression that builds an equal :class:`DeviceSpec`."""
    return _print(spec, "")


def _classes(obj: Any, found: set[str]) -> set[str]:
    """The spec classes ``obj`` is built from (for the generated module's imports)."""
    if dataclasses.is_dataclass(obj):
        found.add(type(obj).__name__)
        for f in dataclasses.fields(obj):
            if f.init:
                _classes(getattr(obj, f.name), found)
    elif isinstance(obj, tuple):
        for item in obj:
            _classes(item, found)
    return found


def context(model: Model, options: Options) -> dict[str, Any]:
    spec = spec_from_model(model)
    text = print_spec(spec)
    return {
        "header": header(model, options),
        "provenance": provenance(model),
        "package": options.package,
        "model": model,
        "spec": text,
        "imports": sorted((name for name in _classes(spec, set()) if f"{name}(" in text), key=str.lower),
    }
