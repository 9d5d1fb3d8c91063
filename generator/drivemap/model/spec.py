"""The one typed path from a compiled :class:`~drivemap.model.nodes.Model` to the runtime's :class:`DeviceSpec`.

:func:`spec_from_model` is what the simulator factory, the live verbs, the gateway, the exporters
and ``drivemap build`` use; the generated ``spec.py`` is this object printed
(:mod:`drivemap.backends.views.spec`), so a built package and an unbuilt map give equal specs.
Nothing here renders or executes generated text.
"""

from __future__ import annotations

import dataclasses
import sys
import types
from typing import Any, TypeVar

from drivemap.model.nodes import Model, Register
from drivemap.runtime.client.dynamic import client_package
from drivemap.runtime.sim.model import ModelSimulator, simulator_main
from drivemap.runtime.spec import (
    AlignmentSpec,
    CommErrorSpec,
    DeviceSpec,
    EnumSpec,
    ExceptionSpec,
    FunctionSpec,
    IdentitySpec,
    PolicySpec,
    RegisterSpec,
    ReservedSpec,
    SerialSpec,
    TimingSpec,
)

__all__ = ["load_package", "project", "register_spec", "spec_from_model"]

_T = TypeVar("_T")


def _runtime_class(cls: type) -> type:
    """The runtime spec class a model class is (or extends)."""
    return next(c for c in cls.__mro__ if c.__module__ == DeviceSpec.__module__)


def _projected(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return project(value, _runtime_class(type(value)))
    if isinstance(value, tuple):
        return tuple(_projected(v) for v in value)
    return value


def project(node: object, cls: type[_T]) -> _T:
    """``node`` (a model node, which extends the runtime class ``cls``) as a plain ``cls``: the
    fields the runtime declares, nested nodes projected likewise; the compile-time extras are dropped."""
    return cls(**{f.name: _projected(getattr(node, f.name)) for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                  if f.init})


def _num(value: float | None) -> int | float | None:
    """A number as the map means it: an int when it is whole (so the printed spec reads ``10``, not ``10.0``)."""
    if value is None:
        return None
    return int(value) if float(value).is_integer() else float(value)


def _whole(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)


def _default(value: float | str | None) -> int | float | str | bool | None:
    if isinstance(value, (str, bool)):
        return value
    return _num(value)


def register_spec(model: Model, reg: Register) -> RegisterSpec:
    """The runtime description of one register (or array) of ``model``."""
    enum_values = tuple(v.value for v in model.enum(reg.enum).members) if reg.enum else ()
    return RegisterSpec(
        name=reg.name, address=reg.address, type=reg.type, table=reg.table, access=reg.access,
        count=reg.count, stride=reg.stride, word_order=reg.word_order,
        scale=_whole(reg.scale), offset=_whole(reg.offset), unit=reg.unit,
        min=_num(reg.min), max=_num(reg.max), defaults=tuple(_default(d) for d in reg.defaults),
        reflect=reg.reflect, storage=reg.storage, write_delay_ms=_num(reg.write_delay_ms),
        enum=reg.enum, enum_values=enum_values,
        bits=_projected(reg.bits), page=reg.page,
        command_value=reg.command_value, broadcast=reg.broadcast, refuse_while_running=reg.refuse_while_running,
        param=reg.param, source=reg.source,
        running_advice=reg.running_advice.text() if reg.running_advice else None,
        byte_order=reg.byte_order, length=reg.length,
        encoding=reg.encoding if reg.type == "string" else "ascii",
        scale_register=reg.scale_register, not_available=reg.not_available, min_read=reg.min_read,
        values=tuple((v.value, v.label) for v in reg.values), precision=reg.precision, first_index=reg.first_index,
        bits_class=reg.bits_class,
    )


def _serial(model: Model) -> SerialSpec:
    port = model.protocol.ports[0]
    return SerialSpec(
        mode=port.default_mode or port.modes[0], baudrate=port.default_baudrate, parity=port.default_parity,
        stop_bits=port.default_stop_bits,
        data_bits=8 if 8 in port.data_bits or not port.data_bits else port.data_bits[0],
    )


def _timing(model: Model) -> TimingSpec:
    t = model.protocol.timing
    return TimingSpec(
        silent_interval_chars=_num(t.silent_interval_chars), silent_interval_floor_ms=_num(t.silent_interval_floor_ms),
        silent_interval_floor_above_bps=t.silent_interval_floor_above_bps,
        processing_ms=(_whole(t.processing_ms[0]), _whole(t.processing_ms[1])) if t.processing_ms else None,
        inter_frame_gap_ms=_num(t.inter_frame_gap_ms), broadcast_gap_ms=_num(t.broadcast_gap_ms),
        response_timeout_ms=_num(t.response_timeout_ms), retries=t.retries,
    )


def spec_from_model(model: Model) -> DeviceSpec:
    """The runtime's description of ``model``: registers, dialect, timing, enums (no YAML, no generated code)."""
    p = model.protocol
    return DeviceSpec(
        model=model.name, title=model.device.title, modes=p.modes, unit_min=p.unit_min, unit_max=p.unit_max,
        broadcast_address=p.broadcast_address, serial=_serial(model),
        function_codes=tuple(FunctionSpec(fc.code, fc.max_quantity, fc.broadcast, fc.broadcast_reason)
                             for fc in p.function_codes),
        exceptions=tuple(ExceptionSpec(ex.code, ex.name, ex.meaning) for ex in p.exceptions),
        timing=_timing(model),
        registers=tuple(register_spec(model, r) for r in model.registers),
        reserved=tuple(ReservedSpec(r.start, r.end, r.readable,
                                    r.page, r.table)
                       for r in model.reserved),
        comm_errors=tuple(CommErrorSpec(c.code, c.name, c.meaning) for c in p.comm_errors),
        exception_policy=tuple(PolicySpec(c.case, c.code) for c in p.exception_policy),
        comm_error_policy=tuple(PolicySpec(c.case, c.code) for c in p.comm_error_policy),
        comm_error_history=p.comm_error_history,
        configuration=(p.configuration.register, p.configuration.value) if p.configuration else None,
        max_frame_bytes=p.max_frame_bytes,
        fixed_units=tuple(sorted({x.fixed_unit for x in p.ports if x.fixed_unit is not None
                                  and not p.unit_min <= x.fixed_unit <= p.unit_max})),
        running_state=(p.running_state.register, p.running_state.values) if p.running_state else None,
        reply_quirks=tuple(q.quirk for q in p.reply_quirks),
        max_gap=p.max_gap,
        alignment=tuple(AlignmentSpec(a.table, start=a.start, end=a.end, start_multiple=a.start_multiple,
                                      quantity_multiple=a.quantity_multiple, min_quantity=a.min_quantity,
                                      whole_values=a.whole_values, operations=a.operations, exception=a.exception,
                                      source=a.source)
                        for a in p.alignment),
        identity=tuple(IdentitySpec(c.register, c.kind, c.values, c.source) for c in model.identity),
        enums=tuple(project(e, EnumSpec) for e in model.enums),
    )


def load_package(model: Model) -> types.ModuleType:
    """The package of ``model`` as ``drivemap build`` would write it (``Client``, ``AsyncClient``,
    ``SPEC``, enums ..., and a ``simulator`` submodule with its ``Simulator``), built from
    :func:`spec_from_model` without generating or running code; each call builds afresh."""
    spec = spec_from_model(model)
    name = f"drivemap_inmemory_{model.name}"
    package = client_package(spec, name)
    package.__path__ = []  # a package, so that ``importlib.import_module(f"{name}.simulator")`` works
    simulator = types.ModuleType(f"{name}.simulator", f"Simulator of {spec.title}")
    simulator.Simulator = type("Simulator", (ModelSimulator,), {"SPEC": spec, "__module__": simulator.__name__})  # type: ignore[attr-defined]
    simulator.MODEL = spec.model  # type: ignore[attr-defined]
    simulator.main = simulator_main(simulator.Simulator)  # type: ignore[attr-defined]
    sys.modules[simulator.__name__] = package.simulator = simulator  # type: ignore[attr-defined]
    return package
