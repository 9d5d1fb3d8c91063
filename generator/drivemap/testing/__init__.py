"""Test and benchmark helpers (not used by generated code at run time)."""

from drivemap.testing.vserial import (
    DIRECTIONS,
    Direction,
    FaultPlan,
    FrameFault,
    VirtualSerialLine,
    open_pair,
    split_frames,
)

__all__ = [
    "DIRECTIONS",
    "Direction",
    "FaultPlan",
    "FrameFault",
    "VirtualSerialLine",
    "open_pair",
    "split_frames",
]
