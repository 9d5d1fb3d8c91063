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
import os
import termios
import threading
from collections.abc import Iterator
from types import TracebackType
from typing import Any, Literal

from drivemap.testing.vfaults import DIRECTIONS, Direction, FaultPlan, FrameFault, check_direction, split_frames
from drivemap.testing.vrelay import Relay, RelayPath

_DEFAULT_GAP = 0.002

__all__ = [
    "DIRECTIONS",
    "Direction",
    "FaultPlan",
    "FrameFault",
    "VirtualSerialLine",
    "open_pair",
    "split_frames",
]

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


class VirtualSerialLine(Relay):
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
        self.faults = FaultPlan(self._cond, self._inject)
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
        self._paths: dict[Direction, RelayPath] = {
            "to_device": RelayPath("to_device", m_master, d_master),
            "to_master": RelayPath("to_master", d_master, m_master),
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
        path = self._paths[check_direction(direction)]
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
        path = self._paths[check_direction(direction)]
        with self._cond:
            return self._cond.wait_for(
                lambda: self._closed or sum(len(d) for _, d in path.captured) >= nbytes, timeout
            ) and not self._closed

    def wait_delivered(self, direction: str, nbytes: int, timeout: float = 5.0) -> bool:
        """Wait until at least ``nbytes`` were delivered in ``direction``; False on timeout."""
        path = self._paths[check_direction(direction)]
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

