"""``--state`` files are user data: nothing in them is lost, a file that cannot be read
fully is refused with a located error and left byte-for-byte untouched, and writes are atomic.

* units of the file that this run does not simulate, cells the model does not keep in EEPROM (or
  no longer has) and other top-level keys survive every write;
* ``version: 999``, a unit key ``"abc"``, a value that is not an integer or does not fit its
  register, another model, broken JSON, a FIFO or a link to ``/dev/zero`` are refused
  (``path:line:col: error: ...``), by the API (:class:`StateFileError`) and by
  ``drivemap simulate`` (exit 2, no traceback);
* a write replaces the file by rename (a new inode), and through a symlink rather than over it.
"""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path
from typing import Any

import pytest

from drivemap.runtime.sim.simulator import SimulatorError, StateFileError
from tests.helpers_live import run

ROOT = Path(__file__).resolve().parents[3]


def sim_class() -> Any:
    return importlib.import_module("drivemap_models.ev.simulator").Simulator


def write_06(address: int, value: int) -> bytes:
    return bytes([0x06]) + address.to_bytes(2, "big") + value.to_bytes(2, "big")


EEPROM_CELL = "digital_speed[0]"  # ev: 0x0308, EEPROM, raw 0..3000 (u16)
EEPROM_ADDRESS = 0x0308


def state_text(units: dict[str, Any], **top: Any) -> str:
    return json.dumps({"model": "ev", "version": 1, "units": units, **top}, indent=2, sort_keys=True) + "\n"


def test_units_not_simulated_and_unknown_cells_are_kept(tmp_path: Path) -> None:
    state = tmp_path / "ev.json"
    state.write_text(state_text(
        {"1": {EEPROM_CELL: 100, "no_such_cell": 5, "digital_speed_ram[0]": 7},
         "2": {EEPROM_CELL: 200, "digital_speed[1]": 201},
         "7": {EEPROM_CELL: 700}},
        comment="kept by the owner of this file",
    ), encoding="utf-8")
    sim = sim_class()([1], state_file=state)  # only unit 1 this time
    assert sim.get(EEPROM_CELL) == 100
    assert sim.handle(1, write_06(EEPROM_ADDRESS, 1500)) is not None  # written through at once
    sim.save_state()
    data = json.loads(state.read_text(encoding="utf-8"))
    assert data["units"]["1"][EEPROM_CELL] == 1500
    assert data["units"]["1"]["no_such_cell"] == 5 and data["units"]["1"]["digital_speed_ram[0]"] == 7
    assert data["units"]["2"] == {EEPROM_CELL: 200, "digital_speed[1]": 201}
    assert data["units"]["7"] == {EEPROM_CELL: 700}
    assert data["comment"] == "kept by the owner of this file"
    again = sim_class()([2, 7], state_file=state)
    assert again.get(EEPROM_CELL, 2) == 200 and again.get("digital_speed[1]", 2) == 201
    assert again.get(EEPROM_CELL, 7) == 700


def test_ram_cell_in_the_file_does_not_replace_the_power_up_value(tmp_path: Path) -> None:
    state = tmp_path / "ev.json"
    state.write_text(state_text({"1": {"digital_speed_ram[1]": 7}}), encoding="utf-8")
    fresh = sim_class()([1])
    sim = sim_class()([1], state_file=state)
    assert sim.get("digital_speed_ram[1]") == fresh.get("digital_speed_ram[1]")


BAD = {
    "version_999": ('{"model": "ev", "version": 999, "units": {}}', 1, 17, "version 999 is not supported"),
    "version_string": ('{"model": "ev", "version": "1", "units": {}}', 1, 17, "version '1' is not supported"),
    "unit_abc": ('{"model": "ev", "version": 1,\n "units": {"abc": {}}}', 2, 12, "unit 'abc' is not a unit id"),
    "unit_300": ('{"model": "ev", "version": 1,\n "units": {"300": {}}}', 2, 12, "unit '300' is not a unit id"),
    "unit_01": ('{"model": "ev", "version": 1,\n "units": {"01": {}}}', 2, 12, "unit '01' is not a unit id"),
    "value_text": ('{"model": "ev", "version": 1,\n "units": {"1": {\n  "digital_speed[0]": "x"}}}', 3, 3,
                   "is not an integer"),
    "value_float": ('{"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": 1.5}}}', 1, 47,
                    "is not an integer"),
    "value_range": ('{"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": 70000}}}', 1, 47,
                    "does not fit"),
    "value_bool": ('{"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": true}}}', 1, 47,
                   "is not an integer"),
    "cells_list": ('{"model": "ev", "version": 1, "units": {"1": [1, 2]}}', 1, 41, "cells must be an object"),
    "units_list": ('{"model": "ev", "version": 1, "units": [1]}', 1, 31, "'units' must be an object"),
    "model": ('{"model": "v2", "version": 1, "units": {}}', 1, 2, "not 'ev'"),
    "not_json": ('{"model": "ev",\n  "units": {"1": {', 2, 19, "cannot read simulator state"),
    "not_object": ('[1, 2, 3]', 1, 1, "a state file is a JSON object"),
    "deep": ("[" * 100_000 + "]" * 100_000, 1, 1, "cannot read simulator state"),
    "duplicate_key": ('{"model": "ev", "version": 1,\n "units": {"1": {"digital_speed[0]": 1,\n'
                      '  "digital_speed[0]": 2}}}', 3, 3, "duplicate key 'digital_speed[0]'"),
    "huge_integer": ('{"model": "ev", "version": 1, "units": {"1": {"digital_speed[0]": 1' + "0" * 5000 + '}}}',
                     1, 1, "cannot read simulator state: Exceeds the limit"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_unreadable_file_is_refused_located_and_untouched(tmp_path: Path, case: str) -> None:
    text, line, col, message = BAD[case]
    state = tmp_path / "ev.json"
    state.write_text(text, encoding="utf-8")
    before = state.read_bytes(), state.stat().st_mtime_ns
    with pytest.raises(StateFileError) as info:
        sim_class()([1], state_file=state)
    assert isinstance(info.value, SimulatorError)
    assert str(info.value).startswith(f"{state}:{line}:{col}: error: "), str(info.value)
    assert message in str(info.value)
    assert (state.read_bytes(), state.stat().st_mtime_ns) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ev.json"]  # no temporary file either


def test_special_files_are_refused_without_blocking(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    zero = tmp_path / "zero.json"
    zero.symlink_to("/dev/zero")
    for path in (fifo, zero, tmp_path):
        with pytest.raises(StateFileError, match="not a regular file"):
            sim_class()([1], state_file=path)
    assert zero.is_symlink() and os.readlink(zero) == "/dev/zero"


def test_writes_replace_the_file_atomically_and_follow_a_symlink(tmp_path: Path) -> None:
    real = tmp_path / "real.json"
    real.write_text(state_text({"2": {EEPROM_CELL: 200}}), encoding="utf-8")
    link = tmp_path / "link.json"
    link.symlink_to(real.name)
    inode = real.stat().st_ino
    sim = sim_class()([1], state_file=link)
    sim.handle(1, write_06(EEPROM_ADDRESS, 1234))
    assert link.is_symlink()
    assert real.stat().st_ino != inode  # renamed into place, not rewritten in place
    data = json.loads(real.read_text(encoding="utf-8"))
    assert data["units"]["1"][EEPROM_CELL] == 1234 and data["units"]["2"] == {EEPROM_CELL: 200}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]


def test_simulate_refuses_the_file_with_a_located_error(tmp_path: Path) -> None:
    state = tmp_path / "ev.json"
    text = '{\n  "model": "ev",\n  "version": 999,\n  "units": {"1": {}, "2": {"digital_speed[0]": 5}}\n}\n'
    state.write_text(text, encoding="utf-8")
    proc = run("simulate", "ev", "--tcp", "127.0.0.1:0", "--unit", "1", "--state", str(state), timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.splitlines()[0].startswith(f"{state}:3:3: error: state file version 999"), proc.stderr
    assert "Traceback" not in proc.stderr
    assert state.read_text(encoding="utf-8") == text


def test_a_state_file_that_could_never_be_saved_is_refused_at_start(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder\n", encoding="utf-8")
    with pytest.raises(StateFileError, match=r"a_file/ev\.json:1:1: error: cannot save simulator state in"):
        sim_class()([1], state_file=blocker / "ev.json")
    assert blocker.read_text(encoding="utf-8") == "not a folder\n"
    proc = run("simulate", "ev", "--tcp", "127.0.0.1:0", "--state", "/proc/drivemap-no-such/ev.json", timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith("/proc/drivemap-no-such/ev.json:1:1: error: cannot save simulator state in /proc")
    assert "Traceback" not in proc.stderr


def test_a_save_that_fails_later_is_reported_and_the_simulator_keeps_serving(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "d"
    folder.mkdir()
    sim = sim_class()([1], state_file=folder / "ev.json")
    folder.rmdir()
    folder.write_text("the folder became a file\n", encoding="utf-8")  # every save now fails
    reply = sim.handle(1, write_06(EEPROM_ADDRESS, 1500))
    assert reply == write_06(EEPROM_ADDRESS, 1500)                       # the write is answered
    assert sim.get(EEPROM_CELL) == 1500
    assert sim.handle(1, bytes([0x03]) + EEPROM_ADDRESS.to_bytes(2, "big") + (1).to_bytes(2, "big")) == \
        bytes([0x03, 0x02]) + (1500).to_bytes(2, "big")                  # and so is the next request
    assert sim.save_error is not None and "cannot save simulator state" in sim.save_error
    assert "still serving, EEPROM changes are not saved" in capsys.readouterr().err
