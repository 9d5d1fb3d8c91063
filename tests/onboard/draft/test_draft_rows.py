"""Draft, row by row: offsets that are no addresses, and two readings of one row that disagree."""

from __future__ import annotations

from drivemap.onboard.draft.assemble import Draft, draft
from drivemap.onboard.draft.tables import Row, Source, Table


def _one_table(header: list[str], body: list[list[str]], page: int, label: str, text: str = "") -> Draft:
    """The draft of a document holding one table: ``header`` over ``body``, on ``page``."""
    rows = [Row(cells, page, i + 1) for i, cells in enumerate([header, *body])]
    return draft(Source("doc.pdf", "0" * 64, [Table(None, rows, page, None, "", label=label)], text), "doc")


def test_offsets_are_never_drafted_as_addresses() -> None:
    """A register table whose numbers are offsets from a block's base (offsets in words or bytes, the
    table does not say) drafts no register at an offset as if it were an address. With no start address
    printed beside the block its rows, and those of its headerless continuation on the next page, are
    listed; with one (``0x1000``, once, in a cell of the block) they are drafted at start + offset, the
    document's own sum, with the address open for review."""
    from drivemap.onboard.draft.tables import Row, Source, Table

    head = [Row(["Start address", "Offset", "", "Type", "R/W", "Content", "Unit"], 1, 1),
            Row(["", "HEX", "DEC", "", "", "", ""], 1, 2)]
    names = ["Sleep", "UnderVolt", "OverVolt", "Balance", "FullCharge", "Empty", "Recharge"]  # no array
    body = [Row(["", f"0x{4 * i:04X}", str(4 * i), "UINT32", "RW", names[i], "mV"], 1, 3 + i) for i in range(4)]
    page2 = [Row([f"0x{4 * i:04X}", str(4 * i), "UINT32", "RW", names[i], "mV"], 2, i + 1) for i in range(4, 7)]
    tables = [Table(None, head + body, 1, None, "", label="p.1 table 1"), Table(None, page2, 2, None, "", label="p.2 table 1")]
    result = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms")
    assert result.registers == []
    reasons = [s.reason for s in result.skipped if s.text.split(" | ")[0].startswith("0x")]
    assert len(reasons) == 7
    assert all("offset" in r and "from a base address" in r and "to be stated by a person" in r for r in reasons)

    body[1].cells[0] = "0x1000"  # the base, once, in the middle of its merged cell
    result = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms")
    assert [r.entry["address"] for r in result.registers] == [0x1000 + 4 * i for i in range(7)]
    assert all("address" in r.entry["review"] for r in result.registers)  # type: ignore[operator]

    # the same table headed as addresses drafts its rows at them
    head[0].cells[1], body[1].cells[0] = "Register address", ""
    result = draft(Source("meter.pdf", "0" * 64, tables[:1], ""), "meter")
    assert [r.entry["address"] for r in result.registers] == [0, 4, 8, 12]


def test_two_readings_of_one_row_that_disagree_leave_the_field_open() -> None:
    """One printed row read twice (a page's grid seen as two tables whose columns split differently:
    ``u | int16`` against ``uint16``) states two types: neither is taken. Rows of different pages at one
    address are different registers (pages, sections) and keep their own."""
    from drivemap.onboard.draft.assemble import _contradictions
    from drivemap.onboard.draft.tables import Drafted

    def reg(where: str, rtype: str) -> Drafted:
        return Drafted({"table": "holding", "address": 778, "type": rtype}, where)

    same_page = [reg("p.4 table 1 row 29", "s16"), reg("p.4 table 2 row 7", "u16")]
    _contradictions(same_page)
    for d in same_page:
        assert "type" not in d.entry and d.entry["review"] == ["type"]
        assert any("p.4 table 1 row 29: s16; p.4 table 2 row 7: u16" in n for n in d.notes)
    pages = [reg("p.11 line 1056", "s16"), reg("p.12 line 1186", "u16")]
    _contradictions(pages)
    assert [d.entry["type"] for d in pages] == ["s16", "u16"] and all("review" not in d.entry for d in pages)
    agree = [reg("p.4 table 1 row 29", "u16"), reg("p.4 table 2 row 7", "u16")]
    _contradictions(agree)
    assert [d.entry["type"] for d in agree] == ["u16", "u16"]


def test_a_span_with_a_full_width_tilde_is_one_register_of_two_words() -> None:
    """``5004～5005`` (full-width tilde, as Chinese typesetting prints it) reads as ``5004~5005``."""
    from drivemap.onboard.draft.cells import is_address_range
    from drivemap.onboard.draft.tables import Row, Source, Table

    assert is_address_range("0x10～0x1F") and is_address_range("0x10~0x1F")
    rows = [Row(["No.", "Name", "Register", "Data type", "Unit"], 6, 1),
            Row(["11.", "Total Output Energy", "5004～5005", "U32", "0.1kWh"], 6, 2),
            Row(["12.", "Daily Output Energy", "5006", "U16", "0.1kWh"], 6, 3)]
    result = draft(Source("inverter.pdf", "0" * 64, [Table(None, rows, 6, None, "", label="p.6 table 1")], ""), "inv")
    total = next(r.entry for r in result.registers if r.entry.get("label") == "Total Output Energy")
    assert (total["address"], total["type"], total["scale"], total["unit"]) == (5004, "u32", 0.1, "kWh")


def test_a_row_without_a_type_column_states_the_type_token_it_writes() -> None:
    """A table without a type column: a row whose remark writes one type token (``S16``) states that type;
    a row that writes two different ones states none."""
    from drivemap.onboard.draft.fields import Context, Raw, draft_fields

    ctx = Context("doc.docx", lambda _: False)
    one = draft_fields(Raw(604, "holding", "table 9 row 4", cells={"unit": "1W", "description": "A phase power R 1W S16"}), ctx)
    assert one.entry["type"] == "s16" and "type" not in (one.entry.get("review") or ())
    assert any("the row says 'S16'" in n for n in one.notes)
    two = draft_fields(Raw(605, "holding", "table 9 row 5", cells={"unit": "1W"}, text="low word U16, with 606 as S32"), ctx)
    assert "type" not in two.entry and "type" in two.entry["review"]  # type: ignore[operator]


def test_a_documents_own_glossary_of_types_decides_its_type_tokens() -> None:
    """A document that defines its type words (``I32  Signed integer (32 bits)``) is read by them: a
    token the usual words do not know (``I32``, ``I64``) takes the document's meaning, with the line
    that defines it; a prose line is no definition; a token defined two ways defines nothing; a length
    that disagrees with the defined width leaves the type open."""
    from drivemap.onboard.draft.cells import type_glossary
    from drivemap.onboard.draft.tables import Row, Source, Table

    text = ("1.1 Definitions of Terms\nU16 Unsigned integer (16 bits)\nI32 Signed integer (32 bits)\n"
            "I64 Signed integer (64 bits)\nINT16: 16-bit signed integer\nR4 - IEEE 754 floating point (32 bits)\n"
            "Temperature Signed integer (16 bits)\nX9 Signed integer (16 bits)\nX9 Unsigned integer (16 bits)\n")
    glossary = type_glossary(text)
    assert {k: v[0] for k, v in glossary.items()} == {"U16": "u16", "I32": "s32", "I64": "s64", "INT16": "s16", "R4": "f32"}
    assert glossary["I32"][1] == "I32 Signed integer (32 bits)"

    rows = [Row(["SN", "Name", "Type", "Unit", "Address", "Quantity"], 3, 1),
            Row(["1", "Phase A current", "I32", "A", "32272", "2"], 3, 2),
            Row(["2", "Total energy", "I64", "kWh", "32274", "4"], 3, 3),
            Row(["3", "Frequency", "R4", "Hz", "32278", "2"], 3, 4),
            Row(["4", "Odd", "I32", "A", "32280", "1"], 3, 5)]
    result = draft(Source("meter.pdf", "0" * 64, [Table(None, rows, 3, None, "", label="p.3 table 1")], text), "meter")
    by = {r.entry["label"]: r for r in result.registers}
    assert [by[n].entry.get("type") for n in ("Phase A current", "Total energy", "Frequency")] == ["s32", "s64", "f32"]
    assert any("the document defines 'I32'" in n and "line 3" in n for n in by["Phase A current"].notes)
    assert "type" not in by["Odd"].entry and "type" in by["Odd"].entry["review"]
    assert any("but the row gives 1 register" in n for n in by["Odd"].notes)


def test_a_german_register_table_is_read_by_its_headers_and_its_access_cells() -> None:
    """``Datentyp``, ``Multiplikator``, ``Laenge [Word / 16bit]``, ``Einheit``, ``Allg. Erlaeuterung``,
    ``Register-Bit`` name their columns; a column whose every filled cell is an access (``r/w``, ``r``)
    is the access column whatever it is headed (``EVCC-Home MODBUS RTU``, which otherwise reads as a
    second address column); C's ``uint16_t`` is u16; a writable register a word wide is a holding
    register; a row with an address of its own after bit rows is the next register, not more text."""
    from drivemap.onboard.draft.cells import parse_type
    from drivemap.onboard.draft.columns import find_layouts, role_of
    from drivemap.onboard.draft.tables import Row, Source, Table

    assert [role_of(h) for h in ("Datentyp", "Multiplikator", "Laenge [Word / 16bit]", "Einheit",
                                 "Allg. Erlaeuterung", "Register-Bit", "Zugriff")] == \
        ["type", "scale", "length", "unit", "description", "bit", "access"]
    assert (parse_type("uint16_t"), parse_type("int32_t", 2), parse_type("uint8")) == ("u16", "s32", None)

    header = ["Register- Adresse", "Register-Bit", "Datentyp", "Multiplikator", "Laenge [Word / 16bit]", "Default- Wert [-]",
              "Einheit", "Registerbezeichnung / Name", "Allg. Erlaeuterung", "EVCC-Home MODBUS RTU"]
    body = [["101", "-", "uint16_t", "1", "1", "16", "A", "Ladestromvorgabe", "Ladestrom in A", "r/w"],
            ["126", "-", "uint16_t", "1", "1", "0", "A", "Ladestromwert", "aktueller Wert", "r"],
            ["139", "-", "char", "1", "1", "0", "-", "CP-Signal Zustand", "ASCII kodiert", "r"],
            ["700", "0", "bit", "1", "1/16", "0", "-", "DIP-Switch SW1.1", "0: OFF, 1: ON", "r"],
            ["", "1", "bit", "1", "1/16", "0", "-", "DIP-Switch SW1.2", "", "r"],
            ["800-815", "-", "char", "1", "16", "-", "-", "Herstellerbezeichnung", "16-Bit encoded ASCII", "r"]]
    layout = find_layouts([header, *body])[0]
    assert layout.roles["access"] == 9 and layout.other_address is None and layout.roles["bit"] == 1
    rows = [Row(cells, 1, i + 1) for i, cells in enumerate([header, *body])]
    result = draft(Source("wallbox.pdf", "0" * 64, [Table(None, rows, 1, None, "", label="p.1 table 1")], ""), "wb")
    by = {r.entry["address"]: r for r in result.registers}
    written, read = by[101].entry, by[126].entry
    assert (written["table"], written["type"], written["access"], written["unit"]) == ("holding", "u16", "rw", "A")
    assert any("only holding registers are" in n for n in by[101].notes)
    assert "table" not in read and "table" in read["review"]  # read-only: holding or input, the table does not say
    assert "type" not in by[139].entry and any("a char in one register" in n for n in by[139].notes)
    assert [b["label"] for b in by[700].entry["bits"]][:2] == ["DIP-Switch SW1.1", "DIP-Switch SW1.2"]  # type: ignore[attr-defined]
    listed = [s for s in result.skipped if "800-815" in s.text]
    assert (800 in by) != bool(listed)  # drafted or listed with its reason, not text of the bit register
    assert "Herstellerbezeichnung" not in " ".join(by[700].notes) + str(by[700].entry)


def test_a_modicon_column_beside_the_physical_address_states_the_table_and_lsw_msw_the_word_order() -> None:
    """``Modicom address 300001 | Physical address 0000h``: the 6-digit (or 5-digit) Modicon number of the
    same address states the table (3: input, 4: holding); one that names another address states nothing.
    "In INT32 ... formats, the word order is LSW-> MSW" states the word order of the whole document."""
    from drivemap.onboard.draft.assemble import _word_order
    from drivemap.onboard.draft.rows import modicon_reference
    from drivemap.onboard.draft.tables import Row, Source, Table

    assert [modicon_reference(c) for c in ("300001", "300769", "40092", "465536", "400000", "12345", "3000")] == \
        [(0, "input"), (768, "input"), (91, "holding"), (65535, "holding"), None, None, None]
    assert _word_order("formats, the word order is LSW-> MSW.") == ("low_first", "word order is LSW-> MSW")
    assert _word_order("Word order: MSW first")[0] == "high_first"

    text = "For all the formats the byte order is MSB->LSB. In INT32 formats, the word order is LSW-> MSW.\n"
    rows = [Row(["Modicom address", "Physical address", "Length (words)", "Variable", "Data Format"], 8, 1),
            Row(["300001", "0000h", "2", "V L1-N", "INT32"], 8, 2),
            Row(["400003", "0002h", "2", "V L2-N", "INT32"], 8, 3),
            Row(["300009", "0004h", "2", "V L3-N", "INT32"], 8, 4)]
    result = draft(Source("meter.pdf", "0" * 64, [Table(None, rows, 8, None, "", label="p.8 table 1")], text), "meter")
    by = {r.entry["address"]: r for r in result.registers}
    assert (by[0].entry["table"], by[0].entry["type"], by[0].entry["word_order"]) == ("input", "s32", "low_first")
    assert any("prints 300001, the Modicon number of address 0 in the input registers" in n for n in by[0].notes)
    assert by[2].entry["table"] == "holding"
    assert "table" not in by[4].entry  # 300009 is address 8, not 4: it states nothing about this row


def test_a_weight_a_name_and_unit_column_and_a_merged_notes_cell_state_the_scale() -> None:
    """``VARIABLE / ENG. UNIT`` cells print the unit beside the name (``V L1-N``): the unit, never a
    resolution (no "scale 1" from it). ``Value weight: Volt*10`` states scale 0.1 V; a Notes cell drawn
    down over the rows below it (a merged PDF cell: pdfplumber gives those rows no cell) is theirs too.
    A weight in another unit than the row's leaves the scale open."""
    from types import SimpleNamespace

    from drivemap.onboard.draft.read_pdf import _spanned
    from drivemap.onboard.draft.tables import Row, Source, Table
    from drivemap.onboard.draft.units import parse_scale, unit_in_name

    assert parse_scale("Value weight: Volt*10") is not None
    assert (parse_scale("Value weight: Ampere*1000").scale, parse_scale("Value weight: Ampere*1000").unit) == (0.001, "A")  # type: ignore[union-attr]
    assert (parse_scale("Value weight: PF*1000").scale, parse_scale("Value weight: PF*1000").unit) == (0.001, None)  # type: ignore[union-attr]
    assert [unit_in_name(c) for c in ("V L1-N", "kWh(+) TOT", "KWh(+) PAR", "VAR L2", "PF L1", "DMD W max", "W V")] == \
        ["V", "kWh", "kWh", "var", None, "W", None]

    def cell(top: float, bottom: float) -> tuple[float, float, float, float]:
        return (0.0, top, 10.0, bottom)

    rows = [SimpleNamespace(bbox=(0, 0, 20, 10), cells=[cell(0, 10), cell(0, 10)]),
            SimpleNamespace(bbox=(0, 10, 20, 20), cells=[cell(10, 20), cell(10, 40)]),
            SimpleNamespace(bbox=(0, 20, 20, 30), cells=[cell(20, 30), None]),
            SimpleNamespace(bbox=(0, 30, 20, 40), cells=[cell(30, 40), None]),
            SimpleNamespace(bbox=(0, 40, 20, 50), cells=[cell(40, 50), cell(40, 50)]),
            SimpleNamespace(bbox=(0, 50, 20, 60), cells=[cell(50, 60), None])]  # covered from the left, not above
    texts = [["a", "Notes"], ["1", "Value weight: Volt*10"], ["2", ""], ["3", ""], ["4", ""], ["5", ""]]
    found = SimpleNamespace(rows=rows)
    assert _spanned(found, texts) == {2: {1: "Value weight: Volt*10"}, 3: {1: "Value weight: Volt*10"}}

    header = ["Modicom address", "Physical address", "Length (words)", "VARIABLE ENG. UNIT", "Data Format", "Notes"]
    body = [["300001", "0000h", "2", "V L1-N", "INT32", "Value weight: Volt*10"],
            ["300003", "0002h", "2", "V L2-N", "INT32", ""],
            ["300005", "0004h", "2", "A L1", "INT32", ""],
            ["300056", "0037h", "1", "Hz", "INT16", "Value weight: Hz*10"],
            ["300057", "0038h", "1", "Hz", "INT16", ""]]
    spans = {2: {5: "Value weight: Volt*10"}, 3: {5: "Value weight: Volt*10"}}
    table_rows = [Row(c, 8, i + 1, spanned=spans.get(i, {})) for i, c in enumerate([header, *body])]
    result = draft(Source("m.pdf", "0" * 64, [Table(None, table_rows, 8, None, "", label="p.8 table 1")],
                         "the word order is LSW-> MSW."), "m")
    by = {r.entry["address"]: r for r in result.registers}
    assert (by[0].entry["scale"], by[0].entry["unit"], by[0].entry["label"]) == (0.1, "V", "V L1-N")
    assert (by[2].entry["scale"], by[2].entry["unit"]) == (0.1, "V")  # the merged Notes cell
    assert any("a cell drawn over this row" in n for n in by[2].notes)
    assert "scale" not in by[4].entry and by[4].entry["unit"] == "A"  # Volt*10 on an A row: open
    assert (by[55].entry["scale"], by[55].entry["unit"]) == (0.1, "Hz")
    assert "scale" not in by[56].entry and "scale" in by[56].entry["review"]  # the unit is no resolution


def test_the_lines_inside_a_ruled_header_box_are_one_header_row() -> None:
    """A ruled header box whose heading breaks onto a second line (``Unit/Ra`` over ``tio``), read with the
    rows below it by their text lines: the lines inside the box are one header row (so the unit column is
    found), the lines below it are rows. A second ruled row of the box that holds a digit is no header."""
    from types import SimpleNamespace

    from drivemap.onboard.draft.read_pdf import _body, _join_header_lines

    rows = [SimpleNamespace(bbox=(0, 0, 90, 8)), SimpleNamespace(bbox=(0, 8, 90, 16)),
            SimpleNamespace(bbox=(0, 20, 90, 28))]
    texts = [["Name", "Register", "Unit/Ra"], ["", "", "tio"], ["Feed-in limit", "5011", "0.01kW"]]
    boxes = [[(0.0, 30.0), (30.0, 60.0), (60.0, 90.0)], [None, None, (60.0, 90.0)],
             [(0.0, 30.0), (30.0, 60.0), (60.0, 90.0)]]
    _join_header_lines(SimpleNamespace(rows=rows), 16.0, texts, boxes)
    assert texts[0] == ["Name", "Register", "Unit/Ra tio"] and not any(texts[1])
    assert texts[2] == ["Feed-in limit", "5011", "0.01kW"]

    cell = (0.0, 0.0, 30.0, 8.0)
    numbered = SimpleNamespace(rows=[SimpleNamespace(cells=[cell, cell, cell]), SimpleNamespace(cells=[cell])],
                               extract=lambda: [["No.", "Name", "Unit"], ["5011", None, None]], bbox=(0, 0, 90, 16))
    assert _body(None, numbered) is None  # a digit in the second ruled row: rows of a table, not a header box


def test_a_hex_span_of_two_registers_is_one_value_and_a_reserved_span_is_listed() -> None:
    """``0x0500 - 0x0501`` with 4 bytes is one float over two registers, as ``5031 - 5032`` is; a span
    named reserved (``预备中``, "in reserve") is listed, never drafted."""

    header = ["Adr (Offset)", "R/W", "Value", "Bytes", "Type", "Range", "Description"]
    body = [["0x0500 - 0x0501", "R", "Current L1", "4", "float", "0 … xA", "RMS output current of phase L1"],
            ["0x0512 - 0x0513", "R", "Power Overall", "4", "float", "0 … xW", "overall Power on all phases"],
            ["0x012E - 0x012F", "R", "", "4", "uint32", "", "预备中"]]
    result = _one_table(header, body, 5, "p.5 table 2")
    by = {r.entry["address"]: r.entry for r in result.registers}
    assert by[0x500]["type"] == "f32" and by[0x512]["type"] == "f32"
    assert 0x12E not in by and any("预备中" in s.text for s in result.skipped)


def test_offsets_under_a_start_address_printed_beside_their_block_are_drafted_with_the_address_open() -> None:
    """A table of offsets (``偏移Index``) whose block start (``0x1000``) is printed once beside its rows, in
    a cell drawn over rows of several pages (its text level with rows of the next page, left of the
    table): each row of the block, on its own page's table too (shifted under the first page's columns),
    is drafted at start + offset, the document's own sum, with ``review: [address]`` and both readings in
    its notes. A block beside which two different starts are printed is listed, not drafted."""
    from drivemap.onboard.draft.tables import Row, Source, Table

    header = [["起始地址码 Address Field", "偏移Index", "", "数据类型 Type", "R/W", "数据内容Content", "单位 Unit"],
              ["", "HEX", "DEC", "", "", "", ""]]
    first = [Row(c, 1, i + 1, table="p.1 table 1", top=80.0 + 10 * i) for i, c in enumerate([
        *header, ["", "0x0000", "0", "UINT16", "RW", "VolSmartSleep", "mV"],
        ["", "0x0002", "2", "UINT16", "RW", "VolCellUV", "mV"], ["", "0x0004", "4", "UINT16", "RW", "VolCellOV", "mV"]])]
    second = [Row(c, 2, i + 1, table="p.2 table 1", top=50.0 + 10 * i) for i, c in enumerate([
        ["0x0006", "6", "UINT16", "RW", "VolBalan", "mV"], ["0x0008", "8", "UINT16", "RW", "VolSOC", "mV"],
        ["0x0000", "0", "UINT16", "R", "CellVol0", "mV"], ["0x0002", "2", "UINT16", "R", "CellVol1", "mV"]])]
    tables = [Table(None, first, 1, None, "", label="p.1 table 1"),
              Table(None, second, 2, None, "", label="p.2 table 1", margin=[(2, 55.0, "0x1000"), (2, 75.0, "0x1200")])]
    result = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms")
    by = {r.entry["address"]: r for r in result.registers}
    assert sorted(by) == [0x1000, 0x1002, 0x1004, 0x1006, 0x1008, 0x1200, 0x1202]
    assert by[0x1008].entry["label"] == "VolSOC" and "address" in by[0x1008].entry["review"]  # type: ignore[operator]
    assert any("0x1008" in n and "bytes (0x1004)" in n for n in by[0x1008].notes)

    # a person who knows the unit says so: the address is the one that unit gives, no longer open
    from drivemap.onboard.draft.assemble import Hints

    for unit, want in (("registers", 0x1008), ("bytes", 0x1004)):
        hinted = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms", Hints((("offset", unit),)))
        at = {r.entry["label"]: r for r in hinted.registers}["VolSOC"]
        assert at.entry["address"] == want and "address" not in at.entry.get("review", [])  # type: ignore[operator]
        assert any(f"counted in {unit}: source: assumed by the user (--assume offset={unit})" in n for n in at.notes)
        assert not any(n.endswith("address to review") for n in at.notes)
        assert any(f"--assume offset={unit}" in line for line in hinted.review)
    assert sorted(r.entry["address"] for r in hinted.registers) == [0x1000, 0x1001, 0x1002, 0x1003, 0x1004,
                                                                    0x1200, 0x1201]

    tables[1].margin.append((2, 78.0, "0x1400"))  # two starts beside the second block: it has none
    result = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms")
    assert 0x1200 not in {r.entry["address"] for r in result.registers}
    assert any("p.2 table 1 row 3" == s.where and "offset" in s.reason for s in result.skipped)


def test_an_address_printed_in_no_cell_of_a_table_is_listed_with_its_line() -> None:
    """Text inside a ruled table that starts with a hex address in none of its cells (a cell drawn over
    bit rows across a page break: ``0x00A0 160 UINT32 4 R``) is a row of its own, listed, never lost;
    hex words in cells or outside the table are not."""
    from types import SimpleNamespace

    from drivemap.onboard.draft.read_pdf import _orphans

    def word(text: str, x: float, y: float) -> dict[str, object]:
        return {"text": text, "x0": x, "x1": x + 20, "top": y, "bottom": y + 8}

    found = SimpleNamespace(bbox=(90, 50, 700, 500), rows=[
        SimpleNamespace(cells=[(90, 50, 150, 60), (150, 50, 700, 60)]),
        SimpleNamespace(cells=[None, (150, 300, 700, 310)])])
    every = [word("0x0004", 100, 51), word("0x00A0", 100, 200), word("160", 125, 200), word("UINT32", 160, 200),
             word("0x1200", 40, 200)]
    hexes = [w for w in every if str(w["text"]).startswith("0x")]
    rows = _orphans(every, hexes, found, 5, "p.5 table 1")
    assert [r.cells for r in rows] == [["0x00A0", "160", "UINT32"]]
    assert rows[0].where() == "p.5 table 1, text in no cell at y 200"


def test_a_value_said_in_a_unit_and_a_row_naming_its_low_and_high_register() -> None:
    """"Rated Current in A" says the value is in amperes, one per count; "(Reg_Low–0x030D, Reg_High-0x030E)"
    says the low word is at the lower address (low_first) for that register, where the document states no
    word order of its own. "stored in Amtron" is no unit."""
    from drivemap.onboard.draft.fields import _halves
    from drivemap.onboard.draft.units import parse_scale

    said = parse_scale("Rated Current in A")
    assert said is not None and (said.scale, said.unit) == (1, "A")
    assert parse_scale("stored in Amtron memory") is None and parse_scale("in A", unit_cell=True) is None
    assert _halves("(Reg_Low–0x030D, Reg_High-0x030E)") == ("low_first", "Low–0x030D, Reg_High-0x030E")
    assert _halves("high word: 101, low word: 100")[0] == "low_first"  # type: ignore[index]
    assert _halves("Reg_Low–0x030D, Reg_High-0x0310") is None  # not one apart

    header = ["Register (hex)", "Register (dec)", "Data Type", "Name", "Description"]
    body = [["0x0309", "30778", "UINT16", "Rated Current", "Rated Current in A Values: 0 or 6 ≤ x ≤ 32"],
            ["0x030D - 0x030E", "30782", "UINT32", "Charging session meter count",
             "Charging session meter count in Wh (Reg_Low–0x030D, Reg_High-0x030E)"]]
    result = _one_table(header, body, 5, "p.5 table 1")
    by = {r.entry["address"]: r.entry for r in result.registers}
    assert (by[0x309]["scale"], by[0x309]["unit"]) == (1, "A")
    assert (by[0x30D]["type"], by[0x30D]["word_order"], by[0x30D]["unit"]) == ("u32", "low_first", "Wh")


def test_a_range_within_0_to_32767_reads_the_same_signed_and_unsigned() -> None:
    """A one-register value whose signedness the document leaves open, with a printed range inside
    0..32767 at its stated scale, is u16 (every value it may hold reads the same as s16), with a note and
    the range; a range reaching past raw 32767, a negative range, no range or no scale leave the type
    open. A range that as the value would need more counts than one register holds is raw counts; one printed
    without saying raw or value is read both ways for the type. ``[0000 6300]`` (square brackets, a space) is a range as ``[0,6300]`` is."""
    from drivemap.onboard.draft.cells import parse_range

    assert parse_range("[0000 6300]") == (0, 6300, "") and parse_range("[1 2 3]") is None
    header = ["Addr", "Register meaning", "R/W", "data range", "unit"]
    body = [["100", "Max charge current", "R/W", "[0,185]", "1A"],
            ["101", "Grid power", "R", "[-32768,32767]", "1W"],
            ["102", "Battery voltage", "R/W", "[0,6000]", "0.01V"],
            ["103", "Offset", "R/W", "[-100,100]", "1W"],
            ["104", "Counter", "R", "", "1"],
            ["105", "Energy", "R", "[0,40000]", "1Wh"],
            ["106", "Bus voltage", "R", "[0,60000]", "0.01V"],
            ["107", "Radiator temperature", "R", "[0,3000]", "0.1℃"],
            ["108", "DC voltage", "R", "[0,4000]", "0.1V"]]
    result = _one_table(header, body, 1, "table 5")
    by = {r.entry["address"]: r for r in result.registers}
    assert by[100].entry["type"] == "u16" and "type" not in by[100].entry.get("review", [])  # type: ignore[operator]
    assert (by[100].entry["min"], by[100].entry["max"]) == (0, 185)
    assert any("reads the same either way" in n for n in by[100].notes)
    assert by[101].entry["type"] == "s16"  # the range is the whole span of s16: stated
    # [0,6000] at 0.01 V: as volts it would need 600000 counts, more than a register holds: raw, 0..60 V
    assert (by[102].entry["type"], by[102].entry["min"], by[102].entry["max"]) == ("u16", 0, 60)
    for address in (103, 104, 105, 106, 108):
        assert "type" in by[address].entry["review"], by[address].entry  # type: ignore[operator]
    # [0,3000] at 0.1 °C: raw counts or the value? raw 0..3000 or 0..30000, within 0..32767 either way: u16,
    # the range itself left out (which reading is meant, the row does not say); [0,4000] at 0.1 V: 40000 counts
    assert by[107].entry["type"] == "u16" and "min" not in by[107].entry
    assert any("raw counts or the value" in n for n in by[107].notes)


def test_a_remark_that_says_only_read_write_is_the_access() -> None:
    """Sungrow's function tables print ``Read-Write`` or ``Read-only`` in their Remarks column: a remark that
    is only an access word states the access (a written, word-wide register is a holding register); a
    longer remark states none."""
    from drivemap.onboard.draft.cells import parse_access

    assert [parse_access(t) for t in ("Read-Write", "read write", "Write-only")] == ["rw", "rw", "w"]
    header = ["No.", "Name", "Register", "Data type", "Data range", "Unit/Ratio", "Remarks"]
    body = [["5.", "Feed-in Limitation Ratio", "13088", "U16", "0-1000", "0.1%", "Read-Write"],
            ["1.", "Min. Feed-in Power", "5622", "U16", "", "0.01kW", "Read-only"],
            ["2.", "Mode", "13090", "U16", "0-2", "", "Read-Write only when stopped"]]
    result = _one_table(header, body, 15, "p.15 table 1")
    by = {r.entry["address"]: r for r in result.registers}
    assert (by[13088].entry["access"], by[13088].entry["table"]) == ("rw", "holding")
    assert any("the remark says 'Read-Write'" in n for n in by[13088].notes)
    assert "access" not in by[5622].entry and "table" not in by[5622].entry  # read-only: holding or input
    assert "access" not in by[13090].entry


def test_values_listed_one_a_line_and_a_unit_printed_in_the_wrong_case() -> None:
    """A notes cell listing one value a line (``0x00 50HZ`` / ``0x01 60hz``, a label running on to the next
    line) is the register's value list; a list whose first values are not printed, amounts said with
    "means", and zero-padded numbers past 9 (hex or decimal?) are not. A unit cell's ``0.1kwh`` or
    ``0.01v`` names one unit whatever its case and says so; ``1S`` (siemens or seconds?) names none, nor does
    a hex literal (``0x0A``: no "× 0 A")."""
    from drivemap.onboard.draft.cells import parse_enum
    from drivemap.onboard.draft.units import parse_scale

    assert parse_enum("0x00 使能卖电 \nsell electricity enabled\n0x01 使能内置 built-in") == [
        (0, "使能卖电 sell electricity enabled"), (1, "使能内置 built-in")]
    assert parse_enum("根据电压 According to voltage\n根据容量 capacity\n2 没有电池 no battery") is None
    assert parse_enum("3800 means 38V\n6100 means 61V") is None
    assert parse_enum("0000 standby\n0010 fault") is None
    assert parse_enum("0000 standby\n0001 selfcheck") == [(0, "standby"), (1, "selfcheck")]
    assert parse_enum("1. first do this\n2. then that") is None
    found = parse_scale("0.1kwh", unit_cell=True)
    assert found is not None and (found.scale, found.unit) == (0.1, "kWh") and "read as kWh" in found.reading
    assert parse_scale("1S", unit_cell=True) is None and parse_scale("0.1kwh") is None
    from drivemap.onboard.draft.units import seconds_cell

    timeout = seconds_cell("1S", "Ups_delay time")  # a conductance is never a delay: seconds
    assert timeout is not None and (timeout.scale, timeout.unit) == (1, "s") and "seconds" in timeout.reading
    assert seconds_cell("S", "Restart times") is None and seconds_cell("S", "Conductance") is None
    # a hex literal's x is no "times": "#define SOLAX 0x0A" states no unit A
    assert parse_scale("#define Bat_SOLAX_HV 0x0A") is None and parse_scale("x0.1A") is not None
    header = ["Addr", "Register meaning", "R/W", "data range", "unit", "note"]
    body = [["183", "Grid Frequency", "R/W", "[0 1]", "", "0x00 50HZ\n0x01 60hz"],
            ["514", "Daily charge of the battery", "R", "", "0.1kwh", ""],
            ["126", "Grid charging start voltage", "R/W", "[0000 6300]", "0.01v", ""],
            ["102", "Batt Capacity", "R/W", "[0,2000]", "1 Ah", "200 means 200AH"],
            ["209", "Ups_delay time", "R/W", "", "S", ""]]
    result = _one_table(header, body, 3, "table 8")
    by = {r.entry["address"]: r for r in result.registers}
    listed = result.data["enums"][by[183].entry["enum"]]["values"]
    assert [(v["value"], v["label"]) for v in listed] == [(0, "50HZ"), (1, "60hz")]
    assert by[183].entry["review"] == ["table"]  # no type or scale to state for listed values
    assert (by[514].entry["scale"], by[514].entry["unit"]) == (0.1, "kWh")
    assert by[514].entry["review"] == ["table", "type"]  # holding or input? u16 or s16? the document does not say
    assert (by[126].entry["scale"], by[126].entry["unit"], by[126].entry["type"]) == (0.01, "V", "u16")
    assert (by[102].entry["scale"], by[102].entry["unit"], by[102].entry["max"]) == (1, "Ah", 2000)
    assert (by[209].entry["scale"], by[209].entry["unit"]) == (1, "s")  # a unit cell without a resolution: scale 1


def test_a_page_drawn_apart_is_read_under_the_header_column_by_column_in_order() -> None:
    """A headerless table on the next page whose columns are drawn apart from the header's (wider or
    narrower, a name cell split in two on some rows): its rows with as many cells as the header has
    headings say where each heading's column lies on this page, and every cell goes under the column
    it overlaps most; with no such row it is not read under the header."""
    from drivemap.onboard.draft.pdf_grid import Grid, order_grid, relay

    def by_order(texts: list[list[str]], boxes: list[list[tuple[float, float] | None]], grid: Grid) -> list[list[str]] | None:
        drawn = order_grid(boxes, grid)
        return None if drawn is None else relay(texts, boxes, drawn)

    grid = Grid([(0, (60, 95), True), (1, (95, 202), True), (2, (202, 237), True), (3, (237, 300), True)], 4,
                (60, 300), 0)
    texts = [["060", "Day active energy", "R", "0.1kWh"], ["", "Day", "_Active", ""], ["061", "Grid power", "R", "1W"]]
    boxes = [[(55, 89), (89, 232), (232, 262), (262, 300)], [None, (89, 160), (160, 232), None],
             [(55, 89), (89, 232), (232, 262), (262, 300)]]
    assert by_order(texts, boxes, grid) == [["060", "Day active energy", "R", "0.1kWh"], ["", "Day _Active", "", ""],
                                            ["061", "Grid power", "R", "1W"]]
    assert by_order([texts[1]], [boxes[1]], grid) is None  # no row as wide as the header
    from drivemap.onboard.draft.cells import parse_address

    found = parse_address("190 •")  # a bullet glyph printed beside the number
    assert found is not None and found.dec_value == 190


def test_an_address_given_two_meanings_is_drafted_as_neither() -> None:
    """A row without an address of its own under a register's row (one address cell drawn over both)
    that names a unit of its own, another than the register's, is a second register at that address
    (one model's beside another's): neither is drafted, both are listed with why. Two rows of drawn
    tables at one address of a stated table, with two names, are listed alike; the same register printed
    twice, or a name cut short ("limitation" of "Power limitation"), keeps the first as before."""
    from drivemap.onboard.draft.writer import settle

    header = ["Addr", "Register meaning", "R/W", "data range", "unit"]
    body = [["098", "String inverter RCD leak current", "R", "[0,65535]", "0.01A"],
            ["", "Hybird Year grid sell low word", "", "", "0.1kwh"],
            ["099", "Limiter power", "R", "", "1W"]]
    result = _one_table(header, body, 13, "p.13 table 1")
    assert [r.entry["address"] for r in result.registers] == [99]
    reason = next(s.reason for s in result.skipped if s.text.startswith("address 98 (0x0062)"))
    assert "names another register with a unit of its own ('0.1kwh'" in reason and "two meanings" in reason

    head = ["Reg. Type", "Address", "Name", "R/W", "Type", "Unit"]
    first = [["Holding", "1000", "Charge Point State", "R", "UINT16", ""], ["Holding", "1100", "Max current", "R", "UINT16", "0.1 A"],
             ["Holding", "1200", "Power limitation", "R", "UINT16", "W"]]
    second = [["Holding", "1000", "Hems Current Limit (A)", "R/W", "UINT16", "A"], ["Holding", "1100", "Max current", "R", "UINT16", "0.1 A"],
              ["Holding", "1200", "limitation", "R", "UINT16", "W"]]
    tables = [Table(None, [Row(c, p, i + 1, table=f"p.{p} table 1") for i, c in enumerate([head, *rows])], p, None, "",
                    label=f"p.{p} table 1") for p, rows in ((1, first), (7, second))]
    result = draft(Source("evse.pdf", "0" * 64, tables, ""), "evse")
    text, errors = settle(result, "", "evse.yaml")
    assert not errors
    assert sorted(int(r.entry["address"]) for r in result.registers) == [1100, 1200]  # type: ignore[call-overload]
    listed = [s for s in result.skipped if "another meaning" in s.reason]
    assert sorted(s.where for s in listed) == ["p.1 table 1 row 2", "p.7 table 1 row 2"]
    assert all(s.text.startswith("address 1000 (0x03E8)") for s in listed)


def test_a_page_drawn_as_the_page_before_goes_on_under_the_header() -> None:
    """After a page read column by column in order, the next page drawn in that page's frame is read
    under the columns as that page drew them (though no row of its own has as many cells as the
    header has headings), where its cells read as their headings say; a page whose cells do not
    (no address under the address heading) is a table of its own."""
    from drivemap.onboard.draft.pdf_grid import grid_of
    from drivemap.onboard.draft.read_pdf import _Found, _Joiner

    def found(page: int, texts: list[list[str]], boxes: list[list[tuple[float, float] | None]],
              frame: tuple[float, float], grid: bool = False) -> _Found:
        rows = [Row(list(t), page, i + 1, table=f"p.{page} table 1") for i, t in enumerate(texts)]
        return _Found(Table(None, rows, page, None, "", label=f"p.{page} table 1"),
                      grid_of(texts, boxes, frame) if grid else None, boxes, frame)

    head = [["Addr", "Register meaning", "R/W", "unit"], ["000", "Device type", "R", ""]]
    head_boxes: list[list[tuple[float, float] | None]] = [[(60, 95), (95, 202), (202, 237), (237, 300)]] * 2
    page6 = [["060", "Day active energy", "", "R", "0.1kWh"]]  # a grid of its own: five columns, one empty
    page7 = [["072", "String", "Grid voltage AC", "R", "0.1V"], ["073", "String", "Grid voltage A", "R", "0.1V"]]
    split: list[list[tuple[float, float] | None]] = [[(55, 89), (89, 125), (125, 232), (232, 262), (262, 300)]] * 2
    page8 = [["", "Grid voltage", "Hybrid", "R", "0.1V"]]
    joiner = _Joiner()
    joiner.add(found(5, head, head_boxes, (60, 300), grid=True))
    joiner.add(found(6, page6, [[(55, 89), (89, 232), None, (232, 262), (262, 300)]], (55, 300)))
    joiner.add(found(7, page7, split, (55, 300)))
    joiner.add(found(8, page8, split[:1], (55, 300)))
    first = joiner.tables[0]
    assert [r.cells for r in first.rows[2:]] == [["060", "Day active energy", "R", "0.1kWh"],
                                                ["072", "String Grid voltage AC", "R", "0.1V"],
                                                ["073", "String Grid voltage A", "R", "0.1V"]]
    assert "as the page before drew them" in first.rows[3].relaid
    assert [t.label for t in joiner.tables] == ["p.5 table 1", "p.8 table 1"]


def test_a_fraction_in_a_multiplier_column_is_the_scale() -> None:
    """``1/100`` under ``Multiplikator`` (multiplier) is scale 0.01; a bare ``1`` is scale 1."""
    header = ["Register-Adresse", "Datentyp", "Multiplikator", "Einheit", "Registerbezeichnung / Name", "r/w"]
    body = [["167", "uint16_t", "1/100", "V", "Spannung U1", "r"], ["126", "uint16_t", "1", "A", "Ladestromwert", "r"]]
    by = {r.entry["address"]: r for r in _one_table(header, body, 2, "p.2 table 1").registers}
    assert (by[167].entry["scale"], by[167].entry["unit"]) == (0.01, "V")
    assert (by[126].entry["scale"], by[126].entry["unit"]) == (1, "A")


def test_a_header_box_reads_lines_down_to_the_next_ruled_table_and_a_lone_first_row_is_listed() -> None:
    """A ruled header box's text lines are read down to the next ruled table on the page, not to the page's
    foot (that table's rows are its own: read twice, the first reading, cut up, took their addresses). A
    headerless table whose first row is an address span with cells beside it is listed row by row, as a
    page of a register table whose header is elsewhere, though it is the only such row."""
    from types import SimpleNamespace

    from drivemap.onboard.draft.read_pdf import _body
    from drivemap.onboard.draft.rows import _headerless

    cropped: list[tuple[float, float, float, float]] = []

    def crop(box: tuple[float, float, float, float]) -> SimpleNamespace:
        cropped.append(box)
        return SimpleNamespace(find_tables=lambda settings: [])

    cell = (65.0, 144.0, 200.0, 179.0)
    box = SimpleNamespace(rows=[SimpleNamespace(cells=[cell, cell, cell])], extract=lambda: [["Adr", "R/W", "Value"]],
                          bbox=(65.0, 144.0, 553.0, 179.0))
    assert _body(SimpleNamespace(crop=crop, height=842.0), box, 315.0) is None
    assert _body(SimpleNamespace(crop=crop, height=842.0), box) is None
    assert cropped == [(65.0, 144.0, 553.0, 315.0), (65.0, 144.0, 553.0, 842.0)]

    rows = [Row(["0x0013 - 0x001A", "R", "Serial Number", "16", "ascii"], 3, 1, table="p.3 table 1"),
            Row(["4. Status (0x0100 - 0x02FF)", "", "", "", ""], 3, 2, table="p.3 table 1"),
            Row(["The following registers contain", "", "", "", ""], 3, 3, table="p.3 table 1")]
    listed = _headerless(Table(None, rows, 3, None, "", label="p.3 table 1"))
    assert [s.where for s in listed] == ["p.3 table 1 row 1"] and "without a header row" in listed[0].reason
    prose = [Row(["Note 12", "see below", "", "", ""], 3, 1, table="p.3 table 2")]
    assert _headerless(Table(None, prose, 3, None, "", label="p.3 table 2")) == []
