"""The gateway configuration: its JSON Schema and checks, every error located (file:line:col), no traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.gateway.config import SCHEMA_PATH

ROOT = Path(__file__).resolve().parents[2]

GOOD = """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1}
buses:
  - name: line1
    tcp: 127.0.0.1:5020
    devices:
      - {name: pump1, model: vfd1000, unit: 1, poll: [{group: monitor, interval: 1}]}
"""

BAD = [
    ("mqtt: {host: 127.0.0.1}", "mqtt: {host: 127.0.0.1, qos: 3}", "3:30: error: mqtt.qos: 3 is not one of 0, 1, 2"),
    ("model: vfd1000", "model: vfd1001", "8:30: error: no map for model 'vfd1001'"),
    ("unit: 1,", "unit: 250,", "8:45: error: unit 250 is not a unit id of vfd1000"),
    ("group: monitor", "group: monitr", "8:63: error: vfd1000 has no group 'monitr'"),
    ("poll:", "publish: [nope], poll:", "8:58: error: vfd1000 has no register 'nope'"),
    ("    tcp: 127.0.0.1:5020\n", "    tcp: 127.0.0.1:5020\n    serial: {port: /dev/null}\n",
     "5:5: error: bus 'line1': give exactly one of serial, tcp and rtu_over_tcp (got tcp, serial)"),
    ("name: pump1", "name: gateway", "8:16: error: device name 'gateway' is reserved"),
    ("name: plant\n", "name: plant\nbogus: 1\n", "3:1: error: unknown key 'bogus' in (top level)"),
    ("mqtt: {host: 127.0.0.1}\n", "", "1:1: error: nothing to serve: give mqtt, opcua or both"),
    ("model: vfd1000", "map: missing.yaml", "8:28: error: no such map file"),
    ("mqtt: {host: 127.0.0.1}", "opcua: {endpoint: 'opc.tcp://127.0.0.1:4840/', security: [Basic256Sha256_Sign]}",
     "3:8: error: security policies that sign, and client certificates, need certificate and private_key"),
]


@pytest.mark.parametrize(("old", "new", "expected"), BAD, ids=[b[2].split("error: ")[1][:40] for b in BAD])
def test_bad_configs_are_located(tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str,
                                 expected: str) -> None:
    assert old in GOOD
    path = tmp_path / "gw.yaml"
    path.write_text(GOOD.replace(old, new, 1))
    assert main(["gateway", "--check", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:{expected}" in err, err
    assert "Traceback" not in err


def test_check_prints_the_plan(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "gw.yaml"
    path.write_text(GOOD)
    assert main(["gateway", "--check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "pump1: vfd1000 unit 1: 19 registers every 1 s in 1 requests" in out


def test_example_config_is_valid(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.helpers_gateway import free_port  # --check binds the endpoint: a free port, not 4840

    path = tmp_path / "plant.yaml"
    path.write_text((ROOT / "docs/examples/plant.yaml").read_text().replace(":4840/", f":{free_port()}/"))
    assert main(["gateway", "--check", str(path)]) == 0
    assert "3 devices" in capsys.readouterr().out


def test_schema_ships_like_the_map_schema() -> None:
    assert SCHEMA_PATH.resolve() == (ROOT / "schemas/gateway.schema.json").resolve()
    data = json.loads(SCHEMA_PATH.read_text())
    assert data["$schema"].endswith("2020-12/schema")
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert '"data/*.json"' in pyproject  # the wheel carries data/gateway.schema.json like data/drivemap.schema.json
