"""Running the core's operations (generators of exchanges) on a bus: :func:`run` (sync),
:func:`arun` (asyncio), and their ``_replay`` forms for an operation whose first exchanges a read
program has carried out already (:mod:`drivemap.runtime.client.protocol.programs`)."""

from __future__ import annotations

from collections.abc import Generator, Sequence
from typing import TypeVar

from pymodbus.pdu import ModbusPDU

from drivemap.runtime.client.transport.bus import AsyncBus, Bus
from drivemap.runtime.client.transport.exchange import Exchange
from drivemap.runtime.errors import DriveError

T = TypeVar("T")
Op = Generator[Exchange, "ModbusPDU | None", T]


def run(bus: Bus, op: Op[T]) -> T:
    """Run an operation on a bus; a failed exchange is raised inside the operation (``throw``)."""
    return run_replay(bus, op, ())


def run_replay(bus: Bus, op: Op[T], replies: Sequence[ModbusPDU | None]) -> T:
    """:func:`run` for an operation whose first exchanges have been carried out already (a read
    program's, :mod:`drivemap.runtime.client.protocol.programs`): it gets ``replies`` for them, then the bus's."""
    try:
        ex = next(op)
        for reply in replies:
            ex = op.send(reply)
        while True:
            try:
                reply = bus.exchange(ex)
            except DriveError as exc:
                ex = op.throw(exc)
            else:
                ex = op.send(reply)
    except StopIteration as stop:
        return stop.value  # type: ignore[no-any-return]


async def arun(bus: AsyncBus, op: Op[T]) -> T:
    """The asyncio twin of :func:`run`."""
    return await arun_replay(bus, op, ())


async def arun_replay(bus: AsyncBus, op: Op[T], replies: Sequence[ModbusPDU | None]) -> T:
    """The asyncio twin of :func:`run_replay`."""
    try:
        ex = next(op)
        for reply in replies:
            ex = op.send(reply)
        while True:
            try:
                reply = await bus.exchange(ex)
            except DriveError as exc:
                ex = op.throw(exc)
            else:
                ex = op.send(reply)
    except StopIteration as stop:
        return stop.value  # type: ignore[no-any-return]


__all__ = ["Op", "arun", "arun_replay", "run", "run_replay"]
