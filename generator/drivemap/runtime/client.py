"""The client runtime that generated ``Client`` / ``AsyncClient`` classes build on.

Protocol behaviour lives in :class:`Core`, written once as generators ("sans I/O"): an operation
yields :class:`~drivemap.runtime.bus.Exchange` requests and receives the replies; :class:`ClientBase`
runs it on a :class:`Bus`, :class:`AsyncClientBase` on an :class:`AsyncBus`. Every check on the
caller's input happens before the first request is yielded, so a bad value never sends a byte.

Generated packages subclass the bases, declare one typed accessor per register
(:class:`ReadOnly`, :class:`WriteOnly`, :class:`ReadWrite` and their ``Array`` and ``Async``
forms; read-only accessors have no ``write``) and a frozen ``Snapshot`` dataclass for
:meth:`ClientBase.read`.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping, Sequence
from typing import Any, ClassVar, Generic, Literal, Self, TypeVar, overload

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.diag_message import ReturnQueryDataRequest
from pymodbus.pdu.register_message import (
    ReadHoldingRegistersRequest,
    ReadInputRegistersRequest,
    WriteMultipleRegistersRequest,
    WriteSingleRegisterRequest,
)

from .bus import AsyncBus, Bus, Exchange, Stats
from .codec import Codec, EnumCodec, FieldsCodec, FlagCodec, RawCodec, raw_to_words, words_to_raw
from .errors import (
    BroadcastRead,
    DeviceException,
    DriveError,
    IndexOutOfRange,
    InvalidArgument,
    InvalidValue,
    NotBroadcastable,
    PartialWrite,
    ReadOnlyRegister,
    TransportError,
    UnknownRegister,
    UnsupportedFunction,
    ValueOutOfRange,
    WriteOnlyRegister,
    WrongPage,
)
from .planner import Key, ReadRequest, max_write_words, plan_reads, read_function, units
from .spec import DeviceSpec, FunctionSpec, PageSpec, RegisterSpec

log = logging.getLogger("drivemap")

T = TypeVar("T")
S = TypeVar("S", bound="SnapshotBase")
PagePolicy = Literal["raise", "switch"]
Op = Generator[Exchange, "ModbusPDU | None", T]


# ----------------------------------------------------------------------------- snapshot
@dataclasses.dataclass(frozen=True)
class SnapshotBase:
    """Values read together; generated subclasses add one typed field per readable register.

    ``snap.motor_speed`` is the value (None when not read; a tuple for arrays), ``snap[acc]`` the
    value of one accessor, typed.
    """

    _values: Mapping[Key, Any] = dataclasses.field(default_factory=dict, repr=False, compare=False)

    def __repr__(self) -> str:
        shown = ", ".join(
            f"{f.name}={getattr(self, f.name)!r}" for f in dataclasses.fields(self)
            if f.name != "_values" and getattr(self, f.name) is not None
        )
        return f"{type(self).__name__}({shown})"

    @overload
    def __getitem__(self, accessor: _Element[T]) -> T: ...
    @overload
    def __getitem__(self, accessor: _Array[T, Any]) -> tuple[T, ...]: ...
    def __getitem__(self, accessor: _Element[T] | _Array[T, Any]) -> T | tuple[T, ...]:
        if isinstance(accessor, _Array):
            return tuple(self._values[k] for k in accessor.keys)
        return self._values[accessor.key]  # type: ignore[no-any-return]


# ----------------------------------------------------------------------------- per-spec tables
@dataclasses.dataclass(frozen=True)
class _SpecTables:
    """What the per-call path needs from a :class:`DeviceSpec`, computed once per spec."""

    readable: frozenset[str]
    """Names of the readable registers."""
    selectors: frozenset[str]
    """Names of the registers that select a page of some register."""
    read_code: int | None
    """The read function code (:func:`read_function`), None when the map lists none."""
    read_request: type[ModbusPDU] | None
    all_keys: tuple[Key, ...]
    """Every readable element, in :func:`planner.units` order (what ``read_all`` reads)."""
    decode: Mapping[str, tuple[int, bool, bool, bool]]
    """Per readable register: (words, signed, low word first, is a page selector)."""
    fc06: FunctionSpec | None
    fc10: FunctionSpec | None
    write_limit: int
    """:func:`max_write_words` of the spec."""


_TABLES: dict[int, tuple[DeviceSpec, _SpecTables]] = {}


def _tables(spec: DeviceSpec) -> _SpecTables:
    """The tables of ``spec`` (cached by identity; specs are module-level constants)."""
    hit = _TABLES.get(id(spec))
    if hit is not None and hit[0] is spec:
        return hit[1]
    selectors = frozenset(r.page.selector for r in spec.registers if r.page is not None)
    code = read_function(spec)
    tables = _SpecTables(
        readable=frozenset(r.name for r in spec.registers if r.readable),
        selectors=selectors,
        read_code=code,
        read_request=None if code is None else (ReadHoldingRegistersRequest if code == 0x03
                                                 else ReadInputRegistersRequest),
        all_keys=tuple(u.key for u in units(spec) if u.key),
        decode={r.name: (r.words, r.signed, r.word_order == "low_first", r.name in selectors)
                for r in spec.registers if r.readable},
        fc06=spec.function(0x06),
        fc10=spec.function(0x10),
        write_limit=max_write_words(spec),
    )
    _TABLES[id(spec)] = (spec, tables)
    return tables


# ----------------------------------------------------------------------------- core
class Core:
    """Per-client protocol state and the operations, as generators of exchanges."""

    def __init__(self, spec: DeviceSpec, unit: int, exceptions: Mapping[int, type[DeviceException]],
                 page_policy: PagePolicy, broadcast: bool) -> None:
        if not isinstance(page_policy, str) or page_policy not in ("raise", "switch"):
            raise InvalidArgument(f"page_policy must be 'raise' or 'switch', not {page_policy!r}")
        self.spec = spec
        self.unit = unit
        self.exceptions = exceptions
        self.page_policy = page_policy
        self.broadcast = broadcast
        self.tables = _tables(spec)
        self.pages: dict[str, int] = {}  # selector -> value it is known to show
        self.pending_configuration: list[str] = []
        self.pending_power_cycle: list[str] = []

    # -- checks and replies
    def raise_for(self, reply: ModbusPDU | None, function: int) -> ModbusPDU:
        if reply is None:
            raise TransportError(f"no reply to function 0x{function:02X}")
        if reply.isError():
            code = reply.exception_code
            cls = self.exceptions.get(code, DeviceException)
            known = self.spec.exception(code)
            raise cls(code, function, name=known.name if known else None, meaning=known.meaning if known else None)
        return reply

    def exchange(self, pdu: ModbusPDU, hold_ms: float = 0.0) -> Exchange:
        return Exchange(self.unit, pdu, self.spec.timing, not self.broadcast, hold_ms)

    # -- pages
    def _page_ops(self, page: PageSpec | None) -> Op[None]:
        if page is None:
            return
        current = self.pages.get(page.selector)
        if current == page.value:
            return
        sel = self.spec.register(page.selector)
        if self.page_policy == "switch":
            yield from self._write_words(sel.address, raw_to_words(sel, page.value), hold_ms=sel.write_delay_ms or 0)
            self.pages[page.selector] = page.value
            return
        if current is None and not self.broadcast and sel.readable:
            words = yield from self._read_words(sel.address, sel.words)
            current = self.pages[page.selector] = words_to_raw(sel, words)
            if current == page.value:
                return
        raise WrongPage(f"{page.selector} shows page {current}, not {page.value} (use page_policy='switch')")

    def _read_words(self, address: int, count: int) -> Op[list[int]]:
        code = self.tables.read_code
        cls = self.tables.read_request
        if code is None or cls is None:
            raise UnsupportedFunction("the map lists no read function (03h/04h)")
        reply = yield Exchange(self.unit, cls(address=address, count=count), self.spec.timing,
                               expect_reply=not self.broadcast)
        if reply is None or reply.isError():
            reply = self.raise_for(reply, code)
        registers = reply.registers
        if len(registers) != count:
            raise TransportError(f"asked {count} registers at 0x{address:04X}, got {len(registers)}")
        return list(registers)

    def _write_request(self, address: int, words: list[int]) -> tuple[ModbusPDU, int]:
        """The write request for ``words`` at ``address`` (06h for one word where possible, else 10h)."""
        fc06, fc10 = self.tables.fc06, self.tables.fc10
        if len(words) == 1 and fc06 is not None and (not self.broadcast or fc06.broadcast):
            return WriteSingleRegisterRequest(address=address, registers=words), 0x06
        if fc10 is not None and (not self.broadcast or fc10.broadcast):
            return WriteMultipleRegistersRequest(address=address, registers=words), 0x10
        raise UnsupportedFunction(f"no function code of the map writes {len(words)} word(s) here")

    def _write_words(self, address: int, words: list[int], hold_ms: float = 0.0) -> Op[None]:
        """One write request (06h for one word where possible, else 10h)."""
        pdu, code = self._write_request(address, words)
        reply = yield self.exchange(pdu, hold_ms)
        if not self.broadcast:
            self.raise_for(reply, code)

    # -- reads
    def check_readable(self, keys: Iterable[Key]) -> None:
        if self.broadcast:
            raise BroadcastRead("a broadcast client cannot read (nobody answers a broadcast)")
        readable = self.tables.readable
        for name, _ in keys:
            if name not in readable:
                self.spec.register(name)  # KeyError for a name the map does not have
                raise WriteOnlyRegister(f"{name} is write-only")

    def read_raw(self, keys: Sequence[Key], plan: tuple[ReadRequest, ...], *,
                 checked: bool = False) -> Op[dict[Key, int]]:
        """Read ``keys`` with ``plan``; ``checked``: the caller has already run :meth:`check_readable`."""
        if not checked:
            self.check_readable(keys)
        tables = self.tables
        decode = tables.decode
        request = tables.read_request
        pages = self.pages
        unit, timing, expect_reply = self.unit, self.spec.timing, not self.broadcast
        out: dict[Key, int] = {}
        for req in plan:
            if req.page is not None:
                yield from self._page_ops(req.page)
            # _read_words, inlined: this loop is every read's path
            if request is None or tables.read_code is None:
                raise UnsupportedFunction("the map lists no read function (03h/04h)")
            count = req.count
            reply = yield Exchange(unit, request(address=req.address, count=count), timing, expect_reply)
            if reply is None or reply.isError():
                reply = self.raise_for(reply, tables.read_code)
            words = reply.registers
            if len(words) != count:
                raise TransportError(f"asked {count} registers at 0x{req.address:04X}, got {len(words)}")
            for key, offset in req.cells:
                size, signed, low_first, selector = decode[key[0]]
                if size == 1:
                    raw = words[offset]
                    if signed and raw & 0x8000:
                        raw -= 0x10000
                else:
                    first, second = words[offset], words[offset + 1]
                    raw = (second << 16) | first if low_first else (first << 16) | second
                    if signed and raw & 0x80000000:
                        raw -= 0x100000000
                out[key] = raw
                if selector:
                    pages[key[0]] = raw
        return out

    # -- writes
    def check_write(self, key: Key) -> RegisterSpec:
        reg = self.spec.register(key[0])
        if not reg.writable:
            raise ReadOnlyRegister(f"{reg.element_name(key[1])} is read-only")
        if self.broadcast and not reg.broadcast:
            raise NotBroadcastable(f"{reg.element_name(key[1])} may not be written by broadcast")
        return reg

    @staticmethod
    def not_the_command(reg: RegisterSpec, key: Key, raw: object) -> ValueOutOfRange:
        """A command register written with another value than the map's command value."""
        return ValueOutOfRange(f"{reg.element_name(key[1])} is a command: only {reg.command_value} may be written "
                               f"(use .execute()), not {raw!r}")

    def write_raw(self, items: Sequence[tuple[Key, int]]) -> Op[None]:
        """Write raw values, contiguous runs in one 10h request where the map allows it.

        Requests go out in address order and stop at the first failure. When the write needed
        several requests, that failure is raised as :class:`PartialWrite` (written / unconfirmed /
        not written elements); a single request raises its own error (all or nothing).
        """
        limit = self.tables.write_limit
        if self.broadcast and not (self.tables.fc10 and self.tables.fc10.broadcast):
            limit = 0
        if len(items) == 1:  # one element: one request, all or nothing (the common case, kept lean)
            key, raw = items[0]
            reg = self.check_write(key)
            if reg.command_value is not None and raw != reg.command_value:
                raise self.not_the_command(reg, key, raw)
            words = raw_to_words(reg, raw)
            if len(words) > 1 and limit == 0:
                raise UnsupportedFunction(f"{reg.name}: the map has no 10h for a multi-word write")
            if reg.page is not None:
                yield from self._page_ops(reg.page)
            pdu, code = self._write_request(reg.element_address(key[1]), words)  # _write_words, inlined
            reply = yield Exchange(self.unit, pdu, self.spec.timing, not self.broadcast, reg.write_delay_ms or 0.0)
            if not self.broadcast:
                self.raise_for(reply, code)
            self._after_write(reg, key, int(raw))  # raw fits its type (raw_to_words checked): the words' value
            return
        regs = [(reg, key, raw_to_words(reg, raw)) for key, raw in items for reg in (self.check_write(key),)]
        for (key, raw), (reg, _, _) in zip(items, regs, strict=True):
            if reg.command_value is not None and raw != reg.command_value:
                raise self.not_the_command(reg, key, raw)
        groups: list[list[tuple[RegisterSpec, Key, list[int]]]] = []
        for item in sorted(regs, key=lambda r: r[0].element_address(r[1][1])):
            reg, key, words = item
            if groups:
                last_reg, last_key, _ = groups[-1][-1]
                start = groups[-1][0][0].element_address(groups[-1][0][1][1])
                end = last_reg.element_address(last_key[1]) + last_reg.words
                if (reg.element_address(key[1]) == end and reg.page == last_reg.page
                        and end + reg.words - start <= limit):
                    groups[-1].append(item)
                    continue
            groups.append([item])
        for group in groups:
            for reg, _key, words in group:
                if len(words) > 1 and limit == 0:
                    raise UnsupportedFunction(f"{reg.name}: the map has no 10h for a multi-word write")
        written: list[str] = []
        for number, group in enumerate(groups):
            reg0, key0, _ = group[0]
            sending = False
            try:
                yield from self._page_ops(reg0.page)
                words = [w for _, _, ws in group for w in ws]
                hold = max((r.write_delay_ms or 0.0) for r, _, _ in group)
                sending = True
                yield from self._write_words(reg0.element_address(key0[1]), words, hold)
            except DriveError as exc:
                if len(groups) == 1:
                    raise  # one request: all or nothing, the error says which
                names = [[r.element_name(k[1]) for r, k, _ in g] for g in groups]
                unsure = sending and isinstance(exc, TransportError)
                raise PartialWrite(
                    exc, written=tuple(written), maybe_written=tuple(names[number]) if unsure else (),
                    not_written=tuple(n for g in names[number + (1 if unsure else 0):] for n in g),
                ) from exc
            for reg, key, ws in group:
                self._after_write(reg, key, words_to_raw(reg, ws))
                written.append(reg.element_name(key[1]))

    def _after_write(self, reg: RegisterSpec, key: Key, raw: int) -> None:
        if reg.name in self.tables.selectors:
            self.pages[reg.name] = raw
        reflect = reg.reflect
        if reflect != "configuration" and reflect != "power_cycle":
            return
        name = reg.element_name(key[1])
        if reflect == "configuration" and name not in self.pending_configuration:
            self.pending_configuration.append(name)
        elif reflect == "power_cycle" and name not in self.pending_power_cycle:
            self.pending_power_cycle.append(name)
            log.warning("%s: written; takes effect after the drive is powered off and on again", name)

    def apply_configuration(self) -> Op[None]:
        if self.spec.configuration is None:
            raise UnsupportedFunction("the map defines no configuration command")
        name, value = self.spec.configuration
        reg = self.spec.register(name)
        self.check_write((name, 0))
        yield from self._page_ops(reg.page)
        yield from self._write_words(reg.address, raw_to_words(reg, value), reg.write_delay_ms or 0.0)
        self.pending_configuration.clear()

    def loopback(self, data: int) -> Op[int]:
        if self.spec.function(0x08) is None:
            raise UnsupportedFunction("the map does not list 08h (diagnostics / loopback)")
        if not isinstance(data, int) or isinstance(data, bool) or not 0 <= data <= 0xFFFF:
            raise InvalidValue("loopback data must be an int 0..0xFFFF")
        if self.broadcast:
            raise BroadcastRead("loopback needs a reply; a broadcast client cannot ask for one")
        reply = self.raise_for((yield self.exchange(ReturnQueryDataRequest(message=data))), 0x08)
        echoed = getattr(reply, "message", None)
        value = int.from_bytes(echoed, "big") if isinstance(echoed, bytes) else echoed
        if value != data:
            raise TransportError(f"loopback echoed {value!r}, sent {data:#06x}")
        return data


def _run(bus: Bus, op: Op[T]) -> T:
    """Run an operation on a bus; a failed exchange is raised inside the operation (``throw``)."""
    try:
        ex = next(op)
        while True:
            try:
                reply = bus.exchange(ex)
            except DriveError as exc:
                ex = op.throw(exc)
            else:
                ex = op.send(reply)
    except StopIteration as stop:
        return stop.value  # type: ignore[no-any-return]


async def _arun(bus: AsyncBus, op: Op[T]) -> T:
    """The asyncio twin of :func:`_run`."""
    try:
        ex = next(op)
        while True:
            try:
                reply = await bus.exchange(ex)
            except DriveError as exc:
                ex = op.throw(exc)
            else:
                ex = op.send(reply)
    except StopIteration as stop:
        return stop.value  # type: ignore[no-any-return]


# ----------------------------------------------------------------------------- accessors
class _Element(Generic[T]):
    """One register (or one array element) of one client."""

    def __init__(self, owner: Any, codec: Codec[T], index: int = 0) -> None:
        self._owner = owner
        self.codec = codec
        self.spec = codec.spec
        self.index = index
        self._key: Key = (codec.spec.name, index)
        self._keys: tuple[Key, ...] = (self._key,)

    @property
    def key(self) -> Key:
        return self._key

    @property
    def keys(self) -> tuple[Key, ...]:
        return self._keys

    @property
    def name(self) -> str:
        return self.spec.element_name(self.index)

    @property
    def address(self) -> int:
        return self.spec.element_address(self.index)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} @0x{self.address:04X}>"


class ReadOnly(_Element[T]):
    """A readable register: ``read()`` gives the engineering value, ``read_raw()`` the raw one."""

    def read(self) -> T:
        return self.codec.decode(self._owner._read_raw_keys(self._keys)[self._key])

    def read_raw(self) -> int:
        return self._owner._read_raw_keys(self._keys)[self._key]  # type: ignore[no-any-return]


class WriteOnly(_Element[T]):
    """A writable register; ``write`` checks type, range and access before sending."""

    def write(self, value: T) -> None:
        self._owner._write_raw_items([(self._key, self.codec.encode(value))])

    def write_raw(self, raw: int) -> None:
        self._owner._write_raw_items([(self.key, RawCodec(self.spec).encode(raw))])


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
        self._owner._write_raw_items([(self._key, _command_value(self.spec))])


class ReadWriteCommand(ReadWrite[T], Command[T]):
    """A readable command register: :class:`Command` plus ``read``."""


def _command_value(spec: RegisterSpec) -> int:
    if spec.command_value is None:
        raise UnsupportedFunction(f"{spec.name} is not a command register")
    return spec.command_value


E_co = TypeVar("E_co", bound=_Element[Any])


class _Array(Generic[T, E_co]):
    """An array register: indexable; ``read()``/``write()`` handle all elements at once."""

    element_type: ClassVar[type[_Element[Any]]] = _Element

    def __init__(self, owner: Any, codec: Codec[T]) -> None:
        self._owner = owner
        self.codec = codec
        self.spec = codec.spec
        self._elements = [self.element_type(owner, codec, i) for i in range(codec.spec.count)]
        self._keys: tuple[Key, ...] = tuple((codec.spec.name, i) for i in range(codec.spec.count))

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
    def name(self) -> str:
        return self.spec.name

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}[{len(self)}] @0x{self.spec.address:04X}>"


class _ReadArrayMixin(_Array[T, E_co]):
    def read(self) -> tuple[T, ...]:
        raw = self._owner._read_raw_keys(self.keys)
        return tuple(self.codec.decode(raw[k]) for k in self.keys)


class _WriteArrayMixin(_Array[T, E_co]):
    def write(self, values: Sequence[T]) -> None:
        """Write every element (one 10h request where the map allows it)."""
        if len(values) != len(self):
            raise InvalidValue(f"{self.name}: expected {len(self)} values, got {len(values)}")
        self._owner._write_raw_items([(k, self.codec.encode(v)) for k, v in zip(self.keys, values, strict=True)])


class ReadOnlyArray(_ReadArrayMixin[T, ReadOnly[T]]):
    element_type = ReadOnly


class WriteOnlyArray(_WriteArrayMixin[T, WriteOnly[T]]):
    element_type = WriteOnly


class ReadWriteArray(_ReadArrayMixin[T, ReadWrite[T]], _WriteArrayMixin[T, ReadWrite[T]]):
    element_type = ReadWrite


class AsyncReadOnly(_Element[T]):
    """Async form of :class:`ReadOnly`."""

    async def read(self) -> T:
        return self.codec.decode((await self._owner._read_raw_keys(self._keys))[self._key])

    async def read_raw(self) -> int:
        return (await self._owner._read_raw_keys(self.keys))[self.key]  # type: ignore[no-any-return]


class AsyncWriteOnly(_Element[T]):
    """Async form of :class:`WriteOnly`."""

    async def write(self, value: T) -> None:
        await self._owner._write_raw_items([(self._key, self.codec.encode(value))])

    async def write_raw(self, raw: int) -> None:
        await self._owner._write_raw_items([(self.key, RawCodec(self.spec).encode(raw))])


class AsyncReadWrite(AsyncReadOnly[T], AsyncWriteOnly[T]):
    """Async form of :class:`ReadWrite`."""

    async def modify(self, update: Callable[[T], T]) -> T:
        return await self._owner.read_modify_write(self, update)  # type: ignore[no-any-return]


class AsyncCommand(AsyncWriteOnly[T]):
    """Async form of :class:`Command`."""

    async def execute(self) -> None:
        """Send the command (write the map's command value)."""
        await self._owner._write_raw_items([(self._key, _command_value(self.spec))])


class AsyncReadWriteCommand(AsyncReadWrite[T], AsyncCommand[T]):
    """Async form of :class:`ReadWriteCommand`."""


class _AsyncReadArrayMixin(_Array[T, E_co]):
    async def read(self) -> tuple[T, ...]:
        raw = await self._owner._read_raw_keys(self.keys)
        return tuple(self.codec.decode(raw[k]) for k in self.keys)


class _AsyncWriteArrayMixin(_Array[T, E_co]):
    async def write(self, values: Sequence[T]) -> None:
        if len(values) != len(self):
            raise InvalidValue(f"{self.name}: expected {len(self)} values, got {len(values)}")
        await self._owner._write_raw_items([(k, self.codec.encode(v)) for k, v in zip(self.keys, values, strict=True)])


class AsyncReadOnlyArray(_AsyncReadArrayMixin[T, AsyncReadOnly[T]]):
    element_type = AsyncReadOnly


class AsyncWriteOnlyArray(_AsyncWriteArrayMixin[T, AsyncWriteOnly[T]]):
    element_type = AsyncWriteOnly


class AsyncReadWriteArray(_AsyncReadArrayMixin[T, AsyncReadWrite[T]], _AsyncWriteArrayMixin[T, AsyncReadWrite[T]]):
    element_type = AsyncReadWrite


Readable = _Element[Any] | _Array[Any, Any]


# ----------------------------------------------------------------------------- clients
class _Common(Generic[S]):
    """State and helpers shared by the sync and async client bases."""

    SPEC: ClassVar[DeviceSpec]
    SNAPSHOT: ClassVar[type[SnapshotBase]] = SnapshotBase
    EXCEPTIONS: ClassVar[Mapping[int, type[DeviceException]]] = {}
    CODECS: ClassVar[Mapping[str, Codec[Any]]] = {}
    _plans: ClassVar[dict[Any, tuple[ReadRequest, ...]]]
    _shape: ClassVar[dict[str, int]]
    _table: ClassVar[dict[Key, tuple[Callable[[int], Any], str | None, int]]]
    _defaults: ClassVar[dict[str, Any] | None]

    _core: Core
    _accessors: dict[str, Any]

    def _setup(self, unit: int, page_policy: PagePolicy, broadcast: bool) -> None:
        self._core = Core(self.SPEC, unit, self.EXCEPTIONS, page_policy, broadcast)
        self._accessors = {}

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
    def _snapshot_table(cls) -> dict[Key, tuple[Callable[[int], Any], str | None, int]]:
        """Per readable element: (decode, snapshot field or None, index in the field's tuple or -1).

        Computed once per class (each element on first use); the count of an array field is
        ``cls._shape[field]``.
        """
        table: dict[Key, tuple[Callable[[int], Any], str | None, int]] | None = cls.__dict__.get("_table")
        if table is None:
            names = {f.name for f in dataclasses.fields(cls.SNAPSHOT)}
            cls._shape = {r.name: r.count for r in cls.SPEC.registers if r.name in names and r.is_array}
            table = cls._table = {}
            for reg in cls.SPEC.registers:
                if reg.readable and reg.name in cls.CODECS:
                    field = reg.name if reg.name in names else None
                    for i in range(reg.count):
                        table[(reg.name, i)] = (cls.CODECS[reg.name].decode, field, i if reg.is_array else -1)
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
        # what the dataclass __init__ does (every field set, in order), without its per-field setattr calls
        snap = object.__new__(self.SNAPSHOT)
        state = snap.__dict__
        state.update(defaults)
        state["_values"] = values
        state.update(fields)
        return snap  # type: ignore[return-value]

    @classmethod
    def _snapshot_defaults(cls) -> dict[str, Any] | None:
        """Field values of an empty ``SNAPSHOT`` when building it without ``__init__`` is exact, else None.

        Exact for what the client template generates: a frozen dataclass whose fields are all in
        ``__init__`` and default to None (``_values`` aside), without ``__post_init__`` or
        ``__slots__``. Computed once per class.
        """
        if "_defaults" in cls.__dict__:
            return cls._defaults
        snapshot = cls.SNAPSHOT
        params = getattr(snapshot, "__dataclass_params__", None)
        fields = dataclasses.fields(snapshot)
        exact = (params is not None and params.frozen and not hasattr(snapshot, "__post_init__")
                 and not hasattr(snapshot, "__slots__") and snapshot.__new__ is object.__new__
                 and all(f.init and (f.name == "_values" or f.default is None) for f in fields))
        defaults = {f.name: None for f in fields} if exact else None
        cls._defaults = defaults
        return defaults

    @staticmethod
    def _keys(accessors: Iterable[Readable]) -> list[Key]:
        keys: list[Key] = []
        for acc in accessors:
            keys.extend(acc.keys)
        return keys

    def _by_name_value(self, acc: Any, value: Any) -> int:
        codec = acc.codec
        if isinstance(codec, (EnumCodec, FlagCodec)) and isinstance(value, int) and not isinstance(value, enum.Enum):
            value = (codec.enum_type if isinstance(codec, EnumCodec) else codec.flag_type)(value)
        elif isinstance(codec, FieldsCodec) and isinstance(value, Mapping):
            value = codec.data_type(**value)
        return codec.encode(value)  # type: ignore[no-any-return]


class ClientBase(_Common[S]):
    """Synchronous client of one unit on a :class:`Bus`."""

    def __init__(self, bus: Bus, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.unit_min}..{spec.unit_max}"
                               + (f" (or fixed port units {list(spec.fixed_units)})" if spec.fixed_units else ""))
        self.bus = bus
        self._owns_bus = _owns_bus
        self._setup(unit, page_policy, _broadcast)

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
        """A client that writes to every unit at once (generated when the map has a broadcast address)."""
        raise UnsupportedFunction(f"{cls.SPEC.model}: the map gives no broadcast address")

    @property
    def stats(self) -> Stats:
        """Counters of the bus (shared by every client on it)."""
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
        plan = (type(keys) is tuple and self._plans.get(keys)) or self.plan(keys)  # this class's own cache
        with self.bus.lock:
            return _run(self.bus, core.read_raw(keys, plan, checked=True))

    def _write_raw_items(self, items: Sequence[tuple[Key, int]]) -> None:
        with self.bus.lock:
            _run(self.bus, self._core.write_raw(items))

    # public API
    def read(self, *accessors: Readable) -> S:
        """Read the given registers together, in the fewest requests the map allows."""
        return self._snapshot(self._read_raw_keys(self._keys(accessors)))

    def read_all(self) -> S:
        """Read every readable register (plan computed once per client class)."""
        core = self._core
        keys = core.tables.all_keys
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        plan = self.plan()
        with self.bus.lock:
            return self._snapshot(_run(self.bus, core.read_raw(keys, plan, checked=True)))

    def write_many(self, items: Iterable[tuple[WriteOnly[Any] | ReadWrite[Any], Any]]) -> None:
        """Write several registers; contiguous ones go out in one 10h request where the map allows it.

        If it takes several requests and one fails, :class:`PartialWrite` says what was written."""
        self._write_raw_items([(acc.key, acc.codec.encode(value)) for acc, value in items])

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


class AsyncClientBase(_Common[S]):
    """Asyncio client of one unit on an :class:`AsyncBus` (same API, awaited)."""

    def __init__(self, bus: AsyncBus, unit: int = 1, *, page_policy: PagePolicy = "raise", _broadcast: bool = False,
                 _owns_bus: bool = False) -> None:
        spec = self.SPEC
        if not _broadcast and not spec.valid_unit(unit):
            raise InvalidValue(f"unit {unit} outside the map's range {spec.unit_min}..{spec.unit_max}"
                               + (f" (or fixed port units {list(spec.fixed_units)})" if spec.fixed_units else ""))
        self.bus = bus
        self._owns_bus = _owns_bus
        self._setup(unit, page_policy, _broadcast)

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
        """A client that writes to every unit at once (generated when the map has a broadcast address)."""
        raise UnsupportedFunction(f"{cls.SPEC.model}: the map gives no broadcast address")

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
        plan = (type(keys) is tuple and self._plans.get(keys)) or self.plan(keys)  # this class's own cache
        async with self.bus.lock:
            return await _arun(self.bus, core.read_raw(keys, plan, checked=True))

    async def _write_raw_items(self, items: Sequence[tuple[Key, int]]) -> None:
        op = self._core.write_raw(items)
        async with self.bus.lock:
            await _arun(self.bus, op)

    async def read(self, *accessors: Readable) -> S:
        return self._snapshot(await self._read_raw_keys(self._keys(accessors)))

    async def read_all(self) -> S:
        core = self._core
        keys = core.tables.all_keys
        core.check_readable(())  # the broadcast check: every key of read_all is readable by construction
        plan = self.plan()
        async with self.bus.lock:
            return self._snapshot(await _arun(self.bus, core.read_raw(keys, plan, checked=True)))

    async def write_many(self, items: Iterable[tuple[AsyncWriteOnly[Any] | AsyncReadWrite[Any], Any]]) -> None:
        await self._write_raw_items([(acc.key, acc.codec.encode(value)) for acc, value in items])

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
        keys = [accessor.key]
        async with self.bus.lock:
            raw = await _arun(self.bus, self._core.read_raw(keys, self.plan(keys)))
            new = update(accessor.codec.decode(raw[accessor.key]))
            await _arun(self.bus, self._core.write_raw([(accessor.key, accessor.codec.encode(new))]))
            return new

    async def apply_configuration(self) -> None:
        op = self._core.apply_configuration()
        async with self.bus.lock:
            await _arun(self.bus, op)

    async def loopback(self, data: int = 0xA537) -> int:
        op = self._core.loopback(data)
        async with self.bus.lock:
            return await _arun(self.bus, op)


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
    "broadcast_unit",
]
