"""Draft and offsets: a register table that prints offsets from a base address, not addresses."""

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
