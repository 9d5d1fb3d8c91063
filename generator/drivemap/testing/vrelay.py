"""The relay of a :class:`~drivemap.testing.vserial.VirtualSerialLine`: the thread that moves bytes
between the two ptys, paces them like a UART, applies the fault plan and captures the traffic.

The rules it follows (frames, pacing, faults, line settings) are in :mod:`drivemap.testing.vserial`.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import select
import termios
import threading
import time
from collections import deque

from drivemap.testing.vfaults import Direction, FaultPlan, FrameFault

__all__ = ["Direction", "Relay"]

_READ_SIZE = 65536


class _Item:
    """A run of bytes scheduled for delivery: byte k is due at ``start + (k + 1) * byte_time``."""

    __slots__ = ("start", "data", "pos", "idle_before")

    def __init__(self, start: float, data: bytes, idle_before: float = 0.0) -> None:
        self.start = start
        self.data = data
        self.pos = 0
        #: silence owed before the first byte, counted from the previous byte's real delivery
        self.idle_before = idle_before


class RelayPath:
    """State of one direction of the relay."""

    def __init__(self, name: Direction, src: int, dst: int) -> None:
        self.name = name
        self.src = src
        self.dst = dst
        self.queue: deque[_Item] = deque()
        self.outbuf = bytearray()
        self.free_at = 0.0  # when the (scheduled) transmitter becomes idle
        self.last_write = 0.0  # when bytes were last really written to the receiver
        self.frame_open = False
        self.last_arrival = 0.0
        self.frame_fault: FrameFault | None = None
        self.frame_pos = 0
        self.frame_out = bytearray()
        self.captured: list[tuple[float, bytes]] = []
        self.delivered: list[tuple[float, bytes]] = []

    def busy(self) -> bool:
        return self.frame_open or bool(self.queue) or bool(self.outbuf)



class Relay:
    """The relay thread's work, mixed into :class:`~drivemap.testing.vserial.VirtualSerialLine`
    (which sets these attributes up in its ``__init__``)."""

    _cond: threading.Condition
    _paths: dict[Direction, RelayPath]
    _slave_fds: dict[Direction, tuple[int, int]]
    _wake_r: int
    _wake_w: int
    _stop: bool
    _closed: bool
    _error: BaseException | None
    faults: FaultPlan
    frame_gap: float
    byte_time: float
    burst_interval: float
    spin: float
    capture: bool
    line_settings: bool
    device_parity: str | None

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def _inject(self, direction: Direction, data: bytes) -> None:
        with self._cond:
            if data:
                self._enqueue(self._paths[direction], data, time.monotonic())
        self._wake()

    def _enqueue(self, path: RelayPath, data: bytes, ready: float, idle_before: float = 0.0) -> None:
        # Caller holds the lock.  FIFO: an item never starts before the one ahead of it.
        start = max(ready, path.free_at + idle_before)
        path.queue.append(_Item(start, data, idle_before))
        path.free_at = start + len(data) * self.byte_time

    def _on_input(self, path: RelayPath, data: bytes, now: float) -> None:
        # Caller holds the lock.
        if self.capture:
            path.captured.append((now, data))
        if self.line_settings:
            data = self._through_uarts(path.name, data)
        if path.frame_open and now - path.last_arrival > self.frame_gap:
            self._close_frame(path, now)
        fault = path.frame_fault
        if not path.frame_open:
            path.frame_open = True
            path.frame_pos = 0
            path.frame_out = bytearray()
            fault = path.frame_fault = self.faults.take(path.name)
            if fault is not None and fault.prefix:
                self._enqueue(path, fault.prefix, now + fault.delay)
        path.last_arrival = now
        out: bytes = data
        if fault is not None:
            if fault.drop:
                out = b""
            else:
                if fault.corrupt is not None:
                    index, mask = fault.corrupt
                    offset = index - path.frame_pos
                    if 0 <= offset < len(data):
                        changed = bytearray(data)
                        changed[offset] ^= mask
                        out = bytes(changed)
                if fault.truncate is not None:
                    out = out[: max(0, fault.truncate - path.frame_pos)]
        path.frame_pos += len(data)
        if out:
            path.frame_out += out
            self._enqueue(path, out, now + (fault.delay if fault is not None else 0.0))

    def _close_frame(self, path: RelayPath, now: float) -> None:
        # Caller holds the lock.
        fault = path.frame_fault
        if fault is not None:
            delay = fault.delay
            if fault.suffix:
                self._enqueue(path, fault.suffix, path.last_arrival + delay)
            if fault.duplicate and path.frame_out:
                self._enqueue(path, bytes(path.frame_out), now + delay, idle_before=self.frame_gap)
        path.frame_open = False
        path.frame_fault = None
        path.frame_out = bytearray()

    def _through_uarts(self, direction: Direction, data: bytes) -> bytes:
        """What the receiving end's UART makes of ``data`` (see "Line settings" in the module docstring)."""
        sender, receiver = (_uart_settings(fd) for fd in self._slave_fds[direction])
        if self.device_parity is not None:
            if direction == "to_device":
                receiver = (receiver[0], self.device_parity, *receiver[2:])
            else:
                sender = (sender[0], self.device_parity, *sender[2:])
        if sender == receiver:
            return data
        if sender[0] != receiver[0]:
            return bytes(b ^ 0xFF for b in data)
        if direction == "to_device":
            return data
        out = bytearray()
        for b in data:
            sent = _parity_bit(b, sender[1]) if sender[1] != "N" else 1  # the bit after the data bits
            if receiver[1] != "N":
                ok = sent == _parity_bit(b, receiver[1])
            else:
                ok = sent == 1  # read as the stop bit
            out.append(b if ok else 0)
        return bytes(out)

    def _collect_due(self, path: RelayPath, now: float) -> tuple[float, float]:
        """Move due bytes to the output buffer.

        Returns ``(wake, precise)``: when the relay should look again, and the due time of the
        last byte of the chunk being transmitted (which is worth a short spin to hit exactly).
        """
        bt = self.byte_time
        while path.queue:
            item = path.queue[0]
            if item.idle_before and item.pos == 0:
                # the silence starts when the previous byte really left, not when it was due
                if path.outbuf:
                    return now + self.burst_interval, math.inf
                item.start = max(item.start, path.last_write + item.idle_before)
                item.idle_before = 0.0
            if bt == 0.0:
                if now < item.start:
                    return item.start, math.inf
                path.outbuf += item.data[item.pos :]
                path.queue.popleft()
                continue
            last_due = item.start + len(item.data) * bt
            if now < last_due <= now + self.burst_interval:
                # Final stretch: hold the rest and deliver it in one write exactly at last_due,
                # so the receiver is not woken (competing for the CPU) just before that.
                return last_due, last_due
            due = min(len(item.data), int((now - item.start) / bt + 1e-9))
            if due > item.pos:
                path.outbuf += item.data[item.pos : due]
                item.pos = due
            if item.pos >= len(item.data):
                path.queue.popleft()
                continue
            remaining = len(item.data) - item.pos
            next_due = item.start + (item.pos + 1) * bt
            if remaining == 1:
                return last_due, last_due
            # Sleep to the next byte, but not less than burst_interval, never past the last byte.
            return min(last_due, max(next_due, now + self.burst_interval)), last_due
        return math.inf, math.inf

    def _write_out(self, path: RelayPath) -> None:
        if not path.outbuf:
            return
        try:
            written = os.write(path.dst, path.outbuf)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.EAGAIN):
                return
            raise
        if written:
            path.last_write = time.monotonic()
            if self.capture:
                path.delivered.append((path.last_write, bytes(path.outbuf[:written])))
            del path.outbuf[:written]

    def _run(self) -> None:
        paths = list(self._paths.values())
        poller = select.poll()
        registered: dict[int, int] = {}
        try:
            while True:
                with self._cond:
                    if self._stop:
                        return
                    wake, precise = self._advance(paths, time.monotonic())
                    self._cond.notify_all()
                    masks: dict[int, int] = {self._wake_r: select.POLLIN}
                    for path in paths:
                        masks[path.src] = masks.get(path.src, 0) | select.POLLIN
                        if path.outbuf:
                            masks[path.dst] = masks.get(path.dst, 0) | select.POLLOUT
                for fd, mask in masks.items():
                    if registered.get(fd) != mask:
                        poller.register(fd, mask)  # register() on a known fd modifies it
                        registered[fd] = mask
                self._serve(self._next_events(poller, wake, precise))
        except BaseException as exc:  # surfaced by close()
            self._error = exc
        finally:
            with self._cond:
                self._closed = True
                self._cond.notify_all()

    def _advance(self, paths: list[RelayPath], now: float) -> tuple[float, float]:
        """Close frames whose gap passed, move due bytes out (lock held); (wake, precise) times of the next event."""
        wake = precise = math.inf
        for path in paths:
            if path.frame_open:
                deadline = path.last_arrival + self.frame_gap
                if now > deadline:
                    self._close_frame(path, now)
                else:
                    wake = min(wake, deadline + 1e-4)
            path_wake, path_precise = self._collect_due(path, now)
            wake = min(wake, path_wake)
            precise = min(precise, path_precise)
            self._write_out(path)
        return wake, precise

    def _next_events(self, poller: select.poll, wake: float, precise: float) -> list[tuple[int, int]]:
        now = time.monotonic()
        if precise <= wake:  # next event: the last byte of a chunk, due at `precise`
            if precise - now <= self.spin:
                return self._spin(poller, precise)
            return self._wait(poller, precise - self.spin - now)
        return self._wait(poller, wake - now)

    def _serve(self, events: list[tuple[int, int]]) -> None:
        for fd, event in events:
            if fd == self._wake_r:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_r, 4096)
                continue
            if event & (select.POLLIN | select.POLLHUP | select.POLLERR):
                self._read(fd)

    def _wait(self, poller: select.poll, timeout: float) -> list[tuple[int, int]]:
        """poll() with sub-millisecond precision: poll whole ms, sleep the fraction."""
        if timeout == math.inf:
            return poller.poll(1000)
        if timeout <= 0:
            return poller.poll(0)
        if timeout >= 0.001:
            return poller.poll(int(timeout * 1000))
        events = poller.poll(0)
        if not events:
            time.sleep(timeout)
        return events

    @staticmethod
    def _spin(poller: select.poll, target: float) -> list[tuple[int, int]]:
        """Busy-wait (non-blocking polls, which release the GIL) until ``target`` or input."""
        while True:
            events = poller.poll(0)
            if events or time.monotonic() >= target:
                return events

    def _read(self, fd: int) -> None:
        try:
            data = os.read(fd, _READ_SIZE)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open; cannot happen while we hold the slaves
                time.sleep(0.001)
                return
            raise
        if not data:
            return
        now = time.monotonic()
        with self._cond:
            for path in self._paths.values():
                if path.src == fd:
                    self._on_input(path, data, now)



def _uart_settings(fd: int) -> tuple[int, str, int, int]:
    """(baud rate code, parity N/E/O, data bits, stop bits) a pty end is set to."""
    attrs = termios.tcgetattr(fd)
    cflag = attrs[2]
    # Some kernels keep PARODD but drop PARENB on a pty (and refuse even parity): PARODD alone is odd.
    parity = "O" if cflag & termios.PARODD else ("E" if cflag & termios.PARENB else "N")
    size = {termios.CS5: 5, termios.CS6: 6, termios.CS7: 7, termios.CS8: 8}.get(cflag & termios.CSIZE, 8)
    return attrs[5], parity, size, 2 if cflag & termios.CSTOPB else 1


def _parity_bit(byte: int, parity: str) -> int:
    ones = bin(byte).count("1") & 1
    return ones if parity == "E" else 1 - ones


