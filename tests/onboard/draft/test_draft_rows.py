"""Draft, row by row: offsets that are no addresses, and two readings of one row that disagree."""

from __future__ import annotations

from drivemap.onboard.draft.assemble import draft


def test_offsets_are_listed_not_drafted_as_addresses() -> None:
    """A register table whose numbers are offsets from a block's base (the base printed once in a merged
    cell; offsets in words or bytes, the table does not say) drafts no register at an offset as if it were
    an address: its rows, and those of its headerless continuation on the next page, are listed."""
    from drivemap.onboard.draft.tables import Row, Source, Table

    head = [Row(["Start address", "Offset", "", "Type", "R/W", "Content", "Unit"], 1, 1),
            Row(["", "HEX", "DEC", "", "", "", ""], 1, 2)]
    body = [Row(["", f"0x{4 * i:04X}", str(4 * i), "UINT32", "RW", f"Setting{i}", "mV"], 1, 3 + i) for i in range(4)]
    body[1].cells[0] = "0x1000"  # the base, once, in the middle of its merged cell
    page2 = [Row([f"0x{4 * i:04X}", str(4 * i), "UINT32", "RW", f"Setting{i}", "mV"], 2, i + 1) for i in range(4, 7)]
    tables = [Table(None, head + body, 1, None, "", label="p.1 table 1"), Table(None, page2, 2, None, "", label="p.2 table 1")]
    result = draft(Source("bms.pdf", "0" * 64, tables, ""), "bms")
    assert result.registers == []
    reasons = [s.reason for s in result.skipped if s.text.split(" | ")[0].startswith(("0x", "0x1000"))]
    assert len(reasons) == 7
    assert all("offset" in r and "from a base address" in r and "to be stated by a person" in r for r in reasons)

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
