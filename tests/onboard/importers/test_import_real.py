"""`drivemap import` of Home Assistant and ESPHome files written the way users write them (fixtures of our
own in tests/fixtures/import_real): packages, !include, !secret, substitutions, a switch and a sensor on
one register, bitmask entities on one register, template label maps. Every entity of the source is
accounted for: a register, a bit field, an enum, or a line of the review that names it."""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.onboard.importers.mapdoc import safe

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "import_real"


class _Loader(yaml.SafeLoader):
    pass


_Loader.add_multi_constructor("!", lambda loader, suffix, node: f"!{suffix}")


def source(path: Path) -> Any:
    return yaml.load(path.read_text(encoding="utf-8"), Loader=_Loader)  # noqa: S506 - a SafeLoader subclass


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_home_assistant_package_every_entity_accounted_for(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = FIXTURES / "homeassistant"
    target = tmp_path / "inverter.yaml"
    code, out, err = run(capsys, "import", "homeassistant", str(folder / "configuration.yaml"), "-o", str(target))
    assert code == 0, err  # secrets.yaml there is not YAML: it was never opened
    model = compile_map(target)  # with the python and docs exporters' checks, as build runs them
    names = {r.name for r in model.registers}
    sensors = source(folder / "modbus" / "inverter_sensors.yaml")
    package = source(folder / "packages" / "inverter.yaml")
    assert len(sensors) == 32 and names == {safe(s["name"]) for s in sensors}
    for switch in package["modbus"][0]["switches"]:
        assert f"switch {switch['name']!r} writes the register of {safe(switch['name'] + ' state')}" in out
    power = model.register("inverter_power_state")
    assert power.access == "rw" and list(power.values or ()) == [(1, "on"), (0, "off")]
    templates = [*package["template"][0]["sensor"], *package["template"][1]["binary_sensor"]]
    templates += [{"name": t["friendly_name"]} for t in package["sensor"][0]["sensors"].values()]
    assert len(templates) == 38
    for entry in templates:
        assert re.search(rf"template (binary_)?sensor {re.escape(repr(entry['name']))}", out), entry["name"]
    state = model.enum(model.register("inverter_state_code").enum or "")
    assert [(m.value, m.label) for m in state.members] == [(0, "Standby"), (1, "Self-test"), (2, "Normal"),
                                                           (3, "Alarm"), (4, "Fault")]
    models = model.enum(model.register("inverter_model_code").enum or "")
    assert [(m.value, m.label) for m in models.members] == [(0x301, "SUN-5K-SG04"), (0x302, "SUN-6K-SG04"),
                                                            (0x303, "SUN-8K-SG04"), (0x305, "SUN-12K-SG04")]
    for register, labels in (("battery_status_code", 4), ("grid_status_code", 3), ("inverter_fault_code", 5),
                             ("work_mode_code", 3)):
        assert len(model.enum(model.register(register).enum or "").members) == labels
    assert model.register("inverter_fault_bits").review == ("bits",)  # decoded only in templates
    assert model.register("grid_power").review == () and model.register("grid_power").enum is None
    assert "inverter.yaml:6: !secret inverter_host (named, not read)" in out
    assert "inverter.yaml:4: hub delay: 2 not imported" in out
    assert "'Energy cost today' over energy_today (the user's own logic" in out
    assert model.register("pv1_voltage").scale == 0.1 and model.register("energy_total").type == "u32"


def test_esphome_packages_substitutions_and_bitmasks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = FIXTURES / "esphome"
    target = tmp_path / "heatpump.yaml"
    code, out, err = run(capsys, "import", "esphome", str(folder / "heatpump.yaml"), "-o", str(target))
    assert code == 0, err
    model = compile_map(target)
    regs = {r.name: r for r in model.registers}
    # the package included with vars (base 100, 'Water') and the device's own entities
    assert (regs["water_inlet_temperature"].address, regs["water_outlet_temperature"].address) == (100, 101)
    assert regs["water_inlet_temperature"].scale == 0.1 and regs["heat_pump_compressor_frequency"].table == "input"
    assert regs["heat_pump_target_water_temperature"].access == "rw"
    status = regs["heat_pump_status"]
    assert status.address == 0x20 and [(b.name, b.offset, b.width) for b in status.bits] == [
        ("COMPRESSOR_RUNNING", 0, 1), ("DEFROST_ACTIVE", 1, 1), ("ENABLE", 3, 1), ("OPERATING_MODE", 4, 3)]
    assert status.access == "rw" and status.review == ("access",)  # the switch writes bit 3: the rest is open
    assert "switch 'Heat pump enable' writes bits of heat_pump_status" in out
    alarm = regs["heat_pump_alarm"]  # a lone bitmask: 7 is a 3-bit field, not the whole word
    assert alarm.table == "input" and [(b.offset, b.width) for b in alarm.bits] == [(0, 3)]
    assert len(regs) == 6
    assert "sensor 'Heat pump WiFi signal' (platform wifi_signal: not a Modbus register)" in out
    assert "remote package 'remote' (github://example/esphome-configs/heatpump-extra.yaml@main): not downloaded" in out
    assert "export again with --unit 3" in out  # the substitution '3' reached the controller's address
    assert "heatpump.yaml:17: !secret wifi_ssid (named, not read)" in out
    accounted = sum(len([e for e in source(p).get(k) or [] if e.get("platform") == "modbus_controller"])
                    for p in (folder / "heatpump.yaml", folder / "common" / "temperatures.yaml")
                    for k in ("sensor", "binary_sensor", "number", "switch"))
    assert accounted == 9 == sum(len(r.bits) or 1 for r in model.registers)  # an entity: a register or a bit field


def _case(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text, encoding="utf-8")
    return tmp_path / next(iter(files))


ES_HEAD = "esphome:\n  name: box\nmodbus_controller:\n  - address: 1\n"


@pytest.mark.parametrize(("fmt", "files", "expected"), [
    ("homeassistant", {"top/configuration.yaml": "modbus: !include ../outside.yaml\n", "outside.yaml": "[]\n"},
     r"configuration.yaml:1:9: error: !include \.\./outside\.yaml: outside .* copy the file into that folder"),
    ("homeassistant", {"configuration.yaml": "modbus: !include hubs.yaml\n", "hubs.yaml": "- !include configuration.yaml\n"},
     r"hubs.yaml:1:3: error: !include configuration.yaml: an include cycle"),
    ("homeassistant", {"configuration.yaml": "modbus: !include hubs.yaml\n",
                       "hubs.yaml": "- name: hub\n  type: tcp\n  sensors:\n    - name: a\n      address: x1\n"},
     r"hubs.yaml:4:7: error: a: address 'x1' is not an integer"),
    ("homeassistant", {"configuration.yaml": "modbus:\n  - name: hub\n    type: tcp\n    sensors:\n"
                                             "      - name: power\n        address: 10\n        data_type: int32\n"
                                             "      - name: power low\n        address: 11\n"},
     r"configuration.yaml:8:9: error: 'power low' reads holding address 11, which 'power' \(configuration.yaml:5\) "
     r"reads too: one register, one entity"),
    ("esphome", {"box.yaml": ES_HEAD + "sensor:\n  - platform: modbus_controller\n    name: a\n"
                                       "    register_type: holding\n    address: 1\n"
                                       "  - platform: modbus_controller\n    name: b\n"
                                       "    register_type: holding\n    address: 1\n"},
     r"box.yaml:10:5: error: 'b' reads holding address 1, which 'a' \(box.yaml:6\) reads too: .* with bitmask"),
    ("esphome", {"box.yaml": ES_HEAD + "sensor:\n  - platform: modbus_controller\n    name: odd\n"
                                       "    register_type: holding\n    address: 1\n    bitmask: 5\n"},
     r"box.yaml:6:5: error: odd: bitmask 0x5 is not one run of bits: split it into one entity per run"),
    ("esphome", {"box.yaml": ES_HEAD + "sensor:\n  - platform: modbus_controller\n    name: a\n"
                                       "    register_type: holding\n    address: 1\n    bitmask: 3\n"
                                       "  - platform: modbus_controller\n    name: b\n"
                                       "    register_type: holding\n    address: 1\n    bitmask: 2\n"},
     r"box.yaml:11:5: error: b: bitmask 0x2 reads bits another entity at holding address 1 reads"),
    ("esphome", {"box.yaml": ES_HEAD + "packages:\n  p: !include p.yaml\n",
                 "p.yaml": "sensor:\n  - platform: modbus_controller\n    name: a\n    register_type: holding\n"
                           "    address: 1\n    address: 2\n"},
     r"p.yaml:6:5: error: the key 'address' is given twice in this mapping \(first on line 5\): keep one"),
])
def test_errors_name_the_file_and_line_and_what_to_change(fmt: str, files: dict[str, str], expected: str,
                                                          tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    top = _case(tmp_path, files)
    code, out, err = run(capsys, "import", fmt, str(top), "-o", str(tmp_path / "dev.yaml"))
    assert code == 1 and re.search(expected, err), err
    assert "Traceback" not in err and not (tmp_path / "dev.yaml").exists()


def test_secrets_are_named_never_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    shutil.copytree(FIXTURES / "homeassistant", tmp_path / "ha")
    (tmp_path / "ha" / "secrets.yaml").chmod(0)  # unreadable as well as not YAML
    code, out, err = run(capsys, "import", "homeassistant", str(tmp_path / "ha" / "configuration.yaml"),
                         "-o", str(tmp_path / "inverter.yaml"))
    assert code == 0, err
    assert "!secret time_zone (named, not read)" in out and "192.0.2.10" not in out + (tmp_path / "inverter.yaml").read_text()


def test_label_map_reading_is_bounded_on_hostile_templates() -> None:
    """Unbalanced braces, thousands of branches: linear work (was: each brace scanned to the end)."""
    from drivemap.onboard.importers.ha_labels import label_map, open_fields

    for template in ("{{ states('sensor.a') }}" + "{a" * 9900, "{{ states('sensor.a') }}" + "{% elif v == 1 %}a" * 1000,
                     "{{ states('sensor.a') }}" + "{ " * 9000 + "}" * 9000, "{0: 'a'}" * 50_000):
        start = time.perf_counter()
        assert label_map(template) is None
        open_fields(template)
        assert time.perf_counter() - start < 5  # measured: 0.02 s; the quadratic scan took 86 s on the first
    assert label_map("{% set c = states('sensor.x') | int %}{% set m = {0: 'A', 1: 'B'} %}"
                     "{{ m[c] if c in m else 'Unknown' }}") == ("sensor.x", {0: "A", 1: "B"})
    assert label_map("{{ states('sensor.x') | int * 10 }}") is None
    assert label_map("{{ {0: 'a', 1: 'b'}[states('sensor.x') | int] * 2 }}") is None


def test_includes_are_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A file included over and over (no cycle, a fan-out) stops at the bound, located."""
    (tmp_path / "leaf.yaml").write_text("[]\n", encoding="utf-8")
    (tmp_path / "mid.yaml").write_text("- !include leaf.yaml\n" * 40, encoding="utf-8")
    (tmp_path / "configuration.yaml").write_text(
        "modbus:\n" + "".join("  - !include mid.yaml\n" for _ in range(40)), encoding="utf-8")
    code, _, err = run(capsys, "import", "homeassistant", str(tmp_path / "configuration.yaml"), "-o",
                       str(tmp_path / "x.yaml"))
    assert code == 1 and "error: more than 500 included files: not a device configuration" in err
