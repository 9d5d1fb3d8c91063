"""`drivemap draft`: documents of every format -> a map that validates as written.

The fixtures are made here (openpyxl and python-docx write the Office files, fpdf2 the PDFs); the
seed manuals of shared/manuals are drafted and compared with the proven maps.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.frontend.formats import CURRENT
from drivemap.onboard.draft.cells import parse_address, parse_bits, parse_enum, parse_type
from drivemap.onboard.draft.cli import _time_limit
from drivemap.onboard.draft.naming import snake
from drivemap.onboard.draft.read import TimeLimit
from drivemap.onboard.draft.units import parse_scale

ROOT = Path(__file__).resolve().parents[3]
SEEDS = {"edx": ("004_698379178adcef99.txt", 0.95), "v2": ("003_81ad9a58587804cf.txt", 0.8),
         "vfd1000": ("002_65caa110b92ac236.txt", 0.75), "ev": ("001_47d2095fcebbe4cf.txt", 0.75)}


def _manuals() -> Path:
    for candidate in (ROOT.parent / "shared" / "manuals", Path("/work/shared/manuals")):
        if candidate.is_dir():
            return candidate
    pytest.skip("shared/manuals (the seed manuals) is not beside the repository")


def draft(tmp_path: Path, document: Path, name: str = "dev", *extra: str) -> tuple[int, Path, str]:
    out = tmp_path / "maps" / f"{name}.yaml"
    code = main(["draft", str(document), "-o", str(out), *extra])
    return code, out, out.read_text(encoding="utf-8") if out.exists() else ""


def registers(path: Path) -> dict[str, dict[str, Any]]:
    return {r["name"]: r for r in yaml.safe_load(path.read_text(encoding="utf-8"))["registers"]}


# ---------------------------------------------------------------- cell parsers


@pytest.mark.parametrize(("text", "unit_cell", "scale", "unit"), [
    ("0.01Hz", True, 0.01, "Hz"), ("×0.1 V", False, 0.1, "V"), ("1=0.1A", False, 0.1, "A"),
    ("0 ~ 65535  (1=0.01 VDC)", False, 0.01, "V"), ("Output current (10/1A)", False, 0.1, "A"),
    ("0.1 V/bit", False, 0.1, "V"), ("Hz", True, None, "Hz"), ("1000 means 100.0%", False, 0.1, "%"),
])
def test_scale_and_unit(text: str, unit_cell: bool, scale: float | None, unit: str) -> None:
    found = parse_scale(text, unit_cell=unit_cell)
    assert found is not None and found.scale == scale and found.unit == unit


def test_scale_with_a_footnote_the_document_does_not_print_is_left_out() -> None:
    found = parse_scale("TM2 AIN input value (1024 / 10V) *1", footnote=lambda n: False)
    assert found is not None and found.scale is None and "footnote *1" in found.note
    printed = parse_scale("TM2 AIN input value (1024 / 10V) *1", footnote=lambda n: True)
    assert printed is not None and printed.scale == pytest.approx(10 / 1024)


def test_addresses_enums_bits_types_names() -> None:
    assert parse_address("00E6H").hex_value == 0xE6  # type: ignore[union-attr]
    assert parse_address("0x1A").hex_value == 0x1A  # type: ignore[union-attr]
    plain = parse_address("40001")
    assert plain is not None and not plain.marked and plain.dec_value == 40001
    assert parse_address("Quantity") is None
    assert parse_enum("Resistive=1, inductive=2") == [(1, "Resistive"), (2, "inductive")]
    assert parse_enum("0: STOP\n2: RUN\n3: EBRAKE") == [(0, "STOP"), (2, "RUN"), (3, "EBRAKE")]
    assert parse_enum("0 ~ 65535 (1=0.01 VDC)") is None
    assert parse_bits("bit0: run, bit1: fault") == [(0, "run"), (1, "fault")]
    assert parse_type("Float") == "f32" and parse_type("signed", 2) == "s32" and parse_type("UINT16") == "u16"
    assert parse_type("") is None
    # a length resizes a type word without a width, never one that states it: "UINT32" with a length of 4
    # (bytes) is u32, not u64; with a length that fits neither words nor bytes the two cells contradict
    assert parse_type("unsigned", 4) == "u64" and parse_type("float", 4) == "f64"
    assert parse_type("UINT32", 4) == "u32" and parse_type("UINT32", 2) == "u32" and parse_type("INT16", 2) == "s16"
    assert parse_type("UINT32", 3) is None and parse_type("DINT", 1) is None and parse_type("float32", 1) is None
    assert snake("Phase 1 line to neutral volts", "x") == "phase_1_line_to_neutral_volts"
    assert snake("馬達狀態", "reg_0000") == "reg_0000"


def test_time_limit_stops_a_slow_step() -> None:
    started = time.monotonic()
    with pytest.raises(TimeLimit, match="time limit"), _time_limit(0.3):  # not an Exception: no library swallows it
        time.sleep(5)
    assert time.monotonic() - started < 2


# ---------------------------------------------------------------- the seed manuals


def _values(model: Any, enum: str) -> set[int]:
    return {v.value for e in model.enums if e.name == enum for v in e.members}


@pytest.mark.parametrize("model", sorted(SEEDS))
def test_seed_manual_draft_validates_and_states_no_wrong_type_or_scale(tmp_path: Path, model: str) -> None:
    name, floor = SEEDS[model]
    code, out, text = draft(tmp_path, _manuals() / name, model)
    assert code == 0 and out.exists()
    drafted = compile_map(out)  # validates as written
    proven = compile_map(ROOT / "maps" / f"{model}.yaml")
    stated = {(r.get("table", "holding"), int(r["address"])): r for r in registers(out).values()}
    cells = {(r.table, r.address + i * r.stride): r for r in drafted.registers for i in range(r.count)}
    exact = 0
    for reg in proven.registers:
        keys = [(reg.table, reg.address + i * reg.stride) for i in range(reg.count)]
        if not all(k in cells for k in keys):
            continue
        mine, entry = cells[keys[0]], stated.get(keys[0], {})
        if "type" in entry and len({r.address for r in proven.registers if r.address == reg.address}) == 1:
            assert mine.type == reg.type, f"{model} {reg.name}: type {mine.type} written, proven {reg.type}"
        if "scale" in entry and len([r for r in proven.registers if r.address == reg.address]) == 1:
            assert mine.scale == pytest.approx(reg.scale), f"{model} {reg.name}: scale {mine.scale}, proven {reg.scale}"
        if mine.bits and reg.bits:
            assert {b.offset for b in mine.bits} == {b.offset for b in reg.bits}, f"{model} {reg.name}: bits"
        if mine.enum and reg.enum:
            assert _values(drafted, mine.enum) == _values(proven, reg.enum), f"{model} {reg.name}: enum values"
        exact += all(cells[k].type == reg.type and cells[k].scale == pytest.approx(reg.scale) for k in keys)
    assert exact / len(proven.registers) >= floor, f"{model}: {exact}/{len(proven.registers)} exact"
    assert f"sha256: {__import__('hashlib').sha256((_manuals() / name).read_bytes()).hexdigest()}" in text
    assert all(r["source"].startswith(name) for r in registers(out).values())


def test_edx_draft_reads_bits_codes_scales_and_signs(tmp_path: Path) -> None:
    code, out, _ = draft(tmp_path, _manuals() / SEEDS["edx"][0], "edx")
    assert code == 0
    regs = {int(r["address"]): r for r in registers(out).values()}
    assert [b["offset"] for b in regs[0xE6]["bits"]] == [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 12]
    assert regs[0xF6]["scale"] == 0.1 and regs[0xF6]["unit"] == "A"
    assert regs[0xF8]["type"] == "s16"
    assert "scale" not in regs[0xF9] and "footnote *1" in regs[0xF9]["notes"]  # the footnote is not printed
    assert "scale" not in regs[0xE7]  # the table does not state it: left out, not guessed
    assert regs[0xE6]["access"] == "rw" and "access" not in regs[0xF6]  # "Only for reading": r, the default
    model = compile_map(out)
    assert len(next(e for e in model.enums if e.name == "FaultDescription").members) >= 30


# ---------------------------------------------------------------- formats


def _xlsx(path: Path, merged: bool = False) -> Path:
    import openpyxl

    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "Input registers"
    sheet.append(["Energy meter register map (function code 04h); floats are IEEE 754, high word first"])
    if merged:
        sheet.merge_cells("A1:F1")
    sheet.append(["Address", "Parameter", "Data type", "Length (words)", "Units", "Access"])
    sheet.append([30001, "Phase 1 line to neutral volts", "Float", 2, "V", "RO"])
    sheet.append([30003, "Phase 2 line to neutral volts", "Float", 2, "V", "RO"])
    sheet.append([30007, "Temperature 1", "INT16", 1, "0.1 °C", "R"])
    sheet.append([30008, "Temperature 2", "INT16", 1, "0.1 °C", "R"])
    sheet.append([30009, "Temperature 3", "INT16", 1, "0.1 °C", "R"])
    sheet.append([30011, "Read", "UINT16", 1, "", "R"])
    book.save(path)
    return path


def test_xlsx_modicon_floats_arrays_and_refused_names(tmp_path: Path) -> None:
    code, out, _ = draft(tmp_path, _xlsx(tmp_path / "meter.xlsx"), "meter")
    assert code == 0
    regs = registers(out)
    volts = regs["phase_1_line_to_neutral_volts"]
    assert (volts["table"], volts["address"], volts["type"], volts["word_order"]) == ("input", 0, "f32", "high_first")
    temp = next(r for r in regs.values() if r.get("count") == 3)
    assert (temp["address"], temp["type"], temp["scale"], temp["unit"]) == (6, "s16", 0.1, "°C")
    assert "read" not in regs  # a client attribute: the compiler refuses it and the draft renames it
    assert compile_map(out).registers
    # written in the current map format (with what it requires), so `drivemap migrate` has nothing to do
    doc = yaml.safe_load(out.read_text(encoding="utf-8"))
    assert doc["drivemap"] == CURRENT
    assert all(fc["broadcast_reason"] for fc in doc["protocol"]["function_codes"] if fc["broadcast"] is None)


def test_xlsx_with_merged_cells_is_drafted_with_the_reason_listed(tmp_path: Path, capsys: Any) -> None:
    code, out, _ = draft(tmp_path, _xlsx(tmp_path / "merged.xlsx", merged=True), "merged")
    assert code == 0 and compile_map(out)
    assert "merged cell ranges" in capsys.readouterr().out


def _docx(path: Path) -> Path:
    import docx

    document = docx.Document()
    document.add_heading("5.1 Holding registers (read with function 03h)", level=2)
    table = document.add_table(rows=1, cols=6)
    for cell, text in zip(table.rows[0].cells, ["Register (hex)", "Description", "Unit", "R/W", "Range", "Default"],
                          strict=True):
        cell.text = text
    for row in (["0x0100", "Frequency setpoint", "0.01Hz", "R/W", "0.00-400.00", "50.00"],
                ["0101h", "Load type", "", "RW", "Resistive=1, inductive=2", ""],
                ["0102h", "Status word", "", "R", "bit0: run, bit1: fault", ""],
                ["0103h", "Output voltage", "×0.1 V", "R", "", ""]):
        cells = table.add_row().cells
        for cell, text in zip(cells, row, strict=True):
            cell.text = text
    document.save(str(path))
    return path


def test_docx_units_ranges_enums_bits_access(tmp_path: Path) -> None:
    code, out, _ = draft(tmp_path, _docx(tmp_path / "drive.docx"), "drive")
    assert code == 0
    regs = {r["address"]: r for r in registers(out).values()}
    assert regs[0x100]["name"] == "frequency_setpoint"
    assert (regs[0x100]["scale"], regs[0x100]["unit"], regs[0x100]["min"], regs[0x100]["max"]) == (0.01, "Hz", 0, 400)
    assert regs[0x100]["default"] == 50 and regs[0x100]["access"] == "rw"
    assert "enum" in regs[0x101] and [b["offset"] for b in regs[0x102]["bits"]] == [0, 1]
    assert regs[0x103]["scale"] == 0.1 and "access" not in regs[0x103]
    model = compile_map(out)
    enum = next(e for e in model.enums if e.name == regs[0x101]["enum"])
    assert [v.label for v in enum.members] == ["Resistive", "inductive"]


def test_csv_hi_lo_byte_columns(tmp_path: Path) -> None:
    doc = tmp_path / "list.csv"
    doc.write_text("Hi Byte,Lo Byte,Name,Unit,R/W\n10,00,Motor current,1=0.1A,R\n10,01,Motor speed,rpm,R\n",
                   encoding="utf-8")
    code, out, _ = draft(tmp_path, doc, "csvdev")
    assert code == 0
    regs = registers(out)
    assert regs["motor_current"]["address"] == 0x1000 and regs["motor_current"]["scale"] == 0.1
    # a unit column that states the unit without a resolution states scale 1; the table stays open
    assert regs["motor_speed"]["unit"] == "r/min" and regs["motor_speed"]["scale"] == 1.0
    assert regs["motor_speed"]["review"] == ["table", "type"]


def test_markdown_and_html_tables(tmp_path: Path) -> None:
    md = tmp_path / "regs.md"
    md.write_text("## Input registers (04h)\n\n| Address | Name | Unit |\n|---|---|---|\n| 0x0000 | Line voltage | 0.1 V |\n"
                  "| 0x0001 | Line current | 0.01 A |\n", encoding="utf-8")
    code, out, _ = draft(tmp_path, md, "mddev")
    assert code == 0 and registers(out)["line_current"]["scale"] == 0.01
    assert registers(out)["line_voltage"]["table"] == "input"
    page = tmp_path / "regs.html"
    page.write_text("<html><body><table><tr><th>Register</th><th>Description</th><th>Access</th></tr>"
                    "<tr><td>0010h</td><td>Run command</td><td>W</td></tr></table></body></html>", encoding="utf-8")
    code, out, _ = draft(tmp_path, page, "htmldev")
    assert code == 0 and registers(out)["run_command"]["access"] == "w"


def _pdf(path: Path, pages: int = 1, text: bool = True, password: str | None = None) -> Path:
    from fpdf import FPDF

    pdf = FPDF()
    if password:
        pdf.set_encryption(owner_password="owner", user_password=password)
    pdf.set_font("Helvetica", size=9)
    for n in range(pages):
        pdf.add_page()
        if not text:
            pdf.rect(20, 20, 100, 50)
            continue
        pdf.cell(text=f"3.{n} Input registers (function code 04h)", new_x="LMARGIN", new_y="NEXT")
        with pdf.table() as table:
            for row in [["Address", "Parameter", "Unit"], [f"0x{2 * n:04X}", f"Voltage {n}", "0.1 V"],
                        [f"0x{2 * n + 1:04X}", f"Current {n}", "0.01 A"]]:
                cells = table.row()
                for cell in row:
                    cells.cell(cell)
    pdf.output(str(path))
    return path


def test_pdf_tables_with_page_and_row_sources(tmp_path: Path) -> None:
    code, out, _ = draft(tmp_path, _pdf(tmp_path / "meter.pdf", pages=2), "pdfdev")
    assert code == 0
    regs = registers(out)
    assert regs["voltage_1"]["address"] == 2 and regs["voltage_1"]["scale"] == 0.1
    assert regs["voltage_1"]["table"] == "input"
    assert "p.2" in regs["voltage_1"]["source"] and "meter.pdf" in regs["voltage_1"]["source"]
    code, out, _ = draft(tmp_path, tmp_path / "meter.pdf", "pdfpage", "--pages", "2")
    assert code == 0 and set(registers(out)) == {"voltage_1", "current_1"}


def test_pdf_table_continues_on_the_next_page(tmp_path: Path) -> None:
    from fpdf import FPDF

    pdf = FPDF()
    pdf.set_font("Helvetica", size=9)
    pdf.add_page()
    pdf.cell(text="2.1 Input registers (function code 04h)", new_x="LMARGIN", new_y="NEXT")
    with pdf.table(repeat_headings=0) as table:
        for row in [["Address", "Parameter", "Unit"]] + [[f"0x{n:04X}", f"Channel {n} voltage", "0.1 V"]
                                                         for n in range(80)]:
            cells = table.row()
            for cell in row:
                cells.cell(cell)
    pdf.output(str(tmp_path / "long.pdf"))
    code, out, _ = draft(tmp_path, tmp_path / "long.pdf", "longtable")
    assert code == 0
    regs = list(registers(out).values())
    assert len(regs) == 80 and all(r["table"] == "input" and r["scale"] == 0.1 for r in regs)
    assert any(r["source"].endswith(("p.2 table 1 row 1", "p.2 table 1 row 2")) for r in regs)


def test_pdf_without_ruled_tables_is_read_from_its_text_lines(tmp_path: Path) -> None:
    from fpdf import FPDF

    pdf = FPDF()
    pdf.set_font("Helvetica", size=9)
    lines = ["Floating point values are IEEE 754, high word first.", "3.1 Input registers (function code 04h)",
             "Address Parameter Data type Length Unit", "30001 Phase 1 line to neutral volts Float 2 V",
             "30003 Phase 2 line to neutral volts Float 2 V", "30007 Float charge voltage",
             "30009 Frequency FLOAT 2 Hz", "30011 Temperature INT16 1 0.1 °C"]
    for page in (lines[:5], lines[5:]):  # the table continues on page 2
        pdf.add_page()
        for line in page:
            pdf.cell(text=line, new_x="LMARGIN", new_y="NEXT")
    pdf.output(str(tmp_path / "text.pdf"))
    code, out, _ = draft(tmp_path, tmp_path / "text.pdf", "textpdf")
    assert code == 0
    regs = registers(out)
    volts = regs["phase_1_line_to_neutral_volts"]
    assert (volts["table"], volts["address"], volts["type"], volts["unit"]) == ("input", 0, "f32", "V")
    assert volts["source"] == "text.pdf p.1 line 4"
    assert "type" not in regs["float_charge_voltage"]  # a type word inside a name is not a type
    assert (regs["temperature"]["type"], regs["temperature"]["scale"], regs["temperature"]["unit"]) == ("s16", 0.1, "°C")
    assert regs["temperature"]["source"] == "text.pdf p.2 line 3"


def test_pdf_page_bound_is_listed(tmp_path: Path, capsys: Any) -> None:
    code, out, _ = draft(tmp_path, _pdf(tmp_path / "long.pdf", pages=6), "longdev", "--max-pages", "2")
    assert code == 0 and len(registers(out)) == 4
    assert "only pages 1-2 of 1-6 read" in capsys.readouterr().out


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize(("make", "message"), [
    (lambda p: _pdf(p / "scan.pdf", text=False), "no text on any page read"),
    (lambda p: _pdf(p / "locked.pdf", password="secret"), "encrypted"),
    (lambda p: (p / "broken.pdf").write_bytes(b"%PDF-1.4\n garbage\n") and p / "broken.pdf", "not a readable PDF"),
    (lambda p: (p / "broken.xlsx").write_bytes(b"PK\x03\x04 not a zip") and p / "broken.xlsx", "corrupt"),
    (lambda p: (p / "prose.txt").write_text("Name\tType\tUnit\nSpeed\tu16\trpm\nTorque\tu16\tNm\n") and p / "prose.txt",
     "no address column"),
    (lambda p: p / "missing.pdf", "cannot read file"),
])
def test_bad_documents_give_one_located_error_and_write_nothing(tmp_path: Path, capsys: Any, make: Any,
                                                                 message: str) -> None:
    document = make(tmp_path)
    code, out, _ = draft(tmp_path, document, "bad")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and not out.exists() and not (tmp_path / "maps").exists()
    assert len(err) == 1 and err[0].startswith(f"{document}: error: ") and message in err[0], err
    assert "Traceback" not in "\n".join(err)


def test_existing_output_is_refused_unless_force(tmp_path: Path, capsys: Any) -> None:
    document = _docx(tmp_path / "drive.docx")
    out = tmp_path / "maps" / "drive.yaml"
    out.parent.mkdir()
    out.write_text("mine\n", encoding="utf-8")
    assert main(["draft", str(document), "-o", str(out)]) == 1
    assert out.read_text(encoding="utf-8") == "mine\n" and "exists; not overwritten" in capsys.readouterr().err
    assert main(["draft", str(document), "-o", str(out), "--force"]) == 0
    assert compile_map(out) and sorted(os.listdir(out.parent)) == ["drive.yaml"]  # no temporary file left


def test_the_verb_in_an_empty_folder_writes_the_project_map(tmp_path: Path) -> None:
    document = _docx(tmp_path / "Acme VFD-100.docx")
    work = tmp_path / "empty"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "generator"), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-m", "drivemap", "draft", str(document)], cwd=work, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert sorted(p.relative_to(work).as_posix() for p in work.rglob("*")) == ["maps", "maps/acme_vfd_100.yaml"]
    assert "drivemap validate maps/acme_vfd_100.yaml" in run.stdout and "Registers drafted: 4" in run.stdout
    check = subprocess.run([sys.executable, "-m", "drivemap", "validate"], cwd=work, env=env, capture_output=True,
                           text=True, timeout=300)
    assert check.returncode == 0 and "maps/acme_vfd_100.yaml: ok" in check.stdout, check.stderr


def test_address_matrix_becomes_arrays_with_the_section_row_that_describes_each_column(tmp_path: Path) -> None:
    doc = tmp_path / "presets.txt"
    doc.write_text("4.6. Preset data\n\nPreset speed No.0 ~ Preset speed No.3   60 ~ 3000 r/min\n"
                   "Preset time No.0 ~ Preset time No.3   1 ~ 100 (1=0.1 s)\n\nRegister addresses (Hex)\n"
                   "Speed Time Torque\n0 0308h 0400h 0700h\n1 0309h 0401h 0701h\n2 030Ah 0402h 0702h\n"
                   "3 030Bh 0403h 0703h\n", encoding="utf-8")
    code, out, _ = draft(tmp_path, doc, "presets")
    assert code == 0
    regs = {r["address"]: r for r in registers(out).values()}
    assert {a: regs[a]["count"] for a in (0x308, 0x400, 0x700)} == {0x308: 4, 0x400: 4, 0x700: 4}
    assert (regs[0x308]["unit"], regs[0x308]["min"], regs[0x308]["max"]) == ("r/min", 60, 3000)
    assert (regs[0x400]["scale"], regs[0x400]["min"], regs[0x400]["max"]) == (0.1, 0.1, 10)
    assert "scale" not in regs[0x700] and "unit" not in regs[0x700]  # no row describes Torque: left out


def test_what_the_compiler_refuses_is_dropped_and_listed_never_written(tmp_path: Path, capsys: Any) -> None:
    doc = tmp_path / "refused.csv"
    doc.write_text("Address,Name,Unit,Range,Default,Access\n"
                   "0x0010,Speed limit,rpm,0-100,500,R/W\n"      # the default is outside the printed range
                   "0x0011,Class,,,,R\n"                          # a Python keyword as a name
                   "0x0011,Mode copy,,,,R\n"                      # the same address again
                   "0x0012,Temperature,0.1 °C,-40.0-125.0,,R\n", encoding="utf-8")
    code, out, _ = draft(tmp_path, doc, "refused")
    printed = capsys.readouterr().out
    assert code == 0 and compile_map(out)
    regs = registers(out)
    assert "default" not in regs["speed_limit"] and "default left out" in regs["speed_limit"]["notes"]
    assert (regs["speed_limit"]["min"], regs["speed_limit"]["max"]) == (0, 100)
    assert "class" not in regs and any(r["address"] == 0x11 for r in regs.values())
    assert len([r for r in regs.values() if r["address"] == 0x11]) == 1 and "overlaps" in printed
    # -40 does not fit the u16 a register without a stated type is: the minimum is dropped, not the type guessed
    assert "min" not in regs["temperature"] and (regs["temperature"]["max"], regs["temperature"]["scale"]) == (125, 0.1)
    assert "min left out: the compiler refused it" in regs["temperature"]["notes"]


_FRAGMENTS = ["Address", "Register No.", "Name", "Unit", "Range", "R/W", "R", "W", "0x0010", "00E6H", "0101h", "40001",
              "30001", "Bit", "Description", "Code", "0", "1", "F", "5-F", "0.01Hz", "1=0.1A", "10/1A", "0 ~ 100",
              "0: STOP", "1: RUN", "bit0: run", "Resistive=1", "(Reserved)", "寄存器", "名稱", "內容", "4.2 Monitor",
              "<table><tr><td>x</td></tr></table>", "|", "---", "*1", "~", "", "-", "(0909h)", "09-10", "No.0",
              "Speed Time", "0 0308h 0400h", "1 0309h 0401h", "<|PAGE-MARK|>", "\f", "30001 Phase volts Float 2 V",
              "40001 Mode UINT16 1", "Data type", "Length", "class", "read", "None", "Very long name " * 8]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(st.sampled_from(_FRAGMENTS), max_size=6), max_size=40),
       st.sampled_from(["\t", " ", " | ", "  "]))
def test_any_text_drafts_or_fails_with_a_located_error(lines: list[list[str]], sep: str) -> None:
    from drivemap.onboard.draft.assemble import draft as draft_map
    from drivemap.onboard.draft.read_text import read_text
    from drivemap.onboard.draft.tables import Source
    from drivemap.onboard.draft.writer import settle

    text = "\n".join(sep.join(cells) for cells in lines)
    source = Source("fuzz.txt", "0" * 64, read_text(text), text)
    result = draft_map(source, "fuzz")
    if result.registers:
        _, errors = settle(result, "", "fuzz.yaml")
        assert errors == []


def test_scale_column_word_units_and_register_numbers_flagged(tmp_path: Path, capsys: Any) -> None:
    doc = tmp_path / "inverter.md"
    doc.write_text("## Input Registers\n\n| Input Register | Name | Range | Scaling | Units/notes |\n|---|---|---|---|---|\n"
                   "| 3 | DC_VOLTS | 0-1000 | 0.1 | Volts |\n| 4 | DC_AMPS | 0-500 | 1 | Amps |\n", encoding="utf-8")
    code, out, _ = draft(tmp_path, doc, "inverter")
    assert code == 0
    regs = registers(out)
    assert (regs["dc_volts"]["scale"], regs["dc_volts"]["unit"], regs["dc_volts"]["address"]) == (0.1, "V", 3)
    assert "range" not in regs["dc_volts"] and "min" not in regs["dc_volts"]  # raw or engineering? not said
    assert (regs["dc_amps"]["scale"], regs["dc_amps"]["unit"], regs["dc_amps"]["max"]) == (1, "A", 500)
    assert "numbers registers from 1" in regs["dc_volts"]["notes"]
    assert "0- or 1-based" in capsys.readouterr().out


def test_coil_and_discrete_input_tables(tmp_path: Path) -> None:
    doc = tmp_path / "io.md"
    doc.write_text("## Coils\n\n| Coil | Name | Notes |\n|---|---|---|\n| 1 | Inverter | |\n| 2 | Charger | R/W |\n\n"
                   "## Discrete Input\n\n| Discrete Input | Name |\n|---|---|\n| 1 | AC in valid |\n", encoding="utf-8")
    code, out, _ = draft(tmp_path, doc, "io")
    assert code == 0
    regs = registers(out)
    assert (regs["inverter"]["table"], regs["charger"]["table"], regs["ac_in_valid"]["table"]) == ("coil", "coil", "discrete")
    assert all("type" not in r and "scale" not in r for r in regs.values())
    codes = {f["code"] for f in yaml.safe_load(out.read_text(encoding="utf-8"))["protocol"]["function_codes"]}
    assert {1, 2} <= codes


def test_a_measured_value_takes_no_value_list_from_its_text() -> None:
    """A row whose unit column states a resolution with a unit (``0.1kW``) is a measured value: numbered
    lines in its free text (often the next row's description, printed above that row's number) are not
    its value list, and its scale is the unit column's. A row with no unit keeps its value list."""
    from drivemap.onboard.draft.fields import Context, Raw, draft_fields

    ctx = Context("doc.pdf", lambda _: False)
    text = "0: two phase\n1: three phase"
    measured = draft_fields(Raw(5000, "input", "p.6 row 20", cells={"type": "U16", "unit": "0.1kW"}, text=text), ctx)
    assert "enum" not in measured.entry and measured.entry["scale"] == 0.1 and measured.entry["unit"] == "kW"
    assert any("not read as this register's" in n for n in measured.notes)
    remark = draft_fields(Raw(5018, "input", "p.7 row 2", cells={"type": "U16", "unit": "0.1V", "description": "Refer to Output type (address: 5002) 0: phase voltage; 2: line voltage"}), ctx)
    assert "enum" not in remark.entry and remark.entry["scale"] == 0.1
    listed = draft_fields(Raw(5001, "input", "p.6 row 27", cells={"type": "U16", "unit": ""}, text=text), ctx)
    assert [v for v, _ in listed.entry["enum"]] == [0, 1]  # type: ignore[union-attr]
