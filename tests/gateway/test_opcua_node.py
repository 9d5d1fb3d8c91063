"""drivemap's OPC UA server checked by node-opcua (from the npm registry), a client that is not the
asyncua the server is built on: browse Objects/<gateway>/<device>, read every variable and compare
it with ``drivemap read``; DataTypes follow the register types (u16 UInt16 ...), EngineeringUnits
carry UNECE codes; a write to a register outside ``writable`` is refused, one inside it arrives.
node-opcua is installed by the test into the tools cache (tests/toolenv.py); it FAILS if it cannot.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from drivemap.compiler import load_model
from drivemap.runtime.sim.serve import ThreadedSimServer
from tests.gateway.test_ha_live import read_all, simulator
from tests.ha_live import preset
from tests.toolenv import require_npm
from tests.waits import free_port, wait_port

pytestmark = pytest.mark.tools

PROBE = Path(__file__).resolve().parents[1] / "js" / "opcua_probe.js"
CONFIG = """gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc}/drivemap/
  namespace: urn:drivemap:plant
  anonymous: true
  anonymous_writes: true
buses:
  - name: line1
    tcp: 127.0.0.1:{line1}
    devices:
      - {{name: pump1, title: Pump 1, model: vfd1000, unit: 1, interval: 1, writable: [communication_setting]}}
  - name: line2
    tcp: 127.0.0.1:{line2}
    devices:
      - {{name: meter, title: Meter, model: sdm630, unit: 1, interval: 1}}
  - name: line3
    tcp: 127.0.0.1:{line3}
    devices:
      - {{name: conveyor, title: Conveyor, model: ev, unit: 2, interval: 1, writable: [rs485_timeout]}}
"""

#: written independently of drivemap's table: the UNECE Rec. 20 codes of the units these maps use
UNECE = {"V": "VLT", "A": "AMP", "Hz": "HTZ", "W": "WTT", "kW": "KWT", "kWh": "KWH", "Wh": "WHR", "VA": "D46",
         "kVA": "KVA", "var": "D44", "kvar": "KVR", "kVAh": "C79", "kvarh": "K3", "r/min": "M46", "%": "P1",
         "s": "SEC", "ms": "C26", "min": "MIN", "h": "HUR", "°C": "CEL", "°": "DD"}
INTEGER = {"u16": "UInt16", "s16": "Int16", "u32": "UInt32", "s32": "Int32", "u64": "UInt64", "s64": "Int64"}


def packed(code: str) -> int:
    return int.from_bytes(code.encode("ascii"), "big")


def expected_type(reg: Any) -> str:
    if reg.table in ("coil", "discrete") or reg.type == "bool":
        return "Boolean"
    if reg.type == "string":
        return "String"
    if reg.bits:
        return {1: "UInt16", 2: "UInt32", 4: "UInt64"}[reg.words]
    whole = float(reg.scale) == 1 and not reg.offset and reg.scale_register is None
    if reg.type in INTEGER and whole:
        return INTEGER[reg.type]
    if reg.type == "f32" and whole:
        return "Float"
    return "Double" if not float(reg.scale).is_integer() or reg.type.startswith("f") else "Int64"


def _same(shown: Any, read: dict[str, Any], reg: Any) -> bool:
    value = read["value"]
    if isinstance(value, (str, dict, list)) and reg.type != "string":
        return str(shown) == str(read["raw"])  # enums and bit fields: the raw number
    if isinstance(value, bool) or reg.type == "string":
        return bool(shown == value)
    if value is None:
        return shown is None
    return abs(float(shown) - float(value)) <= 1e-6 * max(1.0, abs(float(value)))


def _probe(tool_folder: Path, endpoint: str, writes: list[dict[str, Any]]) -> dict[str, Any]:
    env = dict(os.environ, NODE_PATH=str(tool_folder / "node_modules"))  # require() from the tools cache
    done = subprocess.run(["node", str(PROBE), endpoint, "plant", json.dumps(writes)], cwd=tool_folder, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, f"node-opcua probe failed:\n{done.stderr[-3000:]}"
    line = next(x for x in done.stdout.splitlines() if x.startswith("@@drivemap-report@@"))  # node-opcua logs too
    report: dict[str, Any] = json.loads(line.removeprefix("@@drivemap-report@@"))
    return report


def test_node_opcua_reads_what_drivemap_reads(tmp_path: Path) -> None:
    tool = require_npm("node-opcua")
    sims = {"line1": simulator("vfd1000"), "line2": simulator("sdm630", [1])}
    ev = simulator("ev", [2])
    for sim in (*sims.values(), ev):
        preset(sim)
    ports = {"line1": free_port(), "line2": free_port(), "line3": free_port(), "opc": free_port()}
    (tmp_path / "plant.yaml").write_text(CONFIG.format(**ports), encoding="utf-8")
    servers = [ThreadedSimServer(sims["line1"], tcp=("127.0.0.1", ports["line1"])),
               ThreadedSimServer(sims["line2"], tcp=("127.0.0.1", ports["line2"])),
               ThreadedSimServer(ev, tcp=("127.0.0.1", ports["line3"]))]
    gateway: subprocess.Popen[bytes] | None = None
    started = time.monotonic()
    try:
        for server in servers:
            server.start()
        with open(tmp_path / "gateway.log", "wb") as log:
            gateway = subprocess.Popen([sys.executable, "-m", "drivemap", "gateway", str(tmp_path / "plant.yaml")],
                                       stdout=log, stderr=subprocess.STDOUT)
        wait_port(ports["opc"], 60, gateway)
        time.sleep(4)  # a few polls: every variable has its first value
        endpoint = f"opc.tcp://127.0.0.1:{ports['opc']}/drivemap/"
        first = _probe(tool.folder, endpoint, [])
        reads = {"pump1": read_all("vfd1000", ports["line1"]), "meter": read_all("sdm630", ports["line2"]),
                 "conveyor": read_all("ev", ports["line3"], unit=2)}
        writes = [{"node": _node(first, "conveyor", "rs485_error_count"), "type": "UInt16", "value": 5},
                  {"node": _node(first, "conveyor", "rs485_timeout"), "type": "UInt16", "value": 321},
                  {"node": _node(first, "pump1", "pid_setting"), "type": "Double", "value": 5.0}]
        second = _probe(tool.folder, endpoint, writes)
        deadline = time.monotonic() + 10
        while ev.get("rs485_timeout", unit=2) != 321 and time.monotonic() < deadline:
            time.sleep(0.2)
        arrived = ev.get("rs485_timeout", unit=2)
    finally:
        if gateway is not None:
            gateway.terminate()
            try:
                gateway.wait(15)
            except subprocess.TimeoutExpired:
                gateway.kill()
                gateway.wait(5)
        for server in servers:
            server.stop()
    log = (tmp_path / "gateway.log").read_text(errors="replace")
    statuses = [w["status"] for w in second["writes"]]
    assert statuses == ["BadNotWritable", "Good", "BadNotWritable"], (statuses, log[-2000:])
    assert arrived == 321
    counts = {}
    for device, model in (("pump1", "vfd1000"), ("meter", "sdm630"), ("conveyor", "ev")):
        counts[device] = _check_device(first["devices"][device], reads[device], load_model(model))
    print(f"\nnode-opcua: compared {counts} ({time.monotonic() - started:.0f} s)")


def _node(report: dict[str, Any], device: str, register: str) -> str:
    return next(v["node"] for v in report["devices"][device] if v["name"] == register)


def _check_device(variables: list[dict[str, Any]], read: dict[str, Any], model: Any) -> tuple[int, int]:
    """Every register variable: value equals drivemap's read, DataType follows the type, units UNECE."""
    by_name = {e["name"]: e for e in read["registers"]}
    compared, bad = 0, []
    registers = {r.name: r for r in model.registers}
    for var in variables:
        reg = registers.get(var["name"])
        if reg is None:
            continue  # Online and the like
        if var["dataType"] != expected_type(reg):
            bad.append(f"{reg.name} ({reg.type}, scale {reg.scale}): DataType {var['dataType']}, "
                       f"expected {expected_type(reg)}")
        if reg.unit in UNECE and (var["eu"] or {}).get("unitId") != packed(UNECE[reg.unit]):
            bad.append(f"{reg.name}: EngineeringUnits {var['eu']} for {reg.unit}, expected {UNECE[reg.unit]}")
        if not reg.readable:
            if var["status"] != "BadNotReadable":
                bad.append(f"{reg.name} is write-only but reads {var['status']} {var['value']!r}")
            continue
        if var["status"] != "Good":
            bad.append(f"{reg.name}: {var['status']}")
            continue
        values = var["value"] if reg.count > 1 else [var["value"]]
        names = [reg.element_name(i) for i in range(reg.count)]
        for name, shown in zip(names, values, strict=True):
            if name not in by_name:
                continue  # on a page drivemap did not read now
            compared += 1
            if not _same(shown, by_name[name], reg):
                bad.append(f"{name}: node-opcua {shown!r}, drivemap {by_name[name]['value']!r}")
    assert not bad, "\n".join(bad)
    assert compared >= 0.9 * len(by_name), (compared, len(by_name))
    return compared, len(by_name)
