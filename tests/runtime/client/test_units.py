"""Unit ids: the map's settable range plus units a port fixes (EV's RS-232 port answers as 17)."""

from __future__ import annotations

import pytest

from drivemap.runtime.client.transport.bus import Bus
from drivemap.runtime.errors import InvalidValue
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap_models.ev import Client
from drivemap_models.ev.simulator import Simulator


def test_fixed_port_unit_is_valid_and_answers() -> None:
    sim = Simulator([17])
    sim.set("motor_speed", 1234, unit=17)
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        with Client.tcp(host, port=port, unit=17, timeout=1.0) as drive:
            assert drive.motor_speed.read() == 1234


@pytest.mark.parametrize("unit", [0, 16, 18, 255])
def test_units_outside_the_map_are_refused_before_sending(unit: int) -> None:
    with pytest.raises(InvalidValue):
        Client(Bus.tcp("127.0.0.1", 1), unit=unit)
    with pytest.raises(ValueError):
        Simulator([unit])
