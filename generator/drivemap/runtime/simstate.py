"""The simulator's state file: EEPROM-class registers kept across restarts, written atomically."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from .codec import raw_bounds
from .simunit import SimulatorError

if TYPE_CHECKING:
    from .simunit import Unit
    from .spec import DeviceSpec, RegisterSpec

_STATE_VERSION = 1

__all__ = ["StateFile"]


class StateFile:
    """Mixin of :class:`~drivemap.runtime.simulator.Simulator`: saving and loading ``state_file``."""

    spec: DeviceSpec
    state_file: Path | None
    units: dict[int, Unit]
    _cells: dict[str, tuple[RegisterSpec, int]]
    _dirty: bool

    def _eeprom_cells(self) -> list[str]:
        return [name for name, (reg, _) in self._cells.items() if reg.storage == "eeprom"]

    def _save_if_dirty(self) -> None:
        if self._dirty and self.state_file is not None:
            self._write_state(self.state_file)
        self._dirty = False

    def _write_state(self, path: Path) -> None:
        cells = self._eeprom_cells()
        data = {
            "model": self.spec.model,
            "version": _STATE_VERSION,
            "units": {str(uid): {name: unit.values[name] for name in cells} for uid, unit in self.units.items()},
        }
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                json.dump(data, handle, indent=2, sort_keys=True)
                handle.write("\n")
                handle.flush()
                os.fsync(handle.fileno())
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise

    def _load_state(self, path: Path) -> None:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise SimulatorError(f"{path}: cannot read simulator state: {exc}") from exc
        if not isinstance(data, dict) or data.get("model") != self.spec.model:
            raise SimulatorError(f"{path}: state file is not for model {self.spec.model!r}")
        units = data.get("units", {})
        if not isinstance(units, dict):
            raise SimulatorError(f"{path}: 'units' must be a mapping")
        eeprom = set(self._eeprom_cells())
        for uid, values in units.items():
            unit = self.units.get(int(uid))
            if unit is None or not isinstance(values, dict):
                continue
            for name, raw in values.items():
                if name in eeprom and isinstance(raw, int):
                    reg = self._cells[name][0]
                    low, high = raw_bounds(reg)
                    if low <= raw <= high:
                        unit.values[name] = raw

