"""`drivemap draft` on the patterns of public register documents (vendor PDFs and workbooks).

Each fixture is made here (fpdf2, openpyxl, text) and reproduces one pattern seen in a public
document: an address column headed ``NO.`` (or split ``Registe`` / ``rNO.``) with a name cell one
grid column to the right of its header, a header over two rows, ``Assigned`` in a value list,
two-register rows ``1001, 1002``, an address shifted under a spanning header next to a function-code
cell, and words run together. The draft never guesses: what a row does not state is left out and
listed; a row it cannot read is listed with its page and row.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.onboard.draft.cells import parse_bits, signed_hint
from drivemap.onboard.draft.naming import snake


def draft(tmp_path: Path, document: Path, name: str, *extra: str) -> tuple[int, Path]:
    out = tmp_path / "maps" / f"{name}.yaml"
    return main(["draft", str(document), "-o", str(out), *extra]), out


def registers(path: Path) -> dict[str, dict[str, Any]]:
    return {r["name"]: r for r in yaml.safe_load(path.read_text(encoding="utf-8"))["registers"]}


def _table(pdf: Any, rows: list[list[Any]], widths: tuple[int, ...]) -> None:
    """A ruled table; a cell given as (text, colspan, rowspan) spans columns or rows."""
    with pdf.table(col_widths=widths, repeat_headings=0, first_row_as_headings=False) as table:
        for row in rows:
            cells = table.row()
            for cell in row:
                text, colspan, rowspan = cell if isinstance(cell, tuple) else (cell, 1, 1)
                cells.cell(text, colspan=colspan, rowspan=rowspan)


def _growatt_like(path: Path) -> Path:
    from fpdf import FPDF

    pdf = FPDF()
    pdf.set_font("Helvetica", size=8)
    pdf.add_page()
    pdf.cell(text="4.1HoldingReg", new_x="LMARGIN", new_y="NEXT")
    _table(pdf, [["Registe\nrNO.", "Variable\nName", "Description", "Unit", "Initial\nvalue"],
                 ["00", "OnOff", "Remote On/Off", "", "1"],
                 ["06", "PmaxH", "Normal power(high)", "0.1VA", ""],
                 ["07", "PmaxL", "Normal power(low)", "0.1VA", ""],
                 ["3239-3\n249", "Reserve", "Reserve", "", ""]], (16, 30, 50, 16, 16))
    pdf.cell(text="4.2InputReg", new_x="LMARGIN", new_y="NEXT")
    # "VariableName" spans two grid columns; each number cell spans the first two: the name sits
    # in the third grid column, under no header text of its own.
    _table(pdf, [["NO.", ("VariableName", 2, 1), "Description", "Unit", "Note"],
                 [("Firstgroup", 6, 1)],
                 [("0.", 2, 1), "InverterStatus", "Inverter run state", "", "0:waiting, 1:normal, 3:fault"],
                 [("1.", 2, 1), "PpvH", "Inputpower(high)", "0.1W", ""],
                 [("2.", 2, 1), "PpvL", "Inputpower(low)", "0.1W", ""]], (14, 3, 30, 50, 16, 20))
    pdf.add_page()  # the input table goes on, without its header and on a grid of its own
    _table(pdf, [["3.", "Vpv1", "PV1voltage", "0.1V", ""], ["4.", "PV1Curr", "PV1inputcurrent", "0.1A", ""]],
           (17, 30, 50, 16, 20))
    pdf.output(str(path))
    return path


def test_address_column_headed_no_or_split_over_two_lines(tmp_path: Path, capsys: Any) -> None:
    code, out = draft(tmp_path, _growatt_like(tmp_path / "growatt.pdf"), "growattlike")
    assert code == 0
    regs = {(r.get("table"), r["address"]): r for r in registers(out).values()}
    assert {a for t, a in regs if t == "holding"} == {0, 6, 7}  # under "Registe rNO."
    assert {a for t, a in regs if t == "input"} == {0, 1, 2, 3, 4}  # under "NO.", and on page 2
    pmax = regs[("holding", 6)]
    assert (pmax["name"], pmax["scale"], pmax["unit"]) == ("pmax_h", 0.1, "VA")
    status, ppv = regs[("input", 0)], regs[("input", 1)]
    assert status["name"] == "inverter_status" and status["label"] == "InverterStatus"
    assert (ppv["name"], ppv["scale"], ppv["unit"]) == ("ppv_h", 0.1, "W")
    assert "p.2" in regs[("input", 4)]["source"] and regs[("input", 4)]["name"] == "pv1_curr"
    # numbers printed under "NO.": the draft says it cannot tell 0- from 1-based, and states no type
    assert "as printed under 'NO.'" in ppv["notes"] and all("type" not in r for r in regs.values())
    printed = capsys.readouterr().out
    assert "3239-3 249" in printed and "p.1 table 1 row 5" in printed  # the unreadable row is listed
    compile_map(out)


def _solax_like(path: Path) -> Path:
    from fpdf import FPDF

    pdf = FPDF()
    pdf.set_font("Helvetica", size=8)
    pdf.add_page()
    pdf.cell(text="0x04: Read Input Register", new_x="LMARGIN", new_y="NEXT")
    # "Register" spans two grid columns (the address is in the second); "Data" / "format" is one
    # header over two rows between two narrow empty header cells; each type cell spans all three.
    _table(pdf, [[("Function code", 1, 2), ("Register", 2, 2), ("Variable", 1, 2), ("Unit", 1, 2), ("", 1, 2),
                  "Data", ("", 1, 2), ("Length", 1, 2)],
                 ["format"],
                 ["0x04", "", "0x0000", "GridVoltage(X1)", "0.1V", ("uint16", 3, 1), "1"],
                 ["", "", "0x0001", "GridCurrent(X1)", "0.1A", ("int16", 3, 1), "1"],
                 ["", "", "0x0002", "GridPower(X1)", "1W", ("int16", 3, 1), "1"]], (14, 2, 16, 40, 16, 2, 16, 2, 12))
    pdf.output(str(path))
    return path


def test_header_over_two_rows_and_the_first_row_beside_a_function_code(tmp_path: Path) -> None:
    code, out = draft(tmp_path, _solax_like(tmp_path / "solax.pdf"), "solaxlike")
    assert code == 0
    regs = {r["address"]: r for r in registers(out).values()}
    assert set(regs) == {0, 1, 2}  # 0x0000 is the row that also holds the function code
    voltage = regs[0]
    assert (voltage["name"], voltage["table"], voltage["type"], voltage["scale"], voltage["unit"]) == \
        ("grid_voltage", "input", "u16", 0.1, "V")
    assert (regs[1]["type"], regs[2]["type"]) == ("s16", "s16")  # "Data format": int16


def test_a_row_without_an_address_before_the_first_register_is_listed(tmp_path: Path, capsys: Any) -> None:
    doc = tmp_path / "list.csv"
    doc.write_text("Address,Name,Unit\n,Orphan value,V\n0x0010,Inputpower(high),0.1W\n"
                   "0x0011,Inputpower(low),0.1W\n", encoding="utf-8")
    code, out = draft(tmp_path, doc, "orphan")
    assert code == 0
    assert "Orphan value" in capsys.readouterr().out  # skipped, and said so
    # words run together stay one word, and the (high)/(low) of a pair stays in its name
    assert {r["name"]: r["address"] for r in registers(out).values()} == {"inputpower_high": 16,
                                                                          "inputpower_low": 17}


def _workbook(path: Path, title: str) -> Path:
    import openpyxl

    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "Main List"
    for row in [[title], [None, "Registers", "Name", "Units", "Access", "Default", "Description"],
                ["Energy Registers"],
                [None, "1001, 1002", "EnergySum", "kWh", "Read/Write", None, "Total net (bidirectional) energy"],
                [None, "1003, 1005", "Gap", "kWh", "Read-Only", None, "not two consecutive registers"],
                [None, 1201, "PowerSum", "W", "Read-Only", None, "Real power, sum of active phases"],
                [None, 1653, "BaudRate", None, "Read/Write", 0, "0 = DIP Switch Assigned\n4 = 9600 baud"],
                [None, 1654, "Offset", None, "Read/Write", 0, "Signed offset"]]:
        sheet.append(row)
    typed = book.create_sheet("Typed")
    for row in [["Registers", "Name", "Type", "Units"], ["2001, 2002", "EnergyFloat", "float", "kWh"],
                ["2003, 2004", "PulseCount", "int32", ""], ["2005, 2006", "Note", "", ""]]:
        typed.append(row)
    book.save(path)
    return path


def test_two_register_rows_and_no_sign_read_inside_a_word(tmp_path: Path, capsys: Any) -> None:
    code, out = draft(tmp_path, _workbook(tmp_path / "wn.xlsx", "WattNode MODBUS Register List"), "wnlike")
    assert code == 0
    regs = registers(out)
    energy = regs["energy_sum"]
    assert energy["address"] == 1001 and "type" not in energy  # the row states no type: listed, not guessed
    assert "2 registers long, type not stated" in energy["notes"] and "type" in energy["notes"]
    floats = regs["energy_float"]
    # the stated type stays; the order of its words, which the sheet does not give, is left to review
    assert floats["address"] == 2001 and floats["type"] == "f32" and "word_order" not in floats
    assert "word_order" in floats["review"] and "type" not in floats["review"] and "word order" in floats["notes"]
    pulses = regs["pulse_count"]
    assert pulses["type"] == "s32" and "word_order" in pulses["review"] and "word order" in pulses["notes"]
    assert "type" not in regs["baud_rate"]  # "Assigned" is no "signed"
    assert regs["offset"]["type"] == "s16"  # the word itself still is
    printed = capsys.readouterr().out
    assert "'1003, 1005' not readable" in printed and "sheet Main List row 5" in printed
    assert not any(r.get("address") in (1002, 2002) for r in regs.values())
    compile_map(out)


def test_two_register_row_with_a_stated_float_and_word_order(tmp_path: Path) -> None:
    code, out = draft(tmp_path, _workbook(tmp_path / "wn.xlsx", "Floating point values: high word first"), "wnorder")
    assert code == 0
    regs = registers(out)
    assert (regs["energy_float"]["type"], regs["energy_float"]["word_order"]) == ("f32", "high_first")
    assert (regs["pulse_count"]["type"], regs["pulse_count"]["address"]) == ("s32", 2003)
    assert "type" not in regs["energy_sum"]  # the Main List rows still state no type
    compile_map(out)


@pytest.mark.parametrize(("text", "signed"), [
    ("0 = DIP Switch Assigned", False), ("Signed offset", True), ("unsigned", False), ("signed 16-bit", True),
    ("Designed for", False), ("two's complement", True),
])
def test_signed_is_a_word(text: str, signed: bool) -> None:
    assert signed_hint(text) is signed


@pytest.mark.parametrize(("text", "name"), [
    ("InverterStatus", "inverter_status"), ("PV1Curr", "pv1_curr"), ("Ppv1H", "ppv1_h"),
    ("Epv2_todayL", "epv2_today_l"), ("DCBusVoltage", "dc_bus_voltage"), ("Inputpower", "inputpower"),
    ("Phase 1 line to neutral volts", "phase_1_line_to_neutral_volts"), ("kWh total", "kwh_total"),
])
def test_names_split_words_run_together_in_camel_case(text: str, name: str) -> None:
    assert snake(text, "x") == name


def test_a_bit_list_run_into_one_line_is_split_at_each_bit() -> None:
    """A PDF cell's lines read as one: each label ends where the next ``BitN`` starts."""
    assert parse_bits("Bit0:SPIenable Bit1:AutoTestStart Bit2:LVFRTenable Bit3:FreqDerating Enable") == [
        (0, "SPIenable"), (1, "AutoTestStart"), (2, "LVFRTenable"), (3, "FreqDerating Enable")]
    assert parse_bits("Bit0：Resved; Bit5：bDischargeEn； Bit6：ForceDischrEn；") == [
        (0, "Resved"), (5, "bDischargeEn"), (6, "ForceDischrEn")]
    assert parse_bits("Bit0~7:minutes; Bit8~12:hour; Bit13~15:reserved") is None  # fields, not flags
    assert parse_bits("Bit0-3:read:1;SetGPRS IPSuccessed Bit4-7:GPRSstatus") is None
