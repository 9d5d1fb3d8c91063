"""`drivemap import`: round trips through every exporter for every shipped map, SunSpec models against
the proven Fronius map, hand-written Home Assistant / ESPHome / vendor CSV definitions, bad input."""

from __future__ import annotations

import csv
import io
import json
import re
import shutil
from pathlib import Path
from typing import Any

import pytest
from helpers_live import ROOT, cli, no_traceback

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.frontend.formats import CURRENT
from drivemap.vocab.csv_columns import COLUMNS, REGISTER_COLUMNS

MAPS = sorted(p.stem for p in (ROOT / "maps").glob("*.yaml"))
#: the exporter's options for a map that leaves the line open (the same for both exports)
OPTIONS = {"csv": [], "homeassistant": ["--tcp", "127.0.0.1:502"],
           "esphome": ["--baudrate", "9600", "--parity", "none", "--stopbits", "1"]}


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def export(capsys: pytest.CaptureFixture[str], source: str, fmt: str, *extra: str) -> str:
    code, out, err = run(capsys, "export", source, "--format", fmt, *line_options(capsys, source, fmt), *extra)
    assert code == 0, err
    return out


def line_options(capsys: pytest.CaptureFixture[str], source: str, fmt: str) -> list[str]:
    """:data:`OPTIONS` for a map that leaves the line open; none for one that states it (solax: 19200
    only, where 9600 would be refused)."""
    code, _, err = run(capsys, "export", source, "--format", fmt)
    assert code == 0 or "leaves the serial line" in err, err
    return [] if code == 0 else OPTIONS[fmt]


def again(summary: str) -> list[str]:
    """The export options the import's review says reproduce the source (other than the transport)."""
    options: list[str] = []
    for found in re.findall(r"export again with (.*?) \(", summary):
        if not found.startswith(("--tcp", "--rtu-over-tcp")):
            options += found.split()
    return options


def body(text: str) -> list[str]:
    """The YAML without its comment lines (the header names the source file and its title)."""
    return [line for line in text.splitlines() if not line.lstrip().startswith("#")]


@pytest.mark.parametrize("fmt", ["csv", "homeassistant", "esphome"])
@pytest.mark.parametrize("model", MAPS)
def test_round_trip_export_import_export(model: str, fmt: str, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    # ESPHome 2026.6's form carries drivemap's batching whole (register_count, force_new_range); the newest
    # form's round trip is test_esphome_newest_form_brings_back_every_entity
    first = export(capsys, model, fmt, *(["--esphome-version", "2026.6"] if fmt == "esphome" else []))
    source = tmp_path / f"{model}.{fmt}.{'csv' if fmt == 'csv' else 'yaml'}"
    source.write_text(first, encoding="utf-8")
    target = tmp_path / "maps" / f"{model}.yaml"
    code, summary, err = run(capsys, "import", fmt, str(source), "-o", str(target))
    assert code == 0, err
    compile_map(target)  # validates as written
    second = export(capsys, str(target), fmt, *again(summary),
                    *(["--esphome-version", "2026.6"] if fmt == "esphome" else []))
    if fmt == "csv":
        assert second == first  # every column is a map fact: byte for byte
        return
    # what the export left out (a comment line says so) the import lists for review, with its line
    for n, line in enumerate(first.splitlines(), 1):
        if line.startswith("# not exported"):
            assert f"{source.name}:{n}: {line[2:]}" in summary, summary
    lost = [line for line in body(first) if line not in body(second)]
    if (model, fmt) == ("ev", "esphome"):
        # ev's 20 ms write delay reaches ESPHome 2026.6 only as the controller's command_throttle, which does
        # not say which register needs it: the import lists it for review instead of guessing
        assert lost == ["    command_throttle: 20ms"] and "command_throttle 20ms" in summary
        return
    assert body(second) == body(first)


#: one imported map per catalogue source: its CSV carries the evidence level and the origin on every row
CATALOGUE_SAMPLES = ["catalogue/evcc/afore_hybrid", "catalogue/ha_solarman/deye_p3",
                     "catalogue/modbus_local_gateway/device_7_m_24", "catalogue/sunspec/sunspec_ac_meter_abc"]


@pytest.mark.parametrize("path", CATALOGUE_SAMPLES)
def test_csv_carries_evidence_and_origin_both_ways(path: str, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    source = ROOT / "maps" / f"{path}.yaml"
    model = compile_map(source)
    origin = model.device.origin
    assert model.device.evidence == "imported" and origin is not None
    first = export(capsys, str(source), "csv")
    rows = list(csv.DictReader(io.StringIO(first)))
    assert rows and {(r["evidence"], r["origin_project"], r["origin_path"], r["origin_commit"], r["origin_licence"],
                      r["origin_format"]) for r in rows} == {
        ("imported", origin.project, origin.path, origin.commit, origin.licence, origin.format or "")}
    sheet = tmp_path / "sheet.csv"
    sheet.write_text(first, encoding="utf-8")
    target = tmp_path / "maps" / "back.yaml"
    code, _, err = run(capsys, "import", "csv", str(sheet), "-o", str(target))
    assert code == 0, err
    back = compile_map(target)
    assert back.device.evidence == "imported" and back.device.origin == origin
    assert export(capsys, str(target), "csv") == first  # byte for byte, the map-level columns included


def test_csv_map_columns_disagreeing_or_from_before_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first = export(capsys, "sdm630", "csv")
    rows = list(csv.DictReader(io.StringIO(first)))
    assert {r["evidence"] for r in rows} == {"manual"} and {r["origin_project"] for r in rows} == {""}

    def write(name: str, columns: list[str], table: list[dict[str, str]]) -> Path:
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=columns, lineterminator="\n", extrasaction="ignore")
        writer.writeheader()
        writer.writerows(table)
        (tmp_path / name).write_text(out.getvalue(), encoding="utf-8")
        return tmp_path / name

    # a sheet exported before the map-level columns is still drivemap's own; its evidence stays unstated
    old = write("old.csv", list(REGISTER_COLUMNS), rows)
    code, _, err = run(capsys, "import", "csv", str(old), "-o", str(tmp_path / "old.yaml"))
    assert code == 0, err
    assert compile_map(tmp_path / "old.yaml").device.evidence is None
    # one row saying another evidence level is refused at its line, nothing written
    mixed = [dict(r) for r in rows]
    mixed[3]["evidence"] = "verified"
    bad = write("mixed.csv", list(COLUMNS), mixed)
    code, _, err = run(capsys, "import", "csv", str(bad), "-o", str(tmp_path / "mixed.yaml"))
    assert code == 1 and "mixed.csv:5:1: error: evidence 'verified' differs from line 2's 'manual'" in err, err
    assert not (tmp_path / "mixed.yaml").exists()
    odd = [dict(r, evidence="guessed") for r in rows]
    code, _, err = run(capsys, "import", "csv", str(write("odd.csv", list(COLUMNS), odd)), "-o",
                       str(tmp_path / "odd.yaml"))
    assert code == 1 and "odd.csv:2:1: error: evidence 'guessed': one of manual, imported, probed, verified" in err
    half = [dict(r, origin_project="someone/project") for r in rows]
    code, _, err = run(capsys, "import", "csv", str(write("half.csv", list(COLUMNS), half)), "-o",
                       str(tmp_path / "half.yaml"))
    assert code == 1 and "origin_path, origin_commit, origin_licence empty" in err, err


def cells(model: object, first: int) -> dict[int, tuple[str, int, int | None]]:
    out = {}
    for reg in model.registers:  # type: ignore[attr-defined]
        scale = model.register(reg.scale_register).address if reg.scale_register else None  # type: ignore[attr-defined]
        for i in range(reg.count):
            if reg.element_address(i) >= first:
                out[reg.element_address(i)] = (reg.type, reg.words, scale)
    return out


def test_sunspec_models_laid_out_like_the_proven_fronius_map(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    import sunspec2  # noqa: F401  (the sunspec extra is a test dependency: pip install -e '.[test]')
    target = tmp_path / "fronius_models.yaml"
    code, out, err = run(capsys, "import", "sunspec", "1:65", "103", "120", "121", "122", "123", "160:48", "124",
                         "--base", "40000", "-o", str(target))
    assert code == 0, err
    proven = cells(compile_map(ROOT / "maps" / "fronius_symo_hybrid.yaml"), 40000)
    imported = compile_map(target)
    got = cells(imported, 40000)
    assert set(got) == set(proven)
    assert sum(got[a] == proven[a] for a in proven) >= len(proven) - 1
    assert imported.register("a").scale_register == "a_sf" and imported.register("a").not_available == (0xFFFF,)
    st = imported.register("st")
    assert st.enum and imported.enum(st.enum).members[0].label
    assert any(r.bits for r in imported.registers)  # bitfield16/32 -> bits
    assert "point Pad lies past the model's length L" in out


def test_sunspec_without_the_extra(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    import sunspec2

    from drivemap.onboard.importers import sunspec
    models = Path(sunspec2.__file__).parent / "models" / "json"
    pair = [json.loads((models / f"model_{n}.json").read_text(encoding="utf-8")) for n in (1, 101)]
    (tmp_path / "two.json").write_text(json.dumps(pair), encoding="utf-8")
    monkeypatch.setattr(sunspec, "models_dir", lambda: None)
    code, _, err = run(capsys, "import", "sunspec", str(tmp_path / "two.json"), "-o", str(tmp_path / "two.yaml"))
    assert code == 0, err
    assert compile_map(tmp_path / "two.yaml").register("common_model_id").address == 40002
    code, _, err = run(capsys, "import", "sunspec", "103", "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and err.startswith("<command line>:1:") and "needs drivemap[sunspec]" in err
    monkeypatch.undo()
    code, _, err = run(capsys, "import", "sunspec", "160", "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and "model 160 has a repeating group: give its length L as 160:L" in err
    assert not (tmp_path / "x.yaml").exists()


HA = """\
modbus:
  - name: boiler hub
    type: tcp
    host: !secret modbus_host
    port: 502
    timeout: 3
    sensors:
      - name: Flow temperature
        slave: 3
        address: 100
        input_type: input
        data_type: int
        scale: 0.1
        precision: 1
        unit_of_measurement: °C
      - name: Energy
        slave: 3
        address: 0x0200
        data_type: float
        count: 2
        swap: word
        nan_value: "0x7FC00000"
      - name: Serial
        slave: 3
        address: 300
        data_type: string
        count: 8
    binary_sensors:
      - name: Pump running
        slave: 3
        address: 7
        input_type: discrete_input
    switches:
      - name: Pump
        slave: 3
        address: 12
        write_type: coil
        verify:
      - name: Heating
        slave: 3
        address: 40
        command_on: 1
        command_off: 0
    climates:
      - name: Room
        slave: 3
        address: 120
        target_temp_register: 121
        data_type: int16
        scale: 0.5
        max_temp: 30
        min_temp: 5
        temperature_unit: C
    covers:
      - name: Shutter
        address: 1
"""


def test_hand_written_home_assistant(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "configuration.yaml").write_text(HA, encoding="utf-8")
    target = tmp_path / "boiler.yaml"
    code, out, err = run(capsys, "import", "homeassistant", str(tmp_path / "configuration.yaml"), "-o", str(target))
    assert code == 0, err
    m = compile_map(target)
    flow = m.register("flow_temperature")
    assert (flow.table, flow.address, flow.type, flow.scale, flow.unit, flow.access) == ("input", 100, "s16", 0.1, "°C", "r")
    energy = m.register("energy")
    assert (energy.type, energy.word_order, energy.not_available) == ("f32", "low_first", (0x7FC00000,))
    assert m.register("serial_reg").type == "string" and m.register("serial_reg").length == 8  # "serial": a client attribute
    assert (m.register("pump_running").table, m.register("pump").table, m.register("pump").access) == (
        "discrete", "coil", "rw")
    heating = m.register("heating")
    assert heating.access == "w" and {v.value for v in m.enum(heating.enum or "").members} == {0, 1}
    target_temp = m.register("room_target_temperature")
    assert (target_temp.address, target_temp.min, target_temp.max, target_temp.unit) == (121, 5, 30, "°C")
    assert m.register("room_current_temperature").access == "r"
    assert "cover 'Shutter'" in out and "export again with --unit 3" in out
    assert m.protocol.timing.response_timeout_ms == 3000


ESPHOME = """\
esphome:
  name: heat-pump
uart:
  - id: u
    tx_pin: GPIO17
    rx_pin: GPIO16
    baud_rate: 19200
    parity: EVEN
    stop_bits: 1
modbus:
  - id: bus
    send_wait_time: 250ms
modbus_controller:
  - id: hp
    address: 0x10
    update_interval: 30s
sensor:
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Outdoor temperature
    register_type: read
    address: 0x0010
    value_type: S_WORD
    unit_of_measurement: °C
    filters:
      - multiply: 0.1
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Power
    register_type: read
    address: 0x0020
    value_type: U_DWORD_R
    filters:
      - lambda: return x / 3.0;
number:
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Setpoint
    register_type: holding
    address: 0x0100
    value_type: U_WORD
    min_value: 20
    max_value: 60
    step: 0.5
    multiply: 2
select:
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Mode
    address: 0x0101
    value_type: U_WORD
    optionsmap:
      "Off": 0
      "Heat": 1
binary_sensor:
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Defrost
    register_type: coil
    address: 5
text_sensor:
  - platform: modbus_controller
    modbus_controller_id: hp
    name: Firmware
    register_type: holding
    address: 0x0200
    register_count: 4
    raw_encode: ANSI
"""


def test_hand_written_esphome(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "hp.yaml").write_text(ESPHOME, encoding="utf-8")
    code, out, err = run(capsys, "import", "esphome", str(tmp_path / "hp.yaml"), "-o", str(tmp_path / "heat_pump.yaml"))
    assert code == 0, err
    m = compile_map(tmp_path / "heat_pump.yaml")
    outdoor = m.register("outdoor_temperature")
    assert (outdoor.table, outdoor.address, outdoor.type, outdoor.scale) == ("input", 16, "s16", 0.1)
    assert (m.register("power").type, m.register("power").word_order) == ("u32", "low_first")
    assert m.register("power").review == ("scale",)  # the lambda converts it: its scale is for review
    setpoint = m.register("setpoint")
    assert (setpoint.access, setpoint.scale, setpoint.min, setpoint.max) == ("rw", 0.5, 20, 60)
    assert [v.label for v in m.enum(m.register("mode").enum or "").members] == ["Off", "Heat"]
    assert m.register("defrost").table == "coil" and m.register("firmware").length == 4
    port = m.protocol.ports[0]
    assert (port.default_baudrate, port.default_parity) == (19200, "even")
    assert "filter lambda is ESPHome's processing, not imported (review: scale)" in out and "--unit 16" in out


VENDOR = """\
Register Address;Parameter;Data Type;Units;Scale Factor;R/W;Function code
0x0000;Grid voltage;UINT16;V;0.1;R;04
0x0001;Grid frequency;UINT16;Hz;0.01;R;04
0x0002;Active power;INT32;W;1;R;04
0x0010;Power limit;UINT16;%;;RW;03
"""


SIM = {
    "server_list": {"boiler": {"comm": "serial", "port": "/dev/ttyUSB0", "framer": "rtu", "baudrate": 19200,
                               "bytesize": 8, "parity": "E", "stopbits": 1, "device_id": 3,
                               "broadcast_enable": True}},
    "device_list": {"boiler": {
        "setup": {"co size": 1, "di size": 0, "ir size": 4, "hr size": 20, "shared blocks": False,
                  "type exception": True, "defaults": {"value": {"bits": 0, "uint16": 0, "uint32": 0,
                                                                 "float32": 0.0, "float64": 0.0, "string": " "}}},
        "invalid": [], "repeat": [],
        "write": [0, [7, 8], [9, 10], 11, 12],
        "bits": [{"addr": 0, "value": 5}],
        "uint16": [{"addr": 1, "value": 65535}, {"addr": 2}, {"addr": 9, "value": 1}, {"addr": 10, "value": 2}],
        "uint32": [{"addr": [5, 6], "value": 70000}],
        "float32": [{"addr": [7, 8], "value": 0.1}],
        "float64": [],
        "string": [{"addr": [11, 12], "value": "AB1 "}],
    }},
}


def test_vendor_sheet(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sheet = tmp_path / "inverter.csv"
    sheet.write_text(VENDOR, encoding="utf-8")
    # a 32-bit row whose word order the sheet does not give keeps its type; the order is left to review
    code, out, err = run(capsys, "import", "csv", str(sheet), "-o", str(tmp_path / "open.yaml"))
    assert code == 0, err
    assert "active_power: word_order (s32: the sheet does not say which word comes first: review" in out
    power = compile_map(tmp_path / "open.yaml").register("active_power")
    assert (power.type, power.word_order, power.review) == ("s32", None, ("word_order",))
    code, out, err = run(capsys, "import", "csv", str(sheet), "--word-order", "high_first",
                         "-o", str(tmp_path / "inverter.yaml"))
    assert code == 0, err
    m = compile_map(tmp_path / "inverter.yaml")
    grid = m.register("grid_voltage")
    assert (grid.table, grid.address, grid.type, grid.scale, grid.unit, grid.access) == ("input", 0, "u16", 0.1, "V", "r")
    assert m.register("power_limit").table == "holding" and m.register("power_limit").access == "rw"
    bare = tmp_path / "bare.csv"
    bare.write_text("Address,Name\n10,Speed\n", encoding="utf-8")
    code, _, err = run(capsys, "import", "csv", str(bare), "-o", str(tmp_path / "bare.yaml"))
    assert code == 1 and "the table is not stated" in err and "--table" in err
    code, out, err = run(capsys, "import", "csv", str(bare), "--table", "holding", "-o", str(tmp_path / "bare.yaml"))
    assert code == 0 and "speed: type (not stated: review; read as u16 meanwhile)" in out
    assert compile_map(tmp_path / "bare.yaml").register("speed").review == ("type",)
    assert m.register("active_power").review == ()  # --word-order stated it


def test_bad_input_is_located_and_nothing_is_overwritten(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("modbus:\n  - name: x\n    sensors: [\n", encoding="utf-8")
    code, _, err = run(capsys, "import", "homeassistant", str(broken), "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and re.match(rf"{re.escape(str(broken))}:\d+:\d+: error: not YAML", err)
    included = tmp_path / "configuration.yaml"
    included.write_text("homeassistant:\n  name: home\nmodbus: !include modbus.yaml\n", encoding="utf-8")
    code, _, err = run(capsys, "import", "homeassistant", str(included), "-o", str(tmp_path / "x.yaml"))
    assert code == 1 and "configuration.yaml:3:9: error: !include modbus.yaml: no such file" in err  # resolved, not ignored
    included.unlink()
    code, _, err = run(capsys, "import", "excel", str(broken))
    assert code == 1 and err.startswith("<command line>:1:") and "unknown format 'excel'" in err
    code, _, err = run(capsys, "import", "csv", str(tmp_path / "missing.csv"))
    assert code == 1 and "missing.csv:1:1: error: no such file" in err
    shutil.copy(ROOT / "docs" / "exporters" / "examples" / "sdm630.csv", tmp_path / "sdm630.csv")
    mine = tmp_path / "sdm630.yaml"
    mine.write_text("mine\n", encoding="utf-8")
    code, _, err = run(capsys, "import", "csv", str(tmp_path / "sdm630.csv"), "-o", str(mine))
    assert code == 1 and "file exists; not overwritten (pass --force)" in err
    assert mine.read_text(encoding="utf-8") == "mine\n"
    code, _, err = run(capsys, "import", "csv", str(tmp_path / "sdm630.csv"), "-o", str(tmp_path / "other.yaml"),
                       "--model", "sdm630")
    assert code == 1 and "--model sdm630 differs from the file name other.yaml" in err
    code, _, err = run(capsys, "import", "csv", str(tmp_path / "sdm630.csv"), "-o", str(mine), "--force")
    assert code == 0, err
    assert compile_map(mine).register("phase_1_voltage").type == "f32"
    leftovers = sorted(p.name for p in tmp_path.iterdir())
    assert leftovers == ["broken.yaml", "sdm630.csv", "sdm630.yaml"]  # no temporary or stray file


def test_import_cli_in_an_empty_folder(tmp_path: Path) -> None:
    work = tmp_path / "plant"
    work.mkdir()
    shutil.copy(ROOT / "docs" / "exporters" / "examples" / "ev.homeassistant.yaml", tmp_path / "ev.ha.yaml")
    proc = cli("import", "homeassistant", str(tmp_path / "ev.ha.yaml"), cwd=work)
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.relative_to(work).as_posix() for p in work.rglob("*")) == ["maps", "maps/ev.yaml"]
    assert "wrote maps/ev.yaml" in proc.stdout and "review" in proc.stdout
    written = (work / "maps" / "ev.yaml").read_text(encoding="utf-8")
    assert f"\ndrivemap: {CURRENT}\n" in written  # the current map format: `drivemap migrate` has nothing to do
    migrate = cli("migrate", cwd=work)
    assert migrate.returncode == 0 and migrate.stdout == "", migrate.stdout + migrate.stderr
    validate = cli("validate", cwd=work)
    assert validate.returncode == 0 and "maps/ev.yaml: ok" in validate.stdout, validate.stderr


def test_import_and_probe_from_the_installed_wheel(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> None:
    """Both verbs as users get them: the wheel in a fresh virtualenv (without the sunspec extra), run in
    an empty folder outside this checkout; what they write validates there."""
    import subprocess

    from tests.project.test_wheel import _wait_for, free_port, ok
    from tests.project.test_wheel import env as env_fixture
    from tests.project.test_wheel import wheel as wheel_fixture

    bindir = env_fixture.__wrapped__(wheel_fixture.__wrapped__(tmp_path_factory), tmp_path_factory)  # type: ignore[attr-defined]
    work = tmp_path / "new-device"
    work.mkdir()
    (work / "ev.csv").write_text(ok(bindir, work, "export", "ev", "--format", "csv"), encoding="utf-8")
    assert "wrote maps/ev.yaml" in ok(bindir, work, "import", "csv", "ev.csv")
    port = free_port()
    server = subprocess.Popen([str(bindir / "drivemap"), "simulate", "vfd1000", "--tcp", f"127.0.0.1:{port}"],
                              cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(port)
        out = ok(bindir, work, "probe", "--tcp", f"127.0.0.1:{port}", "--range", "0x2000-0x2010", "--rate", "1000")
    finally:
        server.terminate()
        server.wait(timeout=10)
    assert "nothing was written to the device" in out and "wrote maps/probed_device.yaml" in out
    validated = ok(bindir, work, "validate")
    assert "maps/probed_device.yaml: ok" in validated and "maps/ev.yaml: ok" in validated
    from tests.project.test_wheel import drivemap as run_wheel

    needs = run_wheel(bindir, work, "import", "sunspec", "103")
    assert needs.returncode == 1 and "needs drivemap[sunspec]" in needs.stderr and "Traceback" not in needs.stderr
    assert sorted(p.relative_to(work).as_posix() for p in work.rglob("*")) == [
        "ev.csv", "maps", "maps/ev.yaml", "maps/probed_device.yaml"]


JUNK = ["", "x", "-1", "0x", "[]", "{}", "null", "1e999", "abc: [", "99999999", "'", "- - -", "&a [*a]", "!secret s"]


def test_mangled_sources_end_in_located_errors_never_a_traceback(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Lines of real sources replaced by junk: every run ends in 0 or one located error, nothing else."""
    import random

    import sunspec2

    rng = random.Random(25)
    sources = {"homeassistant": [HA], "esphome": [ESPHOME], "csv": [VENDOR],
               "sunspec": [(Path(sunspec2.__file__).parent / "models/json/model_160.json").read_text("utf-8")],
               "json": [export(capsys, "delta_vfd_el_w", "json"), export(capsys, "v2", "json")],
               "pymodbus-sim": [export(capsys, "delta_vfd_el_w", "pymodbus-sim"), json.dumps(SIM, indent=1)]}
    for i in range(100):
        fmt = rng.choice(sorted(sources))
        lines = rng.choice(sources[fmt]).splitlines()
        for _ in range(rng.randint(1, 4)):
            k = rng.randrange(len(lines))
            key = lines[k].split(":", 1)[0] if ":" in lines[k] else ""
            comma = "," if fmt in ("json", "pymodbus-sim") and lines[k].endswith(",") else ""  # often still JSON
            lines[k] = f"{key}: {rng.choice(JUNK)}{comma}" if key and rng.random() < 0.7 else rng.choice(JUNK)
        source = tmp_path / f"s{i}.{ {'csv': 'csv', 'homeassistant': 'yaml', 'esphome': 'yaml'}.get(fmt, 'json') }"
        source.write_text("\n".join(lines) + "\n", encoding="utf-8")
        argv = ["import", fmt, f"{source}:48" if fmt == "sunspec" else str(source), "-o", str(tmp_path / "o" / "m.yaml"),
                "--force", *(["--word-order", "high_first"] if fmt == "csv" else [])]
        code, _, err = run(capsys, *argv)
        assert code in (0, 1), (source, err)
        assert code == 0 or re.search(r"^\S+:\d+:\d+: error: ", err, re.M), (source, err)
    for i in range(80):  # well-formed JSON of the wrong shape: values replaced by others, keys dropped
        fmt = rng.choice(["json", "pymodbus-sim"])
        data = json.loads(rng.choice(sources[fmt]))
        for _ in range(rng.randint(1, 3)):
            box, key = rng.choice(slots(data))
            if isinstance(box, dict) and rng.random() < 0.2:
                del box[key]
            else:
                box[key] = json.loads(rng.choice(SHAPES))
        source = tmp_path / f"shape{i}.json"
        source.write_text(json.dumps(data, indent=1), encoding="utf-8")
        code, _, err = run(capsys, "import", fmt, str(source), "-o", str(tmp_path / "o" / "m.yaml"), "--force")
        assert code in (0, 1), (source, err)
        assert code == 0 or re.search(r"^\S+:\d+:\d+: error: ", err, re.M), (source, err)
        assert "cannot import an entry of this file" not in err, (source, err)  # each shape has its own message


SHAPES = ["null", "-1", "\"x\"", "[]", "{}", "1e999", "99999999", "true", "[[]]", "0.5", "\"\"", "[1, 2]", "{\"a\": 1}"]


def slots(node: object) -> list[tuple[Any, Any]]:
    """Every (container, key or index) of a JSON document."""
    out: list[tuple[Any, Any]] = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        out.append((node, key))
        out += slots(value)
    return out


@pytest.mark.parametrize("model", MAPS)
def test_esphome_newest_form_brings_back_every_entity(model: str, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The default (newest) ESPHome export -- a controller per polling interval, reuse_previous_range,
    text by response_size -- imports back with every entity: the same entities at the same addresses."""
    first = export(capsys, model, "esphome")
    source = tmp_path / f"{model}.esphome.yaml"
    source.write_text(first, encoding="utf-8")
    target = tmp_path / "maps" / f"{model}.yaml"
    code, summary, err = run(capsys, "import", "esphome", str(source), "-o", str(target))
    assert code == 0, err
    second = export(capsys, str(target), "esphome", *again(summary))

    def entities(text: str) -> set[tuple[str, str]]:
        names = re.findall(r"^    name: (.*)$", text, re.M)
        addresses = re.findall(r"^    address: (.*)$", text, re.M)
        return set(zip(names, addresses, strict=False))

    assert entities(second) == entities(first)
