"""drivemap gateway -> MQTT, with real parts: a broker process (mosquitto, else amqtt), generated
simulators over TCP and on a virtual serial line, an independent aiomqtt subscriber."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from drivemap.gateway.config import GatewayConfig
from drivemap.runtime.sim.serve import ThreadedSimServer
from tests.helpers_client import serial_server, simulator, tcp_server
from tests.helpers_gateway import Broker, Subscriber, publish, running, until, write_config


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


def two_buses(port: int, vfd: int, ev: int, extra: str = "") -> str:
    return f"""\
gateway: 1
name: plant
offline_backoff: {{min: 0.2, max: 0.5}}
mqtt: {{host: 127.0.0.1, port: {port}, reconnect: {{min: 0.3, max: 1}}}}
buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.3
    retries: 1
    devices:
      - {{name: pump1, title: Pump 1, model: vfd1000, unit: 1, interval: 0.2,
         writable: [communication_setting, control_command, pid_setting, upper_limit_frequency_setting]}}
  - name: line2
    tcp: 127.0.0.1:{ev}
    timeout: 0.3
    devices:
      - {{name: drive2, model: ev, unit: 2, interval: 0.2, writable: [alarm_reset, net_in, rs485_timeout]}}
{extra}"""


async def settled(measure: Callable[[], int], quiet: float = 0.5, timeout: float = 10.0) -> None:
    """Wait until ``measure()`` has not changed for ``quiet`` seconds (all retained messages arrived)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    last, since = measure(), loop.time()
    while loop.time() - since < quiet:
        assert loop.time() < end, "messages kept arriving"
        await asyncio.sleep(0.05)
        if measure() != last:
            last, since = measure(), loop.time()


def config_for(tmp_path: Path, broker: Broker, vfd_port: int, ev_port: int) -> GatewayConfig:
    return write_config(tmp_path, two_buses(broker.port, vfd_port, ev_port))


async def test_discovery_payloads(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("vfd1000", (1,)) as (_, _, vport), tcp_server("ev", (2,)) as (_, _, eport):
        cfg = config_for(tmp_path, broker, vport, eport)
        async with running(cfg), Subscriber(broker.port, ("homeassistant/#",)) as sub:

            async def config(topic: str) -> Any:  # each device's discovery may still be on its way
                return json.loads(await until(lambda: sub.text(topic), what=topic))

            node = "homeassistant/{}/drivemap_plant_pump1/{}/config"
            number = await until(lambda: sub.text(node.format("number", "communication_setting")), what="number")
            await until(lambda: sub.text("homeassistant/button/drivemap_plant_drive2/alarm_reset/config"), what="button")
            n = json.loads(number)
            assert (n["min"], n["max"], n["step"], n["unit_of_measurement"]) == (-100.0, 100.0, 0.01, "%")
            assert n["command_topic"] == "drivemap/pump1/communication_setting/set"
            assert n["state_topic"] == "drivemap/pump1/communication_setting"
            assert "model_id" not in n["device"]  # Home Assistant 2024.3 refuses an entity whose device has it
            assert n["device"]["name"] == "Pump 1" and "manufacturer" not in n["device"] and "hw_version" not in n["device"]
            assert n["availability_mode"] == "all"
            assert [a["topic"] for a in n["availability"]] == ["drivemap/gateway/plant/availability",
                                                               "drivemap/pump1/availability"]
            select = await config(node.format("select", "control_command"))
            assert select["options"][:2] == ["FORWARD_RUNNING", "REVERSE_RUNNING"] and "state_topic" not in select
            state = await config(node.format("sensor", "inverter_state"))
            assert state["device_class"] == "enum" and "STANDBY" in state["options"]
            bit = await config("homeassistant/binary_sensor/drivemap_plant_drive2/net_in_x3/config")
            assert bit["value_template"] == "{{ 'ON' if value_json['X3'] else 'OFF' }}"
            speed = await config("homeassistant/sensor/drivemap_plant_drive2/motor_speed/config")
            assert speed["unit_of_measurement"] == "rpm" and speed["state_class"] == "measurement"
            timeout = await config("homeassistant/number/drivemap_plant_drive2/rs485_timeout/config")
            assert timeout["device_class"] == "duration" and timeout["max"] == 1000
            press = await config("homeassistant/button/drivemap_plant_drive2/alarm_reset/config")
            assert press["payload_press"] == "PRESS"
            await settled(lambda: len(sub.latest))
            async with Subscriber(broker.port, ("homeassistant/#",)) as late:  # retained: a late subscriber gets all
                await until(lambda: len(late.latest) == len(sub.latest), what="retained discovery")
                assert late.latest == sub.latest
                if broker.kind == "mosquitto":  # amqtt 0.12 clears the flag on some stored messages it delivers
                    assert all(late.retained.values())
            ids = [json.loads(p)["unique_id"] for p in sub.latest.values()]
            assert len(ids) == len(set(ids))
            assert not [t for t in sub.latest if "/switch/" in t]  # maps have no coils


async def test_value_flow(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (esim, _, eport):
        cfg = config_for(tmp_path, broker, vport, eport)
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
            await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="pump1 online")
            assert sub.text("drivemap/gateway/plant/availability") == "online"
            vsim.set("communication_setting", -12.34)
            vsim.set("inverter_state", 1)
            esim.unit(2).set_bit("net_in", "X3", 1)
            esim.set("motor_speed", 1500)
            await until(lambda: sub.text("drivemap/pump1/communication_setting") == "-12.34", what="scaled value")
            await until(lambda: sub.text("drivemap/pump1/inverter_state") == "FORWARD_RUNNING", what="enum name")
            await until(lambda: sub.text("drivemap/drive2/motor_speed") == "1500", what="ev speed")
            bits = json.loads(await until(lambda: sub.text("drivemap/drive2/net_in"), what="bits"))
            await until(lambda: json.loads(sub.text("drivemap/drive2/net_in") or "{}").get("X3") is True, what="X3")
            assert set(bits) == {f"X{i}" for i in range(8)}
            snap = json.loads(sub.text("drivemap/pump1/state") or "{}")
            assert snap["inverter_state"] == "FORWARD_RUNNING" and snap["communication_setting"] == -12.34
            assert len(sub.messages("drivemap/pump1/state")) >= 2  # one snapshot per poll
            assert len(sub.messages("drivemap/pump1/communication_setting")) <= 3  # values only when they change


async def test_command_round_trip_and_checks(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (esim, _, eport):
        cfg = config_for(tmp_path, broker, vport, eport)
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg) as gw:
            await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="online")
            await publish(broker.port, "drivemap/pump1/communication_setting/set", "42.5")
            await until(lambda: sub.text("drivemap/pump1/communication_setting") == "42.5", what="read back")
            assert vsim.get("communication_setting") == pytest.approx(42.5)
            ok = json.loads(sub.messages("drivemap/pump1/error")[-1])
            assert ok["ok"] is True and ok["register"] == "communication_setting"
            await publish(broker.port, "drivemap/pump1/control_command/set", "FORWARD_RUNNING")
            await until(lambda: len(sub.messages("drivemap/pump1/error")) == 2, what="enum outcome")
            assert json.loads(sub.messages("drivemap/pump1/error")[-1])["ok"] is True
            await publish(broker.port, "drivemap/drive2/alarm_reset/set", "PRESS")
            await publish(broker.port, "drivemap/drive2/net_in/set", '{"X1": true, "X5": true}')
            await until(lambda: json.loads(sub.text("drivemap/drive2/net_in") or "{}").get("X5") is True, what="bits")
            assert esim.get_raw("net_in") == 0b100010
            writes = dict(gw.lines[0].bus.stats.by_function)
            bad = [("communication_setting", "100.5", "ValueOutOfRange"), ("communication_setting", "fast", "InvalidValue"),
                   ("inverter_state", "1", "ReadOnlyRegister"), ("control_command", "SIDEWAYS", "InvalidValue"),
                   ("no_such_register", "1", "UnknownRegister"), ("upper_limit_frequency_setting", "-1", "ValueOutOfRange")]
            for register, payload, _ in bad:
                await publish(broker.port, f"drivemap/pump1/{register}/set", payload)
            await until(lambda: len(sub.messages("drivemap/pump1/error")) == 2 + len(bad), what="error outcomes")
            outcomes = [json.loads(p) for p in sub.messages("drivemap/pump1/error")[2:]]
            assert [(o["register"], o["error"]) for o in outcomes] == [(r, e) for r, _, e in bad]
            assert not any(o["ok"] for o in outcomes)
            after = gw.lines[0].bus.stats.by_function
            assert (after.get(0x06, 0), after.get(0x10, 0)) == (writes.get(0x06, 0), writes.get(0x10, 0))
            assert vsim.get("communication_setting") == pytest.approx(42.5)


async def test_retained_commands_are_ignored(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (_, _, eport):
        await publish(broker.port, "drivemap/pump1/communication_setting/set", "77", retain=True)
        cfg = config_for(tmp_path, broker, vport, eport)
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
            await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="online")
            await publish(broker.port, "drivemap/pump1/pid_setting/set", "12.5")
            await until(lambda: sub.text("drivemap/pump1/pid_setting") == "12.5", what="later command done")
            assert vsim.get("communication_setting") == 0
            assert [json.loads(p)["register"] for p in sub.messages("drivemap/pump1/error")] == ["pid_setting"]


async def test_device_goes_offline_and_comes_back(tmp_path: Path, broker: Broker) -> None:
    sim = simulator("vfd1000", (1,))
    server = ThreadedSimServer(sim, tcp=("127.0.0.1", 0)).start()
    assert server.address is not None
    vport = server.address[1]
    try:
        with tcp_server("ev", (2,)) as (_, _, eport):
            cfg = config_for(tmp_path, broker, vport, eport)
            async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
                await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="online")
                await asyncio.to_thread(server.stop)
                await until(lambda: sub.text("drivemap/pump1/availability") == "offline", what="offline")
                assert sub.text("drivemap/drive2/availability") == "online"  # the other bus goes on
                assert sub.text("drivemap/gateway/plant/availability") == "online"
                sim.set("communication_setting", 7.5)
                server = ThreadedSimServer(sim, tcp=("127.0.0.1", vport))
                await asyncio.to_thread(server.start)
                await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="back online")
                await until(lambda: sub.text("drivemap/pump1/communication_setting") == "7.5", what="fresh value")
                states = [p.decode() for p in sub.messages("drivemap/pump1/availability")]
                assert states == ["online", "offline", "online"]
    finally:
        await asyncio.to_thread(server.stop)


async def test_serial_line_value_and_command(tmp_path: Path, broker: Broker) -> None:
    with serial_server("vfd1000", "rtu", (3,), baudrate=38400) as (sim, line):
        cfg = write_config(tmp_path, f"""\
gateway: 1
name: serial
mqtt: {{host: 127.0.0.1, port: {broker.port}}}
buses:
  - name: rs485
    serial: {{port: {line.master_port}, mode: rtu, baudrate: 38400, parity: none, stop_bits: 1}}
    timeout: 0.3
    devices:
      - {{name: vfd3, model: vfd1000, unit: 3, interval: 0.3, writable: [torque_setting_value]}}
""")
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
            sim.set("pid_feedback", 33.3)
            await until(lambda: sub.text("drivemap/vfd3/pid_feedback") == "33.3", what="value over RTU")
            await publish(broker.port, "drivemap/vfd3/torque_setting_value/set", "55.5")
            await until(lambda: sub.text("drivemap/vfd3/torque_setting_value") == "55.5", what="command over RTU")
            assert sim.get("torque_setting_value") == pytest.approx(55.5)
            assert any(f[1] == 0x06 for f in line.frames("to_device"))


async def test_broker_restart_republishes_and_keeps_accepted_commands(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (_, _, eport):
        text = two_buses(broker.port, vport, eport).replace("reconnect: {min: 0.3, max: 1}", "reconnect: {min: 1, max: 4}")
        cfg = write_config(tmp_path, text)
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg) as gw:
            await until(lambda: sub.text("drivemap/pump1/availability") == "online", what="online")
            async with gw.lines[0].bus.lock:  # the line waits here: the command is accepted, not yet sent
                await publish(broker.port, "drivemap/pump1/communication_setting/set", "-3.5")
                await until(lambda: gw.lines[0].commands_accepted == 1, what="command accepted")
                await asyncio.to_thread(broker.stop)
                vsim.set("pid_setting", 66.6)
            await until(lambda: vsim.get("communication_setting") == -3.5, what="command written during the outage")
            failures = gw.mqtt.failures
            await until(lambda: gw.mqtt.failures > failures, what="a failed reconnection attempt")
            await asyncio.to_thread(broker.start)
            await until(lambda: sub.ready.is_set(), what="subscriber back")  # before the gateway's next try (2 s)
            await until(lambda: gw.mqtt.connections == 2, timeout=15, what="gateway reconnected")
            await until(lambda: sub.messages("drivemap/pump1/error"), what="outcome after the outage")
            outcome = json.loads(sub.messages("drivemap/pump1/error")[-1])
            assert outcome["ok"] is True and outcome["register"] == "communication_setting"
        async with Subscriber(broker.port, ("#",)) as late:  # the restarted broker kept nothing: all republished
            await until(lambda: late.text("drivemap/pump1/communication_setting") == "-3.5", what="retained value")
            await until(lambda: late.text("drivemap/pump1/pid_setting") == "66.6", what="value changed in the outage")
            await until(lambda: late.text("homeassistant/number/drivemap_plant_pump1/communication_setting/config"),
                        what="discovery republished")
            await until(lambda: late.text("drivemap/pump1/availability") == "online", what="device availability")
            # the gateway has stopped since: its clean stop says offline
            await until(lambda: late.text("drivemap/gateway/plant/availability") == "offline", what="gateway offline")
