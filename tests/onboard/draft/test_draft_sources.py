"""`drivemap draft` on the layouts of published register lists that earlier drafts misread.

Each fixture is a few rows written here, in the shape of a pattern seen in openly licensed register
documents (a device maker's Markdown page, a workbook of a Modbus-TCP server's registers); the names
and numbers are invented. Every test drafts with the real verb, checks the map validates, and asserts
the drafted fields exactly and what the draft lists for review (the notes of each register, the rows
it did not draft).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import openpyxl
import pytest
import yaml

from drivemap.cli import main
from drivemap.onboard.draft.assemble import draft as draft_source
from drivemap.onboard.draft.read import read_document
from drivemap.onboard.draft.tables import Skipped
from drivemap.onboard.draft.writer import settle

FACTS = ("label", "table", "address", "type", "scale", "unit", "min", "max", "access")
TO_FILL = "left out, to fill from the document: "


def _document(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _workbook(tmp_path: Path, name: str, rows: list[list[Any]]) -> Path:
    book = openpyxl.Workbook()
    sheet = book.active
    assert sheet is not None
    sheet.title = "Point list"
    for row in rows:
        sheet.append(row)
    path = tmp_path / name
    book.save(path)
    return path


def _drafted(tmp_path: Path, document: Path, capsys: pytest.CaptureFixture[str]) -> tuple[list[tuple[Any, ...]],
                                                                                            list[str], str]:
    """The verb's map: each register's facts and notes (the map validates), and the summary printed."""
    out = tmp_path / "maps" / "dev.yaml"
    assert main(["draft", str(document), "-o", str(out)]) == 0
    summary = capsys.readouterr().out
    assert main(["validate", str(out)]) == 0
    registers: list[dict[str, Any]] = yaml.safe_load(out.read_text(encoding="utf-8"))["registers"]
    return [tuple(r.get(f) for f in FACTS) for r in registers], [r.get("notes", "") for r in registers], summary


def _skipped(document: Path) -> list[Skipped]:
    """The rows the verb lists as not drafted (reading, then settling the map as the verb does)."""
    result = draft_source(read_document(document), "dev")
    text, errors = settle(result, "", "dev.yaml")
    assert errors == [] and text
    return result.skipped


# ------------------------------------------------------------ a Markdown heading names the table

def test_the_heading_nearest_the_table_names_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``### Coils`` under a paragraph that names every table, then an ``Access level`` line: coils."""
    doc = _document(tmp_path, "board.md", (
        "# Pump board\n\nRegisters of every kind are served: coils, discrete inputs, input registers and holding "
        "registers.\n\n### Coils\n\nAccess level Read/Write, Size 1 bit\n\n| Function | Address |\n| --- | --- |\n"
        "| VALVE_OPEN | 0x00 |\n| HEATER_ON | 0x01 |\n| BUZZER | 0x02 |\n"))
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    assert facts == [("VALVE_OPEN", "coil", 0, None, None, None, None, None, "rw"),
                     ("HEATER_ON", "coil", 1, None, None, None, None, None, "rw"),
                     ("BUZZER", "coil", 2, None, None, None, None, None, "rw")]
    assert notes == ["", "", ""]  # a coil states everything a coil has
    assert _skipped(doc) == []


# ------------------------------------------------- the 0x column over 1-based coil/discrete numbers

def test_the_0x_column_is_the_address_over_coil_and_discrete_numbers(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``Register Address 0001 | Modbus Address 0x00`` (``10001 | 0x00``): the numbers count from 1."""
    doc = _document(tmp_path, "relays.md", (
        "# Relay board\n\n### Coils\n\n| Function | Register Address | Modbus Address |\n| --- | --- | --- |\n"
        "| RELAY_A | 0001 | 0x00 |\n| RELAY_B | 0002 | 0x01 |\n| RELAY_C | 0003 | 0x02 |\n\n"
        "### Discrete Inputs\n\n| Function | Register Address | Modbus Address |\n| --- | --- | --- |\n"
        "| SWITCH_A | 10001 | 0x00 |\n| SWITCH_B | 10002 | 0x01 |\n"))
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    assert facts == [("RELAY_A", "coil", 0, None, None, None, None, None, None),
                     ("RELAY_B", "coil", 1, None, None, None, None, None, None),
                     ("RELAY_C", "coil", 2, None, None, None, None, None, None),
                     ("SWITCH_A", "discrete", 0, None, None, None, None, None, None),
                     ("SWITCH_B", "discrete", 1, None, None, None, None, None, None)]
    assert notes == [f"{TO_FILL}access"] * 3 + ["", ""]  # a coil may be read-only: its access is not stated
    assert _skipped(doc) == []


# ------------------------------------------------------------------------------ uA is a unit

def test_micro_amps_are_a_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = _document(tmp_path, "sensor.md", (
        "# Sensor board\n\n### Input registers\n\n| Function | Address | Unit |\n| --- | --- | --- |\n"
        "| LOOP_CURRENT | 30001 | uA |\n| BRIDGE_VOLTAGE | 30002 | mV |\n| LEAK_CURRENT | 30003 | μA |\n"))
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    # a unit column stating the unit without a resolution states scale 1
    assert facts == [("LOOP_CURRENT", "input", 0, None, 1.0, "µA", None, None, None),
                     ("BRIDGE_VOLTAGE", "input", 1, None, 1.0, "mV", None, None, None),
                     ("LEAK_CURRENT", "input", 2, None, 1.0, "µA", None, None, None)]
    assert notes == [f"scale 1: the unit column says {u!r} without a resolution; {TO_FILL}type, range"
                     for u in ("uA", "mV", "μA")]


# ------------------------------------------------------- a range printed in another unit than the register's

def test_a_range_printed_in_another_unit_is_left_out_and_noted(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``0-10V Input`` on a register counted in mV is the input's span, not the register's range."""
    doc = _document(tmp_path, "analog.md", (
        "# Analog board\n\n### Input registers\n\n| Function | Address | Description | Unit |\n"
        "| --- | --- | --- | --- |\n| TANK_LEVEL | 30001 | 0-10V Input | mV |\n"
        "| FLOW_LOOP | 30002 | 4-20mA Input | mA |\n| SUPPLY_RAIL | 30003 | 0-24V Input | V |\n"))
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    # the register's own unit: a range; within raw 0..32767 it reads the same signed and unsigned (u16)
    assert facts == [("TANK_LEVEL", "input", 0, None, 1.0, "mV", None, None, None),
                     ("FLOW_LOOP", "input", 1, "u16", 1.0, "mA", 4, 20, None),
                     ("SUPPLY_RAIL", "input", 2, "u16", 1.0, "V", 0, 24, None)]
    said = "scale 1: the unit column says {!r} without a resolution"
    either = "type u16: the document does not say signed or unsigned, but its range {} (raw {}) reads the same " \
             "either way (every raw value from 0 to 32767)"
    assert notes == [f"{said.format('mV')}; range 0..10 printed in V, the register's unit is mV: left out; "
                     f"{TO_FILL}type, range", f"{said.format('mA')}; {either.format('4..20', '4..20')}",
                     f"{said.format('V')}; {either.format('0..24', '0..24')}"]


# ------------------------------------------------------- two address columns that disagree

def test_a_row_whose_two_address_columns_disagree_is_listed_not_drafted(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``30004 | 0x00``: the Modicon number says address 3, the 0x column says 0; the draft picks neither."""
    doc = _document(tmp_path, "meter.md", (
        "# Meter board\n\n### Input registers\n\n| Function | Register Address | Modbus Address |\n"
        "| --- | --- | --- |\n| PHASE_A | 30001 | 0x00 |\n| PHASE_B | 30002 | 0x01 |\n| PHASE_C | 30003 | 0x02 |\n"
        "| PEAK_A | 30004 | 0x00 |\n| PEAK_B | 30005 | 0x01 |\n"))
    facts, notes, summary = _drafted(tmp_path, doc, capsys)
    assert facts == [("PHASE_A", "input", 0, None, None, None, None, None, None),
                     ("PHASE_B", "input", 1, None, None, None, None, None, None),
                     ("PHASE_C", "input", 2, None, None, None, None, None, None)]
    assert notes == [f"{TO_FILL}type, scale, unit, range"] * 3
    assert _skipped(doc) == [
        Skipped("p.1 line 10", "PEAK_A | 30004 | 0x00", "not drafted: 'Register Address' '30004' is address 0x0003, "
                "'Modbus Address' says '0x00': the document states two addresses"),
        Skipped("p.1 line 11", "PEAK_B | 30005 | 0x01", "not drafted: 'Register Address' '30005' is address 0x0004, "
                "'Modbus Address' says '0x01': the document states two addresses")]
    assert "Rows skipped: 2" in summary


# ------------------------------------------------------- a Scalefactor column: divisor or multiplier

_SCALE_HEADER = ["Name", "Address", "Type", "Scalefactor", "Range", "Unit"]


def test_a_scale_factor_column_divides_when_its_ranges_say_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``100`` with ``0 to 655.35`` on a uint16 is raw / 100; a row whose range does not tell follows the
    column; a negative factor is not read and is noted."""
    doc = _workbook(tmp_path, "controller.xlsx", [
        ["Greenhouse controller register list"], _SCALE_HEADER,
        ["Tank level", 100, "uint16", 100, "0 to 655.35", "%"],
        ["Tank temperature", 101, "int16", 10, "-3276.8 to 3276.7", "°C"],
        ["Pump speed", 102, "uint16", 10, None, "RPM"],
        ["Valve offset", 103, "int16", -10, None, "%"],
        ["Fan stage", 104, "uint16", 1, "0 to 3", None]])
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    assert facts == [("Tank level", None, 100, "u16", 0.01, "%", 0, 655.35, None),
                     ("Tank temperature", None, 101, "s16", 0.1, "°C", -3276.8, 3276.7, None),
                     ("Pump speed", None, 102, "u16", 0.1, "r/min", None, None, None),
                     ("Valve offset", None, 103, "s16", None, "%", None, None, None),
                     ("Fan stage", None, 104, "u16", 1, None, 0, 3, None)]
    assert notes == [f"{TO_FILL}table, access", f"{TO_FILL}table, access", f"{TO_FILL}table, range, access",
                     f"scale factor -10 is negative: not read as a scale; {TO_FILL}table, scale, range, access",
                     f"{TO_FILL}table, unit, access"]


def test_a_scale_factor_column_multiplies_when_its_ranges_say_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``10`` with ``0 to 655350`` on a uint16 is raw x 10: the column is not taken as a divisor blindly."""
    doc = _workbook(tmp_path, "inverter.xlsx", [
        _SCALE_HEADER, ["Export limit", 300, "uint16", 10, "0 to 655350", "W"],
        ["Import limit", 301, "uint16", 10, None, "W"]])
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    assert facts == [("Export limit", None, 300, "u16", 10, "W", None, None, None),
                     ("Import limit", None, 301, "u16", 10, "W", None, None, None)]
    assert notes == [f"range 0..655350 printed without saying raw or engineering: left out; {TO_FILL}table, range, "
                     "access", f"{TO_FILL}table, range, access"]


# ------------------------------------------------------- a name column that repeats a few values

_WORDS = ["Inlet pressure", "Outlet pressure", "Filter state", "Pump hours", "Pump starts", "Valve position",
          "Heater power", "Heater hours", "Tank alarm", "Level alarm", "Door state", "Lamp state"]

_TREES = ["Ash", "Birch", "Cedar", "Elm", "Fir", "Hazel", "Larch", "Maple", "Oak", "Pine", "Rowan", "Yew"]


@pytest.mark.parametrize(("service", "labels"), [
    (lambda i: f"org.example.{'pumps' if i < 6 else 'climate'}", _WORDS),  # two services: the description names
    (lambda i: _TREES[i], _TREES),  # another name on every row: the name column names the registers
])
def test_a_name_column_that_repeats_a_few_values_names_no_register(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], service: Callable[[int], str], labels: list[str]) -> None:
    doc = _workbook(tmp_path, "site.xlsx", [["Service name", "Description", "Address", "Type"]] +
                    [[service(i), word, 200 + i, "uint16"] for i, word in enumerate(_WORDS)])
    facts, notes, _ = _drafted(tmp_path, doc, capsys)
    assert facts == [(label, None, 200 + i, "u16", None, None, None, None, None) for i, label in enumerate(labels)]
    assert notes == [f"{TO_FILL}table, scale, unit, range, access"] * 12


@pytest.mark.parametrize("heading", ["Registers", "Enums", "Function codes", "Timing"])
def test_a_table_headed_like_a_section_of_the_docs_page_still_builds(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], heading: str) -> None:
    """A table (or sheet) headed like a fixed section of the generated docs page keeps its heading with
    its place added, so the draft passes the checks of every exporter ``build`` runs."""
    document = _document(tmp_path, "board.md", f"## {heading}\n\n| Address | Name | Unit |\n|---|---|---|\n"
                                                "| 0x0010 | Pump speed | rpm |\n| 0x0011 | Pump current | A |\n")
    facts, _notes, _summary = _drafted(tmp_path, document, capsys)
    assert [f[2] for f in facts] == [0x10, 0x11]
    out = tmp_path / "maps" / "dev.yaml"
    assert main(["validate", "--exporter", "all", str(out)]) == 0
    title = yaml.safe_load(out.read_text(encoding="utf-8"))["groups"][0]["title"]
    assert title.startswith(f"{heading} (") and title != heading
