"""The simulator's ``--state`` file: user data, read completely or not at all, and never thinned out.

Layout (JSON)::

    {"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": 1500, ...}, "2": {...}}}

Rules (a state file is user data: nothing in it is ever lost):

* a file that cannot be read *fully* is refused with a located error (``path:line:col: error: ...``)
  and left untouched: not a regular file, too large, not UTF-8, not JSON, another model, another
  ``version``, a unit key that is not a unit id of the model, a value that is not an integer or does
  not fit its register's type;
* what the run does not simulate is kept as it is: units not served in this run, cells the model
  does not keep in EEPROM (or no longer has), other top-level keys;
* every write replaces the file atomically (temporary file in the same folder, ``fsync``, rename,
  ``fsync`` of the folder) and starts from the document that was loaded, changing only the cells of
  the units simulated now.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
import re
import stat
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["MAX_STATE_BYTES", "STATE_VERSION", "StateFile", "StateProblem"]

STATE_VERSION = 1
#: A state file larger than this is refused (the largest map's EEPROM cells take well under 8 MiB).
MAX_STATE_BYTES = 16 * 1024 * 1024


class StateProblem(ValueError):
    """A state file that cannot be read fully; ``str()`` is ``path:line:col: error: message``.

    :class:`~drivemap.runtime.sim.simulator.Simulator` raises it as its ``StateFileError``."""

    def __init__(self, path: Path | str, message: str, line: int = 1, col: int = 1) -> None:
        self.path = str(path)
        self.line = line
        self.col = col
        self.message = message
        super().__init__(f"{self.path}:{line}:{col}: error: {message}")


def _position(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def _locate(text: str, *keys: str) -> tuple[int, int]:
    """Line and column of the last of ``keys`` found in order (a best effort for messages)."""
    offset = 0
    found = 0
    for key in keys:
        match = re.compile(re.escape(json.dumps(key)) + r"\s*:").search(text, offset)
        if match is None:
            break
        offset = found = match.start()
    return _position(text, found)


def _read_text(path: Path) -> str:
    """The whole file, or :class:`StateProblem` (regular files only, bounded, strict UTF-8)."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise StateProblem(path, "not a regular file (a FIFO, device or folder); refused")
        if info.st_size > MAX_STATE_BYTES:
            raise StateProblem(path, f"state file larger than {MAX_STATE_BYTES} bytes; refused")
        with open(path, "rb") as handle:
            raw = handle.read(MAX_STATE_BYTES + 1)
    except OSError as exc:
        raise StateProblem(path, f"cannot read simulator state: {exc.strerror or exc}") from None
    if len(raw) > MAX_STATE_BYTES:
        raise StateProblem(path, f"state file larger than {MAX_STATE_BYTES} bytes; refused")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _position(raw[: exc.start].decode("utf-8", "replace"), exc.start)
        raise StateProblem(path, "cannot read simulator state: not UTF-8 text", line, col) from None


class _Duplicate(ValueError):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are all different (json keeps the last of two silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _Duplicate(key)
        out[key] = value
    return out


class StateFile:
    """One state file: the document as loaded, the values it gives, and atomic writes of updates.

    ``cells`` maps every EEPROM-class cell of the model to its raw bounds; ``valid_unit`` says
    whether a unit id belongs to the model.
    """

    def __init__(self, path: str | os.PathLike[str], model: str, cells: Mapping[str, tuple[int, int]],
                 valid_unit: Callable[[int], bool]) -> None:
        self.path = Path(path)
        self.model = model
        self.cells = dict(cells)
        self.valid_unit = valid_unit
        #: The document as loaded ({} when there was no file); writes start from it.
        self.document: dict[str, Any] = {}

    # ---- reading -------------------------------------------------------------------------------
    def load(self) -> dict[int, dict[str, int]]:
        """The EEPROM values per unit id in the file (every unit, simulated or not); refuses what it cannot read."""
        if not os.path.lexists(self.path):
            return {}
        text = _read_text(self.path)
        try:
            data = json.loads(text, object_pairs_hook=_no_duplicates)
        except json.JSONDecodeError as exc:
            raise StateProblem(self.path, f"cannot read simulator state: {exc.msg}", exc.lineno, exc.colno) from None
        except RecursionError:
            raise StateProblem(self.path, "cannot read simulator state: nested too deeply") from None
        except _Duplicate as exc:
            line, col = _position(text, max(text.rfind(json.dumps(exc.key)), 0))  # the second one
            raise StateProblem(self.path, f"cannot read simulator state: duplicate key {exc.key!r} (which one "
                                          "is meant?); refused, left untouched", line, col) from None
        except ValueError as exc:  # an integer of thousands of digits (Python's int conversion limit)
            raise StateProblem(self.path, f"cannot read simulator state: {exc}") from None
        values = self._check(text, data)
        self.document = data
        return values

    def _fail(self, text: str, message: str, *keys: str) -> StateProblem:
        line, col = _locate(text, *keys)
        return StateProblem(self.path, message, line, col)

    def _check(self, text: str, data: Any) -> dict[int, dict[str, int]]:
        if not isinstance(data, dict):
            raise self._fail(text, "a state file is a JSON object")
        if data.get("model") != self.model:
            raise self._fail(text, f"state file is for model {data.get('model')!r}, not {self.model!r}", "model")
        version = data.get("version", STATE_VERSION)
        if type(version) is not int or version != STATE_VERSION:
            raise self._fail(text, f"state file version {version!r} is not supported (this drivemap reads "
                                   f"version {STATE_VERSION}); refused, left untouched", "version")
        units = data.get("units", {})
        if not isinstance(units, dict):
            raise self._fail(text, "'units' must be an object of unit id -> cells", "units")
        out: dict[int, dict[str, int]] = {}
        for key, cells in units.items():
            uid = int(key) if isinstance(key, str) and key.isascii() and key.isdigit() and len(key) <= 3 else None
            if uid is None or str(uid) != key or not self.valid_unit(uid):
                raise self._fail(text, f"unit {key!r} is not a unit id of {self.model}", "units", key)
            if not isinstance(cells, dict):
                raise self._fail(text, f"unit {key}: cells must be an object of cell name -> raw value", "units", key)
            loaded: dict[str, int] = {}
            for name, raw in cells.items():
                if type(raw) is not int:
                    raise self._fail(text, f"unit {key}, {name}: raw value {json.dumps(raw)} is not an integer",
                                     "units", key, name)
                bounds = self.cells.get(name)
                if bounds is None:
                    continue  # not an EEPROM cell of this model: kept in the file as it is, not loaded
                if not bounds[0] <= raw <= bounds[1]:
                    raise self._fail(text, f"unit {key}, {name}: raw value {raw} does not fit "
                                           f"{bounds[0]}..{bounds[1]}", "units", key, name)
                loaded[name] = raw
            out[uid] = loaded
        return out

    # ---- writing -------------------------------------------------------------------------------
    def save(self, values: Mapping[int, Mapping[str, int]]) -> None:
        """Write ``values`` (unit id -> EEPROM cell -> raw) over the loaded document, atomically."""
        data = copy.deepcopy(self.document)
        data["model"] = self.model
        data["version"] = STATE_VERSION
        units = data.get("units")
        if not isinstance(units, dict):
            units = data["units"] = {}
        for uid, cells in values.items():
            kept = units.get(str(uid))
            merged = dict(kept) if isinstance(kept, dict) else {}
            merged.update(cells)
            units[str(uid)] = merged
        _atomic_write_json(Path(os.path.realpath(self.path)), data)  # through a symlink, not over it
        self.document = data


def _atomic_write_json(path: Path, data: Any) -> None:
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
    with contextlib.suppress(OSError):  # the rename itself survives a power loss
        folder = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(folder)
        finally:
            os.close(folder)
