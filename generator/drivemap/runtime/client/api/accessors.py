"""Typed accessors of generated clients: one per register (``client.motor_speed``), and the snapshot base.

:class:`ReadOnly`, :class:`WriteOnly`, :class:`ReadWrite` and their ``Array`` and ``Async`` forms;
read-only accessors have no ``write``. An accessor of a register scaled by a scale-factor register
reads that register with it (``read_keys``) and defers the raw value of a write until the factor
has been read (:class:`~drivemap.runtime.client.protocol.sansio.Deferred`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, ClassVar, Generic, TypeVar, overload

from drivemap.runtime.client.protocol.planner import Key
from drivemap.runtime.client.protocol.review import sign_checked
from drivemap.runtime.client.protocol.sansio import Deferred
from drivemap.runtime.client.values.codec import Codec, RawCodec
from drivemap.runtime.errors import DriveError, IndexOutOfRange, InvalidValue, UnsupportedFunction
from drivemap.runtime.spec import RegisterSpec

T = TypeVar("T")


def encode_for_write(codec: Codec[T], value: T) -> int | Deferred:
    """The raw value to write, or a :class:`Deferred` one when it needs the scale factor (checked now)."""
    if codec.scale_key is None:
        return sign_checked(codec.spec, codec.encode(value))
    codec.check(value)
    return Deferred(value, codec)


@dataclasses.dataclass(frozen=True, init=False)
class SnapshotBase:
    """Values read together; generated subclasses add one typed field per readable register.

    ``snap.motor_speed`` is the value (None when not read; a tuple for arrays), ``snap[acc]`` the
    value of one accessor, typed.

    Generated subclasses are frozen dataclasses declared with ``init=False``: they share this
    ``__init__``, which takes any of their fields by keyword, so a map of N registers does not
    generate (and compile at import) an ``__init__`` of N parameters, whose cost grows with N².
    An instance stores only the fields given; the others are the class's default, None.
    """

    _values: Mapping[Key, Any] = dataclasses.field(default_factory=dict, repr=False, compare=False)

    def __init__(self, _values: Mapping[Key, Any] | None = None, **fields: Any) -> None:
        names = _field_names(type(self))
        for name in fields:
            if name not in names:
                raise TypeError(f"{type(self).__name__}.__init__() got an unexpected keyword argument {name!r}")
        state = self.__dict__
        state["_values"] = {} if _values is None else _values
        state.update(fields)

    def __repr__(self) -> str:
        shown = ", ".join(
            f"{f.name}={getattr(self, f.name)!r}" for f in dataclasses.fields(self)
            if f.name != "_values" and getattr(self, f.name) is not None
        )
        return f"{type(self).__name__}({shown})"

    @overload
    def __getitem__(self, accessor: ElementBase[T]) -> T: ...
    @overload
    def __getitem__(self, accessor: ArrayBase[T, Any]) -> tuple[T, ...]: ...
    def __getitem__(self, accessor: ElementBase[T] | ArrayBase[T, Any]) -> T | tuple[T, ...]:
        if isinstance(accessor, ArrayBase):
            return tuple(self._values[k] for k in accessor.keys)
        return self._values[accessor.key]  # type: ignore[no-any-return]



_FIELD_NAMES: dict[type, frozenset[str]] = {}


def _field_names(cls: type) -> frozenset[str]:
    """The dataclass field names of a snapshot class (computed once per class)."""
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = frozenset(f.name for f in dataclasses.fields(cls)) - {"_values"}
    return names


class ElementBase(Generic[T]):
    """One register (or one array element) of one client."""

    #: The client's read program of this element (:mod:`.programs`), made on the first read.
    _program: Callable[[Any], Any] | None = None
    #: The client's writer of this element (:mod:`.writes`), made on the first write.
    _writer: Callable[[Any, Any], Any] | None = None

    def __init__(self, owner: Any, codec: Codec[T], index: int = 0) -> None:
        self._owner = owner
        self.codec = codec
        self.spec = codec.spec
        self.index = index
        self._key: Key = (codec.spec.name, index)
        self._keys: tuple[Key, ...] = (self._key,)
        self._scale = codec.scale_key
        self._read_keys: tuple[Key, ...] = self._keys if self._scale is None else (self._key, self._scale)

    @property
    def key(self) -> Key:
        return self._key

    @property
    def keys(self) -> tuple[Key, ...]:
        return self._keys

    @property
    def read_keys(self) -> tuple[Key, ...]:
        """What a read of this element reads: the element, and its scale factor if it has one."""
        return self._read_keys

    @property
    def name(self) -> str:
        return self.spec.element_name(self.index)

    @property
    def address(self) -> int:
        return self.spec.element_address(self.index)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} @0x{self.address:04X}>"


class ReadOnly(ElementBase[T]):
    """A readable register: ``read()`` gives the engineering value, ``read_raw()`` the raw one."""

    def read(self) -> T:
        program = self._program
        if program is None:
            program = self._program = self._owner._drivemap.element_program(self)
        return program(self._owner)  # type: ignore[no-any-return]

    def read_raw(self) -> int:
        return self._owner._drivemap.read_raw_keys(self._keys)[self._key]  # type: ignore[no-any-return]


class WriteOnly(ElementBase[T]):
    """A writable register; ``write`` checks type, range and access before sending."""

    def write(self, value: T) -> None:
        writer = self._writer
        if writer is None:
            writer = self._writer = self._owner._drivemap.element_writer(self)
        writer(self._owner, value)

    def write_raw(self, raw: int) -> None:
        self._owner._drivemap.write_raw_items([(self.key, RawCodec(self.spec).encode(raw))])


class ReadWrite(ReadOnly[T], WriteOnly[T]):
    """A register that is read and written."""

    def modify(self, update: Callable[[T], T]) -> T:
        """Read, apply ``update`` and write the result back (read-modify-write); returns it."""
        return self._owner.read_modify_write(self, update)  # type: ignore[no-any-return]


class Command(WriteOnly[T]):
    """A command register (the map's ``command``): ``execute()`` writes the map's command value;
    ``write`` / ``write_raw`` refuse any other value before sending."""

    def execute(self) -> None:
        """Send the command (write the map's command value)."""
        self._owner._drivemap.write_raw_items([(self._key, _command_value(self.spec))])


class ReadWriteCommand(ReadWrite[T], Command[T]):
    """A readable command register: :class:`Command` plus ``read``."""


def _command_value(spec: RegisterSpec) -> int:
    if spec.command_value is None:
        raise UnsupportedFunction(f"{spec.name} is not a command register")
    return spec.command_value


E_co = TypeVar("E_co", bound=ElementBase[Any])


class ArrayBase(Generic[T, E_co]):
    """An array register: indexable; ``read()``/``write()`` handle all elements at once."""

    element_type: ClassVar[type[ElementBase[Any]]] = ElementBase
    #: The client's read program of the whole array (:mod:`.programs`), made on the first read.
    _program: Callable[[Any], Any] | None = None

    def __init__(self, owner: Any, codec: Codec[T]) -> None:
        self._owner = owner
        self.codec = codec
        self.spec = codec.spec
        self._elements = [self.element_type(owner, codec, i) for i in range(codec.spec.count)]
        self._keys: tuple[Key, ...] = tuple((codec.spec.name, i) for i in range(codec.spec.count))
        self._scale = codec.scale_key
        self._read_keys = self._keys if self._scale is None else self._keys + (self._scale,)

    def __getitem__(self, index: int) -> E_co:
        try:
            if index >= 0:
                return self._elements[index]  # type: ignore[return-value]
        except (IndexError, TypeError):
            pass
        raise self._bad_index(index)

    def _bad_index(self, index: object) -> DriveError:
        """The error for ``self[index]`` when ``index`` is not an element (Python's negative indexing is not)."""
        if isinstance(index, bool) or not isinstance(index, int):
            return InvalidValue(f"{self.name}: an element index is an int, not {type(index).__name__}")
        count = len(self._elements)
        return IndexOutOfRange(f"{self.name}[{index}]: no such element; {self.name} has {count} elements "
                               f"(index 0..{count - 1})")

    def __len__(self) -> int:
        return len(self._elements)

    def __iter__(self) -> Iterator[E_co]:
        return iter(self._elements)  # type: ignore[arg-type]

    @property
    def keys(self) -> tuple[Key, ...]:
        return self._keys

    @property
    def read_keys(self) -> tuple[Key, ...]:
        return self._read_keys

    @property
    def name(self) -> str:
        return self.spec.name

    def _decode_all(self, raw: Mapping[Key, int]) -> tuple[T, ...]:
        codec = self.codec
        if self._scale is None:
            return tuple(codec.decode(raw[k]) for k in self._keys)
        factor = raw.get(self._scale)
        return tuple(codec.decode_scaled(raw[k], factor) for k in self._keys)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}[{len(self)}] @0x{self.spec.address:04X}>"


class _ReadArrayMixin(ArrayBase[T, E_co]):
    def read(self) -> tuple[T, ...]:
        program = self._program
        if program is None:
            program = self._program = self._owner._drivemap.element_program(self)
        return program(self._owner)  # type: ignore[no-any-return]


def _refuse_open(owner: Any, name: str, keys: Sequence[Key]) -> None:
    """:class:`OpenForReview` for a register open for review (``review:``), before its values are looked at."""
    core = owner._drivemap.core
    if name in core.tables.under_review:
        core.check_write(keys[0])


class _WriteArrayMixin(ArrayBase[T, E_co]):
    def write(self, values: Sequence[T]) -> None:
        """Write every element (one 10h request where the map allows it)."""
        if len(values) != len(self):
            raise InvalidValue(f"{self.name}: expected {len(self)} values, got {len(values)}")
        _refuse_open(self._owner, self.spec.name, self.keys)
        self._owner._drivemap.write_raw_items([(k, encode_for_write(self.codec, v)) for k, v in zip(self.keys, values, strict=True)])


class ReadOnlyArray(_ReadArrayMixin[T, ReadOnly[T]]):
    element_type = ReadOnly


class WriteOnlyArray(_WriteArrayMixin[T, WriteOnly[T]]):
    element_type = WriteOnly


class ReadWriteArray(_ReadArrayMixin[T, ReadWrite[T]], _WriteArrayMixin[T, ReadWrite[T]]):
    element_type = ReadWrite


class AsyncReadOnly(ElementBase[T]):
    """Async form of :class:`ReadOnly`."""

    async def read(self) -> T:
        program = self._program
        if program is None:
            program = self._program = self._owner._drivemap.element_program(self)
        return await program(self._owner)  # type: ignore[no-any-return]

    async def read_raw(self) -> int:
        return (await self._owner._drivemap.read_raw_keys(self.keys))[self.key]  # type: ignore[no-any-return]


class AsyncWriteOnly(ElementBase[T]):
    """Async form of :class:`WriteOnly`."""

    async def write(self, value: T) -> None:
        writer = self._writer
        if writer is None:
            writer = self._writer = self._owner._drivemap.element_writer(self)
        await writer(self._owner, value)

    async def write_raw(self, raw: int) -> None:
        await self._owner._drivemap.write_raw_items([(self.key, RawCodec(self.spec).encode(raw))])


class AsyncReadWrite(AsyncReadOnly[T], AsyncWriteOnly[T]):
    """Async form of :class:`ReadWrite`."""

    async def modify(self, update: Callable[[T], T]) -> T:
        return await self._owner.read_modify_write(self, update)  # type: ignore[no-any-return]


class AsyncCommand(AsyncWriteOnly[T]):
    """Async form of :class:`Command`."""

    async def execute(self) -> None:
        """Send the command (write the map's command value)."""
        await self._owner._drivemap.write_raw_items([(self._key, _command_value(self.spec))])


class AsyncReadWriteCommand(AsyncReadWrite[T], AsyncCommand[T]):
    """Async form of :class:`ReadWriteCommand`."""


class _AsyncReadArrayMixin(ArrayBase[T, E_co]):
    async def read(self) -> tuple[T, ...]:
        program = self._program
        if program is None:
            program = self._program = self._owner._drivemap.element_program(self)
        return await program(self._owner)  # type: ignore[no-any-return]


class _AsyncWriteArrayMixin(ArrayBase[T, E_co]):
    async def write(self, values: Sequence[T]) -> None:
        if len(values) != len(self):
            raise InvalidValue(f"{self.name}: expected {len(self)} values, got {len(values)}")
        _refuse_open(self._owner, self.spec.name, self.keys)
        await self._owner._drivemap.write_raw_items([(k, encode_for_write(self.codec, v))
                                            for k, v in zip(self.keys, values, strict=True)])


class AsyncReadOnlyArray(_AsyncReadArrayMixin[T, AsyncReadOnly[T]]):
    element_type = AsyncReadOnly


class AsyncWriteOnlyArray(_AsyncWriteArrayMixin[T, AsyncWriteOnly[T]]):
    element_type = AsyncWriteOnly


class AsyncReadWriteArray(_AsyncReadArrayMixin[T, AsyncReadWrite[T]], _AsyncWriteArrayMixin[T, AsyncReadWrite[T]]):
    element_type = AsyncReadWrite


Readable = ElementBase[Any] | ArrayBase[Any, Any]


__all__ = [
    "AsyncReadOnly",
    "AsyncReadOnlyArray",
    "AsyncReadWrite",
    "AsyncReadWriteArray",
    "AsyncWriteOnly",
    "AsyncWriteOnlyArray",
    "ReadOnly",
    "ReadOnlyArray",
    "ReadWrite",
    "ReadWriteArray",
    "Readable",
    "SnapshotBase",
    "WriteOnly",
    "WriteOnlyArray",
    "encode_for_write",
]
