"""Value sets (``values:``): a write outside the set is refused before the wire by the client and the
CLI, answered out_of_range by the simulator, and exported as selects, docs and CSV (sdm630's codes)."""

from __future__ import annotations

import struct
from typing import Any

import jinja2
import pytest

from drivemap.compiler import load_model
from drivemap.runtime.errors import NotAllowedValue, ValueOutOfRange
from tests.exporter_helpers import parse, render
from tests.helpers_client import package, simulator, tcp_server
from tests.helpers_live import no_traceback, run


def test_the_model_and_spec_carry_sdm630s_value_sets() -> None:
    model = load_model("maps/sdm630.yaml")
    assert [v.value for v in model.register("demand_period").value_set] == [0, 5, 8, 10, 15, 20, 30, 60]
    assert [(v.value, v.label) for v in model.register("system_type").value_set] == [
        (1.0, "1p2w"), (2.0, "3p3w"), (3.0, "3p4w")]
    spec = package("sdm630").SPEC.register("network_baud_rate")
    assert spec.values[2] == (2.0, "9600 baud")
    assert model.register("phase_1_voltage").values == ()  # no set: any value


def test_client_refuses_a_value_outside_the_set_before_the_wire() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        with package("sdm630").Client.tcp(host, port, 1, timeout=2.0) as client:
            for name, value in (("demand_period", 7), ("system_type", 2.5), ("pulse1_width", 150)):
                with pytest.raises(NotAllowedValue) as info:
                    getattr(client, name).write(value)
                assert isinstance(info.value, ValueOutOfRange)  # the gateway's existing handler catches it
                assert client.stats.transactions == 0
            assert "allowed values 0 (demand shows the current value), 5, 8, 10, 15, 20, 30, 60" in str(
                _refusal(client.demand_period, 7))
            assert _refusal(client.system_type, 1.5).allowed == (1.0, 2.0, 3.0)
            client.demand_period.write(15)
            client.system_type.write(2)
            assert sim.get("demand_period") == 15.0 and client.system_type.read() == 2.0


def _refusal(accessor: Any, value: float) -> NotAllowedValue:
    with pytest.raises(NotAllowedValue) as info:
        accessor.write(value)
    return info.value


async def test_async_client_refuses_it_too() -> None:
    with tcp_server("sdm630") as (_sim, host, port):
        async with package("sdm630").AsyncClient.tcp(host, port, 1, timeout=2.0) as client:
            with pytest.raises(NotAllowedValue):
                await client.network_baud_rate.write(2.5)
            assert client.stats.transactions == 0


def test_simulator_answers_a_value_outside_the_set_out_of_range() -> None:
    sim = simulator("sdm630")
    write = bytes.fromhex("1000020002 04".replace(" ", ""))
    assert sim.handle(1, write + struct.pack(">f", 7.0)) == b"\x90\x03"
    assert sim.get("demand_period") == 60.0  # unchanged (the default)
    assert sim.handle(1, write + struct.pack(">f", 30.0)) == bytes.fromhex("1000020002")
    assert sim.get("demand_period") == 30.0


def test_cli_write_refuses_it_naming_the_allowed_values() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        bad = run("write", "sdm630", "--tcp", f"{host}:{port}", "system_type=2.5")
        good = run("write", "sdm630", "--tcp", f"{host}:{port}", "system_type=3")
        assert sim.get("system_type") == 3.0
    no_traceback(bad)
    assert bad.returncode == 1
    assert "system_type: 2.5 is not one of the allowed values 1 (1p2w), 2 (3p3w), 3 (3p4w)" in bad.stderr
    assert good.returncode == 0, good.stderr


def test_read_shows_the_label_of_the_value() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        sim.set("network_baud_rate", 3)
        proc = run("read", "sdm630", "--tcp", f"{host}:{port}", "network_baud_rate")
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if "network_baud_rate" in line)
    assert "19200 baud" in row


def test_home_assistant_select_writes_the_words_of_the_chosen_value() -> None:
    doc = parse("homeassistant", render(load_model("maps/sdm630.yaml"), "homeassistant"))
    selects = {s["unique_id"]: s for block in doc["template"] for s in block.get("select", ())}
    select = selects["sdm630_system_type_select"]
    env = jinja2.Environment(autoescape=False)
    options = env.from_string(select["options"]).render()
    assert options == "['1p2w', '3p3w', '3p4w']"
    for state, option in (("3.0", "3p4w"), ("1", "1p2w"), ("2.5", "")):
        assert env.from_string(select["state"]).render(states=lambda entity, state=state: state) == option
    action = select["select_option"][0]
    assert action["action"] == "modbus.write_register" and action["data"]["address"] == 10
    value = env.from_string(action["data"]["value"]).render(option="3p3w")
    assert value == str(list(struct.unpack(">HH", struct.pack(">f", 2.0))))  # 10h with the f32 of 2
    assert "sdm630_phase_1_voltage_select" not in selects  # a reading without a set: no select


def test_esphome_select_maps_options_to_the_f32_bit_patterns() -> None:
    doc = parse("esphome", render(load_model("maps/sdm630.yaml"), "esphome"))
    select = next(s for s in doc["select"] if s["name"] == "sdm630 demand_period")
    assert select["value_type"] == "U_DWORD"
    assert select["optionsmap"]["15 min"] == struct.unpack(">I", struct.pack(">f", 15.0))[0]
    assert select["optionsmap"]["demand shows the current value"] == 0
    assert not any(s["name"] == "sdm630 demand_period" for s in doc.get("number", ()))


def test_csv_and_docs_list_the_values() -> None:
    rows = {r["name"]: r for r in parse("csv", render(load_model("maps/sdm630.yaml"), "csv"))}
    assert rows["pulse1_width"]["values"] == "60 | 100 | 200"
    assert rows["system_type"]["values"] == "1 (1p2w) | 2 (3p3w) | 3 (3p4w)"
    assert rows["phase_1_voltage"]["values"] == ""
    docs = (package("sdm630").__file__ or "").replace("drivemap_models/sdm630/__init__.py", "docs/sdm630.md")
    with open(docs, encoding="utf-8") as handle:
        text = handle.read()
    assert "values: 60, 100, 200 (a write of any other value is refused)" in text


def test_codecs_of_every_kind_keep_to_the_set() -> None:
    from drivemap.runtime.client.values.codec import FloatCodec, IntCodec, OptionalCodec, StringCodec
    from drivemap.runtime.spec import RegisterSpec

    scaled = FloatCodec(RegisterSpec("ramp", 1, scale=0.1, unit="s", values=((0.5, None), (1.0, "slow"))))
    assert scaled.encode(0.5) == 5 and scaled.encode(1.0) == 10
    with pytest.raises(NotAllowedValue, match=r"ramp: 0.7 s is not one of the allowed values 0.5, 1 \(slow\)"):
        scaled.encode(0.7)
    whole = OptionalCodec(IntCodec(RegisterSpec("mode", 2, type="s16", values=((-1, "off"), (3, None)),
                                                not_available=(-32768,))))
    assert whole.encode(-1) == -1 and whole.encode(None) == -32768
    with pytest.raises(NotAllowedValue):
        whole.encode(2)
    text = StringCodec(RegisterSpec("profile", 3, type="string", length=2, values=(("AUTO", None), ("MAN", None))))
    assert text.encode("MAN") == int.from_bytes(b"MAN\x00", "big")
    with pytest.raises(NotAllowedValue, match="'auto' is not one of the allowed values AUTO, MAN"):
        text.encode("auto")


def test_verify_write_safe_tries_only_values_of_the_set() -> None:
    from types import SimpleNamespace

    from drivemap.live.verify_write import test_raws

    model = load_model("maps/sdm630.yaml")
    codecs = {name: codec for name, codec in vars(package("sdm630").client).get("CODECS", {}).items()}
    session = SimpleNamespace(target=SimpleNamespace(model=model, codecs=codecs))
    reg = model.register("pulse1_divisor1")  # before: its min and max (0, 5); now one other value of the set
    original = struct.unpack(">I", struct.pack(">f", 0.0))[0]
    tries = test_raws(session, reg, original)  # type: ignore[arg-type]
    assert tries == [("the value 1 (0.01 kWh(kVArh)/imp)", struct.unpack(">I", struct.pack(">f", 1.0))[0])]


def test_cli_write_takes_a_label_of_the_set() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        proc = run("write", "sdm630", "--tcp", f"{host}:{port}", "system_type=3P4W", "network_baud_rate=19200 baud")
        assert proc.returncode == 0, proc.stderr
        assert sim.get("system_type") == 3.0 and sim.get("network_baud_rate") == 3.0
