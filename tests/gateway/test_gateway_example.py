"""The README's walk-through, for real, in an empty folder: ``drivemap gateway --example > plant.yaml``,
``drivemap simulate ... &`` and ``drivemap gateway plant.yaml`` (the example as printed, only its ports
moved to free ones), each in its own process; the drives must show in an MQTT subscriber and in an OPC
UA browse with asyncua's client, and the README's write must reach pump1. Only 127.0.0.1."""

from __future__ import annotations

import asyncio
import contextlib
import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from asyncua import Client  # noqa: E402

from tests.helpers_gateway import Broker, Subscriber, free_port, publish, until

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs/examples/plant.yaml"
README = ROOT / "README.md"


def readme_commands() -> list[list[str]]:
    """The README's ``drivemap simulate`` commands (one line, joined with ``&``) and its gateway command,
    after its ``drivemap gateway --example > plant.yaml``."""
    lines = [line.strip() for line in README.read_text().splitlines()]
    at = lines.index("drivemap gateway plant.yaml")
    example, simulate, gateway = lines[at - 2], lines[at - 1], lines[at]
    assert example == "drivemap gateway --example > plant.yaml", example
    assert simulate.startswith("drivemap simulate"), simulate
    commands = [part.split() for part in simulate.split("&") if part.strip()]
    return [*commands, gateway.split()]


def readme_write() -> tuple[str, str]:
    """The topic and payload of the README's ``mosquitto_pub`` write."""
    text = " ".join(README.read_text().split())
    found = re.search(r"mosquitto_pub -h 127\.0\.0\.1 -t (\S+) -m (\S+?)`", text)
    assert found, "the README shows no write"
    return found.group(1), found.group(2)


@contextlib.contextmanager
def processes(commands: list[list[str]], cwd: Path) -> Iterator[list[subprocess.Popen[str]]]:
    procs: list[subprocess.Popen[str]] = []
    try:
        for n, argv in enumerate(commands):
            with open(cwd / f"command{n}.log", "w") as log:
                procs.append(subprocess.Popen([sys.executable, "-m", "drivemap", *argv[1:]], cwd=cwd, text=True,
                                              stdout=log, stderr=subprocess.STDOUT))
        yield procs
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)


async def test_readme_two_commands_show_the_drives_in_mqtt_and_opcua(tmp_path: Path) -> None:
    commands = readme_commands()
    assert [c[:2] for c in commands] == [["drivemap", "simulate"]] * 2 + [["drivemap", "gateway"]]
    assert commands[-1][2:] == ["plant.yaml"]
    broker = Broker(tmp_path).start()
    ports = {"5030": str(free_port()), "5031": str(free_port()), "4840": str(free_port()), "1883": str(broker.port)}
    printed = subprocess.run([sys.executable, "-m", "drivemap", "gateway", "--example"], cwd=tmp_path, text=True,
                             capture_output=True, check=True).stdout
    assert printed == EXAMPLE.read_text()  # with the opcua extra (the test extra has it): the whole example
    for old in ("1883", "4840", "5030", "5031"):
        assert old in printed, f"the example no longer uses port {old}"
    moved = re.sub(r"\b(1883|4840|5030|5031)\b", lambda m: ports[m.group(1)], printed)
    (tmp_path / "plant.yaml").write_text(moved)
    argv = [[re.sub(r"\b(5030|5031)\b", lambda m: ports[m.group(1)], a) for a in c] for c in commands]
    try:
        async with Subscriber(broker.port, ("drivemap/#", "homeassistant/#")) as sub:
            with processes(argv, tmp_path) as procs:
                await until(lambda: all(sub.text(f"drivemap/{d}/availability") == "online"
                                        for d in ("pump1", "fan2", "conveyor")), 45, "three drives online in MQTT")
                await until(lambda: sub.text("drivemap/fan2/inverter_state"), 10, "a value of fan2")
                await until(lambda: sub.text("drivemap/conveyor/state"), 10, "a snapshot of conveyor")
                assert "operating_frequency" in json.loads(sub.text("drivemap/pump1/state") or "{}")
                assert sub.text("drivemap/gateway/plant/availability") == "online"
                assert any(t.startswith("homeassistant/") and "drivemap_plant_pump1" in t for t in sub.latest)
                async with Client(f"opc.tcp://127.0.0.1:{ports['4840']}/drivemap/") as client:
                    idx = await client.get_namespace_index("urn:drivemap:plant")
                    plant = await client.nodes.objects.get_child([f"{idx}:plant"])
                    names = {(await n.read_browse_name()).Name for n in await plant.get_children()}
                    assert names == {"pump1", "fan2", "conveyor"}
                    pump = await plant.get_child([f"{idx}:pump1"])
                    children = {(await n.read_browse_name()).Name for n in await pump.get_children()}
                    assert {"Online", "inverter_state", "operating_frequency"} <= children
                    online = await pump.get_child([f"{idx}:Online"])
                    for _ in range(100):
                        if await online.read_value():
                            break
                        await asyncio.sleep(0.1)
                    assert await online.read_value() is True
                topic, payload = readme_write()
                await publish(broker.port, topic, payload)
                await until(lambda: sub.text(topic.removesuffix("/set")) == payload, 15, "the README's write read back")
                device = topic.split("/")[1]
                assert json.loads(sub.messages(f"drivemap/{device}/error")[-1])["ok"] is True
                assert all(p.poll() is None for p in procs), "a process of the README's commands exited"
            gateway_out = (tmp_path / f"command{len(argv) - 1}.log").read_text()
            assert "gateway plant: 2 buses, 3 devices" in gateway_out
            assert "Traceback" not in gateway_out
    finally:
        broker.stop()
