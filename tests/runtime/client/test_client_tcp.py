"""AsyncClient over TCP and serial, many concurrent callers, and RTU over TCP (serial gateways)."""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from pymodbus.framer import FramerType
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import SimData, SimDevice

from drivemap.runtime.errors import DeviceException, DriveTimeout, NotBroadcastable, ValueOutOfRange
from drivemap.runtime.sim.serve import _request_classes
from tests.helpers_client import TIMEOUT, package, serial_server, simulator, tcp_server

ev = package("ev")
v2 = package("v2")


async def test_async_client_tcp() -> None:
    with tcp_server("ev") as (sim, host, port):
        async with ev.AsyncClient.tcp(host, port, unit=1, timeout=TIMEOUT) as drive:
            await drive.digital_speed_ram[0].write(1000)
            await drive.net_in.write(ev.NetIn.X0)
            sim.set("motor_state", int(ev.MotorState.RUN))
            snap = await drive.read(drive.motor_state, drive.motor_speed)
            assert snap.motor_state is ev.MotorState.RUN
            assert await drive.read_by_name("digital_speed_ram[0]") == 1000
            await drive.write_by_name("digital_speed_ram[1]", 1500)
            assert await drive.digital_speed_ram.read() == (1000, 1500) + tuple(
                sim.get(f"digital_speed_ram[{i}]") for i in range(2, 8))
            before = drive.stats.bytes_sent
            with pytest.raises(ValueOutOfRange):
                await drive.digital_speed_ram[0].write(10**9)
            assert drive.stats.bytes_sent == before
            await drive.net_x_input_function[0].write(ev.NetInputFunction(0))
            assert drive.pending_configuration == ("net_x_input_function[0]",)
            await drive.apply_configuration()
            assert drive.pending_configuration == ()
            new = await drive.read_modify_write(drive.net_in, lambda v: v | ev.NetIn.X1)
            assert new == ev.NetIn.X0 | ev.NetIn.X1


async def test_fifty_concurrent_callers_one_transaction_at_a_time() -> None:
    with tcp_server("ev", units=(1, 2)) as (sim, host, port):
        bus = ev.AsyncBus.tcp(host, port, timeout=1.0)
        async with bus:
            clients = [ev.AsyncClient(bus, unit=1), ev.AsyncClient(bus, unit=2)]
            in_flight = 0
            peak = 0
            execute = bus.client.execute

            async def tracked(no_response: bool, pdu: Any) -> Any:
                nonlocal in_flight, peak
                in_flight += 1
                peak = max(peak, in_flight)
                try:
                    return await execute(no_response, pdu)
                finally:
                    in_flight -= 1

            bus.client.execute = tracked

            async def caller(i: int) -> tuple[int, int]:
                drive = clients[i % 2]
                await drive.digital_speed_ram[i % 8].write(100 + i)
                return i, await drive.digital_speed_ram[i % 8].read()

            results = await asyncio.wait_for(asyncio.gather(*(caller(i) for i in range(50))), timeout=60)
            assert peak == 1
            assert len(results) == 50
            assert bus.stats.transactions == 100 and bus.stats.retries == 0
            # each caller reads back a value some caller wrote to the same unit and element
            for i, value in results:
                assert 100 <= value < 150 and (value - 100) % 8 == i % 8 and (value - 100) % 2 == i % 2


@pytest.mark.slow  # a virtual serial line (ptys) and its timeouts
async def test_async_serial_retry_and_timeout() -> None:
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 77)
        drive = ev.AsyncClient.serial(line.master_port, unit=1, baudrate=38400, parity="none", timeout=TIMEOUT,
                                      retries=1)
        async with drive:
            line.faults.drop("to_master")
            assert await drive.motor_speed.read() == 77
            assert drive.stats.retries == 1
            line.faults.drop("to_master", frames=2)
            with pytest.raises(DriveTimeout):
                await drive.motor_speed.read()


async def test_async_broadcast_and_vendor_exception() -> None:
    with serial_server("v2", "rtu", units=(1, 2)) as (sim, line):
        bus = v2.AsyncBus.serial(line.master_port, v2.SPEC.protocol.serial, baudrate=38400, parity="none", timeout=TIMEOUT)
        async with bus:
            with pytest.raises(NotBroadcastable, match="0 表一齐发送指令"):  # 06h/10h broadcast not stated
                v2.AsyncClient.broadcast(bus)
            one = v2.AsyncClient(bus, unit=1)
            sim.inject_exception(0x54)
            with pytest.raises(v2.EXCEPTIONS[0x54]) as info:
                await one.frequency_command.write(10.0)
            assert isinstance(info.value, DeviceException) and info.value.code == 0x54
            assert await one.loopback(0x0F0F) == 0x0F0F


@contextlib.contextmanager
def rtu_over_tcp_server(model: str) -> Iterator[tuple[Any, int]]:
    """The simulator behind a TCP port that speaks RTU frames (like a serial gateway)."""
    sim = simulator(model)
    ready = threading.Event()
    state: dict[str, Any] = {}

    async def serve() -> None:
        server = ModbusTcpServer([SimDevice(id=1, simdata=[SimData(0)])], framer=FramerType.RTU,
                                 address=("127.0.0.1", 0), ignore_missing_devices=True,
                                 custom_pdu=_request_classes(sim))
        await server.serve_forever(background=True)
        state["port"] = server.transport.sockets[0].getsockname()[1]
        state["stop"] = asyncio.Event()
        state["loop"] = asyncio.get_running_loop()
        ready.set()
        await state["stop"].wait()
        await server.shutdown()

    thread = threading.Thread(target=asyncio.run, args=(serve(),), daemon=True)
    thread.start()
    assert ready.wait(10)
    try:
        yield sim, state["port"]
    finally:
        state["loop"].call_soon_threadsafe(state["stop"].set)
        thread.join(10)


def test_rtu_over_tcp() -> None:
    with rtu_over_tcp_server("v2") as (sim, port):
        with v2.Client.rtu_over_tcp("127.0.0.1", port, unit=1, timeout=TIMEOUT) as drive:
            drive.frequency_command.write(60.0)
            assert sim.get("frequency_command") == 60.0
            assert drive.frequency_command.read() == 60.0
            assert drive.stats.bytes_sent == 8 + 8  # two 8-byte RTU frames, no MBAP header
