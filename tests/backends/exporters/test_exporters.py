"""The integration exporters: Home Assistant, ESPHome, pymodbus's simulator, CSV.

The real tools' own checks are in test_exporters_tools.py (marker ``tools``); here: structure,
determinism, hostile text, option errors, ESPHome's batching (its range builder, ported), the
pymodbus simulator's datastore serving the export to the generated client, committed exports.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import re
from pathlib import Path
from typing import Any

import jinja2
import pytest

from drivemap.backends.exporters.homeassistant import jinja_literal
from drivemap.backends.views.integrations import comment_safe
from drivemap.cli import main
from drivemap.compiler import load_model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.client.protocol.planner import plan_reads
from tests import esphome_ranges as esp
from tests.exporter_helpers import (
    HOSTILE,
    INTEGRATIONS,
    MAPS,
    ROOT,
    compile_hostile,
    load,
    parse,
    render,
    shape,
)


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(autouse=True)
def _at_root(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)


def test_list_shows_every_builtin() -> None:
    code, out, _ = run("export", "--list")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    for name in ("python", "docs", "json", *INTEGRATIONS):
        assert name in names


@functools.cache
def _compiled_twice(model: str) -> tuple[Any, Any]:
    """Two separate compilations of ``model`` (shared by its formats: each export renders from both)."""
    return load(model), load(model)


@pytest.mark.parametrize("fmt", INTEGRATIONS)
@pytest.mark.parametrize("model", [*MAPS, "allkinds"])
def test_deterministic_and_parseable(model: str, fmt: str) -> None:
    m, again = _compiled_twice(model)
    first, second = render(m, fmt), render(again, fmt)
    assert first.encode() == second.encode()
    assert parse(fmt, first)


@pytest.mark.parametrize("fmt", INTEGRATIONS)
def test_hostile_text_never_changes_structure(fmt: str, tmp_path: Path) -> None:
    clean, hostile = render(load_model("ev"), fmt), render(compile_hostile(tmp_path), fmt)
    assert shape(parse(fmt, clean)) == shape(parse(fmt, hostile))
    if fmt in ("homeassistant", "esphome"):
        # map text reaches comments only flattened to one line
        for line in hostile.splitlines():
            assert not line.startswith(("second:", "- item")), line
    if fmt == "csv":
        rows = parse(fmt, hostile)
        assert rows[0]["label"] == comment_safe(HOSTILE)
        assert all(len(r) == len(rows[0]) for r in rows)


def test_hostile_labels_survive_home_assistant_templates(tmp_path: Path) -> None:
    """The label template, rendered by Jinja as Home Assistant renders it, returns the label verbatim."""
    model = compile_hostile(tmp_path)
    doc = parse("homeassistant", render(model, "homeassistant"))
    label = next(t for t in doc["template"][0]["sensor"] if t["unique_id"] == "ev_motor_state_label")
    env = jinja2.Environment(autoescape=False)
    for raw, index in (("2", 1), ("0", 0)):
        out = env.from_string(label["state"]).render(states=lambda entity, raw=raw: raw)
        assert out == model.enum("MotorState").members[index].label
        assert out.startswith(HOSTILE[:40])
    assert env.from_string(label["state"]).render(states=lambda entity: "99") == "99"
    assert "{{" not in jinja_literal({"a": "{{ x }}"}) and "%" not in jinja_literal({"a": "{% x %}"})


def test_hostile_labels_survive_esphome_maps(tmp_path: Path) -> None:
    doc = parse("esphome", render(compile_hostile(tmp_path), "esphome"))
    labels = [m["to"] for t in doc["text_sensor"] for f in t["filters"] for m in f["map"]]
    assert f"{HOSTILE} #0" in labels
    selects = [k for s in doc["select"] for k in s["optionsmap"]]
    assert f"{HOSTILE} #0" in selects
    text = render(compile_hostile(tmp_path), "esphome")
    assert "!literal" in text  # '$' in map text is kept from ESPHome's substitutions


def test_home_assistant_keys_by_release() -> None:
    m = load_model("ev")
    current = parse("homeassistant", render(m, "homeassistant"))["modbus"][0]
    old = parse("homeassistant", render(m, "homeassistant", ha_version="2023.9"))["modbus"][0]
    assert "device_address" in current["sensors"][0] and "slave" not in current["sensors"][0]
    assert "slave" in old["sensors"][0] and "device_address" not in old["sensors"][0]
    arrays = [s for s in current["sensors"] if "virtual_count" in s]
    assert arrays and all("slave_count" in s for s in old["sensors"] if s["name"] in {a["name"] for a in arrays})
    code, _, err = run("export", "ev", "--format", "homeassistant", "--baudrate", "9600", "--method", "rtu",
                       "--ha-version", "2019.1")
    assert code == 1 and "--ha-version" in err and "Traceback" not in err


def test_home_assistant_entities_of_ev() -> None:
    doc = parse("homeassistant", render(load_model("ev"), "homeassistant", tcp="127.0.0.1:502"))
    hub = doc["modbus"][0]
    assert (hub["type"], hub["host"], hub["port"]) == ("tcp", "127.0.0.1", 502)
    sensors = {s["name"]: s for s in hub["sensors"]}
    volt = sensors["ev bus_voltage"]
    assert (volt["address"], volt["scale"], volt["precision"], volt["device_class"]) == (9, 0.01, 2, "voltage")
    assert sensors["ev digital_speed"]["virtual_count"] == 7  # one read for the whole array
    assert "ev accel_time_monitor" not in sensors  # page 1 of watch_data_select: not the page exported
    switches = {s["name"]: s for s in hub["switches"]}
    assert switches["ev alarm_reset"]["command_on"] == switches["ev alarm_reset"]["command_off"] == 1
    assert not any(s["address"] < 0x0100 for s in hub["switches"])  # read-only monitor never writable
    bits = [b["name"] for b in doc["template"][0]["binary_sensor"]]
    assert "ev net_in X0" in bits and "ev rs485_comm_settings STOP_BITS" in bits
    page1 = parse("homeassistant", render(load_model("ev"), "homeassistant", page=["watch_data_select=1"]))
    assert "ev accel_time_monitor" in {s["name"] for s in page1["modbus"][0]["sensors"]}


@pytest.mark.parametrize("argv, message", [
    (["--format", "homeassistant"], "--baudrate"),
    (["--format", "homeassistant", "--tcp", "nohost"], "--tcp"),
    (["--format", "esphome", "--baudrate", "9600", "--page", "nope=1"], "--page"),
    (["--format", "esphome", "--baudrate", "9600", "--only", "nogroup"], "--only"),
    (["--format", "esphome", "--baudrate", "9600", "--port", "rs232"], "RTU only"),
    (["--format", "pymodbus-sim", "--unit", "99"], "--unit"),
    (["--format", "csv", "--delimiter", "pipe"], "--delimiter"),
])
def test_option_errors_are_usage_errors(argv: list[str], message: str) -> None:
    code, _, err = run("export", "ev", *argv)
    assert code == 1
    assert message.lower() in err.lower() and "Traceback" not in err


def _esphome_ranges(doc: dict[str, Any], version: str) -> list[esp.Range]:
    if version != "2026.6":
        assert not any(k in str(doc) for k in ("register_count", "force_new_range", "skip_updates", "command_throttle"))
    return esp.update_ranges(doc, reuse=version != "2026.6")


@pytest.mark.parametrize("version", ["2026.6", "2026.10"])
@pytest.mark.parametrize("model", [*MAPS, "allkinds"])
def test_esphome_ranges_match_drivemap_plan(model: str, version: str) -> None:
    """ESPHome's range builder (ported, before and since 2026.9) on the export: every entity decodes its
    own word, no range exceeds the device's limit, and the ranges are drivemap's plan (plus what the
    header reports)."""
    m = load(model)
    text = render(m, "esphome", esphome_version=version)
    doc = parse("esphome", text)
    got = _esphome_ranges(doc, version)
    spec = spec_from_model(m)
    for r in got:
        for item in r.sensors:
            words = item.offset if item.register_type in ("coil", "discrete_input") else item.offset // 2
            assert r.start_address + words == item.word, (item.name, hex(r.start_address))
            assert words + item.register_count <= r.register_count, item.name
    fc = spec.protocol.function(0x03)
    limit = fc.max_quantity if fc and fc.max_quantity else 125
    assert all(r.register_count <= limit for r in got)
    claimed = int(text.split("this file makes ESPHome send ")[1].split()[0])
    assert len(got) == claimed
    keys = {(n.rsplit("[", 1)[0], int(n.rsplit("[", 1)[1][:-1]) if "[" in n else 0)
            for n in _polled_cells(m, doc)}
    plan = plan_reads(spec, keys)
    types = {"holding": "holding", "input": "read", "coil": "coil", "discrete": "discrete_input"}
    spans = sorted((r.register_type, r.start_address, r.register_count) for r in got)
    if claimed == len(plan):
        assert spans == sorted((types[q.table], q.address, q.count) for q in plan)


def _polled_cells(model: Any, doc: dict[str, Any]) -> set[str]:
    types = {"holding": "holding", "input": "read", "coil": "coil", "discrete": "discrete_input"}
    words = {(i.register_type, i.word) for i in esp.items_of(doc) if not i.name.startswith("gap_")}
    return {c.name for c in model.cells() if (types[c.register.table], c.address) in words and c.register.readable
            and (c.register.page is None or c.register.page.value == 0)}


def test_esphome_ev_is_drivemaps_plan_exactly() -> None:
    text = render(load_model("ev"), "esphome", esphome_version="2026.6")
    assert "drivemap plans 19, this file makes ESPHome send 19" in text
    doc = parse("esphome", text)
    gaps = [s for s in doc["sensor"] if str(s.get("id", "")).startswith("gap_")]
    assert gaps and all(s["internal"] for s in gaps)  # reserved words inside a planned read
    assert doc["modbus_controller"][0]["command_throttle"] == "20ms"  # EEPROM write delay of the map


def test_esphome_newest_release_reads_the_plan_without_removed_keys() -> None:
    """2026.9 and later (the default): no register_count, force_new_range, skip_updates or
    command_throttle; holes are read across (reuse_previous_range: true), slower groups get a
    controller of their own, the write delay spaces commands on the hub."""
    text = render(load_model("ev"), "esphome")
    assert "ESPHome 2026.10 (esphome config FILE)" in text
    assert "drivemap plans 19, this file makes ESPHome send 19" in text
    doc = parse("esphome", text)
    assert not [s for s in doc["sensor"] if str(s.get("id", "")).startswith("gap_")]
    assert any(s.get("reuse_previous_range") is True for s in doc["sensor"])
    assert doc["modbus"][0]["turnaround_time"] == "20ms"
    controllers = {c["id"]: c["update_interval"] for c in doc["modbus_controller"]}
    assert controllers == {"device": "15s", "device_20x": "300s"}  # the settings groups: every 300 s
    assert all("command_throttle" not in c for c in doc["modbus_controller"])


@pytest.mark.parametrize(("value", "message"), [("2026.5", "older than the oldest supported release (2026.6)"),
                                                ("next", "is not a release")])
def test_esphome_version_refuses_what_it_cannot_write(value: str, message: str) -> None:
    from drivemap.backends.exporters.base import OptionError

    with pytest.raises(OptionError, match=re.escape(message)):
        render(load_model("ev"), "esphome", esphome_version=value)


@pytest.mark.slow  # a pymodbus server on TCP for every map
def test_pymodbus_simulator_serves_the_export() -> None:
    """pymodbus's simulator datastore, built from the JSON exactly as pymodbus.simulator builds it,
    answers the generated client with the map's image (the real CLI: test_exporters_tools.py)."""
    from tests.sim_helpers import read_back, serve_export

    for model in [*MAPS, "allkinds"]:
        m = load(model)
        with serve_export(m) as (port, unit):
            got, expected = read_back(m, port, unit)
        assert got == expected, model
        if model == "ev":
            assert got["digital_speed"] == (3000,) * 8 and got["digital_duty"][7] == 100


def test_committed_export_is_built_and_checked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "ev.yaml").write_text((ROOT / "maps" / "ev.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    (tmp_path / "pyproject.toml").write_text(
        '[tool.drivemap]\nmaps = "maps"\nout = "gen"\n\n'
        '[[tool.drivemap.exports]]\nformat = "homeassistant"\nmodel = "ev"\noutput = "ha/ev.yaml"\n'
        'options = {tcp = "127.0.0.1:502", page = ["watch_data_select=1"], ha-version = "2024.3"}\n',
        encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert run("build")[0] == 0
    written = (tmp_path / "ha" / "ev.yaml").read_text(encoding="utf-8")
    assert "ev accel_time_monitor" in written and "host: 127.0.0.1" in written
    assert run("check")[0] == 0
    (tmp_path / "ha" / "ev.yaml").write_text(written + "# edited\n", encoding="utf-8")
    code, _, err = run("check")
    assert code == 1 and "ha/ev.yaml" in err
    assert run("build")[0] == 0 and run("check")[0] == 0
    text = (tmp_path / "pyproject.toml").read_text(encoding="utf-8")
    (tmp_path / "pyproject.toml").write_text(text.replace("ha-version", "colour"), encoding="utf-8")
    code, _, err = run("check")
    assert code == 1 and "pyproject.toml:5:1: error: exports: homeassistant for ev: unknown option 'colour'" in err
    (tmp_path / "pyproject.toml").write_text(text.replace('"2024.3"', '"soon"'), encoding="utf-8")
    code, _, err = run("build")
    assert code == 1 and "--ha-version" in err and "Traceback" not in err


def test_csv_rows_are_register_elements() -> None:
    m = load_model("ev")
    rows = parse("csv", render(m, "csv"))
    assert len(rows) == sum(r.count for r in m.registers)
    speed = next(r for r in rows if r["name"] == "digital_speed[3]")
    assert (speed["address_hex"], speed["modicon"], speed["param"], speed["default"]) == ("0x030B", "400780", "03-12", "3000")
    assert json.dumps(rows[0], ensure_ascii=False)
