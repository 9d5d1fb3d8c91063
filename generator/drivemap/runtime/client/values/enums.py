"""The base class of generated enums."""

from __future__ import annotations

import enum
from typing import Any

__all__ = ["DriveEnum"]


class DriveEnum(enum.IntEnum):
    """Base of generated enums: a raw value the map does not name reads as a pseudo-member.

    ``MotorState(99)`` gives ``<MotorState.UNKNOWN_99: 99>`` instead of raising, so a read never
    fails on an undocumented value; writes still accept only the map's values.
    """

    @classmethod
    def _missing_(cls, value: object) -> Any:
        if not isinstance(value, int) or isinstance(value, bool):
            return None
        member = int.__new__(cls, value)
        member._name_ = f"UNKNOWN_{value}"
        member._value_ = value
        return member
