"""A real Home Assistant for the `tools` tests: configured in a temporary folder, run from its own
virtualenv (tests/toolenv.py, ``homeassistant-run``), onboarded through its own API for a token, read
through its websocket API (entity registry + states) and driven through its REST API.

Everything listens on 127.0.0.1 only (HA's ``http`` is bound there, on a free port); every process is
ended in ``stop()``, which the tests call from ``finally``. Also: :func:`preset`, which gives every
register of a simulator a distinct value the map allows, so a comparison cannot pass on zeros.
"""

from __future__ import annotations

import json
import math
import subprocess
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

from drivemap.runtime.sim.simulator import Simulator, SimulatorError
from tests.toolenv import Tool
from tests.waits import free_port

WS_DUMP = Path(__file__).with_name("ha_ws_dump.py")
CLIENT_ID = "http://127.0.0.1/"  # IndieAuth: a loopback URL is a valid client id
#: what HA must never log about the integrations under test
BAD_LOG = ("Ignoring invalid option", "out of range", "is duplicate", "not loaded", "Invalid config",
           "extra keys not allowed")


def _int_value(reg: Any, k: int) -> int:
    """A raw integer, distinct per ``k``, whose engineering value lies within the map's min/max."""
    raw = 1 + k % 97
    while raw in reg.not_available:
        raw += 1
    value = raw * reg.scale + reg.offset
    if reg.min is not None and value < reg.min and reg.scale > 0:
        raw = math.ceil((reg.min - reg.offset) / reg.scale - 1e-9) + k % 3
    if reg.max is not None and raw * reg.scale + reg.offset > reg.max and reg.scale > 0:
        raw = math.floor((reg.max - reg.offset) / reg.scale + 1e-9)
    return raw


#: presets that would make the simulated drive change its own readings while HA reads it (ev: a
#: communication timeout of a few ms trips its comm alarm between two polls, motor_state -> FAULT)
STEADY: dict[str, dict[str, float]] = {"ev": {"rs485_timeout": 0, "rs232_timeout": 0}}


def preset(sim: Simulator) -> list[str]:
    """Give every readable register element of every unit a distinct value the map allows (value
    sets and enums: one of their non-zero values; numbers: inside min/max; bools: true; text: a
    short word), then the :data:`STEADY` values. Page selectors and command registers are left
    alone. Returns the names not set."""
    spec = sim.spec
    selectors = {r.page.selector for r in spec.registers if r.page is not None}
    skipped: list[str] = []
    k = 0
    for reg in spec.registers:
        if reg.name in selectors or reg.command_value is not None or reg.access == "w" or reg.scale_register:
            skipped.append(reg.name)
            continue
        for index in range(reg.count):
            name = reg.element_name(index)
            k += 1
            try:
                _preset_one(sim, reg, name, k)
            except SimulatorError:
                skipped.append(name)
    for name, value in STEADY.get(spec.name, {}).items():
        sim.set(name, value)
    return skipped


def _preset_one(sim: Simulator, reg: Any, name: str, k: int) -> None:
    if reg.values:
        options = [v for v, _ in reg.values if v not in (0, "0", "")] or [v for v, _ in reg.values]
        sim.set(name, options[k % len(options)])
    elif reg.enum_values:
        options = [v for v in reg.enum_values if v != 0] or list(reg.enum_values)
        sim.set_raw(name, options[k % len(options)])
    elif reg.bits:  # flags: a varying non-empty subset; enumerated and wider fields: 0 (a value the maps list)
        flags = sum(b.mask for b in reg.bits if b.width == 1 and b.enum is None)
        sim.set_raw(name, (k * 37) & flags or flags)
    elif reg.table in ("coil", "discrete") or reg.type == "bool":
        sim.set(name, True)
    elif reg.type == "string":
        sim.set(name, f"DM{k}"[: 2 * reg.length])
    elif reg.type.startswith("f"):
        value = 10 + k * 0.25
        if reg.min is not None:
            value = max(value, reg.min)
        if reg.max is not None:
            value = min(value, reg.max)
        sim.set(name, value)
    else:
        sim.set_raw(name, _int_value(reg, k))


class HomeAssistant:
    """``hass -c FOLDER --skip-pip`` on 127.0.0.1:``port``, with ``packages/`` and config entries."""

    def __init__(self, tool: Tool, folder: Path) -> None:
        self.tool = tool
        self.folder = folder
        self.port = free_port()
        self.proc: subprocess.Popen[bytes] | None = None
        self.token: str | None = None
        (folder / "packages").mkdir(parents=True, exist_ok=True)
        (folder / ".storage").mkdir(exist_ok=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def configure(self, packages: dict[str, str], mqtt_port: int | None = None) -> None:
        (self.folder / "configuration.yaml").write_text(
            "homeassistant:\n  name: drivemap-test\n  latitude: 0\n  longitude: 0\n  elevation: 0\n"
            "  unit_system: metric\n  time_zone: UTC\n  packages: !include_dir_named packages\n"
            f"http:\n  server_host: 127.0.0.1\n  server_port: {self.port}\n"
            "api:\nconfig:\nlogger:\n  default: warning\n", encoding="utf-8")
        for name, text in packages.items():
            (self.folder / "packages" / f"{name}.yaml").write_text(text, encoding="utf-8")
        if mqtt_port is not None:
            self._mqtt_entry(mqtt_port)

    def _mqtt_entry(self, port: int) -> None:
        """MQTT is set up from a config entry in this HA (no YAML broker): the stored form of one."""
        entry = {"entry_id": "drivemapmqtttest0000000000000000", "version": 1, "minor_version": 1,
                 "domain": "mqtt", "title": "127.0.0.1", "options": {},
                 "data": {"broker": "127.0.0.1", "port": port, "discovery": True},
                 "pref_disable_new_entities": False, "pref_disable_polling": False, "source": "user",
                 "unique_id": None, "disabled_by": None}
        store = {"version": 1, "minor_version": 1, "key": "core.config_entries", "data": {"entries": [entry]}}
        (self.folder / ".storage" / "core.config_entries").write_text(json.dumps(store), encoding="utf-8")

    def start(self, timeout: float = 180.0) -> None:
        log = open(self.folder / "hass.out", "ab")  # noqa: SIM115 - closed with the process
        self.proc = subprocess.Popen([str(self.tool.exe("hass")), "-c", str(self.folder), "--skip-pip"],
                                     stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"hass exited {self.proc.returncode}:\n{self.log()[-4000:]}")
            try:
                self._request("GET", "/api/onboarding", auth=False)
                return
            except (OSError, urllib.error.URLError):
                time.sleep(1)
        raise RuntimeError(f"hass did not answer on {self.url} in {timeout} s:\n{self.log()[-4000:]}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self.proc = None

    def log(self) -> str:
        text = ""
        for name in ("hass.out", "home-assistant.log"):
            path = self.folder / name
            if path.is_file():
                text += path.read_text(encoding="utf-8", errors="replace")
        return text

    def bad_log_lines(self, words: tuple[str, ...] = ("modbus", "mqtt", "template")) -> list[str]:
        """ERROR/WARNING lines that name one of the integrations under test, or any line with a BAD_LOG text."""
        out = []
        for line in self.log().splitlines():
            low = line.lower()
            if any(b.lower() in low for b in BAD_LOG) or (
                    (" ERROR " in line or " WARNING " in line) and any(w in low for w in words)):
                out.append(line)
        return out

    def _request(self, method: str, path: str, body: Any = None, *, auth: bool = True, form: bool = False) -> Any:
        data = None
        headers: dict[str, str] = {}
        if body is not None:
            if form:
                data = urllib.parse.urlencode(body).encode()
                headers["Content-Type"] = "application/x-www-form-urlencoded"
            else:
                data = json.dumps(body).encode()
                headers["Content-Type"] = "application/json"
        if auth:
            headers["Authorization"] = f"Bearer {self.token}"
        request = urllib.request.Request(self.url + path, data=data, headers=headers, method=method)
        with urllib.request.urlopen(request, timeout=30) as response:
            return json.loads(response.read() or b"null")

    def onboard(self) -> str:
        """The supported way to a token on a fresh instance: the onboarding API creates the owner and
        returns an authorization code, which /auth/token exchanges for an access token."""
        user = {"client_id": CLIENT_ID, "name": "drivemap test", "username": "drivemap",
                "password": "drivemap-test-only", "language": "en"}
        code = self._request("POST", "/api/onboarding/users", user, auth=False)["auth_code"]
        token = self._request("POST", "/auth/token", {"grant_type": "authorization_code", "code": code,
                                                       "client_id": CLIENT_ID}, auth=False, form=True)
        self.token = str(token["access_token"])
        return self.token

    def entities(self) -> dict[str, dict[str, Any]]:
        """entity_id -> {unique_id, platform, state, attributes} from the websocket API (run by HA's python)."""
        done = subprocess.run([str(self.tool.exe("python")), str(WS_DUMP), f"ws://127.0.0.1:{self.port}/api/websocket",
                               str(self.token)], capture_output=True, text=True, timeout=60)
        if done.returncode != 0:
            raise RuntimeError(f"websocket dump failed: {done.stderr[-2000:]}")
        dump = json.loads(done.stdout)
        states = {s["entity_id"]: s for s in dump["states"]}
        out: dict[str, dict[str, Any]] = {}
        for entry in dump["registry"]:
            state = states.get(entry["entity_id"], {})
            out[entry["entity_id"]] = {"unique_id": entry.get("unique_id"), "platform": entry.get("platform"),
                                       "state": state.get("state"), "attributes": state.get("attributes", {})}
        return out

    def call(self, domain: str, service: str, data: dict[str, Any]) -> Any:
        return self._request("POST", f"/api/services/{domain}/{service}", data)

    def wait_for(self, check: Any, timeout: float, what: str) -> dict[str, dict[str, Any]]:
        """Poll entities() until ``check(entities)`` is true; the last entities either way."""
        deadline = time.monotonic() + timeout
        while True:
            found = self.entities()
            if check(found) or time.monotonic() > deadline:
                return found
            if self.proc is not None and self.proc.poll() is not None:
                raise RuntimeError(f"hass exited while waiting for {what}:\n{self.log()[-4000:]}")
            time.sleep(2)
