"""A client package built from a :class:`DeviceSpec` at run time: no generated source, no ``exec``.

:func:`client_package` gives what ``drivemap build`` writes for a map (``Client``, ``AsyncClient``,
the broadcast clients, ``Snapshot``, ``CODECS``, ``EXCEPTIONS``, the enums, flags, bit-field
records and exception classes, ``SPEC``) as classes made from the spec with the same runtime
pieces the generated code uses (:mod:`.declare`'s descriptors, :func:`~.declare.codecs_for`,
:func:`~.records.record`), so the live verbs and the gateway use a map the moment it compiles.
Only the static typing and the register docstrings' prose are the generated package's own.
"""

from __future__ import annotations

import dataclasses
import enum
import sys
import types
from typing import Any

from drivemap.runtime.client.api.accessors import SnapshotBase
from drivemap.runtime.client.api.async_client import AsyncClientBase
from drivemap.runtime.client.api.declare import REG_CLASSES, broadcast_kind_of, codecs_for, kind_of
from drivemap.runtime.client.api.sync_client import ClientBase
from drivemap.runtime.client.protocol.sansio import PagePolicy
from drivemap.runtime.client.transport.bus import AsyncBus, Bus
from drivemap.runtime.client.values.codec import DriveEnum
from drivemap.runtime.client.values.records import record
from drivemap.runtime.errors import DeviceException
from drivemap.runtime.names import bit_attribute, exception_classes
from drivemap.runtime.spec import DeviceSpec, RegisterSpec

__all__ = ["client_class", "client_package"]


def _register_doc(spec: RegisterSpec) -> str:
    where = {"holding": "Address", "input": "Input register", "coil": "Coil", "discrete": "Discrete input"}[spec.table]
    lines = [spec.name, "", f"{where} 0x{spec.address:04X}; {spec.type}, access {spec.access}."]
    if spec.unit or spec.min is not None or spec.max is not None:
        lines.append(f"Unit: {spec.unit or 'none'}; range {spec.min} .. {spec.max}.")
    if spec.source:
        lines.append(f"Manual: {spec.source}.")
    return "\n".join(lines)


def _value_classes(spec: DeviceSpec, module: str) -> list[type]:
    """The enums, flags and bit-field records of ``spec``, as the generated package declares them."""
    classes: list[type] = []
    for e in spec.enums:
        functional: Any = DriveEnum  # the functional API (mypy types the call as a member lookup)
        made: Any = functional(e.name, [(m.name, m.value) for m in e.members], module=module)
        made.__doc__ = f"{e.name} ({e.source})."
        classes.append(made)
    enums = {c.__name__: c for c in classes}
    seen: set[str] = set()
    for reg in spec.registers:
        name = reg.bits_class
        if not reg.bits or reg.enum or name is None or name in seen:
            continue
        seen.add(name)
        if any(b.width > 1 or b.enum for b in reg.bits):
            annotations = {bit_attribute(b.name): enums[b.enum] if b.enum else bool if b.width == 1 else int
                           for b in reg.bits}
            classes.append(record(type(name, (), {"__annotations__": annotations, "__module__": module})))
        else:
            flags: Any = enum.IntFlag
            flag: Any = flags(name, [(b.name, b.mask) for b in reg.bits], module=module)
            classes.append(flag)
    return classes


def _exceptions(spec: DeviceSpec, module: str) -> list[type[DeviceException]]:
    names = exception_classes([(ex.name, ex.code) for ex in spec.protocol.exceptions])
    return [type(cls, (DeviceException,), {"CODE": ex.code, "NAME": ex.name, "MEANING": ex.meaning,
                                            "__module__": module,
                                            "__doc__": f"Exception 0x{ex.code:02X} {ex.name}: {ex.meaning}."})
            for ex, cls in zip(spec.protocol.exceptions, names, strict=True)]


def _snapshot(spec: DeviceSpec, module: str) -> type[SnapshotBase]:
    fields = [(r.name, Any, dataclasses.field(default=None)) for r in spec.registers if r.readable]
    cls = dataclasses.make_dataclass("Snapshot", fields, bases=(SnapshotBase,), frozen=True, repr=False,
                                     init=False, namespace={"__module__": module})
    return cls


def _broadcasts(spec: DeviceSpec) -> list[RegisterSpec]:
    if spec.protocol.broadcast_address is None:
        return []
    return [r for r in spec.registers if r.broadcast and r.writable]


def _broadcast_constructor(made: dict[str, Any], name: str, unit: int | None) -> Any:
    def broadcast(cls: Any, bus: Any, *, page_policy: PagePolicy = "raise") -> Any:
        return made[name](bus, page_policy=page_policy)

    broadcast.__doc__ = f"Writes to every unit at once (unit {unit}); never waits for a reply."
    return broadcast


def client_package(spec: DeviceSpec, name: str | None = None) -> types.ModuleType:
    """The client package of ``spec`` as a module (registered in ``sys.modules`` under ``name``,
    by default ``drivemap_spec_<model>``, so that pickling and logging find its classes)."""
    module = name or f"drivemap_spec_{spec.name}"
    package = types.ModuleType(module, f"drivemap client of {spec.device.title}, built from its spec")
    values = _value_classes(spec, module)
    exceptions = _exceptions(spec, module)
    codecs = codecs_for(spec, *values)
    snapshot = _snapshot(spec, module)
    common = {"SPEC": spec, "EXCEPTIONS": {e.CODE: e for e in exceptions}, "CODECS": codecs, "__module__": module}
    registers = type("_Registers", (), {
        "__module__": module, **{r.name: REG_CLASSES[kind_of(r)](_register_doc(r)) for r in spec.registers}})
    made: dict[str, Any] = {}
    broadcast = _broadcasts(spec)
    sync_ns: dict[str, Any] = {**common, "SNAPSHOT": snapshot}
    async_ns: dict[str, Any] = {**common, "SNAPSHOT": snapshot}
    if broadcast:
        bregisters = type("_BroadcastRegisters", (), {
            "__module__": module, **{r.name: REG_CLASSES[broadcast_kind_of(r)]() for r in broadcast}})
        unit = spec.protocol.broadcast_address

        def sync_init(self: Any, bus: Bus, unit: int | None = unit, *, page_policy: PagePolicy = "raise",
                      _broadcast: bool = True, _owns_bus: bool = False) -> None:
            ClientBase.__init__(self, bus, unit if unit is not None else 0, page_policy=page_policy, _broadcast=True,
                                _owns_bus=_owns_bus)

        def async_init(self: Any, bus: AsyncBus, unit: int | None = unit, *, page_policy: PagePolicy = "raise",
                       _broadcast: bool = True, _owns_bus: bool = False) -> None:
            AsyncClientBase.__init__(self, bus, unit if unit is not None else 0, page_policy=page_policy,
                                     _broadcast=True, _owns_bus=_owns_bus)

        made["BroadcastClient"] = type("BroadcastClient", (bregisters, ClientBase), {**common, "__init__": sync_init})
        made["AsyncBroadcastClient"] = type("AsyncBroadcastClient", (bregisters, AsyncClientBase),
                                            {**common, "__init__": async_init})
        sync_ns["broadcast"] = classmethod(_broadcast_constructor(made, "BroadcastClient", unit))
        async_ns["broadcast"] = classmethod(_broadcast_constructor(made, "AsyncBroadcastClient", unit))
    made["Client"] = type("Client", (registers, ClientBase), sync_ns)
    made["AsyncClient"] = type("AsyncClient", (registers, AsyncClientBase), async_ns)
    for cls in (*values, *exceptions):
        made[cls.__name__] = cls
    made.update(SPEC=spec, CODECS=codecs, EXCEPTIONS=common["EXCEPTIONS"], Snapshot=snapshot, Bus=Bus,
                AsyncBus=AsyncBus)
    package.__dict__.update(made)
    package.__all__ = sorted(made)  # type: ignore[attr-defined]
    sys.modules[module] = package
    return package


def client_class(spec: DeviceSpec) -> type[ClientBase[Any]]:
    """The synchronous ``Client`` class of ``spec`` (see :func:`client_package`)."""
    cls: type[ClientBase[Any]] = client_package(spec).Client
    return cls
