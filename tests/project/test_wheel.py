"""drivemap as users get it: a wheel installed in a fresh virtualenv, run in folders outside this checkout.

The wheel is built from this checkout, installed into a new virtualenv, and every verb runs in an
empty folder elsewhere: ``new``, ``validate``, ``build``, ``check``, the generated client imported
and talking to ``drivemap simulate``; a project configured in ``pyproject.toml`` built from a
sub-folder; the seed maps and the schema found inside the package. Neither the installed package nor
this checkout may change while that happens.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from tests.waits import free_port, wait_port

ROOT = Path(__file__).resolve().parents[2]
SEED_MAPS = sorted((ROOT / "maps").glob("*.yaml"))


def tree_digest(root: Path) -> dict[str, str]:
    """relative path -> sha256 of every file below ``root`` (Python's byte-code caches left out)."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and "__pycache__" not in p.parts}


def checkout_digest() -> dict[str, str]:
    digest: dict[str, str] = {}
    for folder in ("generator", "generated", "maps", "schemas"):
        digest.update({f"{folder}/{k}": v for k, v in tree_digest(ROOT / folder).items()})
    return digest


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    dist = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(ROOT)],
                   check=True, capture_output=True, text=True, timeout=600)
    (found,) = dist.glob("drivemap-*.whl")
    return found


@pytest.fixture(scope="module")
def env(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtualenv with only the wheel (and its dependencies) installed; returns its bin/."""
    where = tmp_path_factory.mktemp("venv") / "v"
    venv.EnvBuilder(with_pip=True).create(where)
    bindir = where / "bin"
    subprocess.run([str(bindir / "python"), "-m", "pip", "install", "-q", str(wheel)], check=True,
                   capture_output=True, text=True, timeout=900)
    return bindir


def site_package(bindir: Path) -> Path:
    out = subprocess.run([str(bindir / "python"), "-c", "import drivemap, os; print(os.path.dirname(drivemap.__file__))"],
                         check=True, capture_output=True, text=True, cwd="/").stdout.strip()
    return Path(out)


def drivemap(bindir: Path, cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    clean["PATH"] = f"{bindir}{os.pathsep}{clean.get('PATH', '')}"
    return subprocess.run([str(bindir / "drivemap"), *argv], cwd=cwd, env=clean, capture_output=True, text=True,
                          timeout=300)


def ok(bindir: Path, cwd: Path, *argv: str) -> str:
    proc = drivemap(bindir, cwd, *argv)
    assert proc.returncode == 0, f"drivemap {' '.join(argv)}:\n{proc.stdout}\n{proc.stderr}"
    assert "Traceback" not in proc.stderr
    return proc.stdout


def test_the_wheel_carries_the_package_schema_and_seed_maps_only(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/", 1)[0] for n in names if not n.split("/", 1)[0].endswith((".dist-info", ".data"))}
    assert tops == {"drivemap", "drivemap_models"}
    with zipfile.ZipFile(wheel) as z:
        for schema in sorted((ROOT / "schemas").glob("*.schema.json")):
            assert z.read(f"drivemap/data/{schema.name}") == schema.read_bytes()
        for seed in SEED_MAPS:
            assert z.read(f"drivemap/data/maps/{seed.name}") == seed.read_bytes()
        assert "drivemap/backends/templates/client.py.jinja" in names
        assert "drivemap_models/ev/client.py" in names and "drivemap_models/py.typed" in names
        entry_points = z.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    assert "drivemap.backends.exporters" in entry_points and "drivemap.runtime.sim.behaviours" in entry_points


def test_a_new_project_end_to_end_from_the_wheel(env: Path, tmp_path: Path) -> None:
    package_before = tree_digest(site_package(env))
    checkout_before = checkout_digest()
    work = tmp_path / "acme-project"
    work.mkdir()
    ok(env, work, "new", "acme")
    assert "maps/acme.yaml: ok" in ok(env, work, "validate")
    ok(env, work, "build")
    assert "up to date" in ok(env, work, "check")
    port = free_port()
    server = subprocess.Popen([str(env / "drivemap"), "simulate", "acme", "--tcp", f"127.0.0.1:{port}"], cwd=work,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(port)
        script = (
            "import json\n"
            "from generated.acme import Client\n"
            f"with Client.tcp('127.0.0.1', port={port}, unit=1) as drive:\n"
            "    drive.frequency_command.write(12.5)\n"
            "    print(json.dumps({'frequency_command': drive.frequency_command.read()}))\n"
        )
        proc = subprocess.run([str(env / "python"), "-c", script], cwd=work, capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
        assert json.loads(proc.stdout) == {"frequency_command": 12.5}
    finally:
        server.terminate()
        server.wait(timeout=10)
    assert tree_digest(site_package(env)) == package_before
    assert checkout_digest() == checkout_before


def test_a_configured_project_from_a_subfolder(env: Path, tmp_path: Path) -> None:
    work = tmp_path / "plant"
    work.mkdir()
    (work / "pyproject.toml").write_text(
        '[project]\nname = "plant"\n\n[tool.drivemap]\nmaps = "devices"\nout = "src/plantdrives"\n', "utf-8")
    ok(env, work, "new", "acme")
    sub = work / "devices" / "notes"
    sub.mkdir()
    ok(env, sub, "build")
    assert (work / "src" / "plantdrives" / "acme" / "client.py").is_file()
    assert "up to date" in ok(env, sub, "check")
    proc = subprocess.run([str(env / "python"), "-c", "import plantdrives.acme as m; print(m.SPEC.name)"],
                          cwd=work / "src", capture_output=True, text=True, timeout=60)
    assert proc.stdout.strip() == "acme", proc.stderr


def test_seed_maps_schema_and_exports_work_from_an_empty_folder(env: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    data = json.loads(ok(env, empty, "export", "ev"))
    assert data["model"] == "ev"
    assert "edx: frames 18" in ok(env, empty, "examples", "edx")
    schema = Path(ok(env, empty, "schema").strip())
    assert schema.is_relative_to(site_package(env))
    assert schema.read_bytes() == (ROOT / "schemas" / "drivemap.schema.json").read_bytes()
    assert "json" in ok(env, empty, "export", "--list")
    proc = subprocess.run([str(env / "python"), "-c", "import drivemap_models.ev as m; print(m.Client.__name__)"],
                          cwd=empty, capture_output=True, text=True, timeout=60)
    assert proc.stdout.strip() == "Client", proc.stderr
    for name in ("generator", "generated"):
        probe = subprocess.run([str(env / "python"), "-c", f"import {name}"], cwd=empty, capture_output=True,
                               text=True, timeout=60)
        assert probe.returncode != 0, f"a top-level module {name!r} is installed"
    assert sorted(p.name for p in empty.iterdir()) == []


def _wait_for(port: int, timeout: float = 20.0) -> None:
    wait_port(port, timeout)


GATEWAY = """\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1, port: {broker}}}
buses:
  - name: line1
    tcp: 127.0.0.1:{sim}
    devices:
      - {{name: conveyor, model: ev, unit: 1, interval: 0.2, publish: [motor_speed, alarm_no]}}
"""


def test_the_gateway_runs_from_the_wheel_in_a_foreign_folder(env: Path, tmp_path: Path) -> None:
    """``drivemap gateway --check`` and a short real run (a broker, ``drivemap simulate``, an MQTT
    subscriber) from the installed wheel, in a folder outside the checkout; without the opcua extra an
    OPC UA configuration is a located error."""
    import asyncio

    import aiomqtt

    from tests.helpers_gateway import Broker

    package_before, checkout_before = tree_digest(site_package(env)), checkout_digest()
    work = tmp_path / "plant"
    work.mkdir()
    broker, sim_port = Broker(tmp_path).start(), free_port()
    (work / "gw.yaml").write_text(GATEWAY.format(broker=broker.port, sim=sim_port))
    assert "conveyor: ev unit 1: 2 registers every 0.2 s in 1 requests" in ok(env, work, "gateway", "--check", "gw.yaml")
    buses = GATEWAY.format(broker=broker.port, sim=sim_port).split("buses:\n", 1)[1]
    (work / "opc.yaml").write_text("gateway: 1\nname: plant\nopcua: {endpoint: 'opc.tcp://127.0.0.1:4840/'}\n"
                                   "buses:\n" + buses)
    probe = subprocess.run([str(env / "python"), "-c", "import asyncua"], cwd=work, capture_output=True, timeout=60)
    assert probe.returncode != 0, "the wheel alone (no opcua extra) brought asyncua"
    proc = drivemap(env, work, "gateway", "--check", "opc.yaml")
    assert proc.returncode == 1 and "opc.yaml:1:1: error: opcua needs the optional extra" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    sim = subprocess.Popen([str(env / "drivemap"), "simulate", "ev", "--tcp", f"127.0.0.1:{sim_port}"], cwd=work,
                           env=clean, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    gateway = subprocess.Popen([str(env / "drivemap"), "gateway", "gw.yaml"], cwd=work, env=clean, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)

    async def seen() -> dict[str, str]:
        got: dict[str, str] = {}
        async with aiomqtt.Client("127.0.0.1", broker.port, identifier="wheel-test") as client:
            await client.subscribe("drivemap/#")
            async with asyncio.timeout(60):
                async for m in client.messages:
                    got[m.topic.value] = bytes(m.payload).decode() if isinstance(m.payload, bytes) else str(m.payload)
                    if got.get("drivemap/conveyor/availability") == "online" and "drivemap/conveyor/motor_speed" in got:
                        return got
        return got

    try:
        _wait_for(sim_port)
        got = asyncio.run(seen())
        assert got["drivemap/conveyor/motor_speed"].isdigit(), got
        assert got["drivemap/gateway/plant/availability"] == "online"
    finally:
        gateway.terminate()
        out, err = gateway.communicate(timeout=30)
        sim.terminate()
        sim.wait(10)
        broker.stop()
    assert gateway.returncode == 0 and "gateway plant stopped" in out, err
    assert "Traceback" not in err
    assert sorted(p.name for p in work.iterdir()) == ["gw.yaml", "opc.yaml"]
    assert tree_digest(site_package(env)) == package_before
    assert checkout_digest() == checkout_before


def test_the_gateway_example_checks_from_the_wheel_in_an_empty_folder(env: Path, tmp_path: Path) -> None:
    """``drivemap gateway --example > plant.yaml`` and ``drivemap gateway --check plant.yaml`` from the
    installed wheel in an empty folder: the example ships in the package, names only seed maps, and is
    a configuration the gateway accepts as printed (without the opcua extra: without its OPC UA part)."""
    package_before, checkout_before = tree_digest(site_package(env)), checkout_digest()
    work = tmp_path / "empty"
    work.mkdir()
    printed = ok(env, work, "gateway", "--example")
    assert printed.startswith("gateway: 1") or "\ngateway: 1\n" in printed, printed[:400]
    assert "# (OPC UA left out: pip install 'drivemap[opcua]'" in printed and "\nopcua:" not in printed
    (work / "plant.yaml").write_text(printed)
    checked = ok(env, work, "gateway", "--check", "plant.yaml")
    assert "registers every" in checked, checked
    assert sorted(p.name for p in work.iterdir()) == ["plant.yaml"]
    assert tree_digest(site_package(env)) == package_before
    assert checkout_digest() == checkout_before


def test_draft_from_the_wheel_in_an_empty_folder(env: Path, tmp_path: Path) -> None:
    """PDF, Word and Excel drafting work after a plain install (pdfplumber, python-docx, openpyxl are
    dependencies of the wheel), and every draft validates as written."""
    from tests.onboard.draft.test_draft import _docx, _pdf, _xlsx

    docs = tmp_path / "docs"
    docs.mkdir()
    work = tmp_path / "plant"
    work.mkdir()
    for document, model in ((_pdf(docs / "meter.pdf", pages=2), "pdfmeter"), (_docx(docs / "drive.docx"), "drive"),
                            (_xlsx(docs / "meter.xlsx"), "xlsxmeter")):
        out = ok(env, work, "draft", str(document), "--model", model)
        assert f"drivemap validate maps/{model}.yaml" in out
    assert sorted(p.name for p in (work / "maps").iterdir()) == ["drive.yaml", "pdfmeter.yaml", "xlsxmeter.yaml"]
    validated = ok(env, work, "validate")
    assert all(f"maps/{m}.yaml: ok" in validated for m in ("drive", "pdfmeter", "xlsxmeter"))
