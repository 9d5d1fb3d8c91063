"""The in-process loopback bus: the client's requests answered by the simulator's handler, no socket."""

from __future__ import annotations

import pytest

from drivemap.runtime.errors import DeviceException, DriveTimeout
from drivemap.testing.loopback import LoopbackClient, loopback_bus
from tests.helpers_client import package, simulator


def test_values_written_are_read_back_and_reach_the_simulator() -> None:
    ev = package("ev")
    sim = simulator("ev", (1,))
    with loopback_bus(sim) as bus:
        drive = ev.Client(bus, unit=1)
        drive.digital_speed_ram[0].write(1000)
        assert drive.digital_speed_ram[0].read() == 1000
        assert sim.get("digital_speed_ram[0]", unit=1) == 1000


def test_requests_go_out_in_order_as_pymodbus_encodes_them() -> None:
    ev = package("ev")
    sim = simulator("ev", (1,))
    with loopback_bus(sim) as bus:
        drive = ev.Client(bus, unit=1)
        drive.digital_speed_ram[0].write(1000)
        drive.motor_state.read()
        client = bus.client
        assert isinstance(client, LoopbackClient)
        assert [frame[0] for _, frame in client.requests] == [0x06, 0x03]
        assert client.requests[0][1][1:3] == drive.digital_speed_ram[0].address.to_bytes(2, "big")


def test_a_device_exception_is_typed() -> None:
    ev = package("ev")
    sim = simulator("ev", (1,))
    with loopback_bus(sim) as bus:
        drive = ev.Client(bus, unit=1)
        with pytest.raises(DeviceException) as info:
            drive.read_registers("holding", 0x7F00, 1)
        assert info.value.code == 0x02


def test_an_unserved_unit_times_out_without_waiting() -> None:
    ev = package("ev")
    with loopback_bus(simulator("ev", (1,))) as bus, pytest.raises(DriveTimeout):
        ev.Client(bus, unit=7).motor_state.read()


def test_a_broadcast_write_reaches_every_unit_without_a_reply() -> None:
    ev = package("ev")
    sim = simulator("ev", (1, 2))
    with loopback_bus(sim) as bus:
        ev.Client.broadcast(bus).digital_speed_ram[0].write(1500)
        assert sim.get("digital_speed_ram[0]", unit=1) == 1500
        assert sim.get("digital_speed_ram[0]", unit=2) == 1500
