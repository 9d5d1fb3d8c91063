"""Connection floods do not lock an operator out of the OPC UA server: raw TCP connections and anonymous
sessions are bounded (per source, in all, anonymous sessions), a handshake that never ends is closed,
and a user's login always finds room. Bounded loops, every connection on 127.0.0.0/8 (the flood comes
from 127.0.0.2 and up, the operator from 127.0.0.1)."""

from __future__ import annotations

import asyncio
import contextlib
import time
from pathlib import Path
from typing import Any

import pytest

from tests.helpers_client import tcp_server
from tests.helpers_gateway import free_port, running, until, write_config

asyncua = pytest.importorskip("asyncua", reason="OPC UA is the optional extra drivemap[opcua] (in the test extra)")
from asyncua import Client  # noqa: E402

NS = "urn:drivemap:limits"


def config(vfd: int, opc: int, limits: str) -> str:
    return f"""\
gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc}/drivemap/
  namespace: {NS}
  users:
    - {{name: operator, password: secret}}
{limits}buses:
  - name: line1
    tcp: 127.0.0.1:{vfd}
    timeout: 0.3
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2}}
"""


async def flood(port: int, count: int, sources: int) -> list[asyncio.StreamWriter]:
    """``count`` raw TCP connections that never speak OPC UA, from 127.0.0.2 .. 127.0.0.(sources+1)."""
    held: list[asyncio.StreamWriter] = []
    for n in range(count):
        source = f"127.0.0.{2 + n % sources}"
        with contextlib.suppress(OSError):
            _, writer = await asyncio.wait_for(
                asyncio.open_connection("127.0.0.1", port, local_addr=(source, 0)), 5)
            held.append(writer)
    return held


async def operator_reads(url: str, timeout: float = 20.0) -> Any:
    client = Client(url, timeout=5)
    client.set_user("operator")
    client.set_password("secret")
    start = time.monotonic()
    async with client:
        idx = await client.get_namespace_index(NS)
        node = await client.nodes.objects.get_child([f"{idx}:plant", f"{idx}:pump1", f"{idx}:Online"])
        value = await node.read_value()
    assert time.monotonic() - start < timeout
    return value


def close(writers: list[asyncio.StreamWriter]) -> None:
    for w in writers:
        w.close()


async def test_a_thousand_raw_connections_leave_room_for_the_operator(tmp_path: Path) -> None:
    opc = free_port()
    with tcp_server("vfd1000", (1,)) as (_, _, port):
        cfg = write_config(tmp_path, config(port, opc, ""))  # the default limits
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            held = await flood(opc, 1000, 100)
            try:
                clients = gw.opcua.server.bserver.clients
                assert len(clients) <= cfg.opcua.limits.max_connections
                assert await operator_reads(f"opc.tcp://127.0.0.1:{opc}/drivemap/") is True
            finally:
                close(held)


async def test_per_source_anonymous_and_handshake_limits(tmp_path: Path) -> None:
    opc = free_port()
    url = f"opc.tcp://127.0.0.1:{opc}/drivemap/"
    limits = ("  limits: {max_connections: 12, per_source: 3, anonymous_sessions: 2, reserve: 3, "
              "handshake_timeout: 1.5}\n")
    with tcp_server("vfd1000", (1,)) as (_, _, port):
        cfg = write_config(tmp_path, config(port, opc, limits))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            clients = gw.opcua.server.bserver.clients
            one_source = await flood(opc, 10, 1)  # 3 held at most from one address
            await asyncio.sleep(0.2)
            assert sum(1 for c in clients if c.peer_name[0] == "127.0.0.2") == 3
            many = await flood(opc, 40, 20)
            await asyncio.sleep(0.2)
            assert len(clients) <= 12 - 3  # the reserve stays free of connections without a user
            assert await operator_reads(url) is True
            await asyncio.sleep(2.0)  # past the handshake timeout: the silent connections are gone
            assert not [c for c in clients if c.peer_name[0] != "127.0.0.1"]
            close(one_source + many)
            anonymous = [Client(url, timeout=5) for _ in range(3)]
            await anonymous[0].connect()
            await anonymous[1].connect()
            with pytest.raises(Exception):  # noqa: B017, PT011 - the third anonymous session is refused
                await anonymous[2].connect()
            try:
                assert await operator_reads(url) is True  # a user still gets in
            finally:
                for c in anonymous[:2]:
                    await c.disconnect()
