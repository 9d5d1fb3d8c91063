"""The asyncio client base (:class:`AsyncClientBase`): the API of
:class:`~drivemap.runtime.client.api.sync_client.ClientBase`, awaited, on an :class:`~drivemap.runtime.client.transport.bus.AsyncBus`."""

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
    Readable,
    encode_for_write,
)
from drivemap.runtime.client.api.base import ClientCommon, S, broadcast_refusal
from drivemap.runtime.client.api.machinery import ClientMachinery, Program, register_flavour
from drivemap.runtime.client.protocol import rawio
from drivemap.runtime.client.protocol.planner import Key, ReadRequest
from drivemap.runtime.client.protocol.review import refuse_open
from drivemap.runtime.client.protocol.sansio import Core, Op, PagePolicy, RawItem, arun, arun_replay
from drivemap.runtime.client.transport.bus import AsyncBus
from drivemap.runtime.errors import ReadOnlyRegister

T = TypeVar("T")


class AsyncMachinery(ClientMachinery):
    """An asyncio client's working parts: operations of the core run on an :class:`AsyncBus`."""

    ASYNC = True
    ACCESSORS = {
        "r": AsyncReadOnly, "w": AsyncWriteOnly, "rw": AsyncReadWrite, "cmd": AsyncCommand,
        "rwcmd": AsyncReadWriteCommand, "r[]": AsyncReadOnlyArray, "w[]": AsyncWriteOnlyArray,
        "rw[]": AsyncReadWriteArray,
    }
    BUS = AsyncBus
    bus: AsyncBus

    async def read_raw_keys(self, keys: Sequence[Key]) -> dict[Key, int]:
        core = self.core
        core.check_readable(keys)
        plan = self.plan_for(keys)
        async with self.bus.lock:
            return await arun(self.bus, core.read_raw(keys, plan, checked=True))

    async def write_raw_items(self, items: Sequence[RawItem]) -> None:
        op = self.core.write_raw(items)
        async with self.bus.lock:
            await arun(self.bus, op)

    def general(self, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], how: str,
                finish: Callable[[Any, dict[Key, int]], Any]) -> tuple[Program, Callable[..., Any]]:
        """The asyncio twin of :meth:`~.sync_client.SyncMachinery.general`."""
        visit = how == "visit"

        def operation(core: Core, now: tuple[ReadRequest, ...]) -> Op[dict[Key, int]]:
            return core.read_visiting_pages(keys, now) if visit else core.read_raw(keys, now, checked=True)

        async def general(client: AsyncClientBase[Any]) -> Any:
            parts = client._drivemap
            core = parts.core
            now = core.plan_with_holes(keys) if core.holes else plan
            async with parts.bus.lock:
                return finish(client, await arun(parts.bus, operation(core, now)))

        async def fallback(client: AsyncClientBase[Any], replies: Sequence[ModbusPDU]) -> Any:
            parts = client._drivemap
            return finish(client, await arun_replay(parts.bus, operation(parts.core, plan), replies))

        return general, fallback


class AsyncClientBase(ClientCommon[S, AsyncBus]):
    """Asyncio client of one unit on an :class:`AsyncBus` (same API, awaited)."""

    bus: AsyncBus
    _drivemap: AsyncMachinery

    @classmethod
    def broadcast(cls, bus: AsyncBus, *, page_policy: PagePolicy = "raise") -> AsyncClientBase[Any]:
        """A client that writes to every unit at once (generated when the map allows a broadcast write).

        Without one it raises :func:`broadcast_refusal`: the map's reason why nothing may be broadcast."""
        raise broadcast_refusal(cls.SPEC)

    async def connect(self) -> None:
        await self.bus.connect()

    async def __aenter__(self) -> Self:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.close()

    async def read(self, *accessors: Readable) -> S:
        parts = self._drivemap
        program = parts.programs.get(accessors)
        if program is None:
            program = parts.read_program(accessors)
        return await program(self)  # type: ignore[no-any-return]

    async def read_all(self) -> S:
        """See :meth:`ClientBase.read_all` (pages visited and restored under ``page_policy="raise"``)."""
        parts = self._drivemap
        return await (parts.all_program or parts.read_all_program())(self)  # type: ignore[no-any-return]

    async def write_many(self, items: Iterable[tuple[AsyncWriteOnly[Any] | AsyncReadWrite[Any], Any]]) -> None:
        items = list(items)
        refuse_open(self._drivemap.core, (acc.key for acc, _ in items))
        await self._drivemap.write_raw_items([(acc.key, encode_for_write(acc.codec, value)) for acc, value in items])

    async def read_by_name(self, name: str) -> Any:
        acc = self.accessor(name)
        self._drivemap.core.check_readable(acc.keys)
        return await acc.read()

    async def write_by_name(self, name: str, value: Any) -> None:
        acc = self.accessor(name)
        if isinstance(acc, ArrayBase):
            if not hasattr(acc, "write"):
                raise ReadOnlyRegister(f"{name} is read-only")
            self._drivemap.core.check_write(acc.keys[0])  # open for review: refused before the values are looked at
            await self._drivemap.write_raw_items([(k, self._drivemap.by_name_value(acc, v)) for k, v in zip(acc.keys, value, strict=True)])
            return
        self._drivemap.core.check_write(acc.key)
        await self._drivemap.write_raw_items([(acc.key, self._drivemap.by_name_value(acc, value))])

    async def read_modify_write(self, accessor: AsyncReadWrite[T], update: Callable[[T], T]) -> T:
        """Read, update and write back; other callers on the bus wait until it is done."""
        self._drivemap.core.check_write(accessor.key)
        keys = accessor.read_keys
        codec = accessor.codec
        async with self.bus.lock:
            raw = await arun(self.bus, self._drivemap.core.read_raw(keys, self._drivemap.plan_for(keys)))
            scale = codec.scale_key
            value = codec.decode(raw[accessor.key]) if scale is None else codec.decode_scaled(raw[accessor.key],
                                                                                                raw.get(scale))
            new = update(value)
            await arun(self.bus, self._drivemap.core.write_raw([(accessor.key, encode_for_write(codec, new))]))
            return new

    async def apply_configuration(self) -> None:
        op = self._drivemap.core.apply_configuration()
        async with self.bus.lock:
            await arun(self.bus, op)

    async def loopback(self, data: int = 0xA537) -> int:
        op = self._drivemap.core.loopback(data)
        async with self.bus.lock:
            return await arun(self.bus, op)

    async def read_registers(self, table: str, address: int, count: int) -> list[int]:
        """The asyncio twin of :meth:`ClientBase.read_registers`."""
        rawio.check_read(self._drivemap.core.spec, table, address, count, self._drivemap.core.broadcast)
        op = rawio.read_registers(self._drivemap.core, table, address, count)
        async with self.bus.lock:
            return await arun(self.bus, op)


register_flavour(AsyncClientBase, AsyncMachinery)

__all__ = ["AsyncClientBase", "AsyncMachinery"]
