"""drivemap gateway -> OPC UA, read and written by asyncua's own client; drives are generated
simulators over TCP. Only 127.0.0.1."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua  # noqa: E402

from tests.helpers_client import tcp_server
from tests.helpers_gateway import free_port, running, until, write_config

NS = "urn:drivemap:test"


def opcua_config(tmp_path: Path, sim_port: int, opc_port: int, security: str = "") -> str:
    return f"""\
gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc_port}/drivemap/
  namespace: {NS}
  users:
    - {{name: operator, password: secret}}
    - {{name: viewer, password: look, write: false}}
{security}buses:
  - name: line1
    tcp: 127.0.0.1:{sim_port}
    timeout: 0.3
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2, writable: [communication_setting, control_command]}}
"""


async def _node(client: Client, *path: str) -> Any:
    idx = await client.get_namespace_index(NS)
    return await client.nodes.objects.get_child([f"{idx}:{p}" for p in path])


async def _status_of_write(node: Any, value: Any, vtype: Any) -> str:
    try:
        await node.write_value(ua.DataValue(ua.Variant(value, vtype)))
    except ua.UaStatusCodeError as exc:
        return type(exc).__name__
    return "Good"


async def test_opcua_address_space_values_and_checked_writes(tmp_path: Path) -> None:
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (sim, _, port):
        cfg = write_config(tmp_path, opcua_config(tmp_path, port, opc_port))
        async with running(cfg) as gw:
            url = f"opc.tcp://127.0.0.1:{opc_port}/drivemap/"
            sim.set("communication_setting", -12.34)
            sim.set("inverter_state", 3)
            await _anonymous_reads_values_units_ranges_and_access(url, gw)
            await _only_the_operator_writes_and_every_write_is_checked(url, gw, sim)
            await _a_wrong_password_is_refused(url)


async def _anonymous_reads_values_units_ranges_and_access(url: str, gw: Any) -> None:
    """An anonymous client reads values, engineering units, ranges, enum names and access levels; its
    writes are denied."""
    async with Client(url) as anonymous:
        setting = await _node(anonymous, "plant", "pump1", "communication_setting")
        online = await _node(anonymous, "plant", "pump1", "Online")
        await until(lambda: gw.devices["pump1"].online, what="online")
        values: dict[str, Any] = {}

        async def refresh() -> None:
            values["setting"] = await setting.read_value()
            values["online"] = await online.read_value()
        for _ in range(200):
            await refresh()
            if values["setting"] == pytest.approx(-12.34) and values["online"] is True:
                break
            await asyncio.sleep(0.05)
        assert values == {"setting": pytest.approx(-12.34), "online": True}
        eu = await (await setting.get_child("0:EngineeringUnits")).read_value()
        assert eu.DisplayName.Text == "%"
        rng = await (await setting.get_child("0:EURange")).read_value()
        assert (rng.Low, rng.High) == (-100.0, 100.0)
        state = await _node(anonymous, "plant", "pump1", "inverter_state")
        enum_values = await (await state.get_child("0:EnumValues")).read_value()
        assert [e.DisplayName.Text for e in enum_values][:3] == ["FORWARD_RUNNING", "REVERSE_RUNNING", "STANDBY"]
        assert await state.read_value() == 3
        read_only = (await state.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
        read_write = (await setting.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
        assert read_only == ua.AccessLevel.CurrentRead.mask
        assert read_write == ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask
        assert await _status_of_write(setting, 10.0, ua.VariantType.Double) == "BadUserAccessDenied"


async def _only_the_operator_writes_and_every_write_is_checked(url: str, gw: Any, sim: Any) -> None:
    """A viewer's write is denied; the operator's out-of-range and read-only writes are refused before the bus, its
    good writes reach the drive."""
    writes_before = dict(gw.lines[0].bus.stats.by_function)
    viewer = Client(url)
    viewer.set_user("viewer")
    viewer.set_password("look")
    async with viewer:
        node = await _node(viewer, "plant", "pump1", "communication_setting")
        assert await _status_of_write(node, 10.0, ua.VariantType.Double) == "BadUserAccessDenied"
    operator = Client(url)
    operator.set_user("operator")
    operator.set_password("secret")
    async with operator:
        node = await _node(operator, "plant", "pump1", "communication_setting")
        assert await _status_of_write(node, 150.0, ua.VariantType.Double) == "BadOutOfRange"
        state = await _node(operator, "plant", "pump1", "inverter_state")
        assert await _status_of_write(state, 1, ua.VariantType.Int64) == "BadNotWritable"
        assert gw.lines[0].bus.stats.by_function.get(0x06, 0) == writes_before.get(0x06, 0)
        assert await _status_of_write(node, 42.5, ua.VariantType.Double) == "Good"
        assert sim.get("communication_setting") == pytest.approx(42.5)
        command = await _node(operator, "plant", "pump1", "control_command")
        assert await _status_of_write(command, 5, ua.VariantType.UInt16) == "Good"  # STOP
        assert await _status_of_write(command, 99, ua.VariantType.UInt16) == "BadOutOfRange"


async def _a_wrong_password_is_refused(url: str) -> None:
    bad = Client(url)
    bad.set_user("operator")
    bad.set_password("wrong")
    with pytest.raises(ua.UaStatusCodeError):
        async with bad:
            pass
