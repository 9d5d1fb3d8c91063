"""Display precision (``precision:``, and the f32 default: the shortest text that reads back as the
same f32) and array numbering (``first_index:``), from the scaffold ``drivemap new`` writes."""

from __future__ import annotations

import contextlib
import io
import json
import random
import struct
from decimal import Decimal
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import load_model
from drivemap.live.fmt import Row
from drivemap.model.nodes import Model
from drivemap.runtime.client.values.codec import display_text
from tests.exporter_helpers import parse, render
from tests.helpers_client import tcp_server
from tests.helpers_live import run


def f32(value: float) -> float:
    return float(struct.unpack(">f", struct.pack(">f", value))[0])


@pytest.fixture(scope="module")
def acme(tmp_path_factory: pytest.TempPathFactory) -> Model:
    folder = tmp_path_factory.mktemp("scaffold")
    out = io.StringIO()
    with contextlib.chdir(folder), contextlib.redirect_stdout(out):
        assert main(["new", "acme"]) == 0
    return load_model(str(Path(folder) / "maps" / "acme.yaml"))


def test_f32_default_is_the_shortest_text_of_the_same_f32() -> None:
    assert display_text(f32(230.2), single=True) == "230.2"
    assert repr(f32(230.2)) == "230.1999969482422"  # what was printed before
    assert display_text(f32(0.1), single=True) == "0.1"
    assert display_text(f32(1e-7), single=True) == "1e-07"
    assert display_text(f32(12000.0), single=True) == "12000.0"  # not 1.2e+04
    assert display_text(f32(-3.0e20), single=True) == "-3e+20"
    assert display_text(float("nan"), single=True) == "nan" and display_text(None) == "None"
    rng = random.Random(7)
    for _ in range(2000):
        x = f32(rng.uniform(-1e6, 1e6) * 10.0 ** rng.randint(-8, 8))
        text = display_text(x, single=True)
        assert f32(float(text)) == x, (x, text)
        digits = len(Decimal(text).normalize().as_tuple().digits)
        if digits > 1:  # no shorter text reads back as the same f32
            assert f32(float(f"{x:.{digits - 1}g}")) != x, (x, text)


def test_precision_formats_every_number() -> None:
    assert display_text(f32(230.2), 1, single=True) == "230.2"
    assert display_text(f32(230.2), 3) == "230.200"
    assert display_text(48.25, 0) == "48"
    assert display_text(5, 2) == "5.00"
    assert display_text(0.30000000000000004) == "0.30000000000000004"  # f64: repr is already shortest


def test_read_and_json_show_the_shortest_f32() -> None:
    with tcp_server("sdm630") as (sim, host, port):
        sim.set("phase_1_voltage", 230.2)
        table = run("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage")
        as_json = run("read", "sdm630", "--tcp", f"{host}:{port}", "phase_1_voltage", "--json")
    assert table.returncode == 0, table.stderr
    assert "230.2 " in table.stdout and "230.199" not in table.stdout
    assert json.loads(as_json.stdout)["registers"][0]["value"] == 230.2


def test_precision_of_the_map_is_used_by_read_and_exports(acme: Model) -> None:
    reg = acme.register("carrier_frequency")
    assert reg.precision == 1
    row = Row(reg.name, reg, 0, 0x40800000, 4.0)
    assert row.value_text() == "4.0"
    voltage = acme.register("line_voltage")
    assert Row(voltage.name, voltage, 0, 0, f32(230.2)).value_text() == "230.2"
    esphome = parse("esphome", render(acme, "esphome"))
    select = next(s for s in esphome["select"] if s["name"] == "acme carrier_frequency")
    assert select["optionsmap"] == {"2 kHz (quiet)": 0x40000000, "4 kHz": 0x40800000, "8 kHz (low loss)": 0x41000000}
    ha = parse("homeassistant", render(acme, "homeassistant"))["modbus"][0]
    sensor = next(s for s in ha["sensors"] if s["name"] == "acme carrier_frequency")
    assert sensor["precision"] == 1


def test_first_index_names_elements_as_the_manual_numbers_them(acme: Model) -> None:
    reg = acme.register("preset_speed")
    assert reg.first_index == 1
    assert [reg.display_name(i) for i in range(reg.count)] == [f"preset_speed {n}" for n in (1, 2, 3, 4)]
    assert reg.element_name(0) == "preset_speed[0]"  # Python and the CLI still index from 0
    from drivemap.model.spec import spec_from_model
    spec = spec_from_model(acme).register("preset_speed")
    assert [spec.display_name(i) for i in range(4)] == [reg.display_name(i) for i in range(4)]
    assert acme.register("frequency_command").display_name(0) == "frequency_command"
    rows = [r for r in parse("csv", render(acme, "csv")) if r["name"].startswith("preset_speed")]
    assert [(r["name"], r["display_name"]) for r in rows][:2] == [("preset_speed[0]", "preset_speed 1"),
                                                                   ("preset_speed[1]", "preset_speed 2")]
    ha = parse("homeassistant", render(acme, "homeassistant"))["modbus"][0]
    names = [s["name"] for s in ha["sensors"] if "preset_speed" in s["name"]]
    assert names == [f"acme preset_speed {n}" for n in (1, 2, 3, 4)]
    esphome = parse("esphome", render(acme, "esphome"))
    assert "acme preset_speed_1" in {n["name"] for n in esphome.get("number", ())}
