"""The runtime's working parts of a client, kept out of the client's namespace.

A generated ``Client`` has its public API (:class:`~.base.ClientCommon` and its sync and async
subclasses), its registers, and one private attribute, ``_drivemap``: the :class:`ClientMachinery`
of that client (its :class:`~.sansio.Core`, its read programs, what it reads and writes with). What
the runtime derives once per client *class* (plans, the snapshot table, compiled readers, the
registers it declares) is the class's :class:`ClassMachinery`, found by :func:`class_machinery`, not
stored on the class. So a register may take any name but ``_drivemap`` and the public API's.

The sync and async forms differ only in how an operation of the core runs on the bus: each client
base names its machinery with :func:`register_flavour` (:mod:`.sync_client`, :mod:`.async_client`).
"""

from __future__ import annotations

import dataclasses
import enum
import weakref
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

from drivemap.runtime.client.api.accessors import ArrayBase, ElementBase, Readable, SnapshotBase, encode_for_write
from drivemap.runtime.client.api.descriptor import Reg
from drivemap.runtime.client.protocol.planner import Key, ReadRequest, plan_reads
from drivemap.runtime.client.protocol.programs import Reader, compile_reader, exchanges
from drivemap.runtime.client.protocol.review import sign_checked, warn_review
from drivemap.runtime.client.protocol.sansio import Core, Deferred, RawItem, spec_tables
from drivemap.runtime.client.protocol.writes import element_writer, refusing_writer
from drivemap.runtime.client.values.codec import Codec, EnumCodec, FieldsCodec, FlagCodec, unwrap

if TYPE_CHECKING:
    from drivemap.runtime.spec import DeviceSpec

__all__ = ["ClassMachinery", "ClientMachinery", "Program", "class_machinery", "register_flavour", "without_programs"]

#: Read programs kept per client (distinct tuples of accessors passed to read()), and compiled per
#: client class (distinct tuples of keys).
_MAX_PROGRAMS = 1024
#: A client's program: the function of the client that reads (sync, or a coroutine function).
Program = Callable[..., Any]
#: (decode or None when scaled by a factor register, snapshot field or None, index in the field's tuple or -1)
Entry = tuple[Callable[[int], Any] | None, str | None, int]
C = TypeVar("C", bound=type)


class ClassMachinery:
    """What the runtime derives once per client class (each part on first use)."""

    def __init__(self, cls: type, flavour: type[ClientMachinery]) -> None:
        self.cls = cls
        #: the machinery of this class's clients (sync or async)
        self.flavour = flavour
        #: False: every read and write takes the general path (:func:`without_programs`)
        self.programs = True
        self.plans: dict[Any, tuple[ReadRequest, ...]] = {}
        self._readers: dict[Any, Reader | None] = {}
        self._table: dict[Key, Entry] | None = None
        self.shape: dict[str, int] = {}
        self._defaults: dict[str, Any] | None = None
        self._defaults_known = False
        self._names: frozenset[str] | None = None
        self._order: tuple[str, ...] = ()

    @property
    def spec(self) -> DeviceSpec:
        spec: DeviceSpec = self.cls.SPEC  # type: ignore[attr-defined]
        return spec

    def plan(self, keys: Iterable[Key] | None = None) -> tuple[ReadRequest, ...]:
        """The read requests for ``keys`` (all readable elements when None); computed once and cached."""
        cache = self.plans
        if keys is None:
            plan = cache.get(None)
            if plan is None:
                plan = cache[None] = self.plan(spec_tables(self.spec).all_keys)
            return plan
        if type(keys) is tuple:  # an accessor's keys: cached as given, skipping the frozenset
            plan = cache.get(keys)
            if plan is None:
                plan = cache[keys] = self.plan(list(keys))
            return plan
        wanted = frozenset(keys)
        plan = cache.get(wanted)
        if plan is None:
            plan = cache[wanted] = plan_reads(self.spec, wanted)
        return plan

    def registers(self) -> frozenset[str]:
        """The names of the registers the class declares (its :class:`~.descriptor.Reg` descriptors)."""
        names = self._names
        if names is None:
            found = {n for klass in self.cls.__mro__ for n, v in vars(klass).items() if isinstance(v, Reg)}
            self._order = tuple(r.name for r in self.spec.registers if r.name in found)
            names = self._names = frozenset(found)
        return names

    @property
    def register_order(self) -> tuple[str, ...]:
        """The declared registers in the map's order."""
        self.registers()
        return self._order

    def snapshot_table(self) -> dict[Key, Entry]:
        """Per readable element: (decode, snapshot field or None, index in the field's tuple or -1);
        decode is None for a register scaled by a scale-factor register (decoded with its factor).
        The count of an array field is ``shape[field]``."""
        table = self._table
        if table is None:
            cls: Any = self.cls
            names = {f.name for f in dataclasses.fields(cls.SNAPSHOT)}
            self.shape = {r.name: r.count for r in cls.SPEC.registers if r.name in names and r.is_array}
            table = self._table = {}
            for reg in cls.SPEC.registers:
                if reg.readable and reg.name in cls.CODECS:
                    field = reg.name if reg.name in names else None
                    codec = cls.CODECS[reg.name]
                    decode = codec.decode if codec.scale_key is None else None  # scaled: needs its factor
                    for i in range(reg.count):
                        table[(reg.name, i)] = (decode, field, i if reg.is_array else -1)
        return table

    def snapshot_defaults(self) -> dict[str, Any] | None:
        """Field values of an empty ``SNAPSHOT`` when building it without ``__init__`` is exact, else None.

        Exact for what the client template generates: a frozen dataclass whose fields all default to
        None (``_values`` aside), without ``__post_init__`` or ``__slots__``. Empty when the class
        uses :class:`SnapshotBase`'s ``__init__`` (``init=False``, what the template generates now):
        unset fields read their default from the class.
        """
        if self._defaults_known:
            return self._defaults
        snapshot = self.cls.SNAPSHOT  # type: ignore[attr-defined]
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
        self._defaults, self._defaults_known = defaults, True
        return defaults

    def compiled(self, kind: str, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...],
                 result: tuple[Key, ...] = ()) -> Reader | None:
        """The compiled reader of ``keys`` for this class (None: the general path), once per class."""
        cache = self._readers
        ck = (kind, keys, result)
        if ck in cache:
            return cache[ck]
        if len(cache) >= _MAX_PROGRAMS or not self.programs:
            return None
        cls: Any = self.cls
        table = self.snapshot_table()
        reader = cache[ck] = compile_reader(kind, keys, plan, spec_tables(cls.SPEC), cls.CODECS, table, self.shape,
                                            cls.SNAPSHOT, self.snapshot_defaults(), result)
        return reader


class ClientMachinery:
    """The working parts of one client (its ``_drivemap``): the core, read programs, the bus it runs on.

    The sync and async forms (:mod:`.sync_client`, :mod:`.async_client`) add how an operation runs on
    the bus: :meth:`general`, :meth:`read_raw_keys` and :meth:`write_raw_items`."""

    #: Whether the client's programs are coroutine functions.
    ASYNC: ClassVar[bool] = False
    #: The accessor class of each kind of register descriptor (:class:`~.descriptor.Reg`).
    ACCESSORS: ClassVar[Mapping[str, type[Any]]] = {}
    #: :class:`~.bus.Bus` or :class:`~.bus.AsyncBus`: what the client's constructors open.
    BUS: ClassVar[Any] = None

    def __init__(self, klass: ClassMachinery, bus: Any, core: Core, owns_bus: bool) -> None:
        self.klass = klass
        self.bus = bus
        self.core = core
        self.owns_bus = owns_bus
        cls: Any = klass.cls
        self.spec: DeviceSpec = cls.SPEC
        self.codecs: Mapping[str, Codec[Any]] = cls.CODECS
        self.snapshot_class: type[SnapshotBase] = cls.SNAPSHOT
        #: read programs: the accessors of a read() -> the program that reads them (keys checked once)
        self.programs: dict[tuple[Readable, ...], Program] = {}
        self.all_program: Program | None = None

    # -- what the sync and async forms define
    def general(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], how: str,
                finish: Callable[[Any, dict[Key, int]], Any]) -> tuple[Program, Callable[..., Any]]:
        """(the general read of ``keys``, its fallback after a program's replies)."""
        raise NotImplementedError

    def read_raw_keys(self, keys: Sequence[Key]) -> Any:
        """Raw values of ``keys`` (a dict; awaitable in the async form)."""
        raise NotImplementedError

    def write_raw_items(self, items: Sequence[RawItem]) -> Any:
        """Write raw values in the order given (awaitable in the async form)."""
        raise NotImplementedError

    # -- plans and snapshots
    def plan_for(self, keys: Sequence[Key]) -> tuple[ReadRequest, ...]:
        """The plan for ``keys``: the class's cached one, or this client's when it knows holes."""
        if self.core.holes:
            return self.core.plan_with_holes(keys)
        return (type(keys) is tuple and self.klass.plans.get(keys)) or self.klass.plan(keys)

    def snapshot(self, raw: Mapping[Key, int]) -> Any:
        """The client's ``Snapshot`` of raw values read."""
        klass = self.klass
        table = klass.snapshot_table()
        shape = klass.shape
        codecs = self.codecs
        values: dict[Key, Any] = {}
        fields: dict[str, Any] = {}
        arrays: dict[str, list[Any]] = {}
        for key, raw_value in raw.items():
            entry = table.get(key)
            if entry is None:  # not a readable element of the map: decode as before, no field
                values[key] = codecs[key[0]].decode(raw_value)
                continue
            decode, name, index = entry
            if decode is None:
                codec = codecs[key[0]]
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
        defaults = klass.snapshot_defaults()
        if defaults is None:
            return self.snapshot_class(_values=values, **fields)
        # what __init__ does, without its per-field setattr calls: only the fields read are stored when
        # the class's defaults are class attributes (SnapshotBase.__init__), else every default is copied
        snap = object.__new__(self.snapshot_class)
        state = snap.__dict__
        if defaults:
            state.update(defaults)
        state["_values"] = values
        state.update(fields)
        return snap

    # -- read programs (drivemap.runtime.client.protocol.programs)
    def bind(self, reader: Reader | None, general: Program, fallback: Callable[..., Any]) -> Program:
        """This client's program of ``reader`` (its requests prepared for this unit), else ``general``."""
        if reader is None:
            return general
        make = reader.make_async if self.ASYNC else reader.make_sync
        return make(exchanges(reader.plan, self.core.unit, self.spec.protocol.timing), general, fallback)

    def snapshot_program(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], visit: bool) -> Program:
        """The program of ``read(...)`` of ``keys`` (``visit``: ``read_all``, pages visited and restored)."""
        general, fallback = self.general(keys, plan, "visit" if visit else "read", _snapshot_of)
        return self.bind(self.klass.compiled("snapshot", keys, plan), general, fallback)

    def read_program(self, accessors: tuple[Readable, ...]) -> Program:
        """The program of ``read(*accessors)``: their keys, checked readable once; cached per tuple of
        accessors (the plan is the class's, cached per tuple of keys; with holes it is the client's)."""
        keys: list[Key] = []
        for acc in accessors:
            keys.extend(acc.read_keys)
        ktuple = tuple(keys)
        self.core.check_readable(ktuple)
        program = self.snapshot_program(ktuple, self.klass.plan(ktuple), False)
        if len(self.programs) < _MAX_PROGRAMS:
            self.programs[accessors] = program
        return program

    def read_all_program(self) -> Program:
        core = self.core
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        if core.tables.read_review:
            warn_review(core, core.tables.all_keys)
        program = self.all_program = self.snapshot_program(core.tables.all_keys, self.klass.plan(), True)
        return program

    def element_program(self, acc: Any) -> Program:
        """The program of ``acc.read()`` (an element or an array of this client), checked readable once."""
        keys: tuple[Key, ...] = acc.read_keys
        self.core.check_readable(keys)
        plan = self.klass.plan(keys)
        general, fallback = self.general(keys, plan, "read", _value_of(acc))
        if acc.codec is not self.codecs.get(acc.spec.name):
            return general
        kind, result = ("value", (acc.key,)) if isinstance(acc, ElementBase) else ("tuple", acc.keys)
        return self.bind(self.klass.compiled(kind, keys, plan, result), general, fallback)

    def element_writer(self, acc: Any) -> Callable[[Any, Any], Any]:
        """The writer of ``acc.write(value)`` for this client (:mod:`.writes`), else the general write."""
        writer = element_writer(self.core, acc, self.ASYNC) if self.klass.programs else None
        if writer is not None:
            return writer
        codec, key = acc.codec, acc.key
        if acc.spec.name in self.core.tables.under_review:  # refused before the value is looked at
            return refusing_writer(self.core, key, self.ASYNC)
        if self.ASYNC:
            async def general_async(client: Any, value: Any) -> None:
                await client._drivemap.write_raw_items([(key, encode_for_write(codec, value))])
            return general_async

        def general(client: Any, value: Any) -> None:
            client._drivemap.write_raw_items([(key, sign_checked(codec.spec, codec.encode(value)) if codec.scale_key is None
                                               else encode_for_write(codec, value))])
        return general

    def by_name_value(self, acc: Any, value: Any) -> int | Deferred:
        """The raw value of ``write_by_name``: ints are accepted for enums and flags, mappings for bit fields."""
        codec = unwrap(acc.codec)
        if isinstance(codec, (EnumCodec, FlagCodec)) and isinstance(value, int) and not isinstance(value, enum.Enum):
            value = (codec.enum_type if isinstance(codec, EnumCodec) else codec.flag_type)(value)
        elif isinstance(codec, FieldsCodec) and isinstance(value, Mapping):
            value = codec.data_type(**value)
        elif acc.spec.type == "bool" and isinstance(value, int) and value in (0, 1):
            value = bool(value)
        return encode_for_write(acc.codec, value)


_FLAVOURS: dict[type, type[ClientMachinery]] = {}
_CLASSES: weakref.WeakKeyDictionary[type, ClassMachinery] = weakref.WeakKeyDictionary()


def register_flavour(base: type, flavour: type[ClientMachinery]) -> None:
    """Clients of ``base`` (and its subclasses) run on ``flavour``'s machinery."""
    _FLAVOURS[base] = flavour


def class_machinery(cls: type) -> ClassMachinery:
    """The :class:`ClassMachinery` of a client class (made on first use, kept while the class lives)."""
    found = _CLASSES.get(cls)
    if found is None:
        flavour = next((_FLAVOURS[k] for k in cls.__mro__ if k in _FLAVOURS), None)
        if flavour is None:
            raise TypeError(f"{cls.__qualname__} is not a drivemap client class")
        found = _CLASSES[cls] = ClassMachinery(cls, flavour)
    return found


def without_programs(cls: C) -> C:
    """A subclass of the client class ``cls`` whose reads and writes all take the general path: planned,
    decoded and checked the general way, no compiled program (what the bench and the tests compare the
    programs against)."""
    general: C = type(f"General{cls.__name__}", (cls,), {"__doc__": cls.__doc__})  # type: ignore[assignment]
    class_machinery(general).programs = False
    return general


def _snapshot_of(client: Any, raw: dict[Key, int]) -> Any:
    return client._drivemap.snapshot(raw)


def _value_of(acc: Any) -> Callable[[Any, dict[Key, int]], Any]:
    """What ``acc.read()`` returns from the raw values read (an element's value, an array's tuple)."""
    if isinstance(acc, ArrayBase):
        return lambda client, raw: acc._decode_all(raw)
    codec, key, scale = acc.codec, acc.key, acc.codec.scale_key
    if scale is None:
        return lambda client, raw: codec.decode(raw[key])
    return lambda client, raw: codec.decode_scaled(raw[key], raw.get(scale))
