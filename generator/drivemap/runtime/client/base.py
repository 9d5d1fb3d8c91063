"""What the sync and async client bases share (:class:`ClientCommon`): accessors by name, plans,
snapshots, read programs (:mod:`drivemap.runtime.client.programs`) and the broadcast refusal.

:mod:`drivemap.runtime.client.sync_client` (sync) and :mod:`drivemap.runtime.client.async_client` (asyncio) build on it.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, ClassVar, Generic, Self, TypeVar

from drivemap.runtime.client.accessors import ArrayBase, ElementBase, Readable, SnapshotBase, encode_for_write
from drivemap.runtime.client.bus import Stats
from drivemap.runtime.client.codec import Codec, EnumCodec, FieldsCodec, FlagCodec, unwrap
from drivemap.runtime.client.descriptor import Reg
from drivemap.runtime.client.planner import Hole, Key, ReadRequest, plan_reads
from drivemap.runtime.client.programs import Reader, compile_reader, exchanges
from drivemap.runtime.client.quirks import accept as accept_reply_quirks
from drivemap.runtime.client.review import sign_checked, warn_review
from drivemap.runtime.client.sansio import Core, Deferred, PagePolicy, spec_tables
from drivemap.runtime.client.writes import element_writer, refusing_writer
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
_tables = spec_tables
#: Read programs kept per client (distinct tuples of accessors passed to read()), and compiled per
#: client class (distinct tuples of keys).
_MAX_PROGRAMS = 1024
#: A client's program: the function of the client that reads (sync, or a coroutine function).
Program = Callable[..., Any]


class ClientCommon(Generic[S, B]):
    """State, constructors and helpers shared by the sync and async client bases (written once for
    both, the bus class aside: ``_BUS``)."""

    SPEC: ClassVar[DeviceSpec]
    SNAPSHOT: ClassVar[type[SnapshotBase]] = SnapshotBase
    EXCEPTIONS: ClassVar[Mapping[int, type[DeviceException]]] = {}
    CODECS: ClassVar[Mapping[str, Codec[Any]]] = {}
    _plans: ClassVar[dict[Any, tuple[ReadRequest, ...]]]
    _shape: ClassVar[dict[str, int]]
    _table: ClassVar[dict[Key, tuple[Callable[[int], Any] | None, str | None, int]]]
    _defaults: ClassVar[dict[str, Any] | None]

    #: The accessor class of each kind of register descriptor (:class:`~.descriptor.Reg`).
    _ACCESSOR_CLASSES: ClassVar[Mapping[str, type[Any]]] = {}
    _register_names: ClassVar[frozenset[str]]
    _register_order: ClassVar[tuple[str, ...]]

    _core: Core
    #: :class:`~.bus.Bus` or :class:`~.bus.AsyncBus`: what the constructors below open.
    _BUS: ClassVar[Any]

    def __init__(self, bus: B, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.protocol.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.protocol.unit_min}..{spec.protocol.unit_max}"
                               + (f" (or fixed port units {list(spec.protocol.fixed_units)})" if spec.protocol.fixed_units else ""))
        self.bus = bus
        if spec.protocol.quirks:  # the map's non-standard reply forms, accepted on this bus (runtime.quirks)
            accept_reply_quirks(bus.client, spec.protocol.quirks)  # type: ignore[attr-defined]
        self._owns_bus = _owns_bus
        self._setup(unit, page_policy, _broadcast, bus.stats)  # type: ignore[attr-defined]

    @classmethod
    def tcp(cls, host: str, port: int = 502, unit: int = 1, *, timeout: float | None = None,
            retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client with its own Modbus TCP connection."""
        return cls(cls._BUS.tcp(host, port, timeout=timeout, retries=retries), unit, page_policy=page_policy,
                   _owns_bus=True)

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, unit: int = 1, *, timeout: float | None = None,
                     retries: int | None = None, page_policy: PagePolicy = "raise") -> Self:
        """A client behind a serial gateway that passes RTU frames over TCP."""
        return cls(cls._BUS.rtu_over_tcp(host, port, timeout=timeout, retries=retries), unit,
                   page_policy=page_policy, _owns_bus=True)

    @classmethod
    def serial(cls, port: str, unit: int = 1, *, timeout: float | None = None, retries: int | None = None,
               page_policy: PagePolicy = "raise", **overrides: Any) -> Self:
        """A client with its own serial line (mode, baud rate, parity: the map's defaults unless overridden)."""
        bus = cls._BUS.serial(port, cls.SPEC.protocol.serial, timeout=timeout, retries=retries, **overrides)
        return cls(bus, unit, page_policy=page_policy, _owns_bus=True)

    @property
    def stats(self) -> Stats:
        """Counters of the bus (shared by every client on it), adaptive-read splits included."""
        stats: Stats = self.bus.stats  # type: ignore[attr-defined]
        return stats

    def close(self) -> None:
        """Close the bus if this client opened it."""
        if self._owns_bus:
            self.bus.close()  # type: ignore[attr-defined]

    def _setup(self, unit: int, page_policy: PagePolicy, broadcast: bool, stats: Stats | None = None) -> None:
        self._core = Core(self.SPEC, unit, self.EXCEPTIONS, page_policy, broadcast, stats)
        #: read programs: the accessors of a read() -> the program that reads them (keys checked once)
        self._programs: dict[tuple[Readable, ...], Program] = {}
        self._all_program: Program | None = None

    @classmethod
    def _registers_declared(cls) -> frozenset[str]:
        """The names of the registers this client class declares (its :class:`~.declare.Reg` descriptors)."""
        names: frozenset[str] | None = cls.__dict__.get("_register_names")
        if names is None:
            found = {n for klass in cls.__mro__ for n, v in vars(klass).items() if isinstance(v, Reg)}
            cls._register_order = tuple(r.name for r in cls.SPEC.registers if r.name in found)
            names = cls._register_names = frozenset(found)
        return names

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
        """Accessor by register name (in the map's order)."""
        self._registers_declared()
        return {name: getattr(self, name) for name in self._register_order}

    def accessor(self, name: str) -> Any:
        """The accessor for ``"name"`` or ``"name[i]"``."""
        base, _, rest = name.partition("[")
        if base not in self._registers_declared():
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

    # -- read programs (drivemap.runtime.client.programs)
    #: Whether the client's programs are coroutine functions (AsyncClientBase).
    _ASYNC: ClassVar[bool] = False
    #: Whether reads run compiled programs; False: every read takes the general path (the bench's
    #: client-overhead section measures both side by side, which is why the programs are kept).
    _PROGRAMS: ClassVar[bool] = True

    @classmethod
    def _compiled(cls, kind: str, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...],
                  result: tuple[Key, ...] = ()) -> Reader | None:
        """The compiled reader of ``keys`` for this class (None: the general path), once per class."""
        cache: dict[Any, Reader | None] | None = cls.__dict__.get("_readers")
        if cache is None:
            cache = {}
            cls._readers = cache  # type: ignore[attr-defined]
        ck = (kind, keys, result)
        if ck in cache:
            return cache[ck]
        if len(cache) >= _MAX_PROGRAMS or not cls._PROGRAMS:
            return None
        table = cls._snapshot_table()
        reader = cache[ck] = compile_reader(kind, keys, plan, _tables(cls.SPEC), cls.CODECS, table, cls._shape,
                                            cls.SNAPSHOT, cls._snapshot_defaults(), result)
        return reader

    def _bind(self, reader: Reader | None, general: Program, fallback: Callable[..., Any]) -> Program:
        """This client's program of ``reader`` (its requests prepared for this unit), else ``general``."""
        if reader is None:
            return general
        make = reader.make_async if self._ASYNC else reader.make_sync
        return make(exchanges(reader.plan, self._core.unit, self.SPEC.protocol.timing), general, fallback)

    def _snapshot_program(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], visit: bool) -> Program:
        """The program of ``read(...)`` of ``keys`` (``visit``: ``read_all``, pages visited and restored)."""
        general, fallback = self._general(keys, plan, "visit" if visit else "read", _snapshot_of)
        return self._bind(self._compiled("snapshot", keys, plan), general, fallback)

    def _read_program(self, accessors: tuple[Readable, ...]) -> Program:
        """The program of ``read(*accessors)``: their keys, checked readable once; cached per tuple of
        accessors (the plan is the class's, cached per tuple of keys; with holes it is the client's)."""
        keys = tuple(self._keys(accessors))
        self._core.check_readable(keys)
        program = self._snapshot_program(keys, self.plan(keys), False)
        if len(self._programs) < _MAX_PROGRAMS:
            self._programs[accessors] = program
        return program

    def _read_all_program(self) -> Program:
        core = self._core
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        if core.tables.read_review:
            warn_review(core, core.tables.all_keys)
        program = self._all_program = self._snapshot_program(core.tables.all_keys, self.plan(), True)
        return program

    def _element_program(self, acc: Any) -> Program:
        """The program of ``acc.read()`` (an element or an array of this client), checked readable once."""
        keys: tuple[Key, ...] = acc.read_keys
        self._core.check_readable(keys)
        plan = self.plan(keys)
        general, fallback = self._general(keys, plan, "read", _value_of(acc))
        if acc.codec is not self.CODECS.get(acc.spec.name):
            return general
        kind, result = ("value", (acc.key,)) if isinstance(acc, ElementBase) else ("tuple", acc.keys)
        return self._bind(self._compiled(kind, keys, plan, result), general, fallback)

    def _element_writer(self, acc: Any) -> Callable[[Any, Any], Any]:
        """The writer of ``acc.write(value)`` for this client (:mod:`.writes`), else the general write."""
        writer = element_writer(self._core, acc, self._ASYNC)
        if writer is not None:
            return writer
        codec, key = acc.codec, acc.key
        if acc.spec.name in self._core.tables.under_review:  # refused before the value is looked at
            return refusing_writer(self._core, key, self._ASYNC)
        if self._ASYNC:
            async def general_async(client: Any, value: Any) -> None:
                await client._write_raw_items([(key, encode_for_write(codec, value))])
            return general_async

        def general(client: Any, value: Any) -> None:
            client._write_raw_items([(key, sign_checked(codec.spec, codec.encode(value)) if codec.scale_key is None
                                     else encode_for_write(codec, value))])
        return general

    def _general(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], how: str,
                 finish: Callable[[Any, dict[Key, int]], Any]) -> tuple[Program, Callable[..., Any]]:
        """(the general read of ``keys``, its fallback after a program's replies); see the subclasses."""
        raise NotImplementedError

    def _by_name_value(self, acc: Any, value: Any) -> int | Deferred:
        codec = unwrap(acc.codec)
        if isinstance(codec, (EnumCodec, FlagCodec)) and isinstance(value, int) and not isinstance(value, enum.Enum):
            value = (codec.enum_type if isinstance(codec, EnumCodec) else codec.flag_type)(value)
        elif isinstance(codec, FieldsCodec) and isinstance(value, Mapping):
            value = codec.data_type(**value)
        elif acc.spec.type == "bool" and isinstance(value, int) and value in (0, 1):
            value = bool(value)
        return encode_for_write(acc.codec, value)



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



def _snapshot_of(client: Any, raw: dict[Key, int]) -> Any:
    return client._snapshot(raw)


def _value_of(acc: Any) -> Callable[[Any, dict[Key, int]], Any]:
    """What ``acc.read()`` returns from the raw values read (an element's value, an array's tuple)."""
    if isinstance(acc, ArrayBase):
        return lambda client, raw: acc._decode_all(raw)
    codec, key, scale = acc.codec, acc.key, acc.codec.scale_key
    if scale is None:
        return lambda client, raw: codec.decode(raw[key])
    return lambda client, raw: codec.decode_scaled(raw[key], raw.get(scale))
