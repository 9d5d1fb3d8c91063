"""Faults a :class:`~drivemap.testing.vserial.VirtualSerialLine` injects frame by frame, and the frame rule.

See the "Faults" and "Frames" sections of :mod:`drivemap.testing.vserial`.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

__all__ = ["DIRECTIONS", "Direction", "FaultPlan", "FrameFault", "check_direction", "split_frames"]

Direction = Literal["to_device", "to_master"]
DIRECTIONS: tuple[Direction, Direction] = ("to_device", "to_master")



def check_direction(direction: str) -> Direction:
    if direction == "to_device":
        return "to_device"
    if direction == "to_master":
        return "to_master"
    raise ValueError(f"direction must be 'to_device' or 'to_master', not {direction!r}")




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

    def __init__(self, lock: threading.Condition, inject: Callable[[Direction, bytes], None]) -> None:
        """``lock``: the line's lock (held while the relay takes a fault); ``inject``: puts bytes on the line."""
        self._lock = lock
        self._inject = inject
        self._queues: dict[Direction, deque[FrameFault]] = {d: deque() for d in DIRECTIONS}

    def add(self, direction: str, fault: FrameFault, frames: int = 1) -> FaultPlan:
        """Queue ``fault`` for the next ``frames`` frames in ``direction`` (after those queued)."""
        d = check_direction(direction)
        if frames < 0:
            raise ValueError("frames must be >= 0")
        with self._lock:
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
        d = check_direction(direction)
        self._inject(d, bytes(data))
        return self

    def pending(self, direction: str) -> int:
        """How many queued frame faults have not been consumed yet."""
        d = check_direction(direction)
        with self._lock:
            return len(self._queues[d])

    def clear(self, direction: str | None = None) -> None:
        """Forget queued faults (for one direction or both).  A frame in flight keeps its fault."""
        with self._lock:
            for d in DIRECTIONS if direction is None else (check_direction(direction),):
                self._queues[d].clear()

    def take(self, direction: Direction) -> FrameFault | None:
        """The next queued fault of ``direction`` (None: pass the frame), consumed (the relay calls it)."""
        # Caller holds the line lock.
        queue = self._queues[direction]
        return queue.popleft() if queue else None


