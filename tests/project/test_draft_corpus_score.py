"""The corpus scorer itself (bench/draftcorpus.py), on registers written here: exact as written, SI-prefix
equal pairs, a null truth unit, open fields, wrong fields, and rows listed as skipped against dropped."""

from __future__ import annotations

import sys

from tests.shared_data import ROOT

sys.path.insert(0, str(ROOT / "bench"))

import draftcorpus  # noqa: E402


def truth(name: str, address: int, table: str = "holding", type: str = "u16", scale: float = 1,
          unit: str | None = None) -> dict[str, object]:
    return {"name": name, "address": address, "table": table, "type": type, "scale": scale, "unit": unit}


def test_exact_wrong_open_and_dropped() -> None:
    t = [truth("energy", 10, "input", "u32", 1, "Wh"), truth("mode", 12), truth("volt", 13, scale=0.1),
         truth("amps", 14, type="s16", scale=0.01, unit="A"), truth("gone", 20), truth("listed", 30),
         truth("elem", 41, unit=None)]
    drafted = [
        {"name": "energy", "address": 10, "table": "input", "type": "u32", "scale": 0.001, "unit": "kWh"},
        {"name": "mode", "address": 12, "unit": "rpm"},  # the truth's unit is null: a drafted unit is not wrong
        {"name": "volt", "address": 13, "review": ["scale"], "unit": "V"},  # open, not wrong
        {"name": "amps", "address": 14, "type": "u16", "scale": 0.01, "unit": "A"},  # u16 stated: wrong
        {"name": "arr", "address": 40, "count": 2, "table": "holding"},
    ]
    s = draftcorpus.score_draft("doc", t, drafted, ["p.3 row 7 0x001F Listed reg: type unknown"])
    assert (s.found, s.exact, s.open, s.listed) == (5, 3, 1, 1)
    assert s.wrong == ["amps@14.type: drafted 'u16', truth 's16'"]
    assert s.dropped == ["gone@20"]
    assert s.not_exact == ["volt@13", "amps@14"]


def test_a_default_standing_in_is_stated() -> None:
    s = draftcorpus.score_draft("doc", [truth("t", 5, "input")], [{"name": "t", "address": 5}], [])
    assert s.wrong == ["t@5.table: drafted 'holding', truth 'input'"] and s.exact == 0
    s = draftcorpus.score_draft("doc", [truth("t", 5, "input")], [{"name": "t", "address": 5, "review": ["table"]}], [])
    assert not s.wrong and s.open == 1 and s.exact == 0


def test_si_prefix_and_unit_differences() -> None:
    assert draftcorpus._si(1, "kW") == (1000.0, "w")
    s = draftcorpus.score_draft("doc", [truth("p", 1, scale=1, unit="W")],
                                [{"name": "p", "address": 1, "scale": 1, "unit": "kW"}], [])
    assert s.wrong == ["p@1.unit: drafted 'kW', truth 'W'"]  # same scale, another prefix
    s = draftcorpus.score_draft("doc", [truth("p", 1, unit="A")], [{"name": "p", "address": 1, "unit": "V"}], [])
    assert s.wrong == ["p@1.unit: drafted 'V', truth 'A'"]


def test_a_register_of_another_table_at_the_address_is_not_this_one() -> None:
    """Holding 4999 "year" and input 4999 "device type code" are two registers: a draft of the input one
    alone finds that one, and the holding one is not found (dropped), not "found with a wrong table"."""
    both = [truth("year", 4999, "holding"), truth("code", 4999, "input")]
    s = draftcorpus.score_draft("doc", both, [{"name": "code", "address": 4999, "table": "input"}], [])
    assert s.found == 1 and s.dropped == ["year@4999"] and not any("table" in w for w in s.wrong)
    # with no input register of its own in the truth, the drafted one is the holding one in the wrong table
    s = draftcorpus.score_draft("doc", both[:1], [{"name": "code", "address": 4999, "table": "input"}], [])
    assert s.found == 1 and any(w.startswith("year@4999.table") for w in s.wrong)


def test_a_unit_spelled_out_is_the_same_unit() -> None:
    s = draftcorpus.score_draft("doc", [truth("t", 1, unit="Hours"), truth("r", 2, unit="k-ohm")],
                                [{"name": "t", "address": 1, "unit": "h"}, {"name": "r", "address": 2, "unit": "kΩ"}], [])
    assert s.exact == 2 and s.wrong == []
    s = draftcorpus.score_draft("doc", [truth("t", 1, unit="Hours")], [{"name": "t", "address": 1, "unit": "s"}], [])
    assert s.wrong == ["t@1.unit: drafted 's', truth 'Hours'"]


def test_a_truth_erratum_scores_the_field_as_the_document_prints_it_and_is_listed() -> None:
    erratum = {"document": "doc", "table": "input", "address": 7, "field": "scale", "truth": 1, "document_says": 0.01,
               "document_unit": "kW", "where": "p.3", "printed": "7 U16 0.01kW"}
    t = [truth("limit", 7, "input"), truth("other", 8, "input")]
    as_printed = [{"name": "limit", "address": 7, "table": "input", "scale": 0.01, "unit": "kW"},
                  {"name": "other", "address": 8, "table": "input", "scale": 0.01, "unit": "kW"}]
    s = draftcorpus.score_draft("doc", t, as_printed, [], [erratum])
    assert s.exact == 1 and s.wrong == ["other@8.scale: drafted 0.01 kW, truth 1.0 "]  # only the erratum's field
    assert s.errata == ["limit@7.scale: truth 1, the document prints '7 U16 0.01kW' (p.3)"]
    as_truth = draftcorpus.score_draft("doc", t[:1], [{"name": "limit", "address": 7, "table": "input"}], [], [erratum])
    assert as_truth.exact == 0 and as_truth.wrong  # the truth's value, against what the document prints: wrong
