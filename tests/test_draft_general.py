"""General drafting rules found on the public corpus, each on an invented document of the same shape:
review markers instead of defaults, document statements (numbering from 1, word order of 32-bit values)
recorded as the source of what they decide, register spans and pairs, spaced type tokens, a per-row
register-type column, a remark that is no range, a bare resolution in a Unit/Ratio column."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.draft.assemble import draft
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
