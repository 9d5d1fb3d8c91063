"""OPC UA as a client sees it: exact writes or a Bad status (no truncation, no rounding), variant types
that follow the register type, UNECE unit ids, write-only registers that are not readable, access
levels that follow the gateway's writable list, and a UserAccessLevel per session. asyncua's client
against the gateway and a simulator on 127.0.0.1."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.helpers_client import tcp_server
from tests.helpers_gateway import free_port, running, until, write_config

asyncua = pytest.importorskip("asyncua", reason="OPC UA is the optional extra drivemap[opcua] (in the test extra)")
from asyncua import Client, ua  # noqa: E402

from drivemap.gateway.opcua_types import unit_id  # noqa: E402

NS = "urn:drivemap:exact"


def config(vfd: int, ev: int, opc: int) -> str:
    return f"""\
gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc}/drivemap/
  namespace: {NS}
  anonymous_writes: false
  users:
    - {{name: operator, password: secret}}
buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.3
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2, writable: [communication_setting, control_command]}}
  - name: line2
    tcp: 127.0.0.1:{ev}
    timeout: 0.3
    devices:
      - {{name: conveyor, model: ev, unit: 1, interval: 0.2, writable: [net_in]}}
"""


async def status(node: Any, value: Any, vtype: Any) -> str:
    try:
        await node.write_value(ua.DataValue(ua.Variant(value, vtype)))
    except ua.UaStatusCodeError as exc:
        return type(exc).__name__
    return "Good"


async def test_opcua_exact_types_units_and_access(tmp_path: Path) -> None:
    opc = free_port()
    url = f"opc.tcp://127.0.0.1:{opc}/drivemap/"
    with tcp_server("vfd1000", (1,)) as (vsim, _, vport), tcp_server("ev", (1,)) as (esim, _, eport):
        cfg = write_config(tmp_path, config(vport, eport, opc))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online and gw.devices["conveyor"].online, what="online")
            operator = Client(url)
            operator.set_user("operator")
            operator.set_password("secret")
            async with operator, Client(url) as anonymous:
                idx = await operator.get_namespace_index(NS)

                async def node(client: Client, *path: str) -> Any:
                    return await client.nodes.objects.get_child([f"{idx}:{p}" for p in ("plant", *path)])

                bits = await node(operator, "conveyor", "net_in")
                writes = dict(gw.lines[1].bus.stats.by_function)
                for value in (2**40, -1, 0x10000):  # another type than the variable's UInt16: refused as such
                    assert await status(bits, value, ua.VariantType.Int64) == "BadTypeMismatch", value
                assert dict(gw.lines[1].bus.stats.by_function) == writes  # nothing truncated reached the drive
                assert await status(bits, 0b101, ua.VariantType.UInt16) == "Good"
                assert esim.get_raw("net_in") == 0b101
                setting = await node(operator, "pump1", "communication_setting")
                assert await status(setting, 12.345, ua.VariantType.Double) == "BadOutOfRange"
                assert await status(setting, float("nan"), ua.VariantType.Double) != "Good"
                assert await status(setting, 12.35, ua.VariantType.Double) == "Good"
                assert vsim.get_raw("communication_setting") == 1235
                # variant types follow the register type
                state = await node(operator, "pump1", "inverter_state")
                assert (await state.read_data_type_as_variant_type()) == ua.VariantType.UInt16
                assert (await setting.read_data_type_as_variant_type()) == ua.VariantType.Double
                # EngineeringUnits: the UNECE common code of % (P1)
                eu = await (await setting.get_child(["0:EngineeringUnits"])).read_value()
                assert eu.UnitId == unit_id("%") == (ord("P") << 8) | ord("1")
                assert eu.NamespaceUri == "http://www.opcfoundation.org/UA/units/un/cefact"
                # a write-only register is not readable: no Good 0
                command = await node(operator, "pump1", "control_command")
                level = (await command.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
                assert level == ua.AccessLevel.CurrentWrite.mask
                read = await command.read_attribute(ua.AttributeIds.Value, raise_on_bad_status=False)
                assert read.StatusCode.value == ua.StatusCodes.BadNotReadable
                # a register the gateway does not take commands for is read-only, whatever the map says
                pid = await node(operator, "pump1", "pid_setting")
                pid_level = (await pid.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
                assert pid_level == ua.AccessLevel.CurrentRead.mask
                assert await status(pid, 10.0, ua.VariantType.Double) != "Good"
                # UserAccessLevel: what each session may do
                rw = ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask
                mine = (await setting.read_attribute(ua.AttributeIds.UserAccessLevel)).Value.Value
                theirs = await (await node(anonymous, "pump1", "communication_setting")).read_attribute(
                    ua.AttributeIds.UserAccessLevel)
                assert (mine, theirs.Value.Value) == (rw, ua.AccessLevel.CurrentRead.mask)
