"""The simulator's EEPROM persistence: its ``--state`` file loaded completely or refused, and saved
without losing what this run does not simulate (the file rules live in :mod:`.simstate`)."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from drivemap.runtime.client.values.codec import raw_bounds
from drivemap.runtime.sim import state as simstate
from drivemap.runtime.sim.unit import SimulatorError

if TYPE_CHECKING:
    from drivemap.runtime.sim.unit import Unit
    from drivemap.runtime.spec import DeviceSpec, RegisterSpec

__all__ = ["Persistence", "StateFileError"]


class StateFileError(SimulatorError):
    """A ``--state`` file that cannot be read fully; ``str()`` is ``path:line:col: error: message``.

    The file is left untouched (see :mod:`drivemap.runtime.sim.state`)."""


class Persistence:
    """Mixin of :class:`~drivemap.runtime.sim.simulator.Simulator`: saving and loading ``state_file``."""

    spec: DeviceSpec
    state_file: Path | None
    units: dict[int, Unit]
    _cells: dict[str, tuple[RegisterSpec, int]]
    _dirty: bool
    _state: simstate.StateFile | None

    def _eeprom_cells(self) -> list[str]:
        return [name for name, (reg, _) in self._cells.items() if reg.storage == "eeprom"]

    #: The last failed save (None after a save that worked): the simulator keeps serving and says so.
    save_error: str | None = None

    def _save_if_dirty(self) -> None:
        if self._dirty and self.state_file is not None:
            try:
                self._write_state(self.state_file)
            except OSError as exc:
                message = (f"{self.state_file}:1:1: error: cannot save simulator state: {exc.strerror or exc}; "
                           "still serving, EEPROM changes are not saved")
                if message != self.save_error:
                    print(message, file=sys.stderr, flush=True)
                self.save_error = message
            else:
                self.save_error = None
        self._dirty = False

    def _write_state(self, path: Path) -> None:
        """Save the EEPROM cells of the simulated units over the loaded file (see :mod:`.simstate`)."""
        if self._state is None:
            self._state = self._state_file(path)
        cells = self._eeprom_cells()
        self._state.save({uid: {name: unit.values[name] for name in cells} for uid, unit in self.units.items()})

    def _state_file(self, path: Path) -> simstate.StateFile:
        bounds = {name: raw_bounds(self._cells[name][0]) for name in self._eeprom_cells()}
        return simstate.StateFile(path, self.spec.name, bounds, self.spec.protocol.valid_unit)

    def _load_state(self, path: Path) -> None:
        """Load the file completely (units not simulated now and unknown cells are kept for the next write)
        or refuse it with :class:`StateFileError`, leaving it untouched."""
        state = self._state_file(path)
        try:
            values = state.load()
        except simstate.StateProblem as exc:
            raise StateFileError(str(exc)) from None
        _probe_writable(path)
        self._state = state
        for uid, cells in values.items():
            unit = self.units.get(uid)
            if unit is not None:
                unit.values.update(cells)
                unit.unset.difference_update(cells)


def _probe_writable(path: Path) -> None:
    """Refuse at start a state file that could never be saved (its folder missing and not creatable,
    read-only, not a folder): a temporary file is created and removed where saves will go."""
    target = Path(os.path.realpath(path))
    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent  # saves create the missing folders; they must be creatable here
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{target.name[:40]}.", suffix=".probe")
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise StateFileError(f"{path}:1:1: error: cannot save simulator state in {folder}: "
                             f"{exc.strerror or exc}; refused at start") from None
    with contextlib.suppress(OSError):
        if target.is_dir():
            raise StateFileError(f"{path}:1:1: error: is a folder, not a state file; refused at start")
