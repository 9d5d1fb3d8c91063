"""Commands are parsed strictly and written exactly, or refused with the reason: no coercion, no rounding,
bounded payloads (the gateway's own checks, before anything is queued; nothing here touches a bus)."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest

from drivemap.gateway.device import Device
from drivemap.gateway.payload import MAX_PAYLOAD_BYTES
from drivemap.gateway.service import Gateway
from drivemap.runtime.client.values.steps import shortest_f32
from drivemap.runtime.errors import InvalidValue, ReadOnlyRegister, ValueOutOfRange
from tests.helpers_gateway import write_config

ROOT = Path(__file__).resolve().parents[2]
ALLKINDS = ROOT / "tests/maps/allkinds.yaml"


@pytest.fixture(scope="module")
def devices(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Device]:
    folder = tmp_path_factory.mktemp("strict")
    cfg = write_config(folder, f"""\
gateway: 1
name: plant
mqtt: {{host: 127.0.0.1}}
buses:
  - name: line1
    tcp: 127.0.0.1:1
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, writable: [communication_setting, control_command, parameter_0008]}}
      - {{name: conveyor, model: ev, unit: 2, writable: [net_in, digital_speed, alarm_reset, rs485_timeout]}}
      - {{name: meter, model: sdm630, unit: 3, writable: [demand_period]}}
      - {{name: io, map: {ALLKINDS}, unit: 4, writable: [run, setpoint]}}
""")


    async def made() -> dict[str, Device]:  # an AsyncBus is made in a loop; parsing commands needs no I/O
        return Gateway(cfg).devices

    return asyncio.run(made())


def refused(device: Device, target: str, payload: str | bytes) -> BaseException:
    with pytest.raises((InvalidValue, ValueOutOfRange, ReadOnlyRegister)) as info:
        device.command(target, payload)
    return info.value


@pytest.mark.parametrize("payload", ['{"X0": 2}', '{"X1": -1}', '{"X0": 1.0}', '{"X0": "yes"}', '{"X0": null}',
                                     "70000", "-1", str(2**40)])
def test_bit_fields_take_only_bits(devices: dict[str, Device], payload: str) -> None:
    refused(devices["conveyor"], "net_in", payload)


def test_bit_fields_written_exactly(devices: dict[str, Device]) -> None:
    conveyor = devices["conveyor"]
    assert conveyor.command("net_in", '{"X0": true, "X1": 1, "X2": false, "X3": 0}').raw == 0b11


def test_values_between_steps_are_refused_not_rounded(devices: dict[str, Device]) -> None:
    pump = devices["pump1"]
    error = refused(pump, "communication_setting", "12.345")
    assert "12.34" in str(error) and "12.35" in str(error) and "refused" in str(error)
    assert pump.command("communication_setting", "12.35").raw == 1235
    assert pump.command("communication_setting", "-0.01").raw == -1


def test_f32_takes_what_a_single_holds(devices: dict[str, Device]) -> None:
    io = devices["io"]  # setpoint: an f32 without a value set
    assert io.command("setpoint", "15").raw is not None
    assert io.command("setpoint", "30.2").raw is not None  # the f32 nearest 30.2 prints as 30.2
    assert "not representable as f32" in str(refused(io, "setpoint", "30.123456789"))
    assert "not one of the allowed values" in str(refused(devices["meter"], "demand_period", "30.2"))  # a value set
    assert shortest_f32(230.1999969482422) == 230.2


@pytest.mark.parametrize("payload", ["1.5", "true", "NaN", "Infinity", "1e400", '"10"', "[10]", "1_0", "\u0661"])
def test_integers_exactly(devices: dict[str, Device], payload: str) -> None:
    refused(devices["conveyor"], "rs485_timeout", payload)


def test_whole_float_is_an_integer(devices: dict[str, Device]) -> None:
    assert devices["conveyor"].command("rs485_timeout", "10.0").raw == 10


@pytest.mark.parametrize("index", ["\u0661", "\uff10", "-1", "0x1", " 1", "1.0"])
def test_array_indexes_are_ascii_digits(devices: dict[str, Device], index: str) -> None:
    refused(devices["conveyor"], f"digital_speed/{index}", "100")


def test_array_index_in_range(devices: dict[str, Device]) -> None:
    conveyor = devices["conveyor"]
    assert conveyor.command("digital_speed/7", "100").target == "digital_speed[7]"
    with pytest.raises(Exception, match="digital_speed"):
        conveyor.command("digital_speed/8", "100")


@pytest.mark.parametrize(("payload", "raw"), [("true", 1), ("ON", 1), ("on", 1), ("1", 1), ("False", 0), ("off", 0),
                                              ("0", 0), ('"true"', 1)])
def test_bool_words(devices: dict[str, Device], payload: str, raw: int) -> None:
    assert devices["io"].command("run", payload).raw == raw


@pytest.mark.parametrize("payload", ["yes", "2", "-1", "1.0", "", "\u0661", "tru", "[true]", '{"run": true}'])
def test_bool_refuses_everything_else(devices: dict[str, Device], payload: str) -> None:
    refused(devices["io"], "run", payload)


def test_enum_values_are_ascii(devices: dict[str, Device]) -> None:
    pump = devices["pump1"]
    assert int(pump.command("control_command", "FORWARD_RUNNING").raw or 0) == 1
    for payload in ("\u0661", '"1"', "SIDEWAYS", "UNKNOWN_0", "1.0"):
        refused(pump, "control_command", payload)


def test_payloads_bounded_before_parsing(devices: dict[str, Device]) -> None:
    pump = devices["pump1"]
    assert "longer than" in str(refused(pump, "communication_setting", b"1" * (MAX_PAYLOAD_BYTES + 1)))
    assert "nests deeper" in str(refused(pump, "communication_setting", "[" * 1000))
    assert "not UTF-8" in str(refused(pump, "communication_setting", b"\xff\xfe"))
    refused(pump, "communication_setting", b"1\x00")


def test_press_only_presses(devices: dict[str, Device]) -> None:
    conveyor = devices["conveyor"]
    assert conveyor.command("alarm_reset", "PRESS").raw == 1
    for payload in ("", " ", "press me", "2"):
        refused(conveyor, "alarm_reset", payload)


def test_only_listed_registers_take_commands(devices: dict[str, Device]) -> None:
    error = refused(devices["pump1"], "pid_setting", "10")
    assert isinstance(error, ReadOnlyRegister) and "writable" in str(error)
    refused(devices["meter"], "network_node", "9")  # published (by default), writable in the map, not listed


def test_f32_values_publish_as_their_shortest_decimal(devices: dict[str, Device]) -> None:
    meter: Any = devices["meter"]
    assert meter.to_json("phase_1_voltage", 230.1999969482422) == 230.2
    assert meter.to_json("phase_1_voltage", 0.10000000149011612) == 0.1
