"""The gateway follows the map's display and write rules, with real parts (a broker process, an
independent subscriber, simulators over TCP, asyncua's client): ``precision:`` in MQTT state text
and discovery, ``first_index:`` in entity names, value sets (``values:``) as selects whose commands
take a label or a value and nothing else, and ``protocol.alignment`` in what it polls and writes."""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jinja2
import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.gateway.device import Device
from drivemap.gateway.discovery import discovery_messages
from drivemap.gateway.service import Gateway
from drivemap.model.spec import spec_from_model as load_spec
from drivemap.runtime.errors import NotAllowedValue
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.runtime.sim.simulator import Simulator
from tests.helpers_client import tcp_server
from tests.helpers_gateway import Broker, Subscriber, free_port, publish, running, until, write_config


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


def acme_map(folder: Path) -> Path:
    """The scaffold's map with ``precision: 2`` on its f32 (default: shortest text, ``4.0``) and
    ``precision: 1`` on a register scaled by 0.01 (default: 2 decimals)."""
    with contextlib.chdir(folder), contextlib.redirect_stdout(io.StringIO()):
        assert main(["new", "acme"]) == 0
    path = folder / "maps" / "acme.yaml"
    text = path.read_text()
    assert "    precision: 1  #" in text and "    scale: 0.01\n" in text
    text = text.replace("    precision: 1  #", "    precision: 2  #")
    text = text.replace("    scale: 0.01\n", "    scale: 0.01\n    precision: 1\n", 1)
    path.write_text(text)
    return path


@contextlib.contextmanager
def map_server(path: Path) -> Iterator[tuple[Any, int]]:
    sim = Simulator(load_spec(compile_map(path)), [1])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        yield sim, server.address[1]


def render(template: str, value: str) -> str:
    """A value template rendered as Home Assistant does (Jinja2)."""
    payload = json.loads(value) if value[:1] in "[{" else None
    return jinja2.Environment().from_string(template).render(value=value, value_json=payload)


def messages_of(tmp_path: Path, text: str) -> dict[str, dict[str, Any]]:
    cfg = write_config(tmp_path, text)

    async def made() -> dict[str, Device]:
        return Gateway(cfg).devices

    out: dict[str, dict[str, Any]] = {}
    for dev in asyncio.run(made()).values():
        for topic, payload in discovery_messages("plant", dev, "homeassistant", "drivemap/gateway/plant/availability"):
            out[topic.split("/", 1)[1].rsplit("/", 1)[0]] = payload
    return out


def recording(sim: Any) -> list[bytes]:
    """Every answer ``sim`` gives (the served PDU), to look for exception replies."""
    answers: list[bytes] = []
    handle = sim.handle

    def wrapped(unit: int, pdu: bytes, **kwargs: Any) -> bytes | None:
        answer: bytes | None = handle(unit, pdu, **kwargs)
        if answer is not None:
            answers.append(bytes(pdu[:1]) + answer)
        return answer

    sim.handle = wrapped
    return answers


# ---------------------------------------------------------------------------------------------- precision
def test_discovery_follows_the_maps_precision(tmp_path: Path) -> None:
    path = acme_map(tmp_path)
    messages = messages_of(tmp_path, f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1}}
buses:
  - {{name: line, tcp: 127.0.0.1:1, devices: [{{name: acme, map: {path}, unit: 1,
      publish: [carrier_frequency, frequency_command, line_voltage]}}]}}
""")
    assert messages["sensor/drivemap_plant_acme/carrier_frequency"]["suggested_display_precision"] == 2
    assert messages["sensor/drivemap_plant_acme/frequency_command"]["suggested_display_precision"] == 1
    assert "suggested_display_precision" not in messages["sensor/drivemap_plant_acme/line_voltage"]  # f32, no precision


async def test_mqtt_state_text_follows_the_maps_precision(tmp_path: Path, broker: Broker) -> None:
    path = acme_map(tmp_path)
    with map_server(path) as (sim, port):
        sim.set("carrier_frequency", 8.0)
        sim.set_raw("frequency_command", 1234)  # 12.34 Hz; precision 1 shows 12.3
        sim.set("line_voltage", 230.2)  # an f32 without precision: the shortest text of the same f32
        cfg = write_config(tmp_path, f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1, port: {broker.port}, reconnect: {{min: 0.3, max: 1}}}}
buses:
  - name: line
    tcp: 127.0.0.1:{port}
    timeout: 0.5
    devices:
      - {{name: acme, map: {path}, unit: 1, interval: 0.2,
         publish: [carrier_frequency, frequency_command, line_voltage]}}
""")
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
            await until(lambda: sub.text("drivemap/acme/carrier_frequency") == "8.00", what="precision 2")
            await until(lambda: sub.text("drivemap/acme/frequency_command") == "12.3", what="precision 1")
            await until(lambda: sub.text("drivemap/acme/line_voltage") == "230.2", what="shortest f32")
            state = {"carrier_frequency": 8.0, "frequency_command": 12.34, "line_voltage": 230.2}  # whole values
            await until(lambda: json.loads(sub.text("drivemap/acme/state") or "{}") == state, what="state")
            assert not [p for p in sub.messages("drivemap/acme/frequency_command") if p != b"12.3"]


# ---------------------------------------------------------------------------------------------- first_index
def test_array_entities_are_numbered_as_the_manual_numbers_them(tmp_path: Path) -> None:
    messages = messages_of(tmp_path, """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1}
buses:
  - {name: line, tcp: 127.0.0.1:1, devices: [{name: conveyor, model: ev, unit: 2,
      publish: [alarm_history, digital_speed]}]}
""")
    first = messages["sensor/drivemap_plant_conveyor/alarm_history_0"]  # topics and ids count from 0 ...
    assert first["name"] == "Alarm history 1"  # ... names as the manual: first_index 1
    assert first["value_template"] == "{{ value_json[0] }}"
    assert messages["sensor/drivemap_plant_conveyor/alarm_history_9"]["name"] == "Alarm history 10"
    assert messages["sensor/drivemap_plant_conveyor/digital_speed_3"]["name"] == "Digital speed 3"  # first_index 0


# ---------------------------------------------------------------------------------------------- value sets
METER = """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1, port: @MQTT@, reconnect: {min: 0.3, max: 1}}
@OPCUA@buses:
  - name: meter
    tcp: 127.0.0.1:@PORT@
    timeout: 0.5
    devices:
      - {name: meter, model: sdm630, unit: 1, interval: 0.2,
         publish: [demand_period, system_type, phase_1_voltage, phase_2_current, total_kwh, frequency],
         writable: [demand_period, system_type]}
"""


def meter_config(mqtt: int, port: int, opc: int | None = None) -> str:
    opcua = (f"opcua: {{endpoint: 'opc.tcp://127.0.0.1:{opc}/drivemap/', namespace: 'urn:drivemap:test', "
             "anonymous_writes: true}\n") if opc else ""
    return METER.replace("@MQTT@", str(mqtt)).replace("@PORT@", str(port)).replace("@OPCUA@", opcua)


def test_a_value_set_is_a_select_of_its_labels_and_values(tmp_path: Path) -> None:
    messages = messages_of(tmp_path, meter_config(1, 1))
    assert "number/drivemap_plant_meter/demand_period" not in messages
    system = messages["select/drivemap_plant_meter/system_type"]
    assert system["options"] == ["1p2w", "3p3w", "3p4w"]
    assert system["command_topic"] == "drivemap/meter/system_type/set"
    assert render(system["value_template"], "3.0") == "3p4w"
    assert render(system["value_template"], "4.0") == "None"  # outside the set: unknown, never a bad option
    demand = messages["select/drivemap_plant_meter/demand_period"]
    assert demand["options"][:3] == ["demand shows the current value", "5", "8"]  # the value where no label
    assert render(demand["value_template"], "0.0") == "demand shows the current value"
    assert render(demand["value_template"], "5.0") == "5"
    assert render(demand["value_template"], "null") == "None"


def test_commands_take_a_label_or_a_value_and_nothing_else(tmp_path: Path) -> None:
    cfg = write_config(tmp_path, meter_config(1, 1))

    async def meter() -> Device:
        return Gateway(cfg).devices["meter"]

    device = asyncio.run(meter())
    codec = device.client.accessor("system_type").codec
    for payload, value in (("1p2w", 1.0), ('"3p3w"', 2.0), ("3", 3.0), ("3.0", 3.0)):
        assert device.command("system_type", payload).raw == codec.encode(value), payload
    demand = device.client.accessor("demand_period").codec
    assert device.command("demand_period", "demand shows the current value").raw == demand.encode(0.0)
    assert device.command("demand_period", "5.0000000001").raw == demand.encode(5.0)  # the set's tolerance
    for payload in ("4", "3p4W", "2.5", "true", '"3"', "4p4w"):
        with pytest.raises(NotAllowedValue, match=r"allowed values 1 \(1p2w\), 2 \(3p3w\), 3 \(3p4w\)"):
            device.command("system_type", payload)


async def test_value_set_commands_over_mqtt(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("sdm630") as (sim, _, port):
        sim.set("system_type", 3.0)
        cfg = write_config(tmp_path, meter_config(broker.port, port))
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg):
            await until(lambda: sub.text("drivemap/meter/system_type") == "3.0", what="system type")
            await publish(broker.port, "drivemap/meter/system_type/set", "1p2w")  # what the select sends
            await until(lambda: sim.get("system_type") == 1.0, what="label written")
            await publish(broker.port, "drivemap/meter/demand_period/set", "8")
            await until(lambda: sim.get("demand_period") == 8.0, what="value written")
            await publish(broker.port, "drivemap/meter/demand_period/set", "7")
            await until(lambda: any(not json.loads(m)["ok"] for m in sub.messages("drivemap/meter/error")),
                        what="refusal")
            refused = next(json.loads(m) for m in sub.messages("drivemap/meter/error") if not json.loads(m)["ok"])
            assert refused["error"] == "NotAllowedValue" and refused["register"] == "demand_period"
            assert refused["allowed"] == [0.0, 5.0, 8.0, 10.0, 15.0, 20.0, 30.0, 60.0]
            assert "allowed values 0 (demand shows the current value), 5, 8, 10" in refused["message"]
            assert sim.get("demand_period") == 8.0


async def test_opcua_refuses_a_value_outside_the_set(tmp_path: Path, broker: Broker) -> None:
    from asyncua import Client, ua
    from asyncua.ua.uaerrors import BadOutOfRange

    opc = free_port()
    with tcp_server("sdm630") as (sim, _, port):
        cfg = write_config(tmp_path, meter_config(broker.port, port, opc))
        async with running(cfg), Client(f"opc.tcp://127.0.0.1:{opc}/drivemap/") as client:
            idx = await client.get_namespace_index("urn:drivemap:test")
            node = await client.nodes.objects.get_child([f"{idx}:plant", f"{idx}:meter", f"{idx}:demand_period"])
            with pytest.raises(BadOutOfRange):
                await node.write_value(ua.DataValue(ua.Variant(7.0, ua.VariantType.Float)))
            await node.write_value(ua.DataValue(ua.Variant(15.0, ua.VariantType.Float)))
            assert sim.get("demand_period") == 15.0


# ---------------------------------------------------------------------------------------------- alignment
async def test_polls_and_writes_keep_the_alignment_rules(tmp_path: Path, broker: Broker) -> None:
    """sdm630 answers 02h to a read that starts inside a float or covers half of one; the gateway's
    polls (scattered registers the planner joins) and writes never earn one."""
    with tcp_server("sdm630") as (sim, _, port):
        answers = recording(sim)
        sim.set("phase_1_voltage", 230.5)
        sim.set("frequency", 50.0)
        cfg = write_config(tmp_path, meter_config(broker.port, port))
        async with Subscriber(broker.port, ("drivemap/#",)) as sub, running(cfg) as gateway:
            await until(lambda: sub.text("drivemap/meter/phase_1_voltage") == "230.5", what="poll")
            await until(lambda: sub.text("drivemap/meter/frequency") == "50.0", what="poll")
            await publish(broker.port, "drivemap/meter/demand_period/set", "30")
            await until(lambda: sim.get("demand_period") == 30.0, what="write")
            polls = gateway.devices["meter"].polls_done
            await until(lambda: gateway.devices["meter"].polls_done >= polls + 3, what="more polls")
        assert answers
        assert [a.hex() for a in answers if a[1] & 0x80] == []  # no exception reply, 02h or other
        assert {a[0] for a in answers} >= {0x03, 0x04, 0x10}
        sim.handle(1, bytes.fromhex("0400010002"))  # what a read starting inside a float would earn ...
        assert answers[-1] == bytes.fromhex("048402")  # ... and the check above would have seen
