"""Modbus TCP for the simulator: every frame answered in order, and no connection ever wedged.

pymodbus's TCP server handles one MBAP frame per read of the socket (a second request in the same
segment waits for more data, and the reply to the first empties the receive buffer), keeps bytes
with a bad protocol id forever, and lets a wrong length field eat the next request. A client then
waits for a reply that never comes on a connection the server still holds open. Here the server's
connections (:class:`SimTcpConnection`, made by :class:`SimTcpServer`) follow these rules:

* every complete frame in the buffer is taken, in order, and answered in order (requests sent
  back to back, in one segment or many, each get their reply);
* an MBAP header that cannot start a frame - protocol id other than 0, a length field outside
  2..254 (unit id + a PDU of 1..253 bytes, Modbus Application Protocol v1.1b3, 4.1) - means the
  framing is lost: the connection is closed at once, so the client learns it at once;
* bytes of an unfinished frame that see no new byte for :data:`PARTIAL_FRAME_TIMEOUT_S` mean the
  same (a length field longer than the data sent): the connection is closed;
* every PDU goes to :meth:`Simulator.handle` with ``always_answer=True``: a malformed PDU (03h with
  extra bytes, 06h one byte short, 10h whose byte count does not match) gets the exception the
  map's ``exception_policy`` names, or the Modbus standard code where the map says the device stays
  silent (silence fits a serial line; on TCP it only costs the client its timeout), and so do
  function codes 00h and 80h-FFh (illegal function);
* a PDU whose own fields give another length than its MBAP header (:func:`pdu_length_problem`)
  may hold the next request's bytes (a length field longer than the frame swallows what follows):
  after its exception reply the connection is closed, so a request it swallowed ends in a closed
  connection, not in silence;
* requests to units the simulator does not serve and broadcasts get no reply, as before;
* a connection that sends nothing for the server's idle timeout (:data:`IDLE_TIMEOUT_S`, 60 s, unless
  ``idle_timeout`` says otherwise: ``drivemap simulate --idle-timeout S``) is closed: idle clients cannot
  hold the server's connections forever (a client reconnects, as after any closed connection).

The frame layout is pymodbus's :class:`~pymodbus.framer.FramerSocket` (which also encodes the
replies); only the header checks and the loop over frames are added.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import deque
from typing import Any

from pymodbus.framer import FramerSocket
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler

from drivemap.runtime.client.transport.bus import sleep_until
from drivemap.runtime.sim.simulator import Simulator

__all__ = [
    "IDLE_TIMEOUT_S",
    "MAX_IDLE_TIMEOUT_S",
    "MAX_MBAP_LENGTH",
    "PARTIAL_FRAME_TIMEOUT_S",
    "SimTcpConnection",
    "SimTcpServer",
    "mbap_problem",
    "pdu_length_problem",
]

log = logging.getLogger("drivemap.simulator")

#: Largest MBAP length field: unit id + a PDU of at most 253 bytes.
MAX_MBAP_LENGTH = 254
#: Seconds an unfinished frame may wait for its next byte before the connection is closed. The
#: bytes of one frame follow each other within a round trip; a frame that stops for this long was
#: announced longer than it is, and whatever comes next would be misread as its rest.
PARTIAL_FRAME_TIMEOUT_S = 0.1
#: Seconds without a byte after which a connection is closed (the default; ``idle_timeout`` of the server).
IDLE_TIMEOUT_S = 60.0
#: The longest idle timeout a server takes (a day).
MAX_IDLE_TIMEOUT_S = 86400.0
_HEADER = 7  # transaction id, protocol id, length, unit id


#: PDU length of request function codes whose length the PDU itself fixes: code -> (length, or
#: (position of a byte count, bytes before and including it) for codes with a byte count).
_FIXED_PDU = {0x01: 5, 0x02: 5, 0x03: 5, 0x04: 5, 0x05: 5, 0x06: 5, 0x07: 1, 0x0B: 1, 0x0C: 1, 0x11: 1, 0x16: 7,
              0x18: 3}
_COUNTED_PDU = {0x0F: 5, 0x10: 5, 0x17: 9}  # position of the byte count


def pdu_length_problem(pdu: bytes) -> str | None:
    """Why the MBAP length cannot be right for ``pdu`` (None: it fits, or the code does not fix a length).

    A request whose own fields give another length than the MBAP header (03h with extra bytes, 06h
    one byte short, 10h whose byte count does not match) is malformed, and the bytes around it may
    belong to the next request: after the exception reply the connection is closed.
    """
    code = pdu[0] if pdu else 0
    want = _FIXED_PDU.get(code)
    if want is None and code in _COUNTED_PDU:
        at = _COUNTED_PDU[code]
        want = at + 1 + pdu[at] if len(pdu) > at else at + 1
    if want is None or want == len(pdu):
        return None
    return f"function 0x{code:02X} takes a PDU of {want} bytes, the MBAP length gives {len(pdu)}"


def mbap_problem(data: bytes) -> str | None:
    """Why the MBAP header at the start of ``data`` cannot begin a frame (None: it can, or too few bytes yet)."""
    if len(data) >= 4 and data[2:4] != b"\x00\x00":
        return f"protocol id 0x{int.from_bytes(data[2:4], 'big'):04X} is not Modbus (0)"
    if len(data) >= 6:
        length = int.from_bytes(data[4:6], "big")
        if not 2 <= length <= MAX_MBAP_LENGTH:
            return f"length field {length} outside 2..{MAX_MBAP_LENGTH}"
    return None


class SimTcpConnection(ServerRequestHandler):
    """One client connection of a :class:`SimTcpServer` (see the module docstring for the rules)."""

    def __init__(self, owner: SimTcpServer) -> None:
        super().__init__(owner, None, None, None)  # type: ignore[no-untyped-call]
        self.sim = owner.sim
        self.max_buffer_size = 1 << 16  # frames are taken as they complete; never drop a backlog unread
        self._queue: deque[tuple[float, int, int, bytes, str | None]] = deque()
        self._worker: asyncio.Task[None] | None = None
        self._stale: asyncio.TimerHandle | None = None
        self._doubt = False  # a frame whose PDU disagrees with its MBAP length was taken
        self._idle: asyncio.TimerHandle | None = None
        self.idle_timeout = owner.idle_timeout

    def callback_connected(self) -> None:
        super().callback_connected()
        self._arm_idle()

    def _arm_idle(self) -> None:
        if self._idle is not None:
            self._idle.cancel()
        seconds = self.idle_timeout if self.idle_timeout is not None else IDLE_TIMEOUT_S
        self._idle = self.loop.call_later(seconds, self.give_up, f"idle for {seconds:g} s")

    # ---- receiving -------------------------------------------------------------------------------
    def callback_data(self, data: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """Take every complete frame of ``data``; returns the bytes used (the rest waits for more)."""
        if self.is_closing or self._doubt:
            return len(data)
        self._arm_idle()
        now = time.monotonic()
        used = 0
        while True:
            rest = data[used:]
            problem = mbap_problem(rest)
            if problem is not None:
                self.give_up(problem, rest)
                return len(data)
            if len(rest) < _HEADER:
                break
            size = 6 + int.from_bytes(rest[4:6], "big")
            if len(rest) < size:
                break
            tid, unit = int.from_bytes(rest[0:2], "big"), rest[6]
            pdu = bytes(rest[_HEADER:size])
            doubt = pdu_length_problem(pdu)
            self._queue.append((now, tid, unit, pdu, doubt))
            used += size
            if doubt is not None:  # answered, then the connection closes: what follows is not trusted
                self._doubt = True
                used = len(data)
                break
        if self._stale is not None:
            self._stale.cancel()
            self._stale = None
        if used < len(data):
            self._stale = self.loop.call_later(PARTIAL_FRAME_TIMEOUT_S, self.give_up,
                                               "unfinished frame: no byte for a while", data[used:])
        if self._queue and (self._worker is None or self._worker.done()):
            self._worker = self.loop.create_task(self._serve())
        return used

    async def _serve(self) -> None:
        """Answer the queued frames one after the other (replies leave in request order)."""
        sim = self.sim
        framer = self.framer
        while self._queue and not self.is_closing:
            arrived, tid, unit, pdu, doubt = self._queue.popleft()
            answer = sim.handle(unit, pdu, always_answer=True)
            if answer is not None:
                delay = sim.reply_delay()
                if delay > 0:
                    await sleep_until(arrived + delay)
                if self.transport is not None and not self.is_closing:
                    # not ModbusProtocol.send: it empties the receive buffer (the next request's bytes)
                    self.transport.write(framer.encode(answer, unit, tid))  # type: ignore[attr-defined]
            if doubt is not None:
                self.give_up(doubt, pdu)

    # ---- giving up -------------------------------------------------------------------------------
    def give_up(self, why: str, data: bytes = b"") -> None:
        """The framing is lost: close the connection (replies already written still leave first)."""
        if self.is_closing:
            return
        log.info("simulator: closing a Modbus TCP connection: %s (%s)", why, data[:16].hex(" "))
        self._queue.clear()
        self._cancel()
        self.close()

    def _cancel(self) -> None:
        if self._idle is not None:
            self._idle.cancel()
            self._idle = None
        if self._stale is not None:
            self._stale.cancel()
            self._stale = None
        if self._worker is not None and not self._worker.done():
            self._worker.cancel()

    def callback_disconnected(self, exc: Exception | None) -> None:
        self._queue.clear()
        self._cancel()
        super().callback_disconnected(exc)


class SimTcpServer(ModbusTcpServer):
    """pymodbus's TCP server with :class:`SimTcpConnection` connections serving ``sim``; a connection
    idle for ``idle_timeout`` seconds (None: :data:`IDLE_TIMEOUT_S`) is closed."""

    def __init__(self, sim: Simulator, context: Any, *, idle_timeout: float | None = None, **kwargs: Any) -> None:
        if idle_timeout is not None and not 0 < idle_timeout <= MAX_IDLE_TIMEOUT_S:
            raise ValueError(f"idle_timeout {idle_timeout!r}: give seconds above 0 up to {MAX_IDLE_TIMEOUT_S:g}")
        self.sim = sim
        self.idle_timeout = idle_timeout
        kwargs.setdefault("framer", "socket")
        super().__init__(context, **kwargs)
        if not issubclass(self.framer, FramerSocket):
            raise ValueError("SimTcpServer speaks Modbus TCP (MBAP) only")

    def callback_new_connection(self) -> SimTcpConnection:
        return SimTcpConnection(self)

    async def shutdown(self) -> None:
        for connection in list(self.active_connections.values()):
            if isinstance(connection, SimTcpConnection):
                connection._cancel()
        await super().shutdown()  # type: ignore[no-untyped-call]
