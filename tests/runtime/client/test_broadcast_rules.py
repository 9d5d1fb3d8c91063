"""Broadcast follows the map (nothing surprising reaches a device): one rule for the same wording in the manuals.

edx (004 §1.3), v2 (003 §2) and vfd1000 (002 §RTU frame format) only name address 0 as the
broadcast address: their 06h/10h broadcast is null with the reason, and ``Client.broadcast`` refuses
with that reason before anything is sent; the simulator ignores such broadcasts. ev prints a
Broadcast column (001 §2.1): its broadcast client works.
"""

from __future__ import annotations

import asyncio

import pytest

from drivemap.runtime.errors import BroadcastRead, NotBroadcastable
from tests.helpers_client import TIMEOUT, package, simulator, tcp_server

UNCLEAR = ("edx", "v2", "vfd1000")


@pytest.mark.parametrize("model", UNCLEAR)
def test_broadcast_client_refused_with_the_maps_reason(model: str) -> None:
    pkg = package(model)
    fc06 = pkg.SPEC.protocol.function(0x06)
    assert fc06.broadcast is None and fc06.broadcast_reason
    bus = pkg.Bus.tcp("127.0.0.1", 9, timeout=TIMEOUT)  # never connected: the refusal comes first
    with pytest.raises(NotBroadcastable) as info:
        pkg.Client.broadcast(bus)
    message = str(info.value)
    assert f"{model}: no broadcast client (unit 0)" in message
    assert "06h by broadcast: not stated in the manual" in message
    assert fc06.broadcast_reason in message
    assert bus.stats.transactions == 0 and not bus.client.connected
    assert not hasattr(pkg, "BroadcastClient")


@pytest.mark.parametrize("model", UNCLEAR)
async def test_async_broadcast_client_refused_with_the_maps_reason(model: str) -> None:
    pkg = package(model)
    bus = pkg.AsyncBus.tcp("127.0.0.1", 9, timeout=TIMEOUT)
    with pytest.raises(NotBroadcastable, match="not stated in the manual"):
        pkg.AsyncClient.broadcast(bus)
    assert bus.stats.transactions == 0


@pytest.mark.parametrize("model", UNCLEAR)
def test_simulator_ignores_a_broadcast_the_map_leaves_unknown(model: str) -> None:
    pkg = package(model)
    reg = next(r for r in pkg.SPEC.registers if r.access == "rw" and not r.enum and not r.bits and r.count == 1
               and r.max is None and not r.command_value)
    sim = simulator(model, (1, 2))
    before = [sim.get_raw(reg.name, unit) for unit in (1, 2)]
    pdu = bytes([0x06]) + reg.address.to_bytes(2, "big") + (before[0] ^ 0x0101).to_bytes(2, "big")
    assert sim.handle(0, pdu) is None
    assert [sim.get_raw(reg.name, unit) for unit in (1, 2)] == before


async def test_ev_broadcast_client_writes_and_refuses_reads() -> None:
    """001 §2.1 prints O for 06h/10h in the Broadcast column: the broadcast client exists."""
    ev = package("ev")
    with tcp_server("ev", (1, 2)) as (sim, host, port):
        async with ev.AsyncBus.tcp(host, port, timeout=TIMEOUT) as bus:
            bc = ev.AsyncClient.broadcast(bus)
            await bc.digital_speed_ram[0].write(1234)
            with pytest.raises(BroadcastRead):
                await bc.read_all()
            assert bus.stats.broadcasts == 1
            for _ in range(250):  # nobody answers a broadcast: wait until both units applied it
                if sim.get("digital_speed_ram[0]", 1) == sim.get("digital_speed_ram[0]", 2) == 1234:
                    break
                await asyncio.sleep(0.02)
            assert await ev.AsyncClient(bus, unit=2).digital_speed_ram[0].read() == 1234
    assert sim.get("digital_speed_ram[0]", 1) == sim.get("digital_speed_ram[0]", 2) == 1234
