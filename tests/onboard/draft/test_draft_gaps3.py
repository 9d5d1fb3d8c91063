"""`drivemap draft` on two more patterns of public register documents.

* A description that lists values, ``N = text`` (``1 = 1200 baud``, ``0 = 50 Hz, 1 = 60 Hz``), as a
  workbook of an energy meter does: those are the values the register holds, never a resolution. A
  list whose items could be either (``1 = 0.1 A, 10 = 1 A``: every amount is the value times one step)
  is drafted as neither and listed for review.
* A register table whose access column is headed ``W/R`` and whose description column is headed
  ``Decription`` (misspelt), as an inverter maker's PDF prints it: both columns are read.

Each fixture is made here (openpyxl, CSV text, fpdf2); the names and numbers are invented.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import openpyxl
import pytest
import yaml
from test_draft_gaps import _table

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.onboard.draft.cells import parse_enum, parse_range, value_list
from drivemap.onboard.draft.columns import role_of


def _draft(tmp_path: Path, document: Path) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """The verb's registers by name and the map's enums; the map validates and compiles."""
    out = tmp_path / "maps" / "dev.yaml"
    assert main(["draft", str(document), "-o", str(out)]) == 0
    assert main(["validate", str(out)]) == 0
    compile_map(out)
    data = yaml.safe_load(out.read_text(encoding="utf-8"))
    return {r["name"]: r for r in data["registers"]}, data.get("enums") or {}


def _values(enums: dict[str, Any], register: dict[str, Any]) -> list[tuple[int, str]]:
    return [(v["value"], v["label"]) for v in enums[register["enum"]]["values"]]


# ------------------------------------------------------------ a value list is values, not a scale

def _meter_workbook(path: Path) -> Path:
    book = openpyxl.Workbook()
    sheet = book.active
    assert sheet is not None
    sheet.title = "Main List"
    for row in [["Meter MODBUS Register List"],
                [None, "Registers", "Name", "Units", "Access", "Default", "Description"],
                ["Communication Registers"],
                [None, 1651, "BaudRate", None, "Read/Write", 0,
                 "1 = 1200 baud\n2 = 2400 baud\n3 = 4800 baud\n4 = 9600 baud"],
                [None, 1652, "BaudSelect", None, "Read/Write", 0,
                 "0 = DIP Switch Assigned\n4 = 9600 baud\n5 = 19200 baud"],
                [None, 1653, "LineFreq", None, "Read/Write", None, "0 = 50 Hz, 1 = 60 Hz"],
                [None, 1654, "TransformerSize", None, "Read/Write", None, "0: 100A 1: 200A"],
                [None, 1655, "SlowBaud", None, "Read/Write", None, "1 = 1200 baud, 2 = 2400 baud"],
                [None, 1656, "CurrentStep", None, "Read-Only", None, "1 = 0.1 A, 10 = 1 A"],
                [None, 1657, "Voltage", None, "Read-Only", None, "Line voltage (1 = 0.1 V)"],
                [None, 1658, "ErrorStatus", None, "Read-Only", None, "Newest error or event (0 = no errors)"],
                [None, 1659, "CurrentFine", "0.1 A", "Read-Only", None, "1 = 0.1 A, 10 = 1 A"]]:
        sheet.append(row)
    book.save(path)
    return path


def test_a_value_list_with_amounts_is_an_enum_never_a_scale(tmp_path: Path) -> None:
    regs, enums = _draft(tmp_path, _meter_workbook(tmp_path / "meter.xlsx"))
    baud = regs["baud_rate"]
    assert "scale" not in baud and "unit" not in baud
    assert _values(enums, baud) == [(1, "1200 baud"), (2, "2400 baud"), (3, "4800 baud"), (4, "9600 baud")]
    assert _values(enums, regs["baud_select"]) == [(0, "DIP Switch Assigned"), (4, "9600 baud"), (5, "19200 baud")]
    # a stated default is kept when it is one of the listed values, else left out and said so
    assert regs["baud_select"]["default"] == 0
    assert "default" not in baud and "default '0' is none of the listed values" in baud["notes"]
    freq = regs["line_freq"]  # "1 = 60 Hz" is the second value, not 60 Hz per count
    assert "scale" not in freq and "unit" not in freq and _values(enums, freq) == [(0, "50 Hz"), (1, "60 Hz")]
    assert _values(enums, regs["transformer_size"]) == [(0, "100A"), (1, "200A")]


def test_a_value_list_that_could_be_a_resolution_is_left_for_review(tmp_path: Path, capsys: Any) -> None:
    """Every amount is the value times one step: values or a resolution? Neither is drafted."""
    regs, _ = _draft(tmp_path, _meter_workbook(tmp_path / "meter.xlsx"))
    for name, printed in (("slow_baud", "1 = 1200 baud, 2 = 2400 baud"), ("current_step", "1 = 0.1 A, 10 = 1 A")):
        reg = regs[name]
        assert "scale" not in reg and "enum" not in reg and "min" not in reg, name
        assert f"'{printed}'" in reg["notes"] and "values or a resolution" in reg["notes"], name
        assert "scale" in reg["notes"].split("left out, to fill from the document: ")[1], name
    printed = capsys.readouterr().out
    assert "slow_baud" in printed and "current_step" in printed
    # one resolution stated once is still a scale; "0 = no errors" alone is no list
    assert (regs["voltage"]["scale"], regs["voltage"]["unit"]) == (0.1, "V")
    assert "enum" not in regs["error_status"] and regs["error_status"].get("scale") in (None, 1.0)
    # the Units column states the resolution: the list restates it
    fine = regs["current_fine"]
    assert (fine["scale"], fine["unit"]) == (0.1, "A") and "enum" not in fine and "value list" not in fine["notes"]


def test_a_value_list_in_a_csv_description(tmp_path: Path) -> None:
    doc = tmp_path / "list.csv"
    doc.write_text("Address,Name,Description\n0x0010,Grid standard,0 = 50 Hz; 1 = 60 Hz\n"
                   "0x0011,Output voltage,1 = 0.1 V\n", encoding="utf-8")
    regs, enums = _draft(tmp_path, doc)
    assert "scale" not in regs["grid_standard"] and _values(enums, regs["grid_standard"]) == [(0, "50 Hz"),
                                                                                             (1, "60 Hz")]
    assert (regs["output_voltage"]["scale"], regs["output_voltage"]["unit"]) == (0.1, "V")


@pytest.mark.parametrize(("text", "values", "ambiguous"), [
    ("1 = 1200 baud, 2 = 2400 baud, 3 = 4800 baud, 4 = 9600 baud",
     [(1, "1200 baud"), (2, "2400 baud"), (3, "4800 baud"), (4, "9600 baud")], False),
    ("0 = 50 Hz, 1 = 60 Hz", [(0, "50 Hz"), (1, "60 Hz")], False),
    ("1 = 0.1 A, 10 = 1 A", [(1, "0.1 A"), (10, "1 A")], True),
    ("0 = 0 V, 1 = 0.1 V, 2 = 0.2 V", [(0, "0 V"), (1, "0.1 V"), (2, "0.2 V")], True),
    ("1 = 1 s, 2 = 1 min", [(1, "1 s"), (2, "1 min")], False),  # two units: no one step
    ("0 = off, 1 = 1 s", [(0, "off"), (1, "1 s")], False),
])
def test_value_list_reading(text: str, values: list[tuple[int, str]], ambiguous: bool) -> None:
    found = value_list(text)
    assert found is not None and (found.items, found.ambiguous) == (values, ambiguous)
    assert parse_enum(text) == (None if ambiguous else values)


@pytest.mark.parametrize("text", ["0 ~ 65535 (1=0.01 VDC)", "Newest error (0 = no errors)", "Line voltage (1 = 0.1 V)",
                                  "1 = 1 A, 1 = 2 A"])
def test_no_value_list(text: str) -> None:
    assert value_list(text) is None and parse_enum(text) is None


# ------------------------------------------------------------ "W/R" and "Decription" headers

@pytest.mark.parametrize(("header", "role"), [
    ("W/R", "access"), ("w / r", "access"), ("R/W", "access"), ("Decription", "description"),
    ("decription", "description"), ("Descripton", "description"), ("Description", "description"),
])
def test_misspelt_and_swapped_headers(header: str, role: str) -> None:
    assert role_of(header) == role


def test_w_r_access_and_a_misspelt_description_column_in_a_csv(tmp_path: Path) -> None:
    doc = tmp_path / "holding.csv"
    doc.write_text("Register,Variable,W/R,Decription,Unit\n"
                   "0x0000,SafetyCode,W/R,0:VDE0126 1:ARN4105 2:AS4777,\n"
                   "0x0001,ChargerUseMode,W,0:Self Use Mode 1:Force Time Use,\n"
                   "0x0002,GridVoltHigh,W/R,GridVoltHigh (1500~3000),0.1V\n"
                   "0x0003,SerialNumber,R,Serial number of the inverter,\n"
                   "0x0004,BusVoltage,R,see Table 2-4 for the limits,V\n", encoding="utf-8")
    regs, enums = _draft(tmp_path, doc)
    assert [regs[n].get("access") for n in ("safety_code", "charger_use_mode", "grid_volt_high", "serial_number")] \
        == ["rw", "w", "rw", None]  # "R" is the schema's default access
    assert "access" not in regs["serial_number"]["notes"].split("left out, to fill from the document: ")[1]
    assert _values(enums, regs["safety_code"]) == [(0, "VDE0126"), (1, "ARN4105"), (2, "AS4777")]
    assert _values(enums, regs["charger_use_mode"]) == [(0, "Self Use Mode"), (1, "Force Time Use")]
    volt = regs["grid_volt_high"]  # the description is read: its range, printed in counts or volts?
    assert (volt["scale"], volt["unit"]) == (0.1, "V") and "range 1500..3000 printed without saying" in volt["notes"]
    bus = regs["bus_voltage"]  # "Table 2-4" names a table: no range 2..4
    assert bus["unit"] == "V" and "min" not in bus and "max" not in bus and "range" in bus["notes"]


@pytest.mark.parametrize(("text", "found"), [
    ("Table 2-2 Run mode description", None), ("X1:Table2-4 X3:Table2-3", None), ("see Figure 3-1", None),
    ("Table 2-2, settable 0~100", (0, 100, "")), ("1500~3000", (1500, 3000, "")),
])
def test_a_table_number_is_no_range(text: str, found: tuple[float, float, str] | None) -> None:
    assert parse_range(text) == found


def _inverter_pdf(path: Path) -> Path:
    from fpdf import FPDF

    pdf = FPDF(orientation="L")
    pdf.set_font("Helvetica", size=7)
    pdf.add_page()
    pdf.cell(text="0x03: Read Holding Register", new_x="LMARGIN", new_y="NEXT")
    # "Data" / "format" is one header over two rows; the access column is "W/R", the description
    # column "Decription"
    _table(pdf, [[("Register", 1, 2), ("Variable", 1, 2), ("W/R", 1, 2), ("Decription", 1, 2), ("Unit", 1, 2), "Data"],
                 ["format"],
                 ["0x0000", "SafetyCode", "W/R", "0:VDE0126 1:ARN4105 2:AS4777", "", "uint16"],
                 ["0x0001", "ChargerUseMode", "W", "0:Self Use Mode 1:Force Time Use", "", "uint16"],
                 ["0x0002", "GridVoltHigh", "W/R", "GridVoltHigh (1500~3000)", "0.1V", "uint16"],
                 ["0x0003", "FirmwareVersion", "R", "Version of the firmware", "", "uint16"]],
           (20, 40, 12, 90, 16, 20))
    pdf.output(str(path))
    return path


def test_w_r_access_and_a_misspelt_description_column_in_a_pdf(tmp_path: Path) -> None:
    regs, enums = _draft(tmp_path, _inverter_pdf(tmp_path / "inverter.pdf"))
    assert {n: (r["table"], r["address"], r["type"], r.get("access")) for n, r in regs.items()} == {
        "safety_code": ("holding", 0, "u16", "rw"), "charger_use_mode": ("holding", 1, "u16", "w"),
        "grid_volt_high": ("holding", 2, "u16", "rw"), "firmware_version": ("holding", 3, "u16", None)}
    assert _values(enums, regs["safety_code"]) == [(0, "VDE0126"), (1, "ARN4105"), (2, "AS4777")]
    assert _values(enums, regs["charger_use_mode"]) == [(0, "Self Use Mode"), (1, "Force Time Use")]
    volt = regs["grid_volt_high"]  # the description is read: its range, printed in counts or volts?
    assert (volt["scale"], volt["unit"]) == (0.1, "V") and "range 1500..3000 printed without saying" in volt["notes"]
    for reg in regs.values():
        assert "access" not in reg.get("notes", "")
