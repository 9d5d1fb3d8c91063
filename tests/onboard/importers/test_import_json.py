"""`drivemap import json` and `drivemap import pymodbus-sim`: round trips through both exporters for every
shipped map, a hand-written pymodbus simulator configuration, entries of the wrong shape (the mangled
sources of both formats are in test_import.py's mangled-sources test)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from test_import import MAPS, SIM, again, export, run

from drivemap.compiler import compile_map


@pytest.mark.parametrize("model", MAPS)
def test_round_trip_json(model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """export json -> import json -> export json: the same file byte for byte, every fact of the contract
    (protocol, registers and arrays, enums, bits, pages, reserved ranges and their tables, known issues,
    identity, examples, errata with their corrected frames)."""
    first = export(capsys, model, "json")
    source = tmp_path / f"{model}.json"
    source.write_text(first, encoding="utf-8")
    target = tmp_path / "maps" / f"{model}.yaml"
    code, summary, err = run(capsys, "import", "json", str(source), "-o", str(target))
    assert code == 0, err
    compile_map(target)  # validates as written
    assert export(capsys, str(target), "json") == first
    assert "skipped: example" not in summary


def test_an_export_without_corrected_frames_or_tables_is_listed(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """An export made before the contract carried an erratum's corrected frames and a reserved range's
    table: the erratum examples are left out and listed, the ranges go to holding unless they clash there."""
    data = json.loads(export(capsys, "vfd1000", "json"))
    for ex in data["examples"]:
        del ex["corrected_request"], ex["corrected_response"]
    for item in data["reserved"]:
        del item["table"]
    source = tmp_path / "old.json"
    source.write_text(json.dumps(data), encoding="utf-8")
    code, summary, err = run(capsys, "import", "json", str(source), "-o", str(tmp_path / "old.yaml"))
    assert code == 0, err
    lost = [ex["name"] for ex in data["examples"] if ex["status"] == "erratum"]
    assert lost and all(f"skipped: example {name} (erratum): the export carries no corrected frame" in summary
                        for name in lost)
    model = compile_map(tmp_path / "old.yaml")
    assert {ex.name for ex in model.examples} == {ex["name"] for ex in data["examples"]} - set(lost)


@pytest.mark.parametrize("model", MAPS)
def test_round_trip_pymodbus_sim(model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """export pymodbus-sim -> import -> export: the simulator's part (server_list, device_list: blocks,
    cells, types, values, write list) byte for byte. Of drivemap's own note section, model, title and
    unit come back; ``note`` names the map file exported, and ``pages``/``not_served`` name page
    selectors and registers of other pages, which the file does not describe (it serves one page as
    plain words), so the imported map has none."""
    first = export(capsys, model, "pymodbus-sim")
    source = tmp_path / f"{model}.pymodbus-sim.json"
    source.write_text(first, encoding="utf-8")
    target = tmp_path / "maps" / f"{model}.yaml"
    code, summary, err = run(capsys, "import", "pymodbus-sim", str(source), "-o", str(target))
    assert code == 0, err
    compile_map(target)
    second = export(capsys, str(target), "pymodbus-sim", *again(summary))
    assert second.split('"server_list"', 1)[1] == first.split('"server_list"', 1)[1]
    before, after = json.loads(first)["drivemap"], json.loads(second)["drivemap"]
    assert [before[k] for k in ("model", "title", "unit")] == [after[k] for k in ("model", "title", "unit")]
    assert (after["pages"], after["not_served"]) == ({}, [])
    assert "no register names" in summary


def test_hand_written_pymodbus_sim(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "boiler.json"
    source.write_text(json.dumps(SIM, indent=1), encoding="utf-8")
    code, out, err = run(capsys, "import", "pymodbus-sim", str(source), "-o", str(tmp_path / "boiler.yaml"))
    assert code == 0, err
    m = compile_map(tmp_path / "boiler.yaml")
    coils = [r for r in m.registers if r.table == "coil"]
    assert len(coils) == 16 and [r.defaults[0] for r in coils[:3]] == [True, False, True]  # 5 = bits 0 and 2
    assert all(r.access == "rw" for r in coils)
    assert (m.register("input_0").type, m.register("input_0").defaults, m.register("input_0").access) == ("u16", (65535,), "r")
    assert m.register("input_1").defaults == (0,)  # no value: the setup's uint16 default
    big = m.register("holding_0")  # cell 5: after the coil cell and the 4 input cells
    assert (big.type, big.word_order, big.defaults, big.access) == ("u32", "high_first", (70000,), "r")
    f = m.register("holding_2")
    assert (f.type, f.access, f.defaults) == ("f32", "rw", (0.10000000149011612,))  # as pymodbus stores 0.1
    assert (m.register("holding_6").type, m.register("holding_6").length, m.register("holding_6").defaults) == (
        "string", 2, ("AB1",))
    assert m.protocol.broadcast_address == 0
    port = m.protocol.ports[0]
    assert (port.default_baudrate, port.default_parity, port.default_stop_bits) == (19200, "even", 1)
    assert "export again with --unit 3" in out and "export again with --serial /dev/ttyUSB0" in out
    assert "cells 9..10 are written as one value: its type and word order are not stated" in out
    assert [r.name for r in m.registers if r.table == "holding" and r.type == "u16"] == ["holding_4", "holding_5"]


def test_json_entries_of_a_wrong_shape_are_located(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = export(capsys, "vfd1000", "json")
    data = json.loads(text)
    cases = [
        (lambda d: d["registers"][3].pop("address"), "registers[3]: 'address' is missing"),
        (lambda d: d["registers"][2].update(type="u17"), "registers[2]: 'type' must be one of"),
        (lambda d: d["registers"][0].update(name="speed[0]"), "speed[0]: an array has at least 2 elements"),
        (lambda d: d["reserved"][0].update(end=-1), "reserved[0]: start and end must be addresses"),
        (lambda d: d["protocol"].update(unit_min="1"), "protocol: 'unit_min' must be an int, not \"1\""),
        (lambda d: d.update(registers={}), "the export: 'registers' must be a list"),
    ]
    for i, (mangle, message) in enumerate(cases):
        copy = json.loads(text)
        mangle(copy)
        source = tmp_path / f"bad{i}.json"
        source.write_text(json.dumps(copy, indent=2), encoding="utf-8")
        code, _, err = run(capsys, "import", "json", str(source), "-o", str(tmp_path / "x.yaml"))
        assert code == 1 and message in err, (message, err)
        assert re.match(rf"{re.escape(str(source))}:\d+:\d+: error: ", err) and "Traceback" not in err
    # the line of the entry, not of the file's start
    source = tmp_path / "bad0.json"
    copy = json.loads(text)
    copy["registers"][3].pop("address")
    source.write_text(json.dumps(copy, indent=2), encoding="utf-8")
    code, _, err = run(capsys, "import", "json", str(source), "-o", str(tmp_path / "x.yaml"))
    line = int(err.split(":")[1])
    assert json.dumps(copy, indent=2).splitlines()[line - 1].strip() == "{" and line > 100
    broken = tmp_path / "broken.json"
    broken.write_text(text[:500], encoding="utf-8")
    code, _, err = run(capsys, "import", "json", str(broken), "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and re.match(rf"{re.escape(str(broken))}:\d+:\d+: error: not JSON", err)
    data["reserved"][0]["table"] = "input"  # an export that states a range's table: kept
    source.write_text(json.dumps(data), encoding="utf-8")
    code, _, err = run(capsys, "import", "json", str(source), "-o", str(tmp_path / "vfd1000.yaml"))
    assert code == 0, err
    assert compile_map(tmp_path / "vfd1000.yaml").reserved[0].table == "input"
    code, _, err = run(capsys, "import", "json", str(broken), str(source), "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and f"{source}:1:1: error: one file per import for this format" in err
    two = tmp_path / "two.json"
    two.write_text(json.dumps({"device_list": {"a": {}, "b": {}}}), encoding="utf-8")
    code, _, err = run(capsys, "import", "pymodbus-sim", str(two), "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and f"{two}:1:17: error: device_list has 2 devices (a, b): import a configuration of one" in err
    assert not (tmp_path / "x.yaml").exists()


def test_json_and_pymodbus_sim_imports_from_the_installed_wheel(tmp_path_factory: pytest.TempPathFactory,
                                                                 tmp_path: Path) -> None:
    """Both formats as users get them: the wheel in a fresh virtualenv, an empty folder outside this
    checkout; the maps they write validate there, with the checks of every exporter."""
    from tests.project.test_wheel import env as env_fixture
    from tests.project.test_wheel import ok
    from tests.project.test_wheel import wheel as wheel_fixture

    bindir = env_fixture.__wrapped__(wheel_fixture.__wrapped__(tmp_path_factory), tmp_path_factory)  # type: ignore[attr-defined]
    work = tmp_path / "from-exports"
    work.mkdir()
    (work / "edx.json").write_text(ok(bindir, work, "export", "edx", "--format", "json"), encoding="utf-8")
    (work / "sim.json").write_text(ok(bindir, work, "export", "vfd1000", "--format", "pymodbus-sim"), encoding="utf-8")
    assert "wrote maps/edx.yaml" in ok(bindir, work, "import", "json", "edx.json")
    assert "wrote maps/vfd_image.yaml" in ok(bindir, work, "import", "pymodbus-sim", "sim.json", "--model", "vfd_image")
    checked = ok(bindir, work, "validate", "--exporter", "all")
    assert "maps/edx.yaml: ok" in checked and "maps/vfd_image.yaml: ok" in checked
    assert ok(bindir, work, "export", "maps/edx.yaml", "--format", "json") == (work / "edx.json").read_text("utf-8")
    assert sorted(p.relative_to(work).as_posix() for p in work.rglob("*")) == [
        "edx.json", "maps", "maps/edx.yaml", "maps/vfd_image.yaml", "sim.json"]
