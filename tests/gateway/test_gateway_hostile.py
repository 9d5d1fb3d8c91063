"""No single MQTT message stops the gateway: the hostile corpus (tests/corpora/mqtt_payloads.py) goes to
every command topic of the example's devices (every register of pump1, fan2 and conveyor, every one
listed writable so that the payloads reach the parsers), each is answered on the result topic as
refused, and afterwards the gateway still polls, publishes and serves OPC UA. Real broker, real
simulators, 127.0.0.1 only."""

from __future__ import annotations

import asyncio
import importlib.util
import json
import time
from collections.abc import Iterator
from pathlib import Path

import aiomqtt
import pytest

from drivemap.compiler import compile_map
from drivemap.model.nodes import Model
from tests.corpora.mqtt_payloads import INDEXES, PAYLOADS
from tests.helpers_client import tcp_server
from tests.helpers_gateway import Broker, Subscriber, free_port, running, until, write_config

ROOT = Path(__file__).resolve().parents[2]
HUGE = 16 * 1024  # payloads longer than this go to one topic per device (they are refused by size alone)
HAS_OPCUA = importlib.util.find_spec("asyncua") is not None


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


def every_writable(model: Model) -> list[str]:
    return [r.name for r in model.registers if r.writable and (not r.readable or r.page is None)]


def config(broker: int, vfd: int, ev: int, opc: int) -> str:
    vfd1000, evm = compile_map(ROOT / "maps/vfd1000.yaml"), compile_map(ROOT / "maps/ev.yaml")
    opcua = f"opcua: {{endpoint: 'opc.tcp://127.0.0.1:{opc}/drivemap/'}}\n" if HAS_OPCUA else ""
    return f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1, port: {broker}}}
{opcua}buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.5
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2, writable: {json.dumps(every_writable(vfd1000))}}}
      - {{name: fan2, model: vfd1000, unit: 2, interval: 0.2, writable: {json.dumps(every_writable(vfd1000))}}}
  - name: line2
    tcp: 127.0.0.1:{ev}
    timeout: 0.5
    devices:
      - {{name: conveyor, model: ev, unit: 1, interval: 0.2, writable: {json.dumps(every_writable(evm))}}}
"""


def command_topics(device: str, model: Model) -> list[str]:
    topics = []
    for reg in model.registers:
        topics.append(f"drivemap/{device}/{reg.name}/set")
        if reg.is_array:
            topics += [f"drivemap/{device}/{reg.name}/0/set", f"drivemap/{device}/{reg.name}/{reg.count}/set"]
            topics += [f"drivemap/{device}/{reg.name}/{i}/set" for i in INDEXES if i]
    return topics


async def test_hostile_corpus_on_every_command_topic(tmp_path: Path, broker: Broker) -> None:
    models = {"pump1": compile_map(ROOT / "maps/vfd1000.yaml"), "fan2": compile_map(ROOT / "maps/vfd1000.yaml"),
              "conveyor": compile_map(ROOT / "maps/ev.yaml")}
    opc = free_port()
    with tcp_server("vfd1000", (1, 2)) as (vsim, _, vport), tcp_server("ev", (1,)) as (_, _, eport):
        cfg = write_config(tmp_path, config(broker.port, vport, eport, opc))
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg) as gw:
            await until(lambda: all(sub.text(f"drivemap/{d}/availability") == "online" for d in models), 20, "online")
            sent: dict[str, list[str]] = {d: [] for d in models}
            started = time.monotonic()
            async with aiomqtt.Client("127.0.0.1", broker.port, identifier="hostile") as client:
                for device, model in models.items():
                    for n, topic in enumerate(command_topics(device, model)):
                        for label, payload in PAYLOADS:
                            if len(payload) > HUGE and n:
                                continue
                            await client.publish(topic, payload, qos=1)
                            sent[device].append(f"{topic} {label}")
            total = sum(len(v) for v in sent.values())
            for device in models:
                await until(lambda d=device: len(sub.messages(f"drivemap/{d}/error")) >= len(sent[d]), 120,
                            f"{len(sent[device])} outcomes of {device}")
            outcomes = {d: [json.loads(p) for p in sub.messages(f"drivemap/{d}/error")] for d in models}
            for device, results in outcomes.items():
                assert len(results) == len(sent[device]), device
                accepted = [(s, o) for s, o in zip(sent[device], results, strict=True) if o["ok"]]
                assert not accepted, accepted[:3]
                assert all(o["error"] and o["error"] != "InternalError" for o in results), \
                    [o for o in results if o["error"] == "InternalError"][:3]
            # still polling and publishing: a value changed after the corpus arrives
            assert all(not t.done() for t in asyncio.all_tasks() if t.get_name().startswith("line"))
            polls = gw.lines[0].polls_done
            vsim.set("communication_setting", 55.55)
            await until(lambda: sub.text("drivemap/pump1/communication_setting") == "55.55", 20, "a value after the corpus")
            assert gw.lines[0].polls_done > polls and gw.lines[0].faults == 0
            assert total > 5000, total
            print(f"{total} hostile commands answered in {time.monotonic() - started:.1f} s")
            if HAS_OPCUA:
                from asyncua import Client

                async with Client(f"opc.tcp://127.0.0.1:{opc}/drivemap/") as opc_client:
                    idx = await opc_client.get_namespace_index("urn:drivemap:plant")
                    node = await opc_client.nodes.objects.get_child([f"{idx}:plant", f"{idx}:pump1",
                                                                     f"{idx}:communication_setting"])
                    assert await node.read_value() == 55.55


async def test_a_failure_nothing_foresaw_stops_nothing(tmp_path: Path, broker: Broker) -> None:
    """A poll or a write that fails with an exception no drivemap code expects (injected here: the
    client raises RuntimeError) is logged; the command is answered ``InternalError``, the line and the
    other devices go on."""
    with tcp_server("vfd1000", (1, 2)) as (vsim, _, vport), tcp_server("ev", (1,)) as (_, _, eport):
        cfg = write_config(tmp_path, config(broker.port, vport, eport, free_port()).replace("opcua:", "# opcua:"))
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg) as gw:
            await until(lambda: sub.text("drivemap/pump1/availability") == "online", 20, "online")
            pump = gw.devices["pump1"]
            real_read, failures = pump.client.read, {"left": 3}

            async def flaky_read(*accessors: object) -> object:
                if failures["left"]:
                    failures["left"] -= 1
                    raise RuntimeError("a reply nothing foresaw")
                return await real_read(*accessors)

            pump.client.read = flaky_read
            acc = pump.client.accessor("communication_setting")
            real_write = type(acc).write_raw

            async def broken_write(self: object, raw: int) -> None:
                raise RuntimeError("a write nothing foresaw")

            type(acc).write_raw = broken_write
            try:
                await until(lambda: failures["left"] == 0, 10, "three failed polls")
                async with aiomqtt.Client("127.0.0.1", broker.port, identifier="odd") as client:
                    await client.publish("drivemap/pump1/communication_setting/set", "1.5", qos=1)
                outcome = json.loads(await until(lambda: (sub.messages("drivemap/pump1/error") or [None])[-1], 10,
                                                 "the outcome"))
                assert outcome["ok"] is False and outcome["error"] == "InternalError", outcome
            finally:
                type(acc).write_raw = real_write
            vsim.set("communication_setting", 7.25)
            await until(lambda: sub.text("drivemap/pump1/communication_setting") == "7.25", 10, "polling again")
            vsim.unit(2).set("communication_setting", 3.5)
            await until(lambda: sub.text("drivemap/fan2/communication_setting") == "3.5", 10, "the other device")
