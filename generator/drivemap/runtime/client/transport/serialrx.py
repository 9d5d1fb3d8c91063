"""Sync serial receive that sees the end of a reply as it arrives (RTU and ASCII).

pymodbus's sync serial client (``ModbusSerialClient.recv(None)`` → ``_wait_for_data``) polls
``in_waiting`` every max(4 characters, 1 ms) and returns only after a poll that saw no new byte,
so it notices the end of a reply 1-2 ms late at 115200 Bd. :class:`SerialReceiver` takes that
client's ``recv`` (instance attribute; pymodbus itself is not patched) and, for a request whose
reply length is known (:func:`reply_length`), reads it as it comes:

1. with a stale-reply guard (:mod:`drivemap.runtime.client.transport.staleguard`, the default): every chunk that
   arrives before the reply, with the moment it was read, goes to :meth:`StaleGuard.skip
   <drivemap.runtime.client.transport.staleguard.StaleGuard.skip>`, which drops and counts what began before the
   request could have been answered; the first chunk it accepts begins the reply;
2. a blocking read of the frame's head (RTU: unit + function; ASCII: ``:`` + 4 hex digits) within
   the response timeout; the head says whether the reply is an exception (shorter frame);
3. a blocking read of the rest of the expected length, each byte within the inter-character
   timeout :attr:`SerialReceiver.gap_s` (a shorter frame ends when the line goes silent that long);
4. a quiet-time wait counted from the last byte: bytes that follow within :attr:`SerialReceiver.quiet_s`
   (with a guard: its ``settle_s``, long enough to see a frame that follows, as pymodbus's own
   receive would) belong to this reply (a longer foreign frame, a duplicate) and are handed over
   with it, so pymodbus's framer, the guard (the last of several complete frames is the reply) and
   the bus's reply checks see them as before.

The silence seen after the last byte is reported (``on_silence``) so the bus counts its quiet time
from the reply's last byte, not from the hand-over.

Anything else — a request whose reply length is unknown, a second ``recv`` in the same
transaction (the framer wanted more: garbage, a bad CRC/LRC), a port without a file descriptor,
local echo handled by pymodbus — goes to pymodbus's own ``recv`` unchanged (and the guard polls
the line itself).
"""

from __future__ import annotations

import os
import select
import time
from collections.abc import Callable
from typing import Any

__all__ = ["SerialReceiver", "reply_length"]

#: Floor of the inter-character timeout (s): ptys and USB adapters deliver in bursts.
MIN_GAP_S = 0.002
#: Floor of the quiet time after the expected length (s).
MIN_QUIET_S = 0.0001


def reply_length(pdu: Any) -> int:
    """Bytes of the RTU frame answering ``pdu`` when it succeeds (0: not known here)."""
    fc = pdu.function_code
    if fc in (0x03, 0x04):
        return 5 + 2 * int(pdu.count)
    if fc in (0x01, 0x02):
        return 5 + (int(pdu.count) + 7) // 8
    if fc in (0x05, 0x06, 0x0F, 0x10):
        return 8
    return 0


class SerialReceiver:
    """Replaces ``client.recv`` of one pymodbus ``ModbusSerialClient`` (see the module docstring)."""

    def __init__(self, client: Any, char_s: float, ascii_mode: bool,
                 on_silence: Callable[[float], None] | None = None) -> None:
        self._client = client
        self._fallback = client.recv  # pymodbus's own, bound to the client
        #: pymodbus's receive returns after a poll interval without a new byte: the silence it has seen.
        self._fallback_silence = float(getattr(client, "_recv_interval", 0.0))
        self._on_silence = on_silence
        #: The stale-reply guard (set by :func:`drivemap.runtime.client.transport.staleguard.guard_sync_client`), or None.
        self.guard: Any = None
        #: Replies this receiver read itself (not through pymodbus's receive).
        self.handled = 0
        self._ascii = ascii_mode
        self.char_s = char_s
        #: Inter-character timeout within a frame (s).
        self.gap_s = max(4.0 * char_s * (2 if ascii_mode else 1), MIN_GAP_S)
        #: Silence after the expected length before the reply is handed over (s).
        self.quiet_s = max(1.5 * char_s, MIN_QUIET_S)
        self._expected = 0  # RTU bytes of the current transaction's reply, 0 when not known
        self._got = 0
        #: time.monotonic() of the last byte this receiver read.
        self.last_byte_at = 0.0
        self._deadline = 0.0
        client.recv = self.recv

    def expect(self, pdu: Any) -> None:
        """A new transaction: ``pdu`` is about to be sent."""
        self._expected = reply_length(pdu)
        self._got = 0

    def takes(self, size: int | None) -> int | None:
        """The descriptor this receiver reads ``recv(size)`` from itself, or None (pymodbus's receive)."""
        if size is not None or not self._expected or self._got:
            return None
        return self._fd()

    def _fd(self) -> int | None:
        sock = self._client.socket
        if sock is None or self._client.comm_params.handle_local_echo:
            return None
        try:
            return int(sock.fileno())
        except (AttributeError, OSError, ValueError):  # serial_for_url transports without a descriptor
            return None

    def recv(self, size: int | None) -> bytes:
        """pymodbus's ``recv``: with ``size=None``, the reply of the current transaction."""
        fd = self.takes(size)
        if fd is None:
            data: bytes = self._fallback(size)
            self._got += len(data) or 0
            if self._on_silence is not None:
                self._on_silence(self._fallback_silence)
            return data
        try:
            data = self._receive(fd)
        except OSError:
            self._client.close()
            from pymodbus.exceptions import ConnectionException

            raise ConnectionException(str(self._client)) from None
        self._got = max(len(data), 1)
        if data:
            self.handled += 1
            if self._on_silence is not None:
                self._on_silence(max(time.monotonic() - self.last_byte_at, 0.0))
        return data

    def _receive(self, fd: int) -> bytes:
        head = 5 if self._ascii else 2
        buf = bytearray()
        timeout = self._client.comm_params.timeout_connect
        self._deadline = time.monotonic() + timeout  # a line that never goes quiet ends here too
        guard = self.guard
        if guard is not None:
            self._skip_stale(fd, buf, guard)
        self._read(fd, buf, head, self.gap_s if buf else self._deadline - time.monotonic(), self.gap_s)
        if len(buf) < head:
            return bytes(buf)  # nothing (timeout) or a frame shorter than any reply: the framer decides
        try:
            fc = int(buf[3:5], 16) if self._ascii else buf[1]
        except ValueError:  # not hex: garbage, handed over as it is
            fc = 0
        total = 5 if fc & 0x80 else self._expected
        if self._ascii:
            total = 2 * total + 1  # ':' + hex of (frame less CRC, plus LRC) + CR LF
        self._read(fd, buf, total, self.gap_s, self.gap_s)
        if len(buf) >= total:  # quiet time from the last byte
            quiet = self.quiet_s if guard is None else max(self.quiet_s, guard.settle_s)
            self._read(fd, buf, 1 << 16, quiet, quiet)
        return bytes(buf)

    def _skip_stale(self, fd: int, buf: bytearray, guard: Any) -> None:
        """Read chunks as they arrive until the guard takes one for the start of the reply (left in
        ``buf``); it drops and counts the stale ones (see the module docstring)."""
        try:
            while True:
                left = self._deadline - time.monotonic()
                if left <= 0 or not select.select([fd], [], [], left)[0]:
                    return
                chunk = os.read(fd, 4096)
                if not chunk:
                    return
                now = time.monotonic()  # after the read: the chunk's first byte came no later than this
                self.last_byte_at = now
                if not guard.skip(now, chunk):
                    buf += chunk
                    return
        finally:
            guard.checked = True

    def _read(self, fd: int, buf: bytearray, total: int, first_s: float, gap_s: float) -> None:
        """Append to ``buf`` until it holds ``total`` bytes, waiting ``first_s`` for the first
        chunk and ``gap_s`` after each one."""
        wait = first_s
        while len(buf) < total:
            if buf and time.monotonic() >= self._deadline:
                return
            ready, _, _ = select.select([fd], [], [], max(wait, 0.0))
            if not ready:
                return
            chunk = os.read(fd, total - len(buf))
            if not chunk:
                return
            buf += chunk
            self.last_byte_at = time.monotonic()
            wait = gap_s
