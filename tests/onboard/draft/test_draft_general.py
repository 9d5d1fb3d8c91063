"""General drafting rules found on the public corpus, each on an invented document of the same shape:
review markers instead of defaults, document statements (numbering from 1, word order of 32-bit values)
recorded as the source of what they decide, register spans and pairs, spaced type tokens, a per-row
register-type column, a remark that is no range, a bare resolution in a Unit/Ratio column."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.draft.assemble import Hints, draft
from drivemap.onboard.draft.read import read_document


def drafted(tmp_path: Path, name: str, text: str) -> dict[str, dict[str, Any]]:
    doc = tmp_path / name
    doc.write_text(text, encoding="utf-8")
    result = draft(read_document(doc), "dev")
    return {str(d.entry["name"]): d.entry for d in result.registers}


def test_fields_left_open_are_review_items_not_defaults(tmp_path: Path) -> None:
    regs = drafted(tmp_path, "list.csv", "Address,Name,Type\n100,Status code,\n102,Energy,U32\n104,Temp,S16\n")
    assert regs["status_code"]["review"] == ["table", "type", "scale"] and "type" not in regs["status_code"]
    # a 32-bit type without a stated word order keeps its type; the word order is open
    assert regs["energy"]["type"] == "u32" and regs["energy"]["review"] == ["table", "word_order", "scale"]
    assert regs["temp"]["type"] == "s16" and regs["temp"]["review"] == ["table", "scale"]


DOC = """\
# Inverter protocol

U32: 32-bit unsigned integer; little-endian for double-word data. Big-endian for byte data.
Visit all registers by subtracting 1 from the register address.

### Input registers (function code 0x04)

| No. | Name | Register | Data type | Data range | Unit/Ratio | Remarks |
| --- | --- | --- | --- | --- | --- | --- |
| 1. | Total power | 5031 - 5032 | S32 | | W | |
| 2. | Power factor | 5035 | S16 | | 0.001 | |
| 3. | Work state | 5038 | UINT 16 | | | Data of address 5039 - 5045 are valid only on fault |
| 4. | Daily energy | 5003 - 5004 | U32 | | 0.1kWh | |
"""


def test_document_statements_decide_and_are_recorded(tmp_path: Path) -> None:
    regs = drafted(tmp_path, "inverter.md", DOC)
    power = regs["total_power"]
    assert (power["table"], power["address"], power["type"], power["word_order"]) == ("input", 5030, "s32", "low_first")
    assert (power["scale"], power["unit"]) == (1.0, "W") and "review" not in power
    assert "address 5031 printed; the protocol address is 5030" in power["notes"]
    assert "'subtracting 1 from the register address'" in power["notes"]
    assert "word_order low_first: inverter.md line 3: '32-bit unsigned integer; little-endian'" in power["notes"]
    assert (regs["power_factor"]["address"], regs["power_factor"]["scale"]) == (5034, 0.001)
    state = regs["work_state"]
    assert state["type"] == "u16" and "min" not in state and "max" not in state  # a remark is no range
    assert (regs["daily_energy"]["scale"], regs["daily_energy"]["unit"]) == (0.1, "kWh")


def test_without_a_statement_the_printed_number_stays_and_is_noted(tmp_path: Path) -> None:
    regs = drafted(tmp_path, "inverter.md", DOC.replace("Visit all registers by subtracting 1 from the register "
                                                        "address.", ""))
    assert regs["total_power"]["address"] == 5031 and "as printed under" in regs["total_power"]["notes"]


def test_register_type_column_pairs_and_plus(tmp_path: Path) -> None:
    regs = drafted(tmp_path, "charger.csv", "Reg. Type,Address,Name,Type,Unit\nHolding,1000,State,UINT 16,\n"
                                            "Input,1020+1021,Active power,UINT 32,W\nHolding,1030~1031,Energy,UINT 32,Wh\n")
    assert (regs["state"]["table"], regs["state"]["type"]) == ("holding", "u16")
    assert (regs["active_power"]["table"], regs["active_power"]["address"], regs["active_power"]["type"]) == \
        ("input", 1020, "u32")
    assert (regs["energy"]["table"], regs["energy"]["address"]) == ("holding", 1030)


RANGES = """\
# Storage inverter protocol

| Addr | Register meaning | R/W | data range | unit | note |
| --- | --- | --- | --- | --- | --- |
| 3 | Device type | R | | | |
| 61 | Self-check time | R/W | [0,1000] | s | MI |
| 501 | Active energy today | R | [-32768,32767] | 0.1kWh | |
| 502 | Counter | R | [0,65535] | | |

## Address areas

0-59 registers are read-only, function code 0x03.
60-499 registers are read/write, function code 0x10.
Battery data (1000-1999) is read with function code 0x04.
"""


def test_range_statements_register_meaning_and_interval_spans(tmp_path: Path) -> None:
    """A line giving an address range one function code decides the table of the rows in it (and says so);
    outside every range the table stays open. ``Register meaning`` is the name column, not a second address
    column. ``[a,b]`` is a range, and a range that is exactly a raw type's span states that type (and no limit)."""
    regs = drafted(tmp_path, "storage.md", RANGES)
    assert set(regs) == {"device_type", "self_check_time", "active_energy_today", "counter"}
    assert regs["device_type"]["table"] == "holding" and "0-59 registers are read-only" in regs["device_type"]["notes"]
    assert regs["self_check_time"]["table"] == "holding" and "60-499" in regs["self_check_time"]["notes"]
    assert regs["self_check_time"]["min"] == 0 and regs["self_check_time"]["max"] == 1000
    # [0,1000] does not say signed or unsigned, but reads the same either way: u16 changes no value it may hold
    assert regs["self_check_time"]["type"] == "u16" and "reads the same either way" in regs["self_check_time"]["notes"]
    energy = regs["active_energy_today"]
    assert "table" in energy["review"] and "table" not in energy  # 501 is in no stated range
    assert energy["type"] == "s16" and "min" not in energy and energy["scale"] == 0.1
    assert regs["counter"]["type"] == "u16" and "type" not in regs["counter"].get("review", [])


PLAIN_FIVE_DIGITS = """\
# Logger protocol

| SN | Name | Read/Write | Type | Unit | Gain | Address | Quantity |
| --- | --- | --- | --- | --- | --- | --- | --- |
| 1 | Date and time | RW | U32 | N/A | 1 | 40000 | 2 |
| 2 | Alarm info | RO | U16 | N/A | 1 | 50000 | 1 |

## Meter

| SN | Name | Read/Write | Type | Unit | Gain | Address | Quantity |
| --- | --- | --- | --- | --- | --- | --- | --- |
| 1 | Phase A voltage | RO | I32 | V | 100 | 32260 | 2 |
| 2 | Phase B voltage | RO | I32 | V | 100 | 32262 | 2 |
"""


def test_five_digit_addresses_no_modicon_number_can_be_and_an_undirected_gain(tmp_path: Path) -> None:
    """A document that prints 40000 and 50000 numbers its registers plainly: its 3xxxx numbers are addresses
    too, not Modicon input references (said on each). A ``Gain`` of 100 does not say raw x 100 or raw / 100:
    the scale stays open, never a guessed multiplier."""
    regs = drafted(tmp_path, "logger.md", PLAIN_FIVE_DIGITS)
    assert regs["alarm_info"]["address"] == 50000 and regs["date_and_time"]["address"] == 40000
    volts = regs["phase_a_voltage"]
    assert volts["address"] == 32260 and "table" not in volts
    assert "address 32260 as printed, not a Modicon number" in volts["notes"] and "the document prints address 40000" in volts["notes"]
    assert "scale" not in volts and "scale" in volts["review"] and "Gain 100: raw x 100 or raw / 100?" in volts["notes"]
    assert regs["date_and_time"]["scale"] == 1  # a gain of 1 is 1 either way


def test_a_persons_hints_fill_only_what_the_document_leaves_open(tmp_path: Path) -> None:
    """``--assume`` and ``--address-base``: used where the document states nothing, recorded on each
    register they decide, in the map's device notes and in the review list; refused when malformed."""
    doc = tmp_path / "hints.csv"
    doc.write_text("No.,Name,Type,Unit\n1,Voltage,,V\n2,Energy,U32,kWh\n3,Mode,S16,\n", encoding="utf-8")
    plain = draft(read_document(doc), "dev")
    regs = {str(d.entry["name"]): d for d in plain.registers}
    assert "table" not in regs["voltage"].entry and "type" not in regs["voltage"].entry
    assert any("0- or 1-based" in r for r in plain.review)
    hinted = draft(read_document(doc), "dev", Hints((("table", "input"), ("type", "f32"), ("word_order", "low_first")), 1))
    regs = {str(d.entry["name"]): d for d in hinted.registers}
    volts, energy, mode = regs["voltage"], regs["energy"], regs["mode"]
    assert volts.entry["table"] == "input" and volts.entry["type"] == "f32" and volts.entry["word_order"] == "low_first"
    assert volts.entry["address"] == 0 and energy.entry["address"] == 1  # numbered from 1, as the person said
    assert "type f32: source: assumed by the user (--assume type=f32)" in volts.notes
    assert "table input: source: assumed by the user (--assume table=input)" in volts.notes
    assert energy.entry["type"] == "u32" and mode.entry["type"] == "s16"  # the document's types stand
    assert "word_order low_first: source: assumed by the user (--assume word_order=low_first)" in energy.notes
    assert "assumed by the user, not read from the document: --assume table=input" in hinted.data["device"]["notes"]
    assert any(r.startswith("assumed by the user: --address-base 1") for r in hinted.review)
    assert not any("0- or 1-based" in r for r in hinted.review)
    as_printed = draft(read_document(doc), "dev", Hints((), 0))
    regs = {str(d.entry["name"]): d for d in as_printed.registers}
    assert regs["voltage"].entry["address"] == 1 and not any("0- or 1-based" in r for r in as_printed.review)
    assert "address as printed: source: assumed by the user (--address-base 0)" in regs["voltage"].notes


def test_iec_hex_addresses_and_a_cell_whose_two_forms_disagree(tmp_path: Path) -> None:
    """``16#2136`` is IEC 61131-3 hex; ``16#2136 = 08502`` prints the decimal beside it. Where the two
    disagree, the row is listed with both readings, never drafted at either."""
    doc = tmp_path / "vfd.csv"
    doc.write_text("Address,Name,Type,Unit\n16#2136 = 08502,Output frequency,U16,0.01Hz\n16#2137,Output current,U16,"
                   "0.1A\n16#2138 = 08510,Output voltage,U16,V\n", encoding="utf-8")
    result = draft(read_document(doc), "dev")
    regs = {str(d.entry["name"]): d.entry for d in result.registers}
    assert regs["output_frequency"]["address"] == 0x2136 and regs["output_current"]["address"] == 0x2137
    assert "output_voltage" not in regs
    (skip,) = result.skipped
    assert skip.reason == "address '16#2138 = 08510': 16#2138 is 8504, the decimal beside it says 8510: the two " \
                          "forms disagree"


def test_a_headerless_page_of_addresses_is_listed_row_by_row(tmp_path: Path) -> None:
    """A table with no header row (its header on an earlier page, over other columns) is not read under a
    guessed header: each of its address rows is listed as skipped with the reason."""
    from drivemap.onboard.draft.rows import grid_raws
    from drivemap.onboard.draft.tables import Row, Table

    rows = [Row(["060", "Day active energy", "", "R"], 10, 1, table="p.10 table 1"),
            Row(["", "continued text", "", ""], 10, 2, table="p.10 table 1"),
            Row(["061", "Day reactive energy", "", "R"], 10, 3, table="p.10 table 1"),
            Row(["079", "Grid frequency", "", "R"], 10, 4, table="p.10 table 1")]
    raws, skipped = grid_raws(Table(None, rows, 10, None, "", label="p.10 table 1"), None, None)
    assert raws == [] and [s.text.split(" | ")[0] for s in skipped] == ["060", "061", "079"]
    assert all(s.reason.startswith("table without a header row: its columns are not known") for s in skipped)
    text = Table(None, [Row(["Note", "a remark"], 10, 1), Row(["See", "page 3"], 10, 2)], 10, None, "")
    assert grid_raws(text, None, None) == ([], [])  # no addresses: no register table, nothing listed



def test_a_string_coded_in_ascii_names_no_framing(tmp_path: Path) -> None:
    """"ASCII code" in a register's cells is how a string is coded, not the device's framing; a document
    that names no framing gets rtu as a placeholder listed to review, one that does gets what it names."""
    table = "Address,Name,Type,Remark\n100,Serial number,U16,MSB: ASCII code\n102,Model,ASCII,\n"
    for name, text, modes, listed in [
        ("strings.csv", table, ["rtu"], True),
        ("framed.md", "The device speaks Modbus ASCII (7E1).\n\n" + table.replace(",", " | "), ["ascii"], False),
        ("both.md", "ASCII mode and RTU mode are both supported.\n\n" + table.replace(",", " | "), ["rtu", "ascii"],
         False),
    ]:
        doc = tmp_path / name
        doc.write_text(text, encoding="utf-8")
        result = draft(read_document(doc), "dev")
        assert result.data["protocol"]["modes"] == modes, name
        assert result.data["protocol"]["ports"][0]["modes"] == modes, name
        assert any(item.startswith("protocol.modes") for item in result.review) is listed, name


def test_a_power_factor_row_proves_a_gain_divides(tmp_path: Path) -> None:
    """A power factor lies between -1 and 1: a Gain of 1000 on its row can only divide, so the document's
    Gain column divides on every row, in every table (each register says why); a gain on a power factor
    with a unit, or a column headed Multiplier, proves nothing."""
    with_pf = PLAIN_FIVE_DIGITS + "| 3 | Power factor | RO | I16 | N/A | 1000 | 32284 | 1 |\n"
    regs = drafted(tmp_path, "logger.md", with_pf)
    volts, pf = regs["phase_a_voltage"], regs["power_factor"]
    assert (volts["scale"], pf["scale"]) == (0.01, 0.001) and "scale" not in volts.get("review", [])
    assert "Gain 100 read as raw / 100: the document's power factor row" in volts["notes"]
    assert "'Power factor') has Gain 1000" in volts["notes"]
    for other in (with_pf.replace("| N/A | 1000 | 32284", "| % | 1000 | 32284"),  # a unit: not the quantity -1..1
                  with_pf.replace("| 1000 | 32284", "| 1 | 32284"),  # a gain of 1 proves nothing
                  with_pf.replace("Power factor", "Power limit")):
        regs = drafted(tmp_path, "logger.md", other)
        assert "scale" not in regs["phase_a_voltage"] and "scale" in regs["phase_a_voltage"]["review"]
    multiplier = with_pf.replace("| Gain |", "| Multiplier |")
    assert drafted(tmp_path, "logger.md", multiplier)["phase_a_voltage"]["scale"] == 100


LIST_AND_FLAT = """\
# Meter register list

| Registers | Name | Units | Access | Description |
| --- | --- | --- | --- | --- |
| 1001 | VoltA | 0.1 V | Read-Only | Voltage, phase A |
| 1002 | PowerA | W | Read-Only | Real power, phase A |
| 1003 | Mode | s | Read/Write | Operating mode |

# Flattened

| index | Registers | Base (hex) | Base (dec, origin-1) | Name | Type | Units |
| --- | --- | --- | --- | --- | --- | --- |
| 1 | 1001 | 3E8 | 1001 | VoltA | uint16_t | 0.1 V |
| 2 | 1002 | 3E9 | 1002 | PowerA | int16_t | W |
| 3 | 1003 | 3EA | 1003 | Mode | int16_t | 1 ms |
"""


def test_a_register_printed_in_two_tables_is_one_register_and_a_header_says_origin_1(tmp_path: Path) -> None:
    """A header saying its numbers count from 1 ("Base (dec, origin-1)", its hex column one less) decides
    the numbering of the whole document; a register printed in two tables (same address and label) is
    one register that takes what only the second printing states (noted where), and a field the two
    printings state differently is left open, naming both."""
    doc = tmp_path / "meter.md"
    doc.write_text(LIST_AND_FLAT, encoding="utf-8")
    result = draft(read_document(doc), "dev")
    regs = {str(d.entry["name"]): d for d in result.registers}
    assert sorted(regs) == ["mode", "power_a", "volt_a"]  # the second printings are joined, not drafted
    volts, power, mode = regs["volt_a"].entry, regs["power_a"].entry, regs["mode"].entry
    assert (volts["address"], volts["type"], volts["scale"], volts["unit"]) == (1000, "u16", 0.1, "V")
    assert "header 'Base (dec, origin-1)', its hex column one less on 3 rows" in "; ".join(regs["volt_a"].notes)
    assert power["type"] == "s16" and "type s16: printed at p.1 line 14 (the same register)" in "; ".join(regs["power_a"].notes)
    assert "access" not in power  # read-only, as the first printing says; the second says nothing of it
    assert "unit" not in mode and "unit left open: the document states it differently" in "; ".join(regs["mode"].notes)
    joined = [s for s in result.skipped if "what it states is joined there" in s.reason]
    assert [s.where for s in joined] == ["p.1 line 13", "p.1 line 14", "p.1 line 15"]
    # a hex column that prints the same numbers contradicts the header: the numbers stay as printed
    same = LIST_AND_FLAT.replace("| 3E8 |", "| 3E9 |")
    doc.write_text(same, encoding="utf-8")
    volts = {str(d.entry["name"]): d.entry for d in draft(read_document(doc), "dev").registers}["volt_a"]
    assert volts["address"] == 1001 and "as printed under" in str(volts["notes"])


def test_the_text_above_a_table_stops_at_the_table_before_it(tmp_path: Path) -> None:
    """Another table's cells say nothing about the next one: a `Read/Write` cell of the first ruled table on
    a PDF page, or of the first table of a text, is no statement about the access or table of the next."""
    from fpdf import FPDF

    first = [["Address", "Name", "Access"], ["100", "Mode", "Read/Write"], ["101", "Setpoint", "Read/Write"]]
    second = [["Address", "Name", "Unit"], ["200", "Voltage", "0.1 V"], ["201", "Current", "0.01 A"]]
    pdf = FPDF()
    pdf.set_font("Helvetica", size=9)
    pdf.add_page()
    for rows in (first, second):
        with pdf.table() as table:
            for row in rows:
                cells = table.row()
                for cell in row:
                    cells.cell(cell)
        pdf.ln(4)
    pdf.output(str(tmp_path / "two.pdf"))
    text = "\n\n".join("\n".join("| " + " | ".join(r) + " |" for r in (rows[:1] + [["---"] * 3] + rows[1:]))
                       for rows in (first, second))
    (tmp_path / "two.md").write_text(text + "\n", encoding="utf-8")
    for name in ("two.pdf", "two.md"):
        regs = {str(d.entry["name"]): d.entry for d in draft(read_document(tmp_path / name), "dev").registers}
        assert regs["mode"]["access"] == "rw", name
        volts = regs["voltage"]
        assert "access" not in volts and "table" not in volts and "table" in volts["review"], name


def test_milli_and_micro_ohm_units(tmp_path: Path) -> None:
    """`mΩ` and `uΩ` (a BMS's wire resistances) are units: a unit column's bare unit is one per count."""
    regs = drafted(tmp_path, "bms.csv", "Address,Name,Type,Unit\n113,Battery resistance,U16,mΩ\n"
                   "114,Wire resistance 0,U16,uΩ\n115,Cell resistance,U16,μΩ\n")
    assert [(r["unit"], r["scale"]) for r in regs.values()] == [("mΩ", 1), ("µΩ", 1), ("µΩ", 1)]


SPAN_TEXT = """\
Visit all registers by subtracting 1 from the register address.

| No. | Name | Register | Data type | Unit |
| --- | --- | --- | --- | --- |
| 1. | Inverter firmware | 13250-13264 | UTF-8 | |
| 2. | Serial number | 4990~4999 | ASCII | |
| 3. | Model name | 5000-5007 | STRING | |
| 4. | Reserved 1 | 13295-13309 | UTF-8 | |
| 5. | Total energy | 5008-5009 | U32 | kWh |
"""


def test_a_span_of_text_is_one_string_register(tmp_path: Path) -> None:
    """A span whose type is text (`13250-13264 | UTF-8`) is one string register over all its registers, its
    encoding as the type says (open where it says only "string"), numbered as the document numbers; a
    numbered reserved row ("Reserved 1") is reserved; text has no scale."""
    regs = drafted(tmp_path, "spans.md", SPAN_TEXT)
    firmware, serial, model = regs["inverter_firmware"], regs["serial_number"], regs["model_name"]
    assert (firmware["address"], firmware["type"], firmware["length"], firmware["encoding"]) == (13249, "string", 15, "utf-8")
    assert (serial["address"], serial["length"], serial.get("encoding", "ascii")) == (4989, 10, "ascii")
    assert firmware["review"] == serial["review"] == ["table"] and "scale" not in firmware  # no table is named
    assert model["length"] == 8 and model["review"] == ["table", "encoding"]
    assert "reserved_1" not in regs and not any(r.get("label", "").startswith("Reserved") for r in regs.values())
    assert regs["total_energy"]["type"] == "u32" and regs["total_energy"]["address"] == 5007


def test_microseconds_and_a_delay_named_in_chinese_or_abbreviated(tmp_path: Path) -> None:
    """`us`, `µs` and `μs` are microseconds (`uS`, microsiemens, is not read as a time); a unit cell `S`
    beside a name that says delay (`延迟`, or `Dly` in a CamelCase name) reads as seconds, as beside `delay`
    or `时间` it did. A lower-case word that only contains `dly` (`friendly`) says nothing."""
    regs = drafted(tmp_path, "bms.csv", "Address,Name,Type,Unit\n"
                   "128,短路保护延迟SCPDelay,U16,us\n129,Pulse width,U16,μs\n130,Conductivity,U16,uS\n"
                   "131,充电过流保护延迟TIMBatCOCP,U16,S\n132,ChgOcpDly,U16,S\n133,Friendly mode,U16,S\n")
    got = [(r.get("unit"), r.get("scale")) for r in regs.values()]
    assert got[:2] == [("µs", 1), ("µs", 1)]
    assert got[2][0] is None and got[5][0] is None  # neither microsiemens nor a friendly mode is a time
    assert got[3:5] == [("s", 1), ("s", 1)]
