"""What a generated client declares: one typed descriptor per register, at class level, and its codecs.

A client package declares each register once, on a class both its ``Client`` and its
``AsyncClient`` inherit::

    class Registers:
        motor_speed: ReadOnlyReg[int] = ReadOnlyReg('''Motor speed ...''')

    class Client(Registers, ClientBase[Snapshot]): ...
    class AsyncClient(Registers, AsyncClientBase[Snapshot]): ...

The descriptor is typed by the client it is read from (``drive.motor_speed`` is a
:class:`~drivemap.runtime.client.api.accessors.ReadOnly` of a ``Client``, an
:class:`~drivemap.runtime.client.api.accessors.AsyncReadOnly` of an ``AsyncClient``; the way pymodbus's
``ModbusClientMixin[T]`` writes its request API once), carries the register's docstring (so
``help(Client)`` and editors show it), and makes the accessor on first use: the client's machinery says
which accessor class a kind of register gets (``ClientMachinery.ACCESSORS``), the accessor is cached in
the instance, so later reads of ``drive.motor_speed`` are plain attribute lookups.

:func:`codecs_for` makes every register's codec from the spec and the package's value classes
(enums, flags, bit-field records), the same way for generated and dynamically built clients.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, Self, TypeVar, overload

from drivemap.runtime.client.api.descriptor import Reg
from drivemap.runtime.client.values.codec import (
    BoolCodec,
    Codec,
    EnumCodec,
    Field,
    FieldsCodec,
    FlagCodec,
    FloatCodec,
    IeeeCodec,
    IntCodec,
    OptionalCodec,
    ScaledCodec,
    StringCodec,
)
from drivemap.runtime.names import bit_attribute
from drivemap.runtime.spec import FLOAT_TYPES, DeviceSpec, RegisterSpec

if TYPE_CHECKING:
    from drivemap.runtime.client.api.accessors import (
        AsyncCommand,
        AsyncReadOnly,
        AsyncReadOnlyArray,
        AsyncReadWrite,
        AsyncReadWriteArray,
        AsyncReadWriteCommand,
        AsyncWriteOnly,
        AsyncWriteOnlyArray,
        Command,
        ReadOnly,
        ReadOnlyArray,
        ReadWrite,
        ReadWriteArray,
        ReadWriteCommand,
        WriteOnly,
        WriteOnlyArray,
    )
    from drivemap.runtime.client.api.async_client import AsyncClientBase
    from drivemap.runtime.client.api.sync_client import ClientBase

__all__ = [
    "BroadcastArrayReg",
    "BroadcastCommandReg",
    "BroadcastReg",
    "Codecs",
    "CommandReg",
    "ReadOnlyArrayReg",
    "ReadOnlyReg",
    "ReadWriteArrayReg",
    "ReadWriteCommandReg",
    "ReadWriteReg",
    "Reg",
    "WriteOnlyArrayReg",
    "WriteOnlyReg",
    "codec_for",
    "codecs_for",
    "kind_of",
]

T = TypeVar("T")
_INTEGER_TYPES = frozenset({"u16", "s16", "u32", "s32", "u64", "s64"})


class ReadOnlyReg(Reg[T]):
    """A read-only register (``read()``, ``read_raw()``)."""

    kind = "r"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> ReadOnly[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncReadOnly[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class WriteOnlyReg(Reg[T]):
    """A write-only register (``write()``, ``write_raw()``)."""

    kind = "w"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> WriteOnly[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncWriteOnly[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class ReadWriteReg(Reg[T]):
    """A register that is read and written (``read()``, ``write()``, ``modify()``)."""

    kind = "rw"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> ReadWrite[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncReadWrite[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class CommandReg(Reg[T]):
    """A write-only command register (``execute()``)."""

    kind = "cmd"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> Command[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncCommand[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class ReadWriteCommandReg(Reg[T]):
    """A readable command register (``read()``, ``execute()``)."""

    kind = "rwcmd"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> ReadWriteCommand[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncReadWriteCommand[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class ReadOnlyArrayReg(Reg[T]):
    """A read-only array register (indexable; ``read()`` reads every element)."""

    kind = "r[]"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> ReadOnlyArray[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncReadOnlyArray[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class WriteOnlyArrayReg(Reg[T]):
    """A write-only array register."""

    kind = "w[]"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> WriteOnlyArray[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncWriteOnlyArray[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class ReadWriteArrayReg(Reg[T]):
    """An array register that is read and written."""

    kind = "rw[]"

    @overload
    def __get__(self, client: None, owner: Any = None) -> Self: ...
    @overload
    def __get__(self, client: ClientBase[Any], owner: Any = None) -> ReadWriteArray[T]: ...
    @overload
    def __get__(self, client: AsyncClientBase[Any], owner: Any = None) -> AsyncReadWriteArray[T]: ...
    def __get__(self, client: Any, owner: Any = None) -> Any:
        return self if client is None else self._bind(client)


class BroadcastReg(WriteOnlyReg[T]):
    """A register a broadcast client may write."""


class BroadcastCommandReg(CommandReg[T]):
    """A command a broadcast client may send."""


class BroadcastArrayReg(WriteOnlyArrayReg[T]):
    """An array register a broadcast client may write."""


def kind_of(spec: RegisterSpec) -> str:
    """The accessor kind of a register (see :class:`Reg`)."""
    kind = spec.access
    if spec.command_value is not None and spec.count == 1 and kind != "r":
        kind = {"w": "cmd", "rw": "rwcmd"}[kind]
    return kind + "[]" if spec.count > 1 else kind


def broadcast_kind_of(spec: RegisterSpec) -> str:
    """The accessor kind of a register on a broadcast client (write-only forms)."""
    if spec.count > 1:
        return "w[]"
    return "cmd" if spec.command_value is not None else "w"


#: The descriptor class of each kind (dynamically built clients use these).
REG_CLASSES: dict[str, type[Reg[Any]]] = {
    "r": ReadOnlyReg, "w": WriteOnlyReg, "rw": ReadWriteReg, "cmd": CommandReg, "rwcmd": ReadWriteCommandReg,
    "r[]": ReadOnlyArrayReg, "w[]": WriteOnlyArrayReg, "rw[]": ReadWriteArrayReg,
}


def _plain_codec(device: DeviceSpec, spec: RegisterSpec, classes: dict[str, Any]) -> Codec[Any]:
    if spec.enum:
        return EnumCodec(spec, classes[spec.enum])
    if spec.bits:
        value_class = classes[spec.bits_class or ""]
        if any(b.width > 1 or b.enum for b in spec.bits):
            fields = [Field(bit_attribute(b.name), b.name, classes[b.enum] if b.enum else None) for b in spec.bits]
            return FieldsCodec(spec, value_class, fields)
        return FlagCodec(spec, value_class)
    if spec.type == "bool":
        return BoolCodec(spec)
    if spec.type == "string":
        return StringCodec(spec)
    if spec.type in FLOAT_TYPES:
        return IeeeCodec(spec)
    if spec.scale_register:
        return ScaledCodec(spec, device.register(spec.scale_register))
    if spec.type in _INTEGER_TYPES and float(spec.scale).is_integer() and float(spec.offset).is_integer():
        return IntCodec(spec)
    return FloatCodec(spec)


def codec_for(device: DeviceSpec, spec: RegisterSpec, classes: dict[str, Any]) -> Codec[Any]:
    """The codec of one register; ``classes`` are the package's enums and bit-field classes by name."""
    codec = _plain_codec(device, spec, classes)
    return OptionalCodec(codec) if spec.not_available else codec


class Codecs(Mapping[str, Codec[Any]]):
    """Register name -> codec, each made on first use and kept (the same object every time after).

    A client package's ``CODECS``: importing a 10,000-register client makes no codec until a register
    is read or written. Iteration follows the map's register order; an unknown name is a KeyError."""

    __slots__ = ("_classes", "_device", "_made")

    def __init__(self, device: DeviceSpec, classes: dict[str, Any]) -> None:
        self._device = device
        self._classes = classes
        self._made: dict[str, Codec[Any]] = {}

    def __getitem__(self, name: str) -> Codec[Any]:
        codec = self._made.get(name)
        if codec is None:  # setdefault: two threads making one codec keep the first
            codec = self._made.setdefault(name, codec_for(self._device, self._device.register(name), self._classes))
        return codec

    def __contains__(self, name: object) -> bool:
        try:
            self._device.register(name)  # type: ignore[arg-type]
        except (KeyError, TypeError):
            return False
        return True

    def __iter__(self) -> Iterator[str]:
        return (reg.name for reg in self._device.registers)

    def __len__(self) -> int:
        return len(self._device.registers)

    def __repr__(self) -> str:
        return f"<Codecs of {self._device.name}: {len(self)} registers, {len(self._made)} made>"


def codecs_for(device: DeviceSpec, *classes: type) -> Codecs:
    """Register name -> codec (raw value <-> Python value), for every register of ``device``, each
    made on first use (:class:`Codecs`).

    ``classes`` are the package's enums, flags and bit-field records (found by ``__name__``)."""
    return Codecs(device, {cls.__name__: cls for cls in classes})
