"""The client runtime that generated ``Client`` / ``AsyncClient`` classes build on.

Protocol behaviour lives in :class:`~drivemap.runtime.core.Core`, written once as generators
("sans I/O"); :class:`ClientBase` runs its operations on a :class:`Bus`, :class:`AsyncClientBase`
on an :class:`AsyncBus`. Every check on the caller's input happens before the first request is
yielded, so a bad value never sends a byte.

Generated packages subclass the bases, declare one typed accessor per register
(:mod:`drivemap.runtime.accessors`: :class:`ReadOnly`, :class:`WriteOnly`, :class:`ReadWrite` and
their ``Array`` and ``Async`` forms; read-only accessors have no ``write``) and a frozen
``Snapshot`` dataclass for :meth:`ClientBase.read`.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, ClassVar, Generic, Self, TypeVar

from . import rawio
from .accessors import (
    AsyncCommand,
    AsyncReadOnly,
    AsyncReadOnlyArray,
    AsyncReadWrite,
    AsyncReadWriteArray,
    AsyncReadWriteCommand,
    AsyncWriteOnly,
    AsyncWriteOnlyArray,
    Command,
    Readable,
    ReadOnly,
    ReadOnlyArray,
    ReadWrite,
    ReadWriteArray,
    ReadWriteCommand,
    SnapshotBase,
    WriteOnly,
    WriteOnlyArray,
    _Array,
    encode_for_write,
)
from .bus import AsyncBus, Bus, Stats
from .codec import Codec, EnumCodec, FieldsCodec, FlagCodec, unwrap
from .core import Core, Deferred, PagePolicy, RawItem, arun, run, spec_tables
from .errors import (
    DeviceException,
    DriveError,
    InvalidValue,
    NotBroadcastable,
    PartialWrite,
    ReadOnlyRegister,
    UnknownRegister,
    UnsupportedFunction,
)
from .planner import Hole, Key, ReadRequest, plan_reads
from .quirks import accept as accept_reply_quirks
from .spec import DeviceSpec

T = TypeVar("T")
S = TypeVar("S", bound=SnapshotBase)
_run = run
_arun = arun
_tables = spec_tables
#: Read programs kept per client (distinct tuples of accessors passed to read()).
_MAX_PROGRAMS = 1024


# ----------------------------------------------------------------------------- clients
class _Common(Generic[S]):
    """State and helpers shared by the sync and async client bases."""

    SPEC: ClassVar[DeviceSpec]
    SNAPSHOT: ClassVar[type[SnapshotBase]] = SnapshotBase
    EXCEPTIONS: ClassVar[Mapping[int, type[DeviceException]]] = {}
    CODECS: ClassVar[Mapping[str, Codec[Any]]] = {}
    _plans: ClassVar[dict[Any, tuple[ReadRequest, ...]]]
    _shape: ClassVar[dict[str, int]]
    _table: ClassVar[dict[Key, tuple[Callable[[int], Any] | None, str | None, int]]]
    _defaults: ClassVar[dict[str, Any] | None]

    _core: Core
    _accessors: dict[str, Any]

    def _setup(self, unit: int, page_policy: PagePolicy, broadcast: bool, stats: Stats | None = None) -> None:
        self._core = Core(self.SPEC, unit, self.EXCEPTIONS, page_policy, broadcast, stats)
        self._accessors = {}
        #: read programs: the accessors of a read() -> the keys they read (checked readable once)
        self._programs: dict[tuple[Readable, ...], tuple[Key, ...]] = {}

    def _register_accessors(self) -> None:
        """Called by generated ``__init__`` after the accessors are set: index them by name."""
        self._accessors = {name: getattr(self, name) for name in self.CODECS if name in self.__dict__}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._plans = {}

    @classmethod
    def _plan_cache(cls) -> dict[Any, tuple[ReadRequest, ...]]:
        cache = cls.__dict__.get("_plans")
        if cache is None:
            cache = cls._plans = {}
        return cache

    @classmethod
    def plan(cls, keys: Iterable[Key] | None = None) -> tuple[ReadRequest, ...]:
        """The read requests for ``keys`` (all readable elements when None); computed once and cached."""
        cache = cls._plan_cache()
        if keys is None:
            plan = cache.get(None)
            if plan is None:
                plan = cache[None] = cls.plan(_tables(cls.SPEC).all_keys)
            return plan
        if type(keys) is tuple:  # an accessor's keys: cached as given, skipping the frozenset
            plan = cache.get(keys)
            if plan is None:
                plan = cache[keys] = cls.plan(list(keys))
            return plan
        wanted = frozenset(keys)
        plan = cache.get(wanted)
        if plan is None:
            plan = cache[wanted] = plan_reads(cls.SPEC, wanted)
        return plan

    @property
    def unit(self) -> int:
        return self._core.unit

    @property
    def page_policy(self) -> PagePolicy:
        return self._core.page_policy

    @property
    def holes(self) -> frozenset[Hole]:
        """Words (bits) this client found the device refuses on their own: ``(table, address)``.

        Found when the device answers 02h to a read that spans several registers (the client
        splits it); later reads never span them. Empty until such a refusal."""
        return frozenset(self._core.holes)

    def _plan_for(self, keys: Sequence[Key]) -> tuple[ReadRequest, ...]:
        """The plan for ``keys``: the class's cached one, or this client's when it knows holes."""
        if self._core.holes:
            return self._core.plan_with_holes(keys)
        return (type(keys) is tuple and self._plans.get(keys)) or self.plan(keys)  # this class's own cache

    @property
    def pending_configuration(self) -> tuple[str, ...]:
        """Elements written whose new value takes effect after :meth:`apply_configuration`."""
        return tuple(self._core.pending_configuration)

    @property
    def pending_power_cycle(self) -> tuple[str, ...]:
        """Elements written whose new value takes effect after a power cycle."""
        return tuple(self._core.pending_power_cycle)

    @property
    def registers(self) -> Mapping[str, Any]:
        """Accessor by register name."""
        return dict(self._accessors)

    def accessor(self, name: str) -> Any:
        """The accessor for ``"name"`` or ``"name[i]"``."""
        base, _, rest = name.partition("[")
        acc = self._accessors.get(base)
        if acc is None:
            raise UnknownRegister(f"{self.SPEC.model} has no register {base!r}")
        if rest:
            if not isinstance(acc, _Array) or not rest.endswith("]") or not rest[:-1].isdigit():
                raise UnknownRegister(f"{name!r} is not an element of an array register")
            index = int(rest[:-1])
            if not 0 <= index < len(acc):
                raise UnknownRegister(f"{name!r}: index out of range 0..{len(acc) - 1}")
            return acc[index]
        return acc

    @classmethod
    def _snapshot_table(cls) -> dict[Key, tuple[Callable[[int], Any] | None, str | None, int]]:
        """Per readable element: (decode, snapshot field or None, index in the field's tuple or -1);
        decode is None for a register scaled by a scale-factor register (decoded with its factor).

        Computed once per class (each element on first use); the count of an array field is
        ``cls._shape[field]``.
        """
        table: dict[Key, tuple[Callable[[int], Any] | None, str | None, int]] | None = cls.__dict__.get("_table")
        if table is None:
            names = {f.name for f in dataclasses.fields(cls.SNAPSHOT)}
            cls._shape = {r.name: r.count for r in cls.SPEC.registers if r.name in names and r.is_array}
            table = cls._table = {}
            for reg in cls.SPEC.registers:
                if reg.readable and reg.name in cls.CODECS:
                    field = reg.name if reg.name in names else None
                    codec = cls.CODECS[reg.name]
                    decode = codec.decode if codec.scale_key is None else None  # scaled: needs its factor
                    for i in range(reg.count):
                        table[(reg.name, i)] = (decode, field, i if reg.is_array else -1)
        return table

    def _snapshot(self, raw: Mapping[Key, int]) -> S:
        table = self._snapshot_table()
        shape = self._shape
        values: dict[Key, Any] = {}
        fields: dict[str, Any] = {}
        arrays: dict[str, list[Any]] = {}
        for key, raw_value in raw.items():
            entry = table.get(key)
            if entry is None:  # not a readable element of the map: decode as before, no field
                values[key] = self.CODECS[key[0]].decode(raw_value)
                continue
            decode, name, index = entry
            if decode is None:
                codec = self.CODECS[key[0]]
                value = values[key] = codec.decode_scaled(raw_value, raw.get(codec.scale_key))  # type: ignore[arg-type]
            else:
                value = values[key] = decode(raw_value)
            if name is None:
                continue
            if index < 0:
                fields[name] = value
            else:
                current = arrays.get(name)
                if current is None:
                    current = arrays[name] = [None] * shape[name]
                current[index] = value
        for name, items in arrays.items():
            fields[name] = tuple(items)
        defaults = self._snapshot_defaults()
        if defaults is None:
            return self.SNAPSHOT(_values=values, **fields)  # type: ignore[return-value]
        # what __init__ does, without its per-field setattr calls: only the fields read are stored when
        # the class's defaults are class attributes (SnapshotBase.__init__), else every default is copied
        snap = object.__new__(self.SNAPSHOT)
        state = snap.__dict__
        if defaults:
            state.update(defaults)
        state["_values"] = values
        state.update(fields)
        return snap  # type: ignore[return-value]

    @classmethod
    def _snapshot_defaults(cls) -> dict[str, Any] | None:
        """Field values of an empty ``SNAPSHOT`` when building it without ``__init__`` is exact, else None.

        Exact for what the client template generates: a frozen dataclass whose fields all default to
        None (``_values`` aside), without ``__post_init__`` or ``__slots__``. Empty when the class
        uses :class:`SnapshotBase`'s ``__init__`` (``init=False``, what the template generates now):
        unset fields read their default from the class. Computed once per class.
        """
        if "_defaults" in cls.__dict__:
            return cls._defaults
        snapshot = cls.SNAPSHOT
        params = getattr(snapshot, "__dataclass_params__", None)
        fields = dataclasses.fields(snapshot)
        exact = (params is not None and params.frozen and not hasattr(snapshot, "__post_init__")
                 and not hasattr(snapshot, "__slots__") and snapshot.__new__ is object.__new__
                 and all(f.init and (f.name == "_values" or f.default is None) for f in fields))
        defaults: dict[str, Any] | None = None
        if exact and snapshot.__init__ is SnapshotBase.__init__:
            defaults = {}
        elif exact:  # a dataclass __init__ of its own (clients generated before init=False): copy the defaults
            defaults = {f.name: None for f in fields}
        cls._defaults = defaults
        return defaults

    @staticmethod
    def _keys(accessors: Iterable[Readable]) -> list[Key]:
        keys: list[Key] = []
        for acc in accessors:
            keys.extend(acc.read_keys)
        return keys

    def _program(self, accessors: tuple[Readable, ...]) -> tuple[Key, ...]:
        """The keys ``read(*accessors)`` reads, checked readable; cached per tuple of accessors (their
        plan is the class's, cached per tuple of keys; a client that knows holes plans with them)."""
        keys = self._programs.get(accessors)
        if keys is None:
            keys = tuple(self._keys(accessors))
            self._core.check_readable(keys)
            if len(self._programs) < _MAX_PROGRAMS:
                self._programs[accessors] = keys
        return keys

    def _by_name_value(self, acc: Any, value: Any) -> int | Deferred:
        codec = unwrap(acc.codec)
        if isinstance(codec, (EnumCodec, FlagCodec)) and isinstance(value, int) and not isinstance(value, enum.Enum):
            value = (codec.enum_type if isinstance(codec, EnumCodec) else codec.flag_type)(value)
        elif isinstance(codec, FieldsCodec) and isinstance(value, Mapping):
            value = codec.data_type(**value)
        elif acc.spec.type == "bool" and isinstance(value, int) and value in (0, 1):
            value = bool(value)
        return encode_for_write(acc.codec, value)


class ClientBase(_Common[S]):
    """Synchronous client of one unit on a :class:`Bus`."""

    def __init__(self, bus: Bus, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.unit_min}..{spec.unit_max}"
                               + (f" (or fixed port units {list(spec.fixed_units)})" if spec.fixed_units else ""))
        self.bus = bus
        if spec.reply_quirks:  # the map's non-standard reply forms, accepted on this bus (runtime.quirks)
            accept_reply_quirks(bus.client, spec.reply_quirks)
        self._owns_bus = _owns_bus
        self._setup(unit, page_policy, _broadcast, bus.stats)

    # constructors
    @classmethod
    def tcp(cls, host: str, port: int = 502, unit: int = 1, *, timeout: float | None = None,
            retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client with its own Modbus TCP connection."""
        return cls(Bus.tcp(host, port, timeout=timeout, retries=retries), unit, page_policy=page_policy, _owns_bus=True)

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, unit: int = 1, *, timeout: float | None = None,
                     retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client behind a serial gateway that passes RTU frames over TCP."""
        return cls(Bus.rtu_over_tcp(host, port, timeout=timeout, retries=retries), unit, page_policy=page_policy,
                   _owns_bus=True)

    @classmethod
    def serial(cls, port: str, unit: int = 1, *, timeout: float | None = None, retries: int | None = None,
               page_policy: PagePolicy = "raise", **overrides: Any) -> Self:
        """A client with its own serial line (mode, baud rate, parity: the map's defaults unless overridden)."""
        bus = Bus.serial(port, cls.SPEC.serial, timeout=timeout, retries=retries, **overrides)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @classmethod
    def broadcast(cls, bus: Bus, *, page_policy: PagePolicy = "raise") -> ClientBase[Any]:
        """A client that writes to every unit at once (generated when the map allows a broadcast write).

        Without one it raises :func:`broadcast_refusal`: the map's reason why nothing may be broadcast."""
        raise broadcast_refusal(cls.SPEC)

    @property
    def stats(self) -> Stats:
        """Counters of the bus (shared by every client on it), adaptive-read splits included."""
        return self.bus.stats

    def connect(self) -> None:
        self.bus.connect()

    def close(self) -> None:
        """Close the bus if this client opened it."""
        if self._owns_bus:
            self.bus.close()

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # plumbing used by accessors
    def _read_raw_keys(self, keys: Sequence[Key]) -> dict[Key, int]:
        core = self._core
        core.check_readable(keys)
        plan = self._plan_for(keys)
        with self.bus.lock:
            return _run(self.bus, core.read_raw(keys, plan, checked=True))

    def _write_raw_items(self, items: Sequence[RawItem]) -> None:
        with self.bus.lock:
            _run(self.bus, self._core.write_raw(items))

    # public API
    def read(self, *accessors: Readable) -> S:
        """Read the given registers together, in the fewest requests the map allows."""
        keys = self._program(accessors)
        core = self._core
        plan = core.plan_with_holes(keys) if core.holes else self._plans.get(keys) or self.plan(keys)
        with self.bus.lock:
            return self._snapshot(_run(self.bus, core.read_raw(keys, plan, checked=True)))

    def read_all(self) -> S:
        """Read every readable register (plan computed once per client class).

        Paged registers: with ``page_policy="raise"`` (the default) it switches the page selector to
        each page it needs and then puts it back to the page it found (also when a read fails);
        with ``"switch"`` it leaves the last page selected."""
        core = self._core
        keys = core.tables.all_keys
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        plan = core.plan_with_holes(keys) if core.holes else self.plan()
        with self.bus.lock:
            return self._snapshot(_run(self.bus, core.read_visiting_pages(keys, plan)))

    def write_many(self, items: Iterable[tuple[WriteOnly[Any] | ReadWrite[Any], Any]]) -> None:
        """Write several registers; contiguous ones go out in one 10h request where the map allows it.

        If it takes several requests and one fails, :class:`PartialWrite` says what was written."""
        self._write_raw_items([(acc.key, encode_for_write(acc.codec, value)) for acc, value in items])

    def read_by_name(self, name: str) -> Any:
        """``client.read_by_name("digital_speed[0]")``: the engineering value (tuple for a whole array)."""
        acc = self.accessor(name)
        self._core.check_readable(acc.keys)
        return acc.read()

    def write_by_name(self, name: str, value: Any) -> None:
        """``client.write_by_name("digital_speed[0]", 1000)``; ints are accepted for enums and flags."""
        acc = self.accessor(name)
        if isinstance(acc, _Array):
            if not hasattr(acc, "write"):
                raise ReadOnlyRegister(f"{name} is read-only")
            self._write_raw_items([(k, self._by_name_value(acc, v)) for k, v in zip(acc.keys, value, strict=True)])
            return
        self._core.check_write(acc.key)
        self._write_raw_items([(acc.key, self._by_name_value(acc, value))])

    def read_modify_write(self, accessor: ReadWrite[T], update: Callable[[T], T]) -> T:
        """Read a register, apply ``update`` to its value and write the result, holding the bus."""
        self._core.check_write(accessor.key)
        with self.bus.lock:
            value = accessor.read()
            new = update(value)
            accessor.write(new)
            return new

    def apply_configuration(self) -> None:
        """Send the map's configuration command; clears :attr:`pending_configuration`."""
        with self.bus.lock:
            _run(self.bus, self._core.apply_configuration())

    def loopback(self, data: int = 0xA537) -> int:
        """Diagnostics 08h sub-function 0: the device echoes ``data``."""
        with self.bus.lock:
            return _run(self.bus, self._core.loopback(data))

    def read_registers(self, table: str, address: int, count: int) -> list[int]:
        """``count`` words (0/1 per coil or discrete input) of ``table`` from ``address``, as the
        device sends them, in one request; checked before the wire (:mod:`drivemap.runtime.rawio`)."""
        rawio.check_read(self._core.spec, table, address, count, self._core.broadcast)
        op = rawio.read_registers(self._core, table, address, count)
        with self.bus.lock:
            return _run(self.bus, op)


class AsyncClientBase(_Common[S]):
    """Asyncio client of one unit on an :class:`AsyncBus` (same API, awaited)."""

    def __init__(self, bus: AsyncBus, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.unit_min}..{spec.unit_max}"
                               + (f" (or fixed port units {list(spec.fixed_units)})" if spec.fixed_units else ""))
        self.bus = bus
        if spec.reply_quirks:  # the map's non-standard reply forms, accepted on this bus (runtime.quirks)
            accept_reply_quirks(bus.client, spec.reply_quirks)
        self._owns_bus = _owns_bus
        self._setup(unit, page_policy, _broadcast, bus.stats)

    @classmethod
    def tcp(cls, host: str, port: int = 502, unit: int = 1, *, timeout: float | None = None,
            retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        return cls(AsyncBus.tcp(host, port, timeout=timeout, retries=retries), unit, page_policy=page_policy,
                   _owns_bus=True)

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, unit: int = 1, *, timeout: float | None = None,
                     retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        return cls(AsyncBus.rtu_over_tcp(host, port, timeout=timeout, retries=retries), unit,
                   page_policy=page_policy, _owns_bus=True)

    @classmethod
    def serial(cls, port: str, unit: int = 1, *, timeout: float | None = None, retries: int | None = None,
               page_policy: PagePolicy = "raise", **overrides: Any) -> Self:
        bus = AsyncBus.serial(port, cls.SPEC.serial, timeout=timeout, retries=retries, **overrides)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @classmethod
    def broadcast(cls, bus: AsyncBus, *, page_policy: PagePolicy = "raise") -> AsyncClientBase[Any]:
        """A client that writes to every unit at once (generated when the map allows a broadcast write).

        Without one it raises :func:`broadcast_refusal`: the map's reason why nothing may be broadcast."""
        raise broadcast_refusal(cls.SPEC)

    @property
    def stats(self) -> Stats:
        return self.bus.stats

    async def connect(self) -> None:
        await self.bus.connect()

    def close(self) -> None:
        if self._owns_bus:
            self.bus.close()

    async def __aenter__(self) -> Self:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.close()

    async def _read_raw_keys(self, keys: Sequence[Key]) -> dict[Key, int]:
        core = self._core
        core.check_readable(keys)
        plan = self._plan_for(keys)
        async with self.bus.lock:
            return await _arun(self.bus, core.read_raw(keys, plan, checked=True))

    async def _write_raw_items(self, items: Sequence[RawItem]) -> None:
        op = self._core.write_raw(items)
        async with self.bus.lock:
            await _arun(self.bus, op)

    async def read(self, *accessors: Readable) -> S:
        keys = self._program(accessors)
        core = self._core
        plan = core.plan_with_holes(keys) if core.holes else self._plans.get(keys) or self.plan(keys)
        async with self.bus.lock:
            return self._snapshot(await _arun(self.bus, core.read_raw(keys, plan, checked=True)))

    async def read_all(self) -> S:
        """See :meth:`ClientBase.read_all` (pages visited and restored under ``page_policy="raise"``)."""
        core = self._core
        keys = core.tables.all_keys
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        plan = core.plan_with_holes(keys) if core.holes else self.plan()
        async with self.bus.lock:
            return self._snapshot(await _arun(self.bus, core.read_visiting_pages(keys, plan)))

    async def write_many(self, items: Iterable[tuple[AsyncWriteOnly[Any] | AsyncReadWrite[Any], Any]]) -> None:
        await self._write_raw_items([(acc.key, encode_for_write(acc.codec, value)) for acc, value in items])

    async def read_by_name(self, name: str) -> Any:
        acc = self.accessor(name)
        self._core.check_readable(acc.keys)
        return await acc.read()

    async def write_by_name(self, name: str, value: Any) -> None:
        acc = self.accessor(name)
        if isinstance(acc, _Array):
            if not hasattr(acc, "write"):
                raise ReadOnlyRegister(f"{name} is read-only")
            await self._write_raw_items([(k, self._by_name_value(acc, v)) for k, v in zip(acc.keys, value, strict=True)])
            return
        self._core.check_write(acc.key)
        await self._write_raw_items([(acc.key, self._by_name_value(acc, value))])

    async def read_modify_write(self, accessor: AsyncReadWrite[T], update: Callable[[T], T]) -> T:
        """Read, update and write back; other callers on the bus wait until it is done."""
        self._core.check_write(accessor.key)
        keys = accessor.read_keys
        codec = accessor.codec
        async with self.bus.lock:
            raw = await _arun(self.bus, self._core.read_raw(keys, self._plan_for(keys)))
            scale = codec.scale_key
            value = codec.decode(raw[accessor.key]) if scale is None else codec.decode_scaled(raw[accessor.key],
                                                                                                raw.get(scale))
            new = update(value)
            await _arun(self.bus, self._core.write_raw([(accessor.key, encode_for_write(codec, new))]))
            return new

    async def apply_configuration(self) -> None:
        op = self._core.apply_configuration()
        async with self.bus.lock:
            await _arun(self.bus, op)

    async def loopback(self, data: int = 0xA537) -> int:
        op = self._core.loopback(data)
        async with self.bus.lock:
            return await _arun(self.bus, op)

    async def read_registers(self, table: str, address: int, count: int) -> list[int]:
        """The asyncio twin of :meth:`ClientBase.read_registers`."""
        rawio.check_read(self._core.spec, table, address, count, self._core.broadcast)
        op = rawio.read_registers(self._core, table, address, count)
        async with self.bus.lock:
            return await _arun(self.bus, op)


def broadcast_refusal(spec: DeviceSpec) -> DriveError:
    """The error ``Client.broadcast`` raises when the map allows no broadcast write, naming why.

    :class:`UnsupportedFunction` without a broadcast address; else :class:`NotBroadcastable` with
    each write function's state (not stated in the manual / not allowed) and the map's reason.
    """
    if spec.broadcast_address is None:
        return UnsupportedFunction(f"{spec.model}: the map gives no broadcast address")
    reasons = []
    for fc in spec.function_codes:
        if fc.code in (0x06, 0x10) and fc.broadcast is not True:
            state = "not stated in the manual" if fc.broadcast is None else "not allowed by the map"
            reasons.append(f"{fc.code:02X}h by broadcast: {state}" + (f" ({fc.broadcast_reason})" if fc.broadcast_reason else ""))
    why = "; ".join(reasons) if reasons else "no register can be written by a function the map allows by broadcast"
    return NotBroadcastable(f"{spec.model}: no broadcast client (unit {spec.broadcast_address}): {why}")


def broadcast_unit(spec: DeviceSpec) -> int:
    if spec.broadcast_address is None:
        raise UnsupportedFunction(f"{spec.model}: the map gives no broadcast address")
    return spec.broadcast_address


__all__ = [
    "AsyncBus",
    "AsyncClientBase",
    "AsyncCommand",
    "AsyncReadOnly",
    "AsyncReadOnlyArray",
    "AsyncReadWrite",
    "AsyncReadWriteArray",
    "AsyncReadWriteCommand",
    "AsyncWriteOnly",
    "AsyncWriteOnlyArray",
    "Bus",
    "ClientBase",
    "Command",
    "Core",
    "DriveError",
    "PagePolicy",
    "PartialWrite",
    "ReadOnly",
    "ReadOnlyArray",
    "ReadWrite",
    "ReadWriteArray",
    "ReadWriteCommand",
    "SnapshotBase",
    "Stats",
    "WriteOnly",
    "WriteOnlyArray",
    "broadcast_refusal",
    "broadcast_unit",
]
