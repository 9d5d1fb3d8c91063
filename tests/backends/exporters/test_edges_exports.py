"""Exports the real tools read as drivemap reads the device: the write function the map allows,
not-available values and padded strings Home Assistant honours, units and device classes it accepts."""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import Any

import jinja2
import pytest
from exporter_helpers import MAPS, load, parse, render

from drivemap.model.nodes import Model

SINGLE = {"holding": 0x06, "coil": 0x05}
MULTIPLE = {"holdings": 0x10, "coils": 0x0F}
HA_WRITE_TYPES = {"holding": 0x06, "holdings": 0x10, "coil": 0x05, "coils": 0x0F}


def _entities(doc: Any) -> list[dict[str, Any]]:
    return [e for key in ("sensor", "number", "select", "switch", "binary_sensor", "text_sensor")
            for e in doc.get(key, []) or []]


@pytest.mark.parametrize("name", [*MAPS, "allkinds"])
def test_home_assistant_switches_write_with_a_function_the_map_lists(name: str) -> None:
    model = load(name)
    doc = parse("homeassistant", render(model, "homeassistant"))
    switches = doc["modbus"][0].get("switches", [])
    for switch in switches:
        code = HA_WRITE_TYPES[switch["write_type"]]
        assert model.protocol.function(code) is not None, (name, switch["name"], switch["write_type"])


@pytest.mark.parametrize("name", [*MAPS, "allkinds"])
def test_esphome_writes_with_a_function_the_map_lists(name: str) -> None:
    model = load(name)
    doc = parse("esphome", render(model, "esphome"))
    for entity in _entities(doc):
        if entity.get("platform") != "modbus_controller":
            continue
        table = {"holding": "holding", "coil": "coil"}.get(entity.get("register_type", "holding"))
        writes = entity.get("use_write_multiple") or "platform" in entity and _writable(entity)
        if not writes or table is None:
            continue
        if entity.get("use_write_multiple"):
            assert model.protocol.function(0x10 if table == "holding" else 0x0F) is not None, entity
        elif entity.get("register_count", 1) == 1 and _one_word(model, entity):
            assert model.protocol.function(SINGLE[table]) is not None, (name, entity["name"])


def _writable(entity: dict[str, Any]) -> bool:
    return "min_value" in entity or "optionsmap" in entity or "assumed_state" in entity or "write_lambda" in entity


def _one_word(model: Model, entity: dict[str, Any]) -> bool:
    return entity.get("value_type", "U_WORD") in ("U_WORD", "S_WORD")


def test_sdm630_reset_is_never_exported_as_a_one_register_write() -> None:
    """The meter has no 06h and takes its reset only as two registers by 10h (sdm630's alignment rules):
    neither tool can write it with a one-register switch, so neither export offers one, and both say why."""
    model = load("sdm630")
    assert model.protocol.function(0x06) is None and model.protocol.function(0x10) is not None
    assert model.register("reset").words == 2
    ha_text = render(model, "homeassistant")
    ha = parse("homeassistant", ha_text)
    assert not any(s["unique_id"] == "sdm630_reset" for s in ha["modbus"][0].get("switches", []))
    assert "not exported as a switch: reset (a switch writes one register" in ha_text
    esphome_text = render(model, "esphome")
    esphome = parse("esphome", esphome_text)
    assert not any(e["name"].endswith("reset") for e in esphome.get("switch", []))
    assert "not exported: reset is a 2-register command" in esphome_text


def _ha_env() -> jinja2.Environment:
    env = jinja2.Environment(autoescape=False)
    env.filters["regex_replace"] = lambda value, find="", replace="": re.sub(find, replace, value)
    return env


def test_not_available_zero_is_a_template_home_assistant_honours() -> None:
    model = load("fronius_symo_hybrid")
    zero = [r for r in model.registers if 0 in r.not_available and not r.is_float and r.readable]
    assert zero, "fronius has counters where 0 means not available"
    doc = parse("homeassistant", render(model, "homeassistant"))
    sensors = doc["modbus"][0]["sensors"]
    assert not [s for s in sensors if "nan_value" in s and not s["nan_value"]]  # HA ignores a falsy nan_value
    templates = {t["unique_id"]: t for t in doc["template"][0]["sensor"]}
    env = _ha_env()
    for reg in zero:
        uid = f"fronius_symo_hybrid_{reg.name}"
        template = templates[uid]
        raw_uid = f"sensor.{uid}_raw"
        assert any(s["unique_id"] == f"{uid}_raw" for s in sensors)

        def available(state: str, raw_uid: str = raw_uid, template: dict[str, Any] = template) -> str:
            return env.from_string(template["availability"]).render(
                states=lambda e: state, has_value=lambda e: True)

        assert available("0") == "False" and available("0.0") == "False" and available("1234") == "True"


def test_nul_padded_strings_are_stripped_for_home_assistant() -> None:
    model = load("fronius_symo_hybrid")
    doc = parse("homeassistant", render(model, "homeassistant"))
    template = next(t for t in doc["template"][0]["sensor"] if t["unique_id"] == "fronius_symo_hybrid_manufacturer")
    out = _ha_env().from_string(template["state"]).render(states=lambda e: "Fronius\x00\x00\x00 ",
                                                          has_value=lambda e: True)
    assert out == "Fronius"


def test_units_and_device_classes_home_assistant_accepts() -> None:
    ev_model, fronius_model = load("ev"), load("fronius_symo_hybrid")
    ev = parse("homeassistant", render(ev_model, "homeassistant"))
    units = {s.get("unit_of_measurement") for s in ev["modbus"][0]["sensors"]}
    assert "r/min" not in units and "rpm" in units
    sdm = parse("homeassistant", render(load("sdm630"), "homeassistant"))
    by_unit = {s.get("unit_of_measurement"): s for s in sdm["modbus"][0]["sensors"]}
    assert "VAr" not in by_unit and by_unit["var"]["device_class"] == "reactive_power"
    assert by_unit["VA"]["device_class"] == "apparent_power"
    current = render(fronius_model, "homeassistant")
    fronius = parse("homeassistant", current)
    entries = fronius["modbus"][0]["sensors"] + fronius["template"][0]["sensor"]
    varh = [e for e in entries if e.get("unit_of_measurement") == "varh"]
    assert varh and all(e["device_class"] == "reactive_energy" for e in varh)
    vah = [e for e in entries if e.get("unit_of_measurement") == "VAh"]
    assert vah and all("device_class" not in e and e["state_class"] == "total_increasing" for e in vah)
    old = render(fronius_model, "homeassistant", ha_version="2024.1")
    assert "device_class: reactive_energy" not in old and "device_class: reactive_energy" in current  # older releases have no such class
    esphome = parse("esphome", render(ev_model, "esphome"))
    assert "r/min" not in str(esphome) and "rpm" in str(esphome)


def test_esphome_numbers_step_at_the_resolution() -> None:
    doc = parse("esphome", render(load("ev"), "esphome"))
    accel = next(n for n in doc["number"] if n["name"] == "ev digital_accel_time_0")
    assert accel["step"] == 0.1 and accel["multiply"] == 10


@pytest.mark.parametrize("name", MAPS)
def test_pymodbus_sim_export_is_the_simulators_start_up_image(name: str) -> None:
    from helpers_client import simulator

    from drivemap.runtime.sim.unit import wire_words

    doc = parse("pymodbus-sim", render(load(name), "pymodbus-sim"))
    device = doc["device_list"][name]
    setup = device["setup"]
    base = {"coil": 0, "discrete": setup["co size"], "input": setup["co size"] + setup["di size"],
            "holding": setup["co size"] + setup["di size"] + setup["ir size"]}
    words = {item["addr"]: item["value"] for item in device["uint16"]}
    for item in device["uint32"]:  # two-word entries, high word first in pymodbus's simulator
        first, second = item["addr"]
        words[first], words[second] = item["value"] >> 16, item["value"] & 0xFFFF
    for item in device["float32"]:
        high, low = struct.unpack(">HH", struct.pack(">f", item["value"]))
        first, second = item["addr"]
        words[first], words[second] = high, low
    sim = simulator(name)  # the generated simulator: the model's behaviour ran its power-up
    pages = doc["drivemap"]["pages"]
    compared = 0
    for reg in sim.spec.registers:
        if reg.bit_table or reg.page is not None and pages.get(reg.page.selector) != reg.page.value:
            continue
        for i in range(reg.count):
            at = base[reg.table] + reg.element_address(i)
            if at in words:
                wire = wire_words(reg, sim.get_raw(reg.element_name(i)))
                assert [words.get(at + k) for k in range(len(wire))] == list(wire), (reg.element_name(i), at)
                compared += 1
    assert compared > 0
    if name == "ev":  # the RAM copies start as the EEPROM values (ev's power-up), not 0
        ram = sim.spec.register("digital_speed_ram")
        assert any(words[base["holding"] + ram.element_address(i)] for i in range(ram.count))


LINE = ("--serial", "/dev/ttyUSB0", "--baudrate", "9600", "--parity", "none", "--stopbits", "1", "--method", "rtu")


def test_devices_on_one_serial_line_share_one_home_assistant_hub() -> None:
    from helpers_live import run

    proc = run("export", "ev:1", "vfd1000:2", "--format", "homeassistant", *LINE)
    assert proc.returncode == 0, proc.stderr
    doc = parse("homeassistant", proc.stdout)
    assert len(doc["modbus"]) == 1  # Home Assistant drops a second hub on the same port
    hub = doc["modbus"][0]
    assert hub["port"] == "/dev/ttyUSB0"
    addresses = {e["unique_id"].split("_")[0]: e["device_address"] for e in hub["sensors"]}
    assert addresses == {"ev": 1, "vfd1000": 2}
    ids = [e["unique_id"] for key in ("sensors", "switches", "binary_sensors") for e in hub.get(key, [])]
    assert len(ids) == len(set(ids))
    twins = parse("homeassistant", run("export", "ev:1", "ev:2", "--format", "homeassistant", *LINE).stdout)
    twin_ids = [e["unique_id"] for e in twins["modbus"][0]["sensors"]]
    assert len(twin_ids) == len(set(twin_ids)) and any(i.startswith("ev_2_") for i in twin_ids)


def test_one_line_exports_refuse_what_cannot_share_a_line(tmp_path: Path) -> None:
    from helpers_live import ROOT, run

    same_unit = run("export", "ev:1", "vfd1000:1", "--format", "homeassistant", *LINE)
    assert same_unit.returncode == 1 and "unit 1 is given to both ev and vfd1000" in same_unit.stderr
    other_format = run("export", "ev:1", "vfd1000:2", "--format", "csv")
    assert other_format.returncode == 1 and "only --format homeassistant" in other_format.stderr
    text = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8")
    assert text.count("default_baudrate: 9600") == 1
    fast = tmp_path / "sdm630.yaml"  # the same meter set to 19200 baud by its owner
    fast.write_text(text.replace("default_baudrate: 9600", "default_baudrate: 19200").replace(
        "../schemas/", f"{ROOT}/schemas/"), encoding="utf-8")
    clash = run("export", "sdm630:1", f"{fast}:2", "--format", "homeassistant", "--serial", "/dev/ttyUSB0")
    assert clash.returncode == 1 and "share its settings" in clash.stderr and "19200" in clash.stderr, clash.stderr
    same = run("export", "sdm630:1", f"{fast}:2", "--format", "homeassistant", "--serial", "/dev/ttyUSB0",
               "--baudrate", "9600")
    assert same.returncode == 0, same.stderr
