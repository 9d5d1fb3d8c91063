"""What `drivemap gateway --check` now refuses (located, exit 1, no traceback) and what it offers:
unique OPC UA user names, endpoints the server can listen on (form, host, port in use: the same error
as the run), serial ports that are serial devices, ``--broker`` and ``--example``."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.gateway.cli import EXAMPLE, example_text
from drivemap.gateway.config import load_config
from tests.helpers_gateway import free_port

ROOT = Path(__file__).resolve().parents[2]

GOOD = """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1}
opcua:
  endpoint: opc.tcp://127.0.0.1:PORT/drivemap/
  users:
    - {name: operator, password: a}
    - {name: viewer, password: b, write: false}
buses:
  - name: line1
    tcp: 127.0.0.1:5020
    devices:
      - {name: pump1, model: vfd1000, unit: 1}
"""


def check(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, *extra: str) -> tuple[int, str, str]:
    path = tmp_path / "gw.yaml"
    path.write_text(text)
    code = main(["gateway", "--check", *extra, str(path)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err.replace(f"{path}:", "")


@pytest.fixture
def good(tmp_path: Path) -> str:
    return GOOD.replace("PORT", str(free_port()))


def test_good_config_passes(tmp_path: Path, capsys: pytest.CaptureFixture[str], good: str) -> None:
    assert check(tmp_path, capsys, good)[0] == 0


@pytest.mark.parametrize(("old", "new", "where"), [
    ("{name: viewer, password: b, write: false}", "{name: operator, password: b, write: false}", "8:14"),
    ("    - {name: viewer, password: b, write: false}\n",
     "  trusted_certificates:\n    - {name: operator, certificate: gw.yaml}\n", "9:14"),
])
def test_user_names_are_unique(tmp_path: Path, capsys: pytest.CaptureFixture[str], good: str, old: str, new: str,
                               where: str) -> None:
    code, _, err = check(tmp_path, capsys, good.replace(old, new))
    assert code == 1 and f"{where}: error: user name 'operator' is used twice (first at line 7)" in err, err


@pytest.mark.parametrize(("endpoint", "message"), [
    ("opc.tcp://127.0.0.1:99999/drivemap/", "is not a valid URL"),
    ("opc.tcp://127.0.0.1/drivemap/", "names no port"),
    ("opc.tcp://:4840/", "names no host"),
    ("opc.tcp://no-such-host.invalid:4840/", "does not resolve"),
    ("opc.tcp://192.0.2.1:4840/drivemap/", "cannot listen on 192.0.2.1:4840"),  # bind only: not this host's
])
def test_invalid_endpoints_are_located(tmp_path: Path, capsys: pytest.CaptureFixture[str], good: str, endpoint: str,
                                       message: str) -> None:
    text = good.replace(good.split("endpoint: ")[1].split("\n")[0], endpoint)
    code, _, err = check(tmp_path, capsys, text)
    assert code == 1 and "5:13: error: endpoint" in err and message in err, err


def test_endpoint_port_in_use_check_and_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        text = GOOD.replace("PORT", str(port))
        code, _, err = check(tmp_path, capsys, text)
        assert code == 1 and f"5:13: error: endpoint 'opc.tcp://127.0.0.1:{port}/drivemap/': port {port} on " \
                             "127.0.0.1 is already in use" in err, err
        path = tmp_path / "gw.yaml"
        assert main(["gateway", str(path)]) == 1  # the run: the same located error, before anything starts
        err = capsys.readouterr().err
        assert "5:13: error: endpoint" in err and "already in use" in err and "Traceback" not in err


@pytest.mark.parametrize(("port", "what"), [("/dev/zero", "'mem' subsystem"), ("/etc/hostname", "a regular file"),
                                            ("/tmp", "a directory")])
def test_serial_port_that_is_not_a_serial_device(tmp_path: Path, capsys: pytest.CaptureFixture[str], port: str,
                                                 what: str) -> None:
    if not Path(port).exists():
        pytest.skip(f"{port} is not on this machine")
    text = GOOD.replace("    tcp: 127.0.0.1:5020\n", f"    serial: {{port: {port}}}\n").replace(
        "opcua:\n  endpoint: opc.tcp://127.0.0.1:PORT/drivemap/\n  users:\n    - {name: operator, password: a}\n"
        "    - {name: viewer, password: b, write: false}\n", "")
    code, _, err = check(tmp_path, capsys, text)
    assert code == 1 and f"error: serial port {port} is " in err and what in err and "not a serial device" in err, err


def test_broker_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str], good: str) -> None:
    code, out, _ = check(tmp_path, capsys, good, "--broker", "broker.example:1884")
    assert code == 0 and "mqtt broker.example:1884 prefix drivemap" in out
    code, out, _ = check(tmp_path, capsys, good, "--broker", "[::1]")
    assert code == 0 and "mqtt ::1:1883" in out
    code, _, err = check(tmp_path, capsys, good, "--broker", "host:99999")
    assert code == 1 and "--broker 'host:99999'" in err


def test_example_is_the_docs_example(capsys: pytest.CaptureFixture[str]) -> None:
    assert EXAMPLE.read_text() == (ROOT / "docs/examples/plant.yaml").read_text()
    assert main(["gateway", "--example"]) == 0
    assert capsys.readouterr().out == example_text()


def test_example_without_opcua_is_mqtt_only_and_valid(tmp_path: Path) -> None:
    text = example_text(opcua=False)
    assert "opcua:" not in text and "endpoint" not in text and "mqtt:" in text
    path = tmp_path / "plant.yaml"
    path.write_text(text)
    cfg = load_config(path)
    assert cfg.opcua is None and cfg.mqtt is not None and len(cfg.devices) == 3
    assert cfg.devices["pump1"].writable == ("communication_setting", "control_command")
    cfg = load_config(path, broker=("10.1.2.3", 1999))
    assert cfg.mqtt is not None and (cfg.mqtt.host, cfg.mqtt.port) == ("10.1.2.3", 1999)


def test_example_ships_in_the_wheel() -> None:
    assert EXAMPLE.parent.name == "data" and EXAMPLE.parent.parent.name == "drivemap"
    assert '"data/*.yaml"' in (ROOT / "pyproject.toml").read_text()  # the wheel carries data/plant.yaml


def test_limits_are_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str], good: str) -> None:
    limits = "  limits: {max_connections: 5, reserve: 5}\n"
    code, _, err = check(tmp_path, capsys, good.replace("  users:\n", limits + "  users:\n"))
    assert code == 1 and "error: reserve 5 leaves no connection for anyone else (max_connections 5)" in err, err
    code, _, err = check(tmp_path, capsys, good.replace("  users:\n", "  limits: {per_source: 0}\n  users:\n"))
    assert code == 1 and "per_source" in err, err
    path = tmp_path / "ok.yaml"
    path.write_text(good.replace("  users:\n", "  limits: {max_connections: 40, handshake_timeout: 2.5}\n  users:\n"))
    cfg = load_config(path)
    assert cfg.opcua is not None and (cfg.opcua.limits.max_connections, cfg.opcua.limits.handshake_timeout,
                                      cfg.opcua.limits.per_source) == (40, 2.5, 10)
