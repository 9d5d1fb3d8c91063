"""The client runtime that generated ``Client`` / ``AsyncClient`` classes build on.

Protocol behaviour lives in :class:`~drivemap.runtime.client.protocol.sansio.Core`, written once as generators
("sans I/O"); :class:`ClientBase` runs its operations on a :class:`Bus`,
:class:`~drivemap.runtime.client.api.async_client.AsyncClientBase` on an :class:`AsyncBus`. Every check on the
caller's input happens before the first request is yielded, so a bad value never sends a byte.
The fault-free path of reads and single writes runs compiled programs
(:mod:`drivemap.runtime.client.protocol.programs`, :mod:`drivemap.runtime.client.protocol.writes`) that fall back to the same
operations for everything else.

Generated packages subclass the bases, declare one typed accessor per register
(:mod:`drivemap.runtime.client.api.accessors`: :class:`ReadOnly`, :class:`WriteOnly`, :class:`ReadWrite` and
their ``Array`` and ``Async`` forms; read-only accessors have no ``write``) and a frozen
``Snapshot`` dataclass for :meth:`ClientBase.read`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any, Self, TypeVar

from pymodbus.pdu import ModbusPDU

from drivemap.runtime.client.api.accessors import (
    ArrayBase,
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
    encode_for_write,
)
from drivemap.runtime.client.api.async_client import AsyncClientBase
from drivemap.runtime.client.api.base import ClientCommon, S, broadcast_refusal, broadcast_unit
from drivemap.runtime.client.api.machinery import ClientMachinery, Program, register_flavour
from drivemap.runtime.client.protocol import rawio
from drivemap.runtime.client.protocol.planner import Key, ReadRequest
from drivemap.runtime.client.protocol.review import refuse_open
from drivemap.runtime.client.protocol.sansio import Core, Op, PagePolicy, RawItem, run, run_replay
from drivemap.runtime.client.transport.bus import AsyncBus, Bus, Stats
from drivemap.runtime.errors import DriveError, PartialWrite, ReadOnlyRegister

T = TypeVar("T")
_run = run


class SyncMachinery(ClientMachinery):
    """A sync client's working parts: operations of the core run on a :class:`Bus`, the bus lock held."""

    ACCESSORS = {
        "r": ReadOnly, "w": WriteOnly, "rw": ReadWrite, "cmd": Command, "rwcmd": ReadWriteCommand,
        "r[]": ReadOnlyArray, "w[]": WriteOnlyArray, "rw[]": ReadWriteArray,
    }
    BUS = Bus
    bus: Bus

    def read_raw_keys(self, keys: Sequence[Key]) -> dict[Key, int]:
        core = self.core
        core.check_readable(keys)
        plan = self.plan_for(keys)
        with self.bus.lock:
            return _run(self.bus, core.read_raw(keys, plan, checked=True))

    def write_raw_items(self, items: Sequence[RawItem]) -> None:
        with self.bus.lock:
            _run(self.bus, self.core.write_raw(items))

    def general(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], how: str,
                finish: Callable[[Any, dict[Key, int]], Any]) -> tuple[Program, Callable[..., Any]]:
        """The general read of ``keys`` (the core's operation; with holes, the client's plan), and
        the same after a read program's replies (the bus lock held): see :mod:`.programs`."""
        visit = how == "visit"

        def operation(core: Core, now: tuple[ReadRequest, ...]) -> Op[dict[Key, int]]:
            return core.read_visiting_pages(keys, now) if visit else core.read_raw(keys, now, checked=True)

        def general(client: ClientBase[Any]) -> Any:
            parts = client._drivemap
            core = parts.core
            now = core.plan_with_holes(keys) if core.holes else plan
            with parts.bus.lock:
                return finish(client, _run(parts.bus, operation(core, now)))

        def fallback(client: ClientBase[Any], replies: Sequence[ModbusPDU]) -> Any:
            parts = client._drivemap
            return finish(client, run_replay(parts.bus, operation(parts.core, plan), replies))

        return general, fallback


class ClientBase(ClientCommon[S, Bus]):
    """Synchronous client of one unit on a :class:`Bus`."""

    bus: Bus
    _drivemap: SyncMachinery

    @classmethod
    def broadcast(cls, bus: Bus, *, page_policy: PagePolicy = "raise") -> ClientBase[Any]:
        """A client that writes to every unit at once (generated when the map allows a broadcast write).

        Without one it raises :func:`broadcast_refusal`: the map's reason why nothing may be broadcast."""
        raise broadcast_refusal(cls.SPEC)

    def connect(self) -> None:
        self.bus.connect()

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def read(self, *accessors: Readable) -> S:
        """Read the given registers together, in the fewest requests the map allows."""
        parts = self._drivemap
        program = parts.programs.get(accessors)
        if program is None:
            program = parts.read_program(accessors)
        return program(self)  # type: ignore[no-any-return]

    def read_all(self) -> S:
        """Read every readable register (plan computed once per client class).

        Paged registers: with ``page_policy="raise"`` (the default) it switches the page selector to
        each page it needs and then puts it back to the page it found (also when a read fails);
        with ``"switch"`` it leaves the last page selected."""
        parts = self._drivemap
        return (parts.all_program or parts.read_all_program())(self)  # type: ignore[no-any-return]

    def write_many(self, items: Iterable[tuple[WriteOnly[Any] | ReadWrite[Any], Any]]) -> None:
        """Write several registers in the order given; one that continues the previous one goes out in the
        same 10h request where the map allows it.

        If it takes several requests and one fails, :class:`PartialWrite` says what was written."""
        items = list(items)
        refuse_open(self._drivemap.core, (acc.key for acc, _ in items))
        self._drivemap.write_raw_items([(acc.key, encode_for_write(acc.codec, value)) for acc, value in items])

    def read_by_name(self, name: str) -> Any:
        """``client.read_by_name("digital_speed[0]")``: the engineering value (tuple for a whole array)."""
        acc = self.accessor(name)
        self._drivemap.core.check_readable(acc.keys)
        return acc.read()

    def write_by_name(self, name: str, value: Any) -> None:
        """``client.write_by_name("digital_speed[0]", 1000)``; ints are accepted for enums and flags."""
        acc = self.accessor(name)
        if isinstance(acc, ArrayBase):
            if not hasattr(acc, "write"):
                raise ReadOnlyRegister(f"{name} is read-only")
            self._drivemap.core.check_write(acc.keys[0])  # open for review: refused before the values are looked at
            self._drivemap.write_raw_items([(k, self._drivemap.by_name_value(acc, v)) for k, v in zip(acc.keys, value, strict=True)])
            return
        self._drivemap.core.check_write(acc.key)
        self._drivemap.write_raw_items([(acc.key, self._drivemap.by_name_value(acc, value))])

    def read_modify_write(self, accessor: ReadWrite[T], update: Callable[[T], T]) -> T:
        """Read a register, apply ``update`` to its value and write the result, holding the bus."""
        self._drivemap.core.check_write(accessor.key)
        with self.bus.lock:
            value = accessor.read()
            new = update(value)
            accessor.write(new)
            return new

    def apply_configuration(self) -> None:
        """Send the map's configuration command; clears :attr:`pending_configuration`."""
        with self.bus.lock:
            _run(self.bus, self._drivemap.core.apply_configuration())

    def loopback(self, data: int = 0xA537) -> int:
        """Diagnostics 08h sub-function 0: the device echoes ``data``."""
        with self.bus.lock:
            return _run(self.bus, self._drivemap.core.loopback(data))

    def read_registers(self, table: str, address: int, count: int) -> list[int]:
        """``count`` words (0/1 per coil or discrete input) of ``table`` from ``address``, as the
        device sends them, in one request; checked before the wire (:mod:`drivemap.runtime.client.protocol.rawio`)."""
        rawio.check_read(self._drivemap.core.spec, table, address, count, self._drivemap.core.broadcast)
        op = rawio.read_registers(self._drivemap.core, table, address, count)
        with self.bus.lock:
            return _run(self.bus, op)


register_flavour(ClientBase, SyncMachinery)

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
