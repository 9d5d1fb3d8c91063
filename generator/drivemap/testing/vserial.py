"""A virtual serial line for tests and benchmarks: two ptys joined by a relay thread.

Real serial code (pyserial ``serial.Serial(port)``, pymodbus's serial client and server,
minimalmodbus) opens each end by its device path, exactly as it would open ``/dev/ttyUSB0``::

    with VirtualSerialLine() as line:
        client = ModbusSerialClient(line.master_port, ...)    # the master (client) end
        server = ModbusSerialServer(..., port=line.device_port)  # the device (server) end
        ...
        assert line.captured("to_device") == bytes.fromhex("01 03 00 00 00 01 84 0a")

Both ptys are in raw mode (no echo, no CR/LF translation, no XON/XOFF), so every byte value,
including ``\\r\\n`` in Modbus ASCII frames, passes unchanged.  No system packages or socat.

Directions
    ``"to_device"``: bytes written on ``master_port``, delivered on ``device_port``.
    ``"to_master"``: bytes written on ``device_port``, delivered on ``master_port``.

Capture
    ``captured(d)`` is what the sending end wrote (before faults); ``delivered(d)`` is what the
    receiving end was given (after faults and injected garbage).  ``chunks(d)`` gives the
    timestamped reads (``time.monotonic()``), ``frames(d)`` splits the captured bytes into frames.

Frames (the rule used by both ``frames()`` and fault injection)
    A frame is a burst of bytes written by one end; a new frame starts when the sending end has
    been idle for more than ``frame_gap`` seconds since the previous chunk in that direction.
    ``frame_gap`` defaults to ``max(0.002, 3.5 * byte_time)`` when a baud rate is given
    (the Modbus RTU t3.5 silent interval, but never below 2 ms of scheduling noise), else 0.002 s.
    Idle time is measured on the sender's writes as the relay reads them, not on the paced output.
    Modbus masters and servers write each frame with one ``write()``, so one frame = one write.

Pacing (``pace=True``, needs ``baudrate``)
    Each direction behaves like a UART transmitter with an unbounded FIFO: byte *k* of the
    stream is delivered no earlier than ``max(ready, previous byte's completion) + byte_time``,
    ``byte_time = bits_per_byte / baudrate``.  The schedule is computed from the clock, not from
    when the relay thread happened to wake, so late wake-ups never slow the line below its rate
    and bytes are never early.  To save CPU the relay wakes at most every ``burst_interval``
    seconds (default 1 ms) in the middle of a chunk, delivering every byte already due; the final
    ``burst_interval`` of each written chunk is delivered in one write exactly when its last
    byte is due (the relay sleeps until ``spin`` seconds before it and busy-waits the rest, as
    OS sleeps overshoot by ~0.1 ms).  The two directions are paced independently (full duplex);
    Modbus is request/response, so they never overlap anyway.

Faults (``line.faults``, see :class:`FaultPlan`)
    Per direction, a FIFO of :class:`FrameFault` entries; each frame that *starts* in that
    direction pops the next entry (or passes untouched when the FIFO is empty).  So
    ``faults.drop("to_master"); faults.corrupt("to_master")`` drops the next response and
    corrupts the one after.  Faults act while the frame streams through (no added latency),
    except ``duplicate`` and ``suffix``, which are emitted when the frame ends (after
    ``frame_gap`` of silence).  Everything is thread-safe and deterministic.

Line settings (``line_settings=True``)
    The relay reads the termios settings each end has set (baud rate, parity, data and stop
    bits; pyserial sets them on open) and passes bytes as two UARTs would.  Same settings:
    unchanged.  Different baud rates: the receiver samples at the wrong rate and makes up
    characters (modelled as every byte inverted, both directions: no valid frame survives).
    Same baud rate, another character format: the receiver sees the sender's parity bit (or
    stop bit) where it expects its own parity or stop bit.  The master end checks it, as
    pyserial enables parity checking and Linux delivers a character with a parity or framing
    error as 0x00 (termios: neither IGNPAR nor PARMRK); the device end is lenient and keeps the
    data bits, as many drives do.  So a wrong parity gives garbled replies, a wrong baud rate
    silence (the device never sees a valid request).  Some kernels refuse or drop parity
    settings on a pty (even parity fails to set, odd keeps only PARODD): ``device_parity``
    ("N", "E" or "O") then declares the device end's parity instead of reading it.

Caveat: pyserial discards pending input when it opens a port, so open both ends before
sending.  The relay keeps both pty slaves open itself, so ends may be closed and reopened
(pymodbus reconnects) without the line hanging up.
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
from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Literal

__all__ = [
    "DIRECTIONS",
    "Direction",
    "FaultPlan",
    "FrameFault",
    "VirtualSerialLine",
    "open_pair",
    "split_frames",
]

Direction = Literal["to_device", "to_master"]
DIRECTIONS: tuple[Direction, Direction] = ("to_device", "to_master")

_READ_SIZE = 65536
_DEFAULT_GAP = 0.002


def _check_direction(direction: str) -> Direction:
    if direction == "to_device":
        return "to_device"
    if direction == "to_master":
        return "to_master"
    raise ValueError(f"direction must be 'to_device' or 'to_master', not {direction!r}")


def _make_raw(fd: int) -> None:
    """Put a tty into raw mode (like cfmakeraw): 8N1, no echo, no translation, no flow control."""
    attrs = termios.tcgetattr(fd)
    iflag, oflag, cflag, lflag = attrs[0], attrs[1], attrs[2], attrs[3]
    iflag &= ~(
        termios.IGNBRK
        | termios.BRKINT
        | termios.PARMRK
        | termios.ISTRIP
        | termios.INLCR
        | termios.IGNCR
        | termios.ICRNL
        | termios.IXON
        | termios.IXOFF
        | termios.IXANY
        | termios.INPCK
    )
    oflag &= ~termios.OPOST
    lflag &= ~(termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN)
    cflag &= ~(termios.CSIZE | termios.PARENB)
    cflag |= termios.CS8 | termios.CREAD | termios.CLOCAL
    attrs[0], attrs[1], attrs[2], attrs[3] = iflag, oflag, cflag, lflag
    cc = attrs[6]
    cc[termios.VMIN] = 1
    cc[termios.VTIME] = 0
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def split_frames(chunks: list[tuple[float, bytes]], gap: float) -> list[bytes]:
    """Join timestamped chunks into frames: a new frame starts after more than ``gap`` s idle."""
    frames: list[bytes] = []
    current = bytearray()
    last: float | None = None
    for stamp, data in chunks:
        if last is not None and stamp - last > gap and current:
            frames.append(bytes(current))
            current = bytearray()
        current += data
        last = stamp
    if current:
        frames.append(bytes(current))
    return frames


@dataclass(frozen=True)
class FrameFault:
    """What to do to one frame.  Fields combine; the default instance passes the frame untouched.

    drop       -- deliver none of the frame's own bytes (``prefix``/``suffix`` still go out,
                  so ``FrameFault(drop=True, prefix=b"...")`` replaces a frame by garbage).
    corrupt    -- ``(byte_index, xor_mask)``: XOR the byte at that index (0-based, counted in
                  the frame as written) with the mask.  If the frame is shorter, nothing changes.
    truncate   -- deliver only the first N bytes of the frame.
    delay      -- hold the frame (and, the line being FIFO, everything behind it) this many
                  extra seconds.
    duplicate  -- after the frame ends, deliver it (as altered) a second time, separated by
                  at least ``frame_gap`` of silence.
    prefix     -- bytes delivered immediately before the frame.
    suffix     -- bytes delivered right after the frame (glued to it, no gap).
    """

    drop: bool = False
    corrupt: tuple[int, int] | None = None
    truncate: int | None = None
    delay: float = 0.0
    duplicate: bool = False
    prefix: bytes = b""
    suffix: bytes = b""


_PASS = FrameFault()


class FaultPlan:
    """Per-direction FIFO of frame faults; reach it as ``line.faults``.

    Every method takes ``frames`` (how many consecutive frames get the fault) and returns
    ``self`` so calls can be chained.  ``frames`` queued entries are consumed one per frame.
    """

    def __init__(self, line: VirtualSerialLine) -> None:
        self._line = line
        self._queues: dict[Direction, deque[FrameFault]] = {d: deque() for d in DIRECTIONS}

    def add(self, direction: str, fault: FrameFault, frames: int = 1) -> FaultPlan:
        """Queue ``fault`` for the next ``frames`` frames in ``direction`` (after those queued)."""
        d = _check_direction(direction)
        if frames < 0:
            raise ValueError("frames must be >= 0")
        with self._line._cond:
            self._queues[d].extend([fault] * frames)
        return self

    def passthrough(self, direction: str, frames: int = 1) -> FaultPlan:
        """Let the next ``frames`` frames through untouched (to aim later faults)."""
        return self.add(direction, _PASS, frames)

    def drop(self, direction: str, frames: int = 1) -> FaultPlan:
        """Lose the next ``frames`` frames entirely."""
        return self.add(direction, FrameFault(drop=True), frames)

    def corrupt(self, direction: str, frames: int = 1, *, byte_index: int = 1, mask: int = 0x01) -> FaultPlan:
        """Flip bits (``mask``) in byte ``byte_index`` of each of the next ``frames`` frames."""
        if byte_index < 0 or not 0 < mask <= 0xFF:
            raise ValueError("byte_index must be >= 0 and mask in 1..255")
        return self.add(direction, FrameFault(corrupt=(byte_index, mask)), frames)

    def truncate(self, direction: str, keep: int, frames: int = 1) -> FaultPlan:
        """Deliver only the first ``keep`` bytes of each of the next ``frames`` frames."""
        if keep < 0:
            raise ValueError("keep must be >= 0")
        return self.add(direction, FrameFault(truncate=keep), frames)

    def delay(self, direction: str, seconds: float, frames: int = 1) -> FaultPlan:
        """Hold each of the next ``frames`` frames ``seconds`` longer before delivering it."""
        if seconds < 0:
            raise ValueError("seconds must be >= 0")
        return self.add(direction, FrameFault(delay=seconds), frames)

    def duplicate(self, direction: str, frames: int = 1) -> FaultPlan:
        """Deliver each of the next ``frames`` frames twice."""
        return self.add(direction, FrameFault(duplicate=True), frames)

    def garbage(
        self, direction: str, data: bytes, frames: int = 1, *, where: Literal["before", "after"] = "before"
    ) -> FaultPlan:
        """Glue ``data`` before (or after) each of the next ``frames`` frames."""
        if where == "before":
            fault = FrameFault(prefix=bytes(data))
        elif where == "after":
            fault = FrameFault(suffix=bytes(data))
        else:
            raise ValueError("where must be 'before' or 'after'")
        return self.add(direction, fault, frames)

    def inject(self, direction: str, data: bytes) -> FaultPlan:
        """Put ``data`` on the line now (noise), behind anything already queued for delivery."""
        d = _check_direction(direction)
        self._line._inject(d, bytes(data))
        return self

    def pending(self, direction: str) -> int:
        """How many queued frame faults have not been consumed yet."""
        d = _check_direction(direction)
        with self._line._cond:
            return len(self._queues[d])

    def clear(self, direction: str | None = None) -> None:
        """Forget queued faults (for one direction or both).  A frame in flight keeps its fault."""
        with self._line._cond:
            for d in DIRECTIONS if direction is None else (_check_direction(direction),):
                self._queues[d].clear()

    def _next(self, direction: Direction) -> FrameFault | None:
        # Caller holds the line lock.
        queue = self._queues[direction]
        return queue.popleft() if queue else None


class _Item:
    """A run of bytes scheduled for delivery: byte k is due at ``start + (k + 1) * byte_time``."""

    __slots__ = ("start", "data", "pos", "idle_before")

    def __init__(self, start: float, data: bytes, idle_before: float = 0.0) -> None:
        self.start = start
        self.data = data
        self.pos = 0
        #: silence owed before the first byte, counted from the previous byte's real delivery
        self.idle_before = idle_before


class _Path:
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


class VirtualSerialLine:
    """Two raw ptys joined by a relay thread; see the module docstring for the rules.

    :param baudrate: line speed; used for pacing and for the default ``frame_gap``.
    :param pace: deliver bytes no faster than ``baudrate`` allows (requires ``baudrate``).
    :param bits_per_byte: bits on the wire per byte (start + data + parity + stop), default 10.
    :param frame_gap: idle time (s) that separates frames; default see module docstring.
    :param capture: record traffic (disable for long benchmarks to save memory).
    :param burst_interval: longest sleep of the relay inside a paced chunk (CPU vs. smoothness).
    :param spin: paced only: the relay sleeps until this long before the last byte of a chunk
        is due and busy-waits the rest, because OS sleeps overshoot by ~0.1 ms (0 disables).
    """

    def __init__(
        self,
        baudrate: int | None = None,
        *,
        pace: bool = False,
        bits_per_byte: int = 10,
        frame_gap: float | None = None,
        capture: bool = True,
        burst_interval: float = 0.001,
        spin: float = 0.0002,
        name: str = "vserial",
        line_settings: bool = False,
        device_parity: str | None = None,
    ) -> None:
        if pace and not baudrate:
            raise ValueError("pace=True needs a baudrate")
        if baudrate is not None and baudrate <= 0:
            raise ValueError("baudrate must be positive")
        self.baudrate = baudrate
        self.pace = pace
        self.bits_per_byte = bits_per_byte
        self.char_time = bits_per_byte / baudrate if baudrate else 0.0
        self.byte_time = self.char_time if pace else 0.0
        if frame_gap is None:
            frame_gap = max(_DEFAULT_GAP, 3.5 * self.char_time)
        self.frame_gap = frame_gap
        self.capture = capture
        self.burst_interval = burst_interval
        self.spin = spin if pace else 0.0
        self._cond = threading.Condition(threading.Lock())
        self.faults = FaultPlan(self)
        self._closed = False
        self._error: BaseException | None = None
        self._fds: list[int] = []
        try:
            m_master, m_slave = self._openpty()
            d_master, d_slave = self._openpty()
            self.master_port: str = os.ttyname(m_slave)
            self.device_port: str = os.ttyname(d_slave)
            self._wake_r, self._wake_w = os.pipe()
            self._fds += [self._wake_r, self._wake_w]
            for fd in (m_master, d_master, self._wake_r, self._wake_w):
                os.set_blocking(fd, False)
        except BaseException:
            self._close_fds()
            raise
        self._paths: dict[Direction, _Path] = {
            "to_device": _Path("to_device", m_master, d_master),
            "to_master": _Path("to_master", d_master, m_master),
        }
        self.line_settings = line_settings or device_parity is not None
        if device_parity not in (None, "N", "E", "O"):
            raise ValueError("device_parity must be 'N', 'E' or 'O'")
        self.device_parity = device_parity
        self._slave_fds: dict[Direction, tuple[int, int]] = {
            "to_device": (m_slave, d_slave), "to_master": (d_slave, m_slave)}  # (sender, receiver)
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=f"{name}-relay", daemon=True)
        self._thread.start()

    def _openpty(self) -> tuple[int, int]:
        master, slave = os.openpty()
        self._fds += [master, slave]
        _make_raw(slave)
        return master, slave

    # ----------------------------------------------------------------- public API

    def __enter__(self) -> VirtualSerialLine:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        speed = f"{self.baudrate} Bd{' paced' if self.pace else ''}" if self.baudrate else "unpaced"
        return f"<VirtualSerialLine {self.master_port} <-> {self.device_port} {speed}>"

    @property
    def closed(self) -> bool:
        return self._closed

    def port(self, side: Literal["master", "device"]) -> str:
        """Device path of one end: ``"master"`` (client) or ``"device"`` (server)."""
        if side == "master":
            return self.master_port
        if side == "device":
            return self.device_port
        raise ValueError("side must be 'master' or 'device'")

    def open_serial(self, side: Literal["master", "device"], **kwargs: Any) -> Any:
        """Open one end with pyserial (``serial.Serial``); caller closes it.  Default timeout 1 s."""
        import serial  # local import: the module itself needs only the standard library

        kwargs.setdefault("timeout", 1.0)
        kwargs.setdefault("baudrate", self.baudrate or 19200)
        return serial.Serial(self.port(side), **kwargs)

    def captured(self, direction: str) -> bytes:
        """Every byte the sending end wrote in ``direction`` since start / last ``clear()``."""
        return b"".join(data for _, data in self.chunks(direction))

    def delivered(self, direction: str) -> bytes:
        """Every byte handed to the receiving end in ``direction`` (after faults)."""
        return b"".join(data for _, data in self.chunks(direction, which="delivered"))

    def chunks(
        self, direction: str, which: Literal["captured", "delivered"] = "captured"
    ) -> list[tuple[float, bytes]]:
        """Timestamped ``(time.monotonic(), bytes)`` reads (captured) or writes (delivered)."""
        path = self._paths[_check_direction(direction)]
        with self._cond:
            return list(path.captured if which == "captured" else path.delivered)

    def frames(self, direction: str, which: Literal["captured", "delivered"] = "captured") -> list[bytes]:
        """Captured (or delivered) bytes split into frames by the ``frame_gap`` idle rule.

        For ``delivered`` with pacing the split reflects write times of the relay and is only
        approximate; ``captured`` frames are exactly the frames the fault logic saw.
        """
        return split_frames(self.chunks(direction, which), self.frame_gap)

    def clear(self) -> None:
        """Forget captured and delivered bytes in both directions (faults are kept)."""
        with self._cond:
            for path in self._paths.values():
                path.captured.clear()
                path.delivered.clear()

    def wait_captured(self, direction: str, nbytes: int, timeout: float = 5.0) -> bool:
        """Wait until at least ``nbytes`` were captured in ``direction``; False on timeout."""
        path = self._paths[_check_direction(direction)]
        with self._cond:
            return self._cond.wait_for(
                lambda: self._closed or sum(len(d) for _, d in path.captured) >= nbytes, timeout
            ) and not self._closed

    def wait_delivered(self, direction: str, nbytes: int, timeout: float = 5.0) -> bool:
        """Wait until at least ``nbytes`` were delivered in ``direction``; False on timeout."""
        path = self._paths[_check_direction(direction)]
        with self._cond:
            return self._cond.wait_for(
                lambda: self._closed or sum(len(d) for _, d in path.delivered) >= nbytes, timeout
            ) and not self._closed

    def wait_idle(self, timeout: float = 5.0) -> bool:
        """Wait until nothing is in flight: all queued bytes delivered and no frame open."""
        with self._cond:
            return self._cond.wait_for(
                lambda: self._closed or not any(p.busy() for p in self._paths.values()), timeout
            ) and not self._closed

    def close(self) -> None:
        """Stop the relay thread and close every fd.  Idempotent.  Open ends see a hang-up."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._stop = True
            self._cond.notify_all()
        self._wake()
        self._thread.join(timeout=5.0)
        self._close_fds()
        if self._error is not None:
            raise RuntimeError("virtual serial relay failed") from self._error

    # ----------------------------------------------------------------- internals

    def _close_fds(self) -> None:
        fds, self._fds = self._fds, []
        for fd in fds:
            with contextlib.suppress(OSError):
                os.close(fd)

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def _inject(self, direction: Direction, data: bytes) -> None:
        with self._cond:
            if data:
                self._enqueue(self._paths[direction], data, time.monotonic())
        self._wake()

    def _enqueue(self, path: _Path, data: bytes, ready: float, idle_before: float = 0.0) -> None:
        # Caller holds the lock.  FIFO: an item never starts before the one ahead of it.
        start = max(ready, path.free_at + idle_before)
        path.queue.append(_Item(start, data, idle_before))
        path.free_at = start + len(data) * self.byte_time

    def _on_input(self, path: _Path, data: bytes, now: float) -> None:
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
            fault = path.frame_fault = self.faults._next(path.name)
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

    def _close_frame(self, path: _Path, now: float) -> None:
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

    def _collect_due(self, path: _Path, now: float) -> tuple[float, float]:
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

    def _write_out(self, path: _Path) -> None:
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
                    now = time.monotonic()
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
                now = time.monotonic()
                if precise <= wake:  # next event: the last byte of a chunk, due at `precise`
                    if precise - now <= self.spin:
                        events = self._spin(poller, precise)
                    else:
                        events = self._wait(poller, precise - self.spin - now)
                else:
                    events = self._wait(poller, wake - now)
                for fd, event in events:
                    if fd == self._wake_r:
                        with contextlib.suppress(BlockingIOError):
                            os.read(self._wake_r, 4096)
                        continue
                    if event & (select.POLLIN | select.POLLHUP | select.POLLERR):
                        self._read(fd)
        except BaseException as exc:  # surfaced by close()
            self._error = exc
        finally:
            with self._cond:
                self._closed = True
                self._cond.notify_all()

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


@contextlib.contextmanager
def open_pair(**line_kwargs: Any) -> Iterator[tuple[VirtualSerialLine, Any, Any]]:
    """``with open_pair(baudrate=9600) as (line, master, device):`` -- a line plus a pyserial
    ``Serial`` opened on each end (timeout 1 s); everything is closed on exit."""
    with VirtualSerialLine(**line_kwargs) as line:
        master = line.open_serial("master")
        try:
            device = line.open_serial("device")
            try:
                yield line, master, device
            finally:
                device.close()
        finally:
            master.close()

