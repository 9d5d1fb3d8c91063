"""What the sync and async client bases share (:class:`ClientCommon`): constructors, accessors by name,
plans and the broadcast refusal; the working parts (snapshots, read programs) are in :mod:`.machinery`.

:mod:`drivemap.runtime.client.api.sync_client` (sync) and :mod:`drivemap.runtime.client.api.async_client` (asyncio) build on it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, ClassVar, Generic, Self, TypeVar

from drivemap.runtime.client.api.accessors import ArrayBase, SnapshotBase
from drivemap.runtime.client.api.machinery import ClientMachinery, Program, class_machinery
from drivemap.runtime.client.protocol.planner import Hole, Key, ReadRequest
from drivemap.runtime.client.protocol.sansio import Core, PagePolicy
from drivemap.runtime.client.transport.bus import Stats
from drivemap.runtime.client.transport.quirks import accept as accept_reply_quirks
from drivemap.runtime.client.values.codec import Codec
from drivemap.runtime.errors import (
    DeviceException,
    DriveError,
    InvalidValue,
    NotBroadcastable,
    UnknownRegister,
    UnsupportedFunction,
)
from drivemap.runtime.spec import DeviceSpec

T = TypeVar("T")
S = TypeVar("S", bound=SnapshotBase)
#: The bus a client runs on (:class:`~.bus.Bus` or :class:`~.bus.AsyncBus`).
B = TypeVar("B")
__all__ = ["B", "ClientCommon", "Program", "S", "broadcast_refusal", "broadcast_unit"]


class ClientCommon(Generic[S, B]):
    """State, constructors and the API shared by the sync and async client bases (written once for
    both). The runtime's working parts are the client's one private attribute, ``_drivemap``
    (:class:`~.machinery.ClientMachinery`), so the class's namespace is its API and its registers."""

    SPEC: ClassVar[DeviceSpec]
    SNAPSHOT: ClassVar[type[SnapshotBase]] = SnapshotBase
    EXCEPTIONS: ClassVar[Mapping[int, type[DeviceException]]] = {}
    CODECS: ClassVar[Mapping[str, Codec[Any]]] = {}

    _drivemap: ClientMachinery

    def __init__(self, bus: B, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.protocol.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.protocol.unit_min}..{spec.protocol.unit_max}"
                               + (f" (or fixed port units {list(spec.protocol.fixed_units)})" if spec.protocol.fixed_units else ""))
        self.bus = bus
        if spec.protocol.quirks:  # the map's non-standard reply forms, accepted on this bus (runtime.quirks)
            accept_reply_quirks(bus.client, spec.protocol.quirks)  # type: ignore[attr-defined]
        klass = class_machinery(type(self))
        core = Core(spec, unit, self.EXCEPTIONS, page_policy, _broadcast, bus.stats)  # type: ignore[attr-defined]
        self._drivemap = klass.flavour(klass, bus, core, _owns_bus)

    @classmethod
    def tcp(cls, host: str, port: int = 502, unit: int = 1, *, timeout: float | None = None,
            retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client with its own Modbus TCP connection."""
        bus = class_machinery(cls).flavour.BUS.tcp(host, port, timeout=timeout, retries=retries)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, unit: int = 1, *, timeout: float | None = None,
                     retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client behind a serial gateway that passes RTU frames over TCP."""
        bus = class_machinery(cls).flavour.BUS.rtu_over_tcp(host, port, timeout=timeout, retries=retries)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @classmethod
    def serial(cls, port: str, unit: int = 1, *, timeout: float | None = None, retries: int | None = None,
               page_policy: PagePolicy = "raise", **overrides: Any) -> Self:
        """A client with its own serial line (mode, baud rate, parity: the map's defaults unless overridden)."""
        bus = class_machinery(cls).flavour.BUS.serial(port, cls.SPEC.protocol.serial, timeout=timeout,
                                                      retries=retries, **overrides)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @property
    def stats(self) -> Stats:
        """Counters of the bus (shared by every client on it), adaptive-read splits included."""
        stats: Stats = self.bus.stats  # type: ignore[attr-defined]
        return stats

    def close(self) -> None:
        """Close the bus if this client opened it."""
        if self._drivemap.owns_bus:
            self.bus.close()  # type: ignore[attr-defined]

    @classmethod
    def plan(cls, keys: Iterable[Key] | None = None) -> tuple[ReadRequest, ...]:
        """The read requests for ``keys`` (all readable elements when None); computed once and cached."""
        return class_machinery(cls).plan(keys)

    @property
    def unit(self) -> int:
        return self._drivemap.core.unit

    @property
    def page_policy(self) -> PagePolicy:
        return self._drivemap.core.page_policy

    @property
    def holes(self) -> frozenset[Hole]:
        """Words (bits) this client found the device refuses on their own: ``(table, address)``.

        Found when the device answers 02h to a read that spans several registers (the client
        splits it); later reads never span them. Empty until such a refusal."""
        return frozenset(self._drivemap.core.holes)

    @property
    def pending_configuration(self) -> tuple[str, ...]:
        """Elements written whose new value takes effect after :meth:`apply_configuration`."""
        return tuple(self._drivemap.core.pending_configuration)

    @property
    def pending_power_cycle(self) -> tuple[str, ...]:
        """Elements written whose new value takes effect after a power cycle."""
        return tuple(self._drivemap.core.pending_power_cycle)

    @property
    def registers(self) -> Mapping[str, Any]:
        """Accessor by register name (in the map's order)."""
        return {name: getattr(self, name) for name in self._drivemap.klass.register_order}

    def accessor(self, name: str) -> Any:
        """The accessor for ``"name"`` or ``"name[i]"``."""
        base, _, rest = name.partition("[")
        if base not in self._drivemap.klass.registers():
            raise UnknownRegister(f"{self.SPEC.name} has no register {base!r}")
        acc = getattr(self, base)
        if rest:
            digits = rest[:-1]
            if not isinstance(acc, ArrayBase) or not rest.endswith("]") or not (digits.isascii() and digits.isdigit()):
                raise UnknownRegister(f"{name!r} is not an element of an array register")
            index = int(rest[:-1])
            if not 0 <= index < len(acc):
                raise UnknownRegister(f"{name!r}: index out of range 0..{len(acc) - 1}")
            return acc[index]
        return acc


def broadcast_refusal(spec: DeviceSpec) -> DriveError:
    """The error ``Client.broadcast`` raises when the map allows no broadcast write, naming why.

    :class:`UnsupportedFunction` without a broadcast address; else :class:`NotBroadcastable` with
    each write function's state (not stated in the manual / not allowed) and the map's reason.
    """
    if spec.protocol.broadcast_address is None:
        return UnsupportedFunction(f"{spec.name}: the map gives no broadcast address")
    reasons = []
    for fc in spec.protocol.function_codes:
        if fc.code in (0x06, 0x10) and fc.broadcast is not True:
            state = "not stated in the manual" if fc.broadcast is None else "not allowed by the map"
            reasons.append(f"{fc.code:02X}h by broadcast: {state}" + (f" ({fc.broadcast_reason})" if fc.broadcast_reason else ""))
    why = "; ".join(reasons) if reasons else "no register can be written by a function the map allows by broadcast"
    return NotBroadcastable(f"{spec.name}: no broadcast client (unit {spec.protocol.broadcast_address}): {why}")


def broadcast_unit(spec: DeviceSpec) -> int:
    if spec.protocol.broadcast_address is None:
        raise UnsupportedFunction(f"{spec.name}: the map gives no broadcast address")
    return spec.protocol.broadcast_address
