"""What the parts of the simulator see of each other, as protocols: a behaviour sees a unit
(:class:`UnitView`), a unit sees its simulator (:class:`SimHost`). The modules that implement them
(:mod:`.unit`, :mod:`.simulator`) import this one, never each other's back, so the simulator's
modules form no circle."""

from __future__ import annotations

from typing import Any, Protocol

from drivemap.runtime.spec import BitSpec, DeviceSpec, RegisterSpec

SimValue = float | int | str | bool | None


class SimHost(Protocol):
    """What a unit needs of its simulator: the device spec, cell names resolved, and a note that
    EEPROM-class values changed (to be saved)."""

    spec: DeviceSpec

    def check_cell(self, name: str) -> str: ...

    def register_of(self, name: str) -> RegisterSpec: ...

    def bit_of(self, name: str, bit: str) -> BitSpec: ...

    def mark_dirty(self) -> None: ...


class UnitView(Protocol):
    """A unit as a behaviour reads and changes it; names are cell names (``motor_speed``, ``digital_speed[3]``)."""

    id: int
    scratch: dict[str, Any]
    unset: set[str]

    @property
    def spec(self) -> DeviceSpec: ...

    def has(self, name: str) -> bool: ...

    def raw(self, name: str) -> int: ...

    def get(self, name: str) -> SimValue: ...

    def number(self, name: str) -> float: ...

    def effective_raw(self, name: str) -> int: ...

    def bit(self, name: str, bit: str) -> int: ...

    def set_raw(self, name: str, raw: int) -> None: ...

    def set(self, name: str, value: SimValue) -> None: ...

    def set_bit(self, name: str, bit: str, value: int) -> None: ...

    def apply_configuration(self) -> None: ...

    def record_comm_error(self, code: int) -> None: ...


__all__ = ["SimHost", "SimValue", "UnitView"]
