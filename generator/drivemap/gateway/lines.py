"""One asyncio task per bus: polls on schedule, commands first, one transaction at a time.

A :class:`Line` owns the :class:`~drivemap.runtime.client.transport.bus.AsyncBus` of one configured bus and the
devices on it. Its task loops: a queued command goes out before the next poll; otherwise the poll
group due first is read with the generated client (one planned read: the planner's fewest
requests for the group's registers), and the bus keeps the maps' timing and retries. Buses run in
parallel, each in its own task; nothing else touches a bus.

A device whose poll fails after the map's retries (timeout, transport error) goes offline; it is
tried again after ``backoff_min`` seconds, then twice as long each time up to ``backoff_max``, and
comes back online by itself at the first poll that succeeds. A device that answers with an
exception reply stays online (it answered); the error is logged.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import deque
from typing import Any, Protocol

from drivemap.gateway.config import BusConfig
from drivemap.gateway.device import Command, Device, PollState
from drivemap.runtime.client.values.codec import OptionalCodec
from drivemap.runtime.errors import DriveError, TransportError

log = logging.getLogger("drivemap.gateway")

_MISSING = object()


class Sink(Protocol):
    """Where values, availability and command outcomes go (MQTT, OPC UA). Never blocks."""

    def publish_values(self, device: Device, values: dict[str, Any], changed: dict[str, Any]) -> None: ...

    def publish_availability(self, device: Device, online: bool) -> None: ...

    def publish_outcome(self, device: Device, outcome: dict[str, Any]) -> None: ...


class Fanout:
    """Several sinks as one."""

    def __init__(self, sinks: list[Sink] | None = None) -> None:
        self.sinks: list[Sink] = list(sinks or [])

    def publish_values(self, device: Device, values: dict[str, Any], changed: dict[str, Any]) -> None:
        for s in self.sinks:
            s.publish_values(device, values, changed)

    def publish_availability(self, device: Device, online: bool) -> None:
        for s in self.sinks:
            s.publish_availability(device, online)

    def publish_outcome(self, device: Device, outcome: dict[str, Any]) -> None:
        for s in self.sinks:
            s.publish_outcome(device, outcome)


def outcome(cmd: Command, error: BaseException | None) -> dict[str, Any]:
    """The published result of a command: ok, or the typed error's class name and message."""
    typed = error is None or isinstance(error, DriveError)
    return {
        "register": cmd.target, "value": cmd.given, "ok": error is None, "source": cmd.source,
        "error": None if error is None else type(error).__name__ if typed else "InternalError",
        "message": "written" if error is None else str(error) if typed else f"{type(error).__name__}: {error}",
    }


class Line:
    """The task of one bus."""

    def __init__(self, cfg: BusConfig, bus: Any, devices: list[Device], sink: Sink,
                 backoff: tuple[float, float] = (1.0, 30.0)) -> None:
        self.cfg = cfg
        self.name = cfg.name
        self.bus = bus
        self.devices = devices
        self.sink = sink
        self.backoff_min, self.backoff_max = backoff
        self._commands: deque[Command] = deque()
        self._wake = asyncio.Event()
        self.stopping = False
        self.polls_done = 0
        self.commands_accepted = 0
        self.faults = 0
        self.started = time.monotonic()

    def submit(self, cmd: Command) -> None:
        """Queue a checked command (it goes out before the next poll)."""
        self._commands.append(cmd)
        self.commands_accepted += 1
        self._wake.set()

    @property
    def pending(self) -> int:
        return len(self._commands)

    async def run(self) -> None:
        self.started = now = time.monotonic()
        for dev in self.devices:
            for poll in dev.polls:
                poll.due = now
        try:
            while not self.stopping:  # a cancellation swallowed below the bus still ends the loop
                try:
                    await self._step()
                except Exception:  # noqa: BLE001 - no device or command may stop the line: logged, next step
                    self.faults += 1
                    log.exception("%s: unexpected failure; the line goes on", self.name)
                    await asyncio.sleep(min(1.0, self.backoff_min))
        finally:
            self.bus.close()

    async def _step(self) -> None:
        if self._commands:
            await self.execute(self._commands.popleft())
            return
        due, device, poll = self._next_due()
        wait = due - time.monotonic()
        if wait > 0:
            self._wake.clear()
            if not self._commands:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._wake.wait(), wait)
            return
        await self.poll(device, poll)

    def _next_due(self) -> tuple[float, Device | None, PollState | None]:
        best: tuple[float, Device | None, PollState | None] = (time.monotonic() + 3600.0, None, None)
        for dev in self.devices:
            if dev.online is False:
                if dev.polls and dev.retry_at < best[0]:
                    best = (dev.retry_at, dev, dev.polls[0])
                continue
            for poll in dev.polls:
                if poll.due < best[0]:
                    best = (poll.due, dev, poll)
        return best

    async def poll(self, device: Device | None, poll: PollState | None) -> None:
        if device is None or poll is None:
            return
        try:
            snap = await device.client.read(*poll.accessors)
        except TransportError as exc:
            self._failed(device, exc)
            return
        except Exception as exc:  # noqa: BLE001 - an exception reply, or a reply nothing foresaw: the line goes on
            device.last_error = f"{type(exc).__name__}: {exc}"
            log.warning("%s: poll of %s failed: %s", device.name, ", ".join(poll.group.registers), device.last_error,
                        exc_info=not isinstance(exc, DriveError))
            poll.due = time.monotonic() + poll.group.interval
            return
        now = time.monotonic()
        poll.due = max(poll.due + poll.group.interval, now) if device.online else now + poll.group.interval
        self.polls_done += 1
        device.polls_done += 1
        self._publish(device, device.snapshot_json(snap, poll.accessors))
        if device.online is not True:
            self._online(device)

    def _publish(self, device: Device, values: dict[str, Any]) -> None:
        changed = {k: v for k, v in values.items() if device.values.get(k, _MISSING) != v}
        device.values.update(values)
        self.sink.publish_values(device, values, changed)

    def _online(self, device: Device) -> None:
        was = device.online
        device.online = True
        device.failures = 0
        now = time.monotonic()
        for poll in device.polls:
            poll.due = min(poll.due, now) if was is False else poll.due
        if was is False:
            log.warning("%s: answering again; online", device.name)
        self.sink.publish_availability(device, True)

    def _failed(self, device: Device, exc: DriveError) -> None:
        device.failures += 1
        device.last_error = f"{type(exc).__name__}: {exc}"
        delay = min(self.backoff_min * 2 ** min(device.failures - 1, 30), self.backoff_max)
        device.retry_at = time.monotonic() + delay
        if device.online is not False:
            device.online = False
            log.warning("%s: no answer after the map's retries (%s); offline, next try in %.1f s",
                        device.name, device.last_error, delay)
            self.sink.publish_availability(device, False)

    async def execute(self, cmd: Command) -> None:
        """Write a checked command, publish its outcome and read the register back."""
        device = cmd.device
        error: Exception | None = None
        try:
            if cmd.raw is None:  # scaled by a scale register: the factor is read just before the write
                await cmd.accessor.write_raw(await self._scaled_raw(cmd))
            else:
                await cmd.accessor.write_raw(cmd.raw)
        except DriveError as exc:
            error = exc
        except Exception as exc:  # noqa: BLE001 - answered like any failed command, and logged
            log.exception("%s: %s <- %r failed", device.name, cmd.target, cmd.given)
            error = exc
        log.info("%s: %s <- %r: %s", device.name, cmd.target, cmd.given, "ok" if error is None else error)
        self.sink.publish_outcome(device, outcome(cmd, error))
        if cmd.done is not None and not cmd.done.done():
            if error is None:
                cmd.done.set_result(None)
            else:
                cmd.done.set_exception(error)
        if error is None:
            await self._read_back(device, cmd.target.partition("[")[0])

    async def _scaled_raw(self, cmd: Command) -> int:
        """The raw value of a command for a register scaled by a scale-factor register: the factor read
        now, the value encoded with it (refused unless it is a whole number of steps at that factor)."""
        codec = cmd.accessor.codec
        inner = codec.inner if isinstance(codec, OptionalCodec) else codec
        assert inner.scale_key is not None
        factor = await cmd.device.client.accessor(inner.scale_key[0]).read_raw()
        if cmd.value is None:
            return int(codec.encode(None))
        return int(codec.encode_scaled(cmd.value, factor))  # exact at this factor or refused (InexactValue)

    async def _read_back(self, device: Device, name: str) -> None:
        if name not in device.cfg.publish:
            return
        acc = device.client.accessor(name)
        try:
            snap = await device.client.read(acc)
        except DriveError as exc:
            log.warning("%s: read-back of %s failed: %s", device.name, name, exc)
            return
        self._publish(device, device.snapshot_json(snap, (acc,)))
