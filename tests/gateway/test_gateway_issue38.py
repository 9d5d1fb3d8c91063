"""What real clients and an adversarial run found in the gateway (issue 38), and writes to registers
whose map leaves open a field that decides the written words (issue 34): real mosquitto/amqtt broker,
real asyncua clients, real simulators on 127.0.0.1."""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from drivemap.cli import main
from drivemap.diagnostics import CompileError
from drivemap.gateway.device import Device
from drivemap.gateway.discovery import discovery_messages
from drivemap.gateway.service import Gateway
from tests.helpers_client import tcp_server
from tests.helpers_gateway import Broker, Subscriber, free_port, publish, running, until, write_config

ROOT = Path(__file__).resolve().parents[2]
#: Modbus write function codes (05h, 06h, 0Fh, 10h): what a refused command must never send.
WRITES = (0x05, 0x06, 0x0F, 0x10)


def written(gw: Gateway) -> list[list[int]]:
    """Requests of each write function code sent on each line so far."""
    return [[line.bus.stats.by_function.get(f, 0) for f in WRITES] for line in gw.lines]
VFD1000 = ROOT / "generator/drivemap/data/maps/vfd1000.yaml"
ALLKINDS = ROOT / "tests/maps/allkinds.yaml"


def reviewed_vfd1000(folder: Path) -> Path:
    """vfd1000's map with pid_setting's scale left open (``review: [scale]``), as a draft writes it."""
    text = VFD1000.read_text(encoding="utf-8")
    marker = "  - name: pid_setting\n"
    assert text.count(marker) == 1
    (folder / "reviewed").mkdir(exist_ok=True)
    path = folder / "reviewed" / "vfd1000.yaml"
    path.write_text(text.replace(marker, marker + "    review: [scale, unit]\n"), encoding="utf-8")
    return path


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


def mqtt_config(folder: Path, port: int, vfd: int, ev: int) -> str:
    return f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1, port: {port}, reconnect: {{min: 0.3, max: 1}}}}
buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.3
    devices:
      - {{name: pump1, map: {reviewed_vfd1000(folder)}, unit: 1, interval: 0.2,
         writable: [communication_setting, pid_setting]}}
  - name: line2
    tcp: 127.0.0.1:{ev}
    timeout: 0.3
    devices:
      - {{name: drive2, model: ev, unit: 2, interval: 0.2, writable: [net_in]}}
"""


async def test_mqtt_commands_exact_as_sent_unique_keys_and_no_writes_while_open(tmp_path: Path,
                                                                             broker: Broker) -> None:
    """Items 3 and 6 of issue 38 and the gateway's part of issue 34, over a real broker: nothing of it
    reaches a device, every refusal is an outcome naming its reason."""
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (esim, _, eport):
        cfg = write_config(tmp_path, mqtt_config(tmp_path, broker.port, vport, eport))
        async with Subscriber(broker.port, ("drivemap/#", "homeassistant/#")) as sub, running(cfg) as gw:
            await until(lambda: sub.text("drivemap/pump1/availability") == "online"
                        and sub.text("drivemap/drive2/availability") == "online", what="online")
            await until(lambda: sub.text("drivemap/pump1/pid_setting") is not None, what="pid_setting read")
            vsim.set("communication_setting", 12.5)
            esim.set_raw("net_in", 0b1)
            writes = written(gw)
            sent = [
                ("pump1", "communication_setting", "1e-400", "InexactValue"),  # 0 as a float
                ("pump1", "communication_setting", "99.999999999999999999", "InexactValue"),  # 100.0 as a float
                ("drive2", "net_in", '{"X0": true, "X0": false}', "InvalidValue"),  # last one would win
                ("pump1", "pid_setting", "10", "UnreviewedRegister"),  # its scale is still open
            ]
            for device, register, payload, _ in sent:
                await publish(broker.port, f"drivemap/{device}/{register}/set", payload)
            await until(lambda: len(sub.messages("drivemap/pump1/error")) == 3
                        and len(sub.messages("drivemap/drive2/error")) == 1, what="outcomes")
            outcomes = {o["value"]: o for o in (json.loads(p) for device in ("pump1", "drive2")
                                                for p in sub.messages(f"drivemap/{device}/error"))}
            assert {v: (o["register"], o["error"], o["ok"]) for v, o in outcomes.items()} == {
                payload: (r, e, False) for _, r, payload, e in sent}
            assert "0.0" in outcomes["1e-400"]["message"]
            assert "100.0" in outcomes["99.999999999999999999"]["message"]
            assert "'X0' twice" in outcomes['{"X0": true, "X0": false}']["message"]
            assert "scale open" in outcomes["10"]["message"] and "review" in outcomes["10"]["message"]
            assert written(gw) == writes  # nothing written
            assert vsim.get("communication_setting") == pytest.approx(12.5) and esim.get_raw("net_in") == 0b1
            # the exact texts still go through
            await publish(broker.port, "drivemap/pump1/communication_setting/set", "99.99")
            await until(lambda: len(sub.messages("drivemap/pump1/error")) == 4, what="outcome")
            assert json.loads(sub.messages("drivemap/pump1/error")[-1])["ok"] is True
            assert vsim.get_raw("communication_setting") == 9999
            # discovery: pid_setting's reads are published (a sensor), no control is offered
            node = "drivemap_plant_pump1"
            await until(lambda: sub.text(f"homeassistant/sensor/{node}/pid_setting/config") is not None,
                        what="discovery")
            assert sub.text(f"homeassistant/number/{node}/pid_setting/config") is None
            assert sub.text(f"homeassistant/number/{node}/communication_setting/config") is not None


def _check(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str) -> tuple[int, str, str]:
    path = tmp_path / "gw.yaml"
    path.write_text(text)
    code = main(["gateway", "--check", str(path)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err.replace(f"{path}:", "")


CHECKED = """\
gateway: 1
name: plant
mqtt: {host: 127.0.0.1}
buses:
  - name: line1
    tcp: 127.0.0.1:5020
    devices:
      - {name: pump1, map: MAP, unit: 1,
         writable: [communication_setting, pid_setting]}
      - {name: io, map: ALLKINDS, unit: 4, writable: [meter, settings]}
"""


def test_check_warns_of_open_registers_and_groups_that_open_nothing(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    text = CHECKED.replace("MAP", str(reviewed_vfd1000(tmp_path))).replace("ALLKINDS", str(ALLKINDS))
    code, out, err = _check(tmp_path, capsys, text)
    assert code == 0, err
    assert "gateway plant" in out
    lines = err.splitlines()
    assert lines[0].startswith("9:") and "warning: vfd1000.pid_setting takes no command" in lines[0]
    assert "scale open" in lines[0] and "unit" not in lines[0]  # the unit decides nothing a write sends
    assert lines[1].startswith("10:") and "warning: group 'meter' of allkinds opens no register" in lines[1]
    assert "none of its registers is writable" in lines[1]
    assert len(lines) == 2  # communication_setting, settings: nothing to say


def test_map_that_is_not_a_regular_file_is_refused_located(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 38 item 20: `map: /dev/zero` was "no such map file"; a FIFO would block the check."""
    fifo = tmp_path / "pipe.yaml"
    import os

    os.mkfifo(fifo)
    for target, kind in (("/dev/zero", "a character device"), (str(tmp_path), "a directory"), (str(fifo), "a FIFO")):
        code, _, err = _check(tmp_path, capsys, CHECKED.replace("MAP", target).replace("ALLKINDS", str(ALLKINDS)))
        assert code == 1
        assert err.startswith("8:") and f"is {kind}, not a regular file" in err, err
    code, _, err = _check(tmp_path, capsys, CHECKED.replace("MAP", str(tmp_path / "none.yaml"))
                          .replace("ALLKINDS", str(ALLKINDS)))
    assert code == 1 and "no such map file" in err


def _io_device(tmp_path: Path) -> Device:
    cfg = write_config(tmp_path, f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1}}
buses:
  - name: line1
    tcp: 127.0.0.1:1
    devices:
      - {{name: io, map: {ALLKINDS}, unit: 4, writable: [settings]}}
""")

    async def made() -> dict[str, Device]:
        return Gateway(cfg).devices

    return asyncio.run(made())["io"]


def test_writable_registers_without_a_range_get_a_number_bounded_by_their_type(tmp_path: Path) -> None:
    """Issue 38 item 4: a writable register the map gives no range gets a number over its type's range
    in engineering units (raw range * scale + offset), which the gateway then takes exactly."""
    io = _io_device(tmp_path)
    numbers = {topic.split("/")[3]: payload for topic, payload in discovery_messages("plant", io, "homeassistant", "x")
               if topic.startswith("homeassistant/number/")}
    assert (numbers["limit_32"]["min"], numbers["limit_32"]["max"], numbers["limit_32"]["step"]) == (
        -21474836.48, 21474836.47, 0.01)  # s32 at 0.01
    assert (numbers["counter_preset"]["min"], numbers["counter_preset"]["max"]) == (0, 2**64 - 1)  # u64
    assert (numbers["balance"]["min"], numbers["balance"]["max"]) == (-(2**63), 2**63 - 1)  # s64
    assert numbers["ramp_limit"]["max"] == 1.7976931348623157e308  # an unscaled f64
    assert (numbers["setpoint"]["min"], numbers["setpoint"]["max"]) == (-100, 100)  # the map's range wins
    for name, payload in (("limit_32", "21474836.47"), ("limit_32", "-21474836.48"), ("counter_preset", str(2**64 - 1))):
        io.command(name, payload)  # the ends are values the register takes
    assert "device_name" not in numbers and "enable" not in numbers  # a string, a bool: no number


def test_a_payload_naming_a_key_twice_is_refused_before_the_bus(tmp_path: Path) -> None:
    from drivemap.runtime.errors import InvalidValue

    with pytest.raises(CompileError):
        write_config(tmp_path, "gateway: 1\nname: x\n")
    io = _io_device(tmp_path)
    with pytest.raises(InvalidValue, match="twice"):
        io.command("limit_32", '{"a": 1, "a": 2}')


# ---------------------------------------------------------------------------------------------- OPC UA
asyncua = pytest.importorskip("asyncua", reason="OPC UA is the optional extra drivemap[opcua] (in the test extra)")
from asyncua import Client, ua  # noqa: E402

NS = "urn:drivemap:issue38"


def opcua_config(folder: Path, opc: int, vfd: int, ev: int) -> str:
    return f"""\
gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc}/drivemap/
  namespace: {NS}
  users:
    - {{name: operator, password: secret}}
buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.3
    devices:
      - {{name: pump1, map: {reviewed_vfd1000(folder)}, unit: 1, interval: 0.2,
         writable: [control_command, pid_setting]}}
  - name: line2
    tcp: 127.0.0.1:{ev}
    timeout: 0.3
    devices:
      - {{name: drive2, model: ev, unit: 2, interval: 0.2, writable: [digital_speed]}}
"""


async def _status(node: Any, value: Any, vtype: Any) -> str:
    try:
        await node.write_value(ua.DataValue(ua.Variant(value, vtype)))
    except ua.UaStatusCodeError as exc:
        return type(exc).__name__
    return "Good"


async def test_opcua_writes_arrays_variant_types_and_open_fields(tmp_path: Path) -> None:
    """Item 5: an array variable is not writable (BadNotWritable, not BadTypeMismatch); a UInt16
    variable takes a UInt16 only. Issue 34: a register whose scale is open is not writable, its value
    is read as usual."""
    opc = free_port()
    url = f"opc.tcp://127.0.0.1:{opc}/drivemap/"
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (2,)) as (_, _, eport):
        cfg = write_config(tmp_path, opcua_config(tmp_path, opc, vport, eport))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online and gw.devices["drive2"].online, what="online")
            vsim.set_raw("pid_setting", 123)
            operator = Client(url, timeout=5)
            operator.set_user("operator")
            operator.set_password("secret")
            async with operator:
                idx = await operator.get_namespace_index(NS)

                async def node(*path: str) -> Any:
                    return await operator.nodes.objects.get_child([f"{idx}:{p}" for p in ("plant", *path)])

                writes = written(gw)
                speeds = await node("drive2", "digital_speed")
                assert await _status(speeds, [1] * 8, ua.VariantType.UInt16) == "BadNotWritable"
                assert await _status(speeds, [1] * 8, ua.VariantType.Int64) == "BadNotWritable"
                command = await node("pump1", "control_command")
                assert await command.read_data_type_as_variant_type() == ua.VariantType.UInt16
                assert await _status(command, 5, ua.VariantType.Int32) == "BadTypeMismatch"
                assert await _status(command, 5.0, ua.VariantType.Double) == "BadTypeMismatch"
                assert await _status(command, 5, ua.VariantType.Int64) == "BadTypeMismatch"
                pid = await node("pump1", "pid_setting")
                level = (await pid.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
                assert level == ua.AccessLevel.CurrentRead.mask  # offered read-only
                assert await _status(pid, 10.0, ua.VariantType.Double) == "BadNotWritable"
                assert written(gw) == writes  # nothing reached a bus
                for _ in range(100):  # its reads are published
                    if await pid.read_value() == pytest.approx(12.3):
                        break
                    await asyncio.sleep(0.05)
                assert await pid.read_value() == pytest.approx(12.3)
                assert await _status(command, 5, ua.VariantType.UInt16) == "Good"  # STOP, as a UInt16


async def test_password_user_gets_in_past_anonymous_sessions_and_silent_connections(tmp_path: Path) -> None:
    """Item 1: ten anonymous sessions and ten silent raw TCP connections from the operator's own host
    (the default limits: 10 per source) do not keep the password user out."""
    opc = free_port()
    url = f"opc.tcp://127.0.0.1:{opc}/drivemap/"
    with tcp_server("vfd1000", (1,)) as (_, _, vport), tcp_server("ev", (2,)) as (_, _, eport):
        cfg = write_config(tmp_path, opcua_config(tmp_path, opc, vport, eport))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            anonymous = [Client(url, timeout=5) for _ in range(10)]
            raw: list[asyncio.StreamWriter] = []
            try:
                for c in anonymous:
                    await c.connect()
                for _ in range(10):
                    _, writer = await asyncio.open_connection("127.0.0.1", opc)
                    raw.append(writer)
                await asyncio.sleep(0.3)
                clients = gw.opcua.server.bserver.clients
                assert len(clients) == 20  # every anonymous session and every silent connection held
                operator = Client(url, timeout=5)
                operator.set_user("operator")
                operator.set_password("secret")
                start = time.monotonic()
                async with operator:  # connects and activates its session
                    print(f"password login past 10 anonymous sessions and 10 silent connections: "
                          f"{time.monotonic() - start:.2f} s")
                    assert time.monotonic() - start < 5
                    idx = await operator.get_namespace_index(NS)
                    online = await operator.nodes.objects.get_child([f"{idx}:plant", f"{idx}:pump1", f"{idx}:Online"])
                    assert await online.read_value() is True
                    for c in anonymous:  # no anonymous session was closed for it
                        assert await c.nodes.server_state.read_value() == ua.ServerState.Running
            finally:
                for w in raw:
                    w.close()
                for c in anonymous:
                    with contextlib.suppress(Exception):
                        await c.disconnect()
