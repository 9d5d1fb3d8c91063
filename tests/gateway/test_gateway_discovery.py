"""Home Assistant discovery as HA reads it: controls only for what the gateway takes commands for, link
settings never discovered as controls unless named, enum states always among the options, number
states always inside the range, units and device classes HA knows, the device as the map states it.
The value templates are rendered with Jinja2 the way Home Assistant renders them."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import jinja2
import pytest

from drivemap.compiler import compile_map
from drivemap.diagnostics import CompileError
from drivemap.gateway.access import LINK_WORDS, group_writables, link_setting
from drivemap.gateway.config import load_config
from drivemap.gateway.device import Device
from drivemap.gateway.discovery import discovery_messages, entity_name
from drivemap.gateway.service import Gateway

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted((ROOT / "maps").glob("*.yaml"))

CONFIG = """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1}
buses:
  - name: line1
    tcp: 127.0.0.1:1
    devices:
      - {name: pump1, model: vfd1000, unit: 1, writable: [communication_setting]}
      - {name: conveyor, model: ev, unit: 2, writable: [rs485_error_count, alarm_reset, net_in]}
      - {name: meter, model: sdm630, unit: 3, writable: [setup]}
      - {name: inv, model: fronius_symo_hybrid, unit: 4, publish: [ac_power, max_power_setting]}
"""


@pytest.fixture(scope="module")
def messages(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    path = tmp_path_factory.mktemp("discovery") / "gw.yaml"
    path.write_text(CONFIG)
    cfg = load_config(path)

    async def made() -> dict[str, Device]:
        return Gateway(cfg).devices

    devices = asyncio.run(made())
    out: dict[str, dict[str, Any]] = {}
    for dev in devices.values():
        for topic, payload in discovery_messages("plant", dev, "homeassistant", "drivemap/gateway/plant/availability"):
            out[topic.split("/", 1)[1].rsplit("/", 1)[0]] = payload  # component/node/object
    return out


def render(template: str, value: str) -> str:
    """A value template rendered as Home Assistant does (Jinja2; its ``float`` filter takes a default)."""
    env = jinja2.Environment()
    payload = json.loads(value) if value[:1] in "[{" else None
    return env.from_string(template).render(value=value, value_json=payload)


def test_controls_only_for_listed_registers(messages: dict[str, dict[str, Any]]) -> None:
    assert "number/drivemap_plant_pump1/communication_setting" in messages
    assert "sensor/drivemap_plant_pump1/pid_setting" in messages  # writable in the map, not listed: a sensor
    assert "number/drivemap_plant_pump1/pid_setting" not in messages
    assert "select/drivemap_plant_pump1/control_command" not in messages  # write-only and not listed: nothing
    assert "button/drivemap_plant_conveyor/alarm_reset" in messages
    assert not [t for t in messages if "drivemap_plant_inv" in t and t.split("/")[0] in ("number", "select",
                                                                                        "button", "switch")]


def test_link_settings_are_not_controls_through_a_group(messages: dict[str, dict[str, Any]]) -> None:
    for name in ("network_node", "network_baud_rate", "network_parity_stop", "password", "password_lock"):
        assert not [t for t in messages if t.endswith(f"drivemap_plant_meter/{name}") and not t.startswith("sensor/")]
    assert "select/drivemap_plant_meter/demand_period" in messages  # the group opened what is not a link setting
    assert "number/drivemap_plant_conveyor/rs485_error_count" in messages  # a link setting named one by one


def test_enum_states_are_among_the_options(messages: dict[str, dict[str, Any]]) -> None:
    state = messages["sensor/drivemap_plant_pump1/inverter_state"]
    assert state["device_class"] == "enum" and "STANDBY" in state["options"]
    assert render(state["value_template"], "STANDBY") == "STANDBY"
    assert render(state["value_template"], "UNKNOWN_0") == "None"  # HA: unknown, never an invalid option
    assert render(state["value_template"], "null") == "None"
    parity = messages["sensor/drivemap_plant_conveyor/rs485_comm_settings_parity"]  # an enumerated bit field
    known = parity["options"][0]
    assert render(parity["value_template"], json.dumps({"PARITY": known})) == known
    assert render(parity["value_template"], json.dumps({"PARITY": "UNKNOWN_3"})) == "None"


def test_number_states_are_inside_the_range(messages: dict[str, dict[str, Any]]) -> None:
    number = messages["number/drivemap_plant_conveyor/rs485_error_count"]
    assert (number["min"], number["max"]) == (1, 10)
    assert render(number["value_template"], "5") == "5"
    assert render(number["value_template"], "0") == "None"  # outside 1..10: unknown in the number ...
    assert render(number["value_template"], "null") == "None"
    reading = messages["sensor/drivemap_plant_conveyor/rs485_error_count_reading"]  # ... and shown here
    assert reading["state_topic"] == number["state_topic"] and "value_template" not in reading


def test_units_and_device_classes(messages: dict[str, dict[str, Any]]) -> None:
    def sensor(node: str, name: str) -> dict[str, Any]:
        return messages[f"sensor/drivemap_plant_{node}/{name}"]

    assert (sensor("conveyor", "motor_speed")["unit_of_measurement"], sensor("conveyor", "motor_speed").get(
        "device_class")) == ("rpm", None)  # HA's REVOLUTIONS_PER_MINUTE; it has no class for speed of rotation
    assert sensor("meter", "phase_1_volt_amps")["device_class"] == "apparent_power"
    assert (sensor("meter", "total_system_var")["unit_of_measurement"], sensor("meter", "total_system_var")[
        "device_class"]) == ("var", "reactive_power")
    kvarh = sensor("meter", "total_kvarh")  # by default no class HA before 2025.6 refuses (it drops the entity)
    assert (kvarh["unit_of_measurement"], kvarh.get("device_class"), kvarh["state_class"]) == (
        "kvarh", None, "total_increasing")
    assert "device_class" not in sensor("meter", "total_vah")  # HA has no class for apparent energy
    assert messages["number/drivemap_plant_pump1/communication_setting"]["suggested_display_precision"] == 2
    assert sensor("inv", "ac_power")["device_class"] == "power"


def test_the_device_as_the_map_states_it(messages: dict[str, dict[str, Any]]) -> None:
    meter = messages["sensor/drivemap_plant_meter/phase_1_voltage"]["device"]
    assert meter["manufacturer"] == "Eastron"
    assert meter["hw_version"] == "manual Eastron SDM630Modbus Smart Meter Modbus Protocol Implementation rev V1.8"
    pump = messages["sensor/drivemap_plant_pump1/inverter_state"]["device"]
    assert "manufacturer" not in pump and "hw_version" not in pump  # vfd1000's map names neither
    assert not any(".txt" in str(p["device"]) or ".pdf" in str(p["device"]) for p in messages.values())


def test_array_entity_names_come_from_one_function() -> None:
    reg = compile_map(ROOT / "maps/ev.yaml").register("digital_speed")
    assert entity_name(reg, None) == "Digital speed" and entity_name(reg, 3) == "Digital speed 3"


@pytest.mark.parametrize("path", MAPS, ids=[p.stem for p in MAPS])
def test_link_setting_rule_on_every_shipped_map(path: Path) -> None:
    model = compile_map(path)
    links = {r.name for r in model.registers if r.writable and link_setting(model, r)}
    expected = {
        "sdm630": {"network_node", "network_baud_rate", "network_parity_stop", "password", "password_lock",
                   "system_type", "pulse1_energy_type"},  # the last two: "requires password" / "MODBUS Protocol"
        "ev": {"net_x_input_function", "comm_error_action", "watch_data_select", "rs485_timeout", "rs485_error_count",
               "rs232_timeout", "rs232_error_count", "rs485_comm_settings", "comm_error_history_clear"},
        "fronius_symo_hybrid": {"f_model_type"},  # switches the register layout the inverter presents
        "wattnode_wnc": {"address", "baudrate", "paritymode"},
    }.get(model.name, set())
    assert links == expected
    for group in model.groups:
        assert not set(group_writables(model, group.name)) & links
    assert "comm" in LINK_WORDS


def test_writable_entries_are_checked(tmp_path: Path) -> None:
    path = tmp_path / "gw.yaml"
    base = CONFIG.replace("writable: [communication_setting]", "writable: @@")
    cases = {
        "[nope]": "vfd1000 has no register or group 'nope'",
        "[inverter_state]": "vfd1000.inverter_state is read-only in the map",
        "true": "writable: true is no longer accepted",
    }
    for entry, message in cases.items():
        path.write_text(base.replace("@@", entry))
        with pytest.raises(CompileError) as info:
            load_config(path)
        assert any(message in d.message for d in info.value.diagnostics), info.value.diagnostics
    path.write_text(CONFIG.replace("writable: [communication_setting]",
                                   "publish: [inverter_state], writable: [pid_setting]"))
    with pytest.raises(CompileError, match="not published"):
        load_config(path)


def test_every_shipped_unit_has_its_unece_code_or_is_named_as_without() -> None:
    from drivemap.gateway.opcua_types import UNECE, unit_id

    without = {"VAh", "varh", "%/s", "%/min"}  # Rec. 20 has no common code for these (docs/gateway.md says so)
    units = {r.unit for path in MAPS for r in compile_map(path).registers if r.unit}
    assert {u for u in units if u not in UNECE} == without & units
    assert unit_id("V") == (ord("V") << 16) | (ord("L") << 8) | ord("T") and unit_id("VAh") == -1
    docs = (ROOT / "docs/gateway.md").read_text()
    for unit in units - without:
        assert f"| {UNECE[unit]} |" in docs or f"/ {UNECE[unit]}" in docs or f"{UNECE[unit]} /" in docs, unit


#: the MQTT device keys Home Assistant 2024.3 accepts (components/mqtt/mixins.py MQTT_ENTITY_DEVICE_INFO_SCHEMA);
#: it refuses the whole entity for any other key ("extra keys not allowed @ data['device']['model_id']")
HA_2024_3_DEVICE_KEYS = {"identifiers", "connections", "manufacturer", "model", "name", "sw_version", "hw_version",
                         "via_device", "suggested_area", "configuration_url", "serial_number"}


def test_discovery_device_has_only_keys_home_assistant_2024_3_accepts(messages: dict[str, dict[str, Any]]) -> None:
    for where, payload in messages.items():
        assert set(payload["device"]) <= HA_2024_3_DEVICE_KEYS, (where, set(payload["device"]) - HA_2024_3_DEVICE_KEYS)


def test_discovery_leaves_out_device_classes_the_configured_release_lacks(tmp_path: Path) -> None:
    """Without `mqtt.ha_version` (the oldest supported release) and with "2024.3", kvarh gets no
    reactive_energy class (HA before 2025.6 refuses the entity); with "2025.6" the class is announced."""

    def meter_classes(text: str) -> dict[str, Any]:
        path = tmp_path / "gw.yaml"
        path.write_text(text)
        cfg = load_config(path)

        async def made() -> dict[str, Device]:
            return Gateway(cfg).devices

        meter = asyncio.run(made())["meter"]
        return {payload["unit_of_measurement"]: payload.get("device_class")
                for _, payload in discovery_messages("plant", meter, "homeassistant", "x", cfg.mqtt.ha_version)
                if payload.get("unit_of_measurement") in ("kvarh", "kWh")}

    assert meter_classes(CONFIG) == {"kvarh": None, "kWh": "energy"}
    old = CONFIG.replace("mqtt: {host: 127.0.0.1}", "mqtt: {host: 127.0.0.1, ha_version: '2024.3'}")
    assert meter_classes(old) == {"kvarh": None, "kWh": "energy"}
    for release in ("2025.6", "2026.1"):
        new = CONFIG.replace("mqtt: {host: 127.0.0.1}", f"mqtt: {{host: 127.0.0.1, ha_version: '{release}'}}")
        assert meter_classes(new) == {"kvarh": "reactive_energy", "kWh": "energy"}
    before = CONFIG.replace("mqtt: {host: 127.0.0.1}", "mqtt: {host: 127.0.0.1, ha_version: '2025.5'}")
    assert meter_classes(before) == {"kvarh": None, "kWh": "energy"}
    bad = CONFIG.replace("mqtt: {host: 127.0.0.1}", "mqtt: {host: 127.0.0.1, ha_version: '24.3'}")
    with pytest.raises(CompileError, match="ha_version"):
        meter_classes(bad)


@pytest.mark.parametrize("unit", ["V", "r/min", "RPM", "VAr", "kVArh", "℃", "degC", "min", "h", "VAh", "Ω", "%/s"])
def test_discovery_and_the_home_assistant_export_read_one_unit_table(unit: str) -> None:
    """The gateway's discovery and the ``homeassistant`` export spell a unit and name its device class alike."""
    from dataclasses import replace

    from drivemap.backends.exporters.homeassistant import _unit_keys
    from drivemap.gateway.discovery import unit_info

    reg = replace(compile_map(ROOT / "maps" / "vfd1000.yaml").registers[0], unit=unit, scale=1.0, offset=0.0,
                  precision=None)
    for release in ((2024, 3), (2025, 6)):  # at the same Home Assistant release (their defaults differ)
        found = unit_info(reg, release)
        exported = _unit_keys(unit, release)
        assert found["unit_of_measurement"] == exported["unit_of_measurement"]
        assert found.get("device_class") == exported.get("device_class")
        assert found["state_class"] == exported.get("state_class", "measurement")
