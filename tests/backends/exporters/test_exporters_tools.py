"""The exports checked by the tools that consume them (marker ``tools``: ``pytest -m tools``).

Each tool runs from its own virtualenv (tests/toolenv.py), so its pins never meet drivemap's:
ESPHome's ``esphome config`` on the newest release (Python 3.12) and on the oldest the exporter
supports (``--esphome-version 2026.6``), Home Assistant's ``hass --script check_config`` (2024.3, the last
release for Python 3.11; it exits 0 even on "Invalid config", so its output is read), and the
``pymodbus.simulator`` command serving the pymodbus-sim export to the generated client.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
from pathlib import Path

import pytest

from drivemap.compiler import load_model
from tests.exporter_helpers import MAPS, compile_hostile, load, parse, render
from tests.toolenv import TOOLS, require

pytestmark = pytest.mark.tools

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


#: (tool, --esphome-version): the newest release and the oldest one the exporter supports
ESPHOME_RELEASES = [("esphome", None), ("esphome-oldest", "2026.6")]


def _esphome_config(folder: Path, name: str, text: str, tool_name: str = "esphome") -> str:
    tool = require(tool_name)
    (folder / name).write_text(text, encoding="utf-8")
    (folder / "secrets.yaml").write_text('wifi_ssid: "drivemap-test"\nwifi_password: "not-a-secret"\n', encoding="utf-8")
    done = subprocess.run([str(tool.exe("esphome")), "config", name], cwd=folder, capture_output=True, text=True,
                          timeout=300, env=dict(os.environ, ESPHOME_NOGITEXTENSION="1"))
    output = done.stdout + done.stderr
    assert done.returncode == 0 and "Failed config" not in output, output[-4000:]
    # nothing the release ignores or migrates: every key written does what the export means
    warnings = [line for line in output.splitlines() if line.startswith("WARNING") and "modbus" in line.lower()]
    assert not warnings, warnings
    return output


@pytest.mark.parametrize(("tool", "version"), ESPHOME_RELEASES)
@pytest.mark.parametrize("model", [*MAPS, "allkinds"])
def test_esphome_config_accepts_the_export(model: str, tool: str, version: str | None, tmp_path: Path) -> None:
    text = render(load(model), "esphome", **({"esphome_version": version} if version else {}))
    output = _esphome_config(tmp_path, f"{model}.yaml", text, tool)
    assert f"INFO ESPHome {TOOLS[tool].split('==')[1]}" in output  # the release the tier means to run
    for entity in parse("esphome", text).get("sensor", [])[:5]:
        if "name" in entity:
            assert entity["name"] in output


@pytest.mark.parametrize(("tool", "version"), ESPHOME_RELEASES)
def test_esphome_config_accepts_hostile_text(tool: str, version: str | None, tmp_path: Path) -> None:
    (tmp_path / "map").mkdir()
    text = render(compile_hostile(tmp_path / "map"), "esphome", **({"esphome_version": version} if version else {}))
    output = _esphome_config(tmp_path, "ev.yaml", text, tool)
    assert "${unit}" in output and "$name" in output  # kept as written: no substitution ran on map text


def _check_config(folder: Path, package: str) -> str:
    tool = require("homeassistant")
    (folder / "packages").mkdir(parents=True, exist_ok=True)
    (folder / "configuration.yaml").write_text("homeassistant:\n  packages: !include_dir_named packages\n",
                                               encoding="utf-8")
    (folder / "packages" / "device.yaml").write_text(package, encoding="utf-8")
    done = subprocess.run([str(tool.exe("hass")), "--script", "check_config", "-c", str(folder), "--info", "all"],
                          capture_output=True, text=True, timeout=900)
    output = _ANSI.sub("", done.stdout + done.stderr)
    for bad in ("Invalid config", "Incorrect config", "Failed config", "is duplicate", "not loaded"):
        assert bad not in output, output[-6000:]
    logged = [line for line in output.splitlines()
              if line.startswith(("ERROR:", "CRITICAL:", "WARNING:homeassistant.components"))]
    assert not logged, logged
    assert done.returncode == 0 and "Successful config (all)" in output, output[-6000:]
    return output


@pytest.mark.parametrize("model", [*MAPS, "allkinds"])
def test_home_assistant_check_config_accepts_the_export(model: str, tmp_path: Path) -> None:
    text = render(load(model), "homeassistant", ha_version="2024.3")
    output = _check_config(tmp_path, text)
    doc = parse("homeassistant", text)
    hub = doc["modbus"][0]
    names = [e["name"] for e in hub.get("sensors", []) + hub.get("switches", []) + hub.get("binary_sensors", [])]
    for name in names:  # every entity reached the validated modbus configuration
        assert f"name: {name} " in output or f"name: {name}\n" in output, name
    for block in doc.get("template", []):
        for entity in block.get("sensor", []) + block.get("binary_sensor", []):
            assert entity["unique_id"] in output


def test_home_assistant_check_config_accepts_hostile_text(tmp_path: Path) -> None:
    (tmp_path / "map").mkdir()
    _check_config(tmp_path / "ha", render(compile_hostile(tmp_path / "map"), "homeassistant", ha_version="2024.3"))


def test_pymodbus_simulator_serves_the_export(tmp_path: Path) -> None:
    """``pymodbus.simulator --json_file`` (pymodbus's own command) serves the export; the generated
    client reads the same values from it as from drivemap's simulator of the map."""
    from tests.sim_helpers import export, free_port, read_back
    from tests.waits import wait_port as _wait_port

    tool = require("pymodbus-simulator")
    for model in MAPS:
        m = load_model(model)
        port, http = free_port(), free_port()
        config = tmp_path / f"{model}.json"
        import json

        config.write_text(json.dumps(export(m, port)), encoding="utf-8")
        log = tmp_path / f"{model}.log"
        with open(log, "w") as out:
            proc = subprocess.Popen([str(tool.exe("pymodbus.simulator")), "--json_file", str(config),
                                     "--modbus_server", model, "--modbus_device", model, "--http_host", "127.0.0.1",
                                     "--http_port", str(http), "--log_file", str(tmp_path / "server.log")],
                                    stdout=out, stderr=subprocess.STDOUT, cwd=tmp_path, start_new_session=True)
        try:
            _wait_port(port, 60)
            got, expected = read_back(m, port, 1)
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(10)
        assert got == expected, (model, log.read_text(encoding="utf-8")[-3000:])
