"""The gateway on the issue-14 types, with real parts: a broker process, an independent subscriber,
asyncua's own client, simulators over TCP (sdm630: f32 input registers; Fronius: strings, u64,
scale registers, not-available values; the synthetic allkinds map: coils, discrete inputs)."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from drivemap.compiler import compile_map
from drivemap.model.spec import spec_from_model
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.runtime.sim.simulator import Simulator
from tests.helpers_client import tcp_server
from tests.helpers_gateway import Broker, Subscriber, free_port, publish, running, until, write_config

ALLKINDS = Path(__file__).resolve().parents[1] / "maps" / "allkinds.yaml"


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path).start()
    yield b
    b.stop()


@contextlib.contextmanager
def allkinds_server() -> Iterator[tuple[Any, int]]:
    sim = Simulator(spec_from_model(compile_map(ALLKINDS)), [1])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        yield sim, server.address[1]


def config(port: int | None, fronius: int, sdm: int, kinds: int, opc: int | None = None) -> str:
    mqtt = f"mqtt: {{host: 127.0.0.1, port: {port}, reconnect: {{min: 0.3, max: 1}}}}\n" if port else ""
    opcua = f"opcua: {{endpoint: 'opc.tcp://127.0.0.1:{opc}/drivemap/', namespace: 'urn:drivemap:test', " \
            "anonymous_writes: true}\n" if opc else ""
    return f"""\
gateway: 1
name: plant
{mqtt}{opcua}buses:
  - name: inverter
    tcp: 127.0.0.1:{fronius}
    timeout: 0.5
    devices:
      - {{name: inv, model: fronius_symo_hybrid, unit: 1, interval: 0.2,
         publish: [manufacturer, ac_current, ac_current_a, site_energy_total, max_power_setting],
         writable: [max_power_setting]}}
  - name: meter
    tcp: 127.0.0.1:{sdm}
    timeout: 0.5
    devices:
      - {{name: meter, model: sdm630, unit: 1, interval: 0.2, publish: [phase_1_voltage, total_kwh]}}
  - name: io
    tcp: 127.0.0.1:{kinds}
    timeout: 0.5
    devices:
      - {{name: io, map: {ALLKINDS}, unit: 1, interval: 0.2, publish: [run, door_open, device_name, temperature],
         writable: [run, device_name]}}
"""


def _preset(fronius: Any, sdm: Any, kinds: Any) -> None:
    fronius.set("manufacturer", "Fronius")
    fronius.set("ac_current_sf", -2)
    fronius.set_raw("ac_current", 1234)
    fronius.set_raw("ac_current_a", 0xFFFF)
    fronius.set("site_energy_total", 2**40 + 5)
    fronius.set("max_power_setting_sf", 1)
    sdm.set("phase_1_voltage", 230.5)
    kinds.set_raw("temperature", -0x8000)
    kinds.set("door_open", True)


async def test_mqtt_values_discovery_and_commands(tmp_path: Path, broker: Broker) -> None:
    with tcp_server("fronius_symo_hybrid") as (fsim, _, fport), tcp_server("sdm630") as (ssim, _, sport), \
            allkinds_server() as (ksim, kport):
        _preset(fsim, ssim, ksim)
        cfg = write_config(tmp_path, config(broker.port, fport, sport, kport))
        async with Subscriber(broker.port, ("drivemap/#", "homeassistant/#")) as sub, running(cfg):
            await until(lambda: sub.text("drivemap/inv/manufacturer") == "Fronius", what="string")
            await until(lambda: sub.text("drivemap/inv/ac_current") == "12.34", what="scaled value")
            assert sub.text("drivemap/inv/ac_current_a") == "null"  # not available
            assert sub.text("drivemap/inv/site_energy_total") == str(2**40 + 5)
            await until(lambda: sub.text("drivemap/meter/phase_1_voltage") == "230.5", what="f32")
            await until(lambda: sub.text("drivemap/io/door_open") == "true", what="discrete input")
            assert sub.text("drivemap/io/run") == "false" and sub.text("drivemap/io/temperature") == "null"
            # discovery: a switch per coil, a binary sensor per discrete input, text sensors for strings
            run = json.loads(await until(lambda: sub.text("homeassistant/switch/drivemap_plant_io/run/config"),
                                         what="coil switch"))
            assert (run["payload_on"], run["state_on"], run["command_topic"]) == ("true", "true", "drivemap/io/run/set")
            door = json.loads(sub.text("homeassistant/binary_sensor/drivemap_plant_io/door_open/config") or "{}")
            assert door["payload_on"] == "true" and door["state_topic"] == "drivemap/io/door_open"
            name = json.loads(sub.text("homeassistant/sensor/drivemap_plant_inv/manufacturer/config") or "{}")
            assert "state_class" not in name and "unit_of_measurement" not in name
            current = json.loads(sub.text("homeassistant/sensor/drivemap_plant_inv/ac_current_a/config") or "{}")
            assert current["value_template"] == "{{ 'None' if value == 'null' else value }}"
            # commands: a coil, a string, a value scaled by its scale register
            await publish(broker.port, "drivemap/io/run/set", "ON")
            await until(lambda: ksim.get("run") is True, what="coil written")
            await publish(broker.port, "drivemap/io/device_name/set", "MIXER")
            await until(lambda: ksim.get("device_name") == "MIXER", what="string written")
            await publish(broker.port, "drivemap/inv/max_power_setting/set", "5005")  # between steps of 10
            await until(lambda: sub.messages("drivemap/inv/error"), what="refused")
            refused = json.loads(sub.messages("drivemap/inv/error")[-1])
            assert refused["ok"] is False and "5000" in refused["message"] and "5010" in refused["message"] and "refused" in refused["message"], refused
            await publish(broker.port, "drivemap/inv/max_power_setting/set", "5000")
            await until(lambda: fsim.get_raw("max_power_setting") == 500, what="scaled write (x 10^1)")
            await until(lambda: sub.text("drivemap/io/run") == "true", what="coil read back")


async def test_opcua_types_of_floats_strings_bools_and_counters(tmp_path: Path) -> None:
    from asyncua import Client, ua

    opc = free_port()
    with tcp_server("fronius_symo_hybrid") as (fsim, _, fport), tcp_server("sdm630") as (ssim, _, sport), \
            allkinds_server() as (ksim, kport):
        _preset(fsim, ssim, ksim)
        cfg = write_config(tmp_path, config(None, fport, sport, kport, opc))
        async with running(cfg):
            async with Client(f"opc.tcp://127.0.0.1:{opc}/drivemap/") as client:
                idx = await client.get_namespace_index("urn:drivemap:test")

                async def node(*path: str) -> Any:
                    return await client.nodes.objects.get_child([f"{idx}:{p}" for p in ("plant", *path)])

                async def value(*path: str) -> Any:
                    return await (await node(*path)).read_data_value(raise_on_bad_status=False)

                async def settled(path: tuple[str, ...], check: Any) -> Any:
                    async def poll() -> Any:
                        dv = await value(*path)
                        return dv if check(dv) else None
                    import asyncio
                    for _ in range(200):
                        dv = await poll()
                        if dv is not None:
                            return dv
                        await asyncio.sleep(0.05)
                    raise AssertionError(f"{path}: {await value(*path)}")

                text = await settled(("inv", "manufacturer"), lambda dv: dv.Value.Value == "Fronius")
                assert text.Value.VariantType == ua.VariantType.String
                volts = await settled(("meter", "phase_1_voltage"), lambda dv: dv.Value.Value == 230.5)
                assert volts.Value.VariantType == ua.VariantType.Float
                energy = await settled(("inv", "site_energy_total"), lambda dv: dv.Value.Value == 2**40 + 5)
                assert energy.Value.VariantType == ua.VariantType.UInt64
                amps = await settled(("inv", "ac_current"), lambda dv: dv.Value.Value == 12.34)
                assert amps.Value.VariantType == ua.VariantType.Double
                door = await settled(("io", "door_open"), lambda dv: dv.Value.Value is True)
                assert door.Value.VariantType == ua.VariantType.Boolean
                missing = await settled(("inv", "ac_current_a"), lambda dv: not dv.StatusCode.is_good())
                assert missing.StatusCode.value == ua.StatusCodes.BadNoData
                run = await node("io", "run")
                await run.write_value(ua.DataValue(ua.Variant(True, ua.VariantType.Boolean)))
                assert ksim.get("run") is True
                label = await node("io", "device_name")
                await label.write_value(ua.DataValue(ua.Variant("FAN", ua.VariantType.String)))
                assert ksim.get("device_name") == "FAN"
