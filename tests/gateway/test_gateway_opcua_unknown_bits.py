"""A bit field whose enumerated field holds a value the map does not list (``UNKNOWN_<n>`` in MQTT)
reaches OPC UA as the raw bits the device sent, not with that field zeroed (found by node-opcua)."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from tests.helpers_client import tcp_server
from tests.helpers_gateway import free_port, running, until, write_config

pytest.importorskip("asyncua", reason="the opcua extra is not installed")
from asyncua import Client  # noqa: E402


async def test_undocumented_bit_field_value_keeps_its_bits(tmp_path: Path) -> None:
    opc = free_port()
    with tcp_server("ev", (1,)) as (sim, _, port):
        sim.set_raw("rs485_comm_settings", 0b1111)  # parity 3: not a value of the map's parity enum
        cfg = write_config(tmp_path, f"""\
gateway: 1
name: plant
opcua: {{endpoint: "opc.tcp://127.0.0.1:{opc}/drivemap/", namespace: "urn:drivemap:bits"}}
buses:
  - name: line
    tcp: 127.0.0.1:{port}
    devices:
      - {{name: conveyor, model: ev, unit: 1, interval: 0.2}}
""")
        async with running(cfg) as gw:
            await until(lambda: gw.devices["conveyor"].online, what="online")
            async with Client(f"opc.tcp://127.0.0.1:{opc}/drivemap/") as client:
                idx = await client.get_namespace_index("urn:drivemap:bits")
                node = await client.nodes.objects.get_child([f"{idx}:plant", f"{idx}:conveyor",
                                                             f"{idx}:rs485_comm_settings"])
                for _ in range(50):  # until the first poll has reached the variable
                    value = await node.read_value()
                    if value:
                        break
                    await asyncio.sleep(0.1)
                assert value == 0b1111
