"""Stale replies on a serial line: bytes that began before our request could have been answered.

RTU and ASCII frames carry no transaction id, so a reply delivered twice by the line (an echo, a
repeater) or a late answer to an earlier request looks exactly like the answer to the next request
of the same shape. Time tells many of them apart: a device starts its answer only after the last
byte of our request has reached it, so on a real line the first byte of the real reply cannot be
complete here before::

    request handed to the port + (request length + 1) x character time

Bytes seen before that moment are stale,
and so are the bytes that follow them with less than :data:`CONTINUATION_CHARS` characters of
silence (the rest of that frame). They are dropped before pymodbus's framer sees them, counted
(:attr:`drivemap.runtime.client.transport.bus.Stats.stale`, once per transaction) and logged; the client goes on
waiting for the real reply within the same timeout. Bytes that arrive while no request is
outstanding (between transactions) are dropped and counted the same way.

Which lines are real: a pty (``socat``, :class:`~drivemap.testing.vserial.VirtualSerialLine`) moves
bytes at once whatever its nominal baud rate, so a device behind it may answer before the request
could have crossed a real wire; dropping that answer would break the line. ``mode``:

* ``None`` (auto, the default): the time rule applies on a port whose driver is a serial driver
  (it answers the ``TIOCGSERIAL`` ioctl: on-board UARTs, USB adapters; ptys do not); elsewhere only
  bytes that arrive while no request is outstanding are dropped;
* ``True``: the line is real (or paced like one, ``VirtualSerialLine(pace=True)``): the time rule
  always applies;
* ``False``: no guard.

The rule errs towards accepting: bytes first seen later than that moment are taken as the reply's
start, even if they arrived just before it (the line is polled). What it cannot catch is a stale
frame that starts after our request ended (a repeater that delays by more than that); a tail of a
stale frame left behind makes the real reply fail its CRC and the request is retried, it is never
taken for the reply.

Frames that follow each other: a stale frame that got past the time rule may be followed by the
real reply; of several complete frames back to back the last is the reply (:func:`last_reply`).
So a receiver takes a reply only after the line has been silent for :attr:`StaleGuard.settle_s`
(:data:`SETTLE_CHARS` characters, at least :data:`_MIN_SETTLE_S`: as long as pymodbus's own sync
receive listens after the last byte, one poll of max(4 characters, 1 ms)). The bus keeps the line
quiet for the silent interval after a reply anyway (3.5 characters, or the map's floor, e.g. 1.75 ms
above 19200 Bd) counted from the reply's last byte, so the settle time overlaps it: it adds at most
half a character, plus the client's own work on the reply.

The guard wraps hooks of a pymodbus serial client instance (the classes are untouched): the
transaction manager's ``low_level_send`` (when the request left) and, for the sync client, ``recv``,
or, for the asyncio client, ``datagram_received`` (every chunk as the event loop reads it). On the
sync client, a receiver that reads the line itself (:class:`drivemap.runtime.client.transport.serialrx.SerialReceiver`)
hands every chunk it reads, with the moment it read it, to :meth:`StaleGuard.skip` until the reply
begins, and waits :attr:`StaleGuard.settle_s` after it; on pymodbus's own receive the guard polls the
line until the earliest possible reply, dropping what arrives before it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from pymodbus.framer import FramerAscii, FramerRTU

__all__ = [
    "CONTINUATION_CHARS",
    "REPLY_START_CHARS",
    "SETTLE_CHARS",
    "StaleGuard",
    "guard_async_client",
    "guard_sync_client",
    "last_reply",
    "real_port",
]

#: Silence (in characters) that ends a stale frame: the characters of one frame are never further
#: apart than 1.5 (Modbus over Serial Line v1.02, 2.5.1.1); at least :data:`_MIN_GAP_S` (host resolution).
CONTINUATION_CHARS = 1.5
_MIN_GAP_S = 0.0005
#: Characters after the end of our request before the first byte of a reply can be complete here.
REPLY_START_CHARS = 1.0
#: Silence (in characters) after a complete reply before it is taken, so that a frame following it is
#: seen (:func:`last_reply`); at least :data:`_MIN_SETTLE_S`. pymodbus's sync receive listens as long.
SETTLE_CHARS = 4.0
_MIN_SETTLE_S = 0.001


class StaleGuard:
    """When the reply to the request in flight can begin, and which bytes came too early.

    ``char_s``: seconds per character on the line; ``on_stale(data, first)``: called with every
    dropped chunk, ``first`` being True for the first chunk of a transaction (count it once);
    ``mode``: see the module docstring.
    """

    def __init__(self, char_s: float, on_stale: Callable[[bytes, bool], None], mode: bool | None = None) -> None:
        self.char_s = char_s
        self.turnaround_s = REPLY_START_CHARS * char_s
        self.gap_s = max(CONTINUATION_CHARS * char_s, _MIN_GAP_S)
        #: Silence after a complete reply before a receiver takes it (s).
        self.settle_s = max(SETTLE_CHARS * char_s, _MIN_SETTLE_S)
        self.on_stale = on_stale
        self.mode = mode
        self.real = False  # the time rule applies to the request in flight
        self.earliest = 0.0  # time.monotonic() of the earliest possible reply (0.0: no request yet)
        self.last_stale = 0.0  # when the last stale byte was seen in this transaction
        self.counted = False
        self.checked = False  # the sync client has looked at the line after this request

    def sent(self, nbytes: int, start: float, port: Any) -> None:
        """A request of ``nbytes`` bytes was handed to ``port`` (a pyserial port) at ``start``."""
        self.real = self.mode is True or (self.mode is None and real_port(port))
        if self.real:
            self.earliest = start + nbytes * self.char_s + self.turnaround_s
        else:
            self.earliest = start
        self.last_stale = 0.0
        self.counted = False
        self.checked = False

    def stale(self, now: float, nbytes: int = 1) -> bool:
        """Whether ``nbytes`` bytes first seen at ``now`` are stale (if so, they are the stale frame's latest).

        On a real line characters arrive one character time apart, so the first of ``nbytes`` bytes
        seen together arrived ``nbytes - 1`` character times before ``now`` at the latest (the
        host may see them late, never early).
        """
        first = now - (nbytes - 1) * self.char_s if self.real and nbytes > 1 else now
        if first < self.earliest or (self.last_stale and first - self.last_stale < self.gap_s):
            self.last_stale = now
            return True
        return False

    def skip(self, now: float, data: bytes) -> bool:
        """Bytes ``data`` read from the line at ``now`` (``time.monotonic()``, read as they arrived):
        True when they are stale (then dropped and counted, :meth:`drop`), False when the reply begins."""
        if self.stale(now, len(data)):
            self.drop(data)
            return True
        return False

    def drop(self, data: bytes) -> None:
        if data:
            first = not self.counted
            self.counted = True
            self.on_stale(data, first)


_REAL: dict[int, tuple[Any, bool]] = {}


def real_port(port: Any) -> bool:
    """Whether ``port`` (a pyserial port) is driven by a serial driver, i.e. carries real characters.

    Linux's serial drivers answer ``TIOCGSERIAL``; a pty does not. Elsewhere: False (no time rule).
    Cached per port object.
    """
    hit = _REAL.get(id(port))
    if hit is not None and hit[0] is port:
        return hit[1]
    real = False
    fd = getattr(port, "fd", None)
    if isinstance(fd, int):
        try:
            import fcntl
            import termios

            request = getattr(termios, "TIOCGSERIAL", None)
            if request is not None:
                fcntl.ioctl(fd, request, bytearray(256))
                real = True
        except (ImportError, OSError):
            real = False
    if len(_REAL) > 64:
        _REAL.clear()
    _REAL[id(port)] = (port, real)
    return real


def _frames(framer: Any, data: bytes) -> list[int]:
    """End offsets of the complete frames (right CRC/LRC) that follow each other from the start of ``data``."""
    ends: list[int] = []
    pos = 0
    if isinstance(framer, FramerAscii):
        while True:
            end = data.find(b"\r\n", pos)
            if end == -1 or not data.startswith(b":", pos):
                return ends
            try:
                raw = bytes.fromhex(data[pos + 1 : end].decode("ascii"))
            except (ValueError, UnicodeDecodeError):
                return ends
            if len(raw) < 3 or FramerAscii.compute_LRC(raw[:-1]) != raw[-1]:
                return ends
            pos = end + 2
            ends.append(pos)
    while len(data) - pos >= 4:
        try:
            cls = framer.decoder.lookupPduClass(data[pos:])
            size = int(cls.calculateRtuFrameSize(data[pos:])) if cls is not None else 0
        except (IndexError, ValueError, TypeError):
            return ends
        if not size or len(data) - pos < size:
            return ends
        if not FramerRTU.check_CRC(data[pos : pos + size - 2], int.from_bytes(data[pos + size - 2 : pos + size], "big")):
            return ends
        pos += size
        ends.append(pos)
    return ends


def last_reply(framer: Any, data: bytes) -> tuple[bytes, bytes]:
    """(what to decode, what to drop): when ``data`` holds several complete frames back to back, all
    but the last are stale (a device answers a request once; what came before the answer is an
    earlier frame delivered again or late)."""
    ends = _frames(framer, data)
    if len(ends) < 2:
        return data, b""
    return data[ends[-2]:], data[: ends[-2]]


def guard_sync_client(client: Any, guard: StaleGuard, receiver: Any = None) -> None:
    """Install ``guard`` on a pymodbus ``ModbusSerialClient`` (instance hooks; the class is untouched).

    ``receiver``: the :class:`~drivemap.runtime.client.transport.serialrx.SerialReceiver` in ``client.recv``, if any; it
    gets the guard and, for the transactions it reads itself, drops stale bytes as they arrive."""
    if guard.mode is False:
        return
    if receiver is not None:
        receiver.guard = guard
    ctx = client.transaction  # the sync client's transaction manager (``ctx`` on the asyncio client)
    plain_send = ctx.low_level_send
    plain_recv = client.recv

    def send(request: bytes, addr: Any = None) -> int:
        port = client.socket
        if request and port is not None:
            waiting = client._in_waiting()
            if waiting:  # arrived between transactions: nobody asked for it
                guard.drop(port.read(waiting))
        start = time.monotonic()
        size: int = plain_send(request, addr=addr)
        if request and port is not None:
            guard.sent(len(request), start, port)
        return size

    def recv(size: int | None) -> bytes:
        if size is None and not guard.checked and client.socket is not None and (
                receiver is None or receiver.takes(size) is None):
            _skip_stale(client, guard)
        data: bytes = plain_recv(size)
        if size is None:
            data, dropped = last_reply(client.framer, data)
            guard.drop(dropped)
        return data

    ctx.low_level_send = send
    client.recv = recv


def _skip_stale(client: Any, guard: StaleGuard) -> None:
    """Poll the line until the earliest possible reply, dropping what arrives before it and the rest of
    that frame; bytes first seen later are left for pymodbus (see the module docstring)."""
    poll = max(min(float(getattr(client, "_recv_interval", 0.001)), guard.gap_s, 0.001), 0.0002)
    deadline = guard.earliest + float(client.comm_params.timeout_connect or 1.0)
    try:
        while True:
            now = time.monotonic()
            waiting = client._in_waiting()
            if waiting:
                if not guard.stale(now, waiting):
                    return
                guard.drop(client.socket.read(waiting))
            elif now >= guard.earliest and (not guard.last_stale or now - guard.last_stale >= guard.gap_s):
                return
            if now > deadline:
                return
            time.sleep(poll)
    finally:
        guard.checked = True


def guard_async_client(client: Any, guard: StaleGuard) -> None:
    """Install ``guard`` on a pymodbus ``AsyncModbusSerialClient`` (instance hooks on its transaction manager)."""
    if guard.mode is False:
        return
    ctx = client.ctx
    plain_send = ctx.low_level_send
    plain_received = ctx.datagram_received

    def send(data: bytes, addr: Any = None) -> None:
        start = time.monotonic()
        plain_send(data, addr=addr)
        if data:
            guard.sent(len(data), start, getattr(ctx.transport, "sync_serial", None))

    def received(data: bytes, addr: Any) -> None:
        future = getattr(ctx, "response_future", None)
        idle = future is None or future.done()
        if idle or guard.stale(time.monotonic(), len(data)):
            guard.drop(data)
            return
        if not ctx.recv_buffer:  # the start of the reply: a stale frame may sit in front of it
            data, dropped = last_reply(ctx.framer, data)
            guard.drop(dropped)
        plain_received(data, addr)

    ctx.low_level_send = send
    ctx.datagram_received = received
