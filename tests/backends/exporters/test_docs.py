"""Generated Markdown docs: every page parses as CommonMark and shows the whole model.

The pages are rendered in memory from the same compiled models ``drivemap build`` uses, parsed with
markdown-it-py, and checked structurally (tables, headings, fences, links). The usage snippet on
each page is executed against that model's simulator over TCP.

Links, leaks, escaping and the usage snippet are checked in tests/backends/exporters/test_docs_links.py; the rendering and
the page parser are in tests/docs_pages.py.
"""

from __future__ import annotations

import dataclasses

import pytest

from drivemap.backends.views import docs
from drivemap.compiler import compile_map
from drivemap.model.nodes import Model
from tests.docs_pages import MAPS, MODEL_IDS, Page, Section, by_name, compile_models, parse_pages, render_outputs


@pytest.fixture(scope="module")
def models() -> list[Model]:
    return compile_models()


@pytest.fixture(scope="module")
def outputs(models: list[Model]) -> dict[str, str]:
    return render_outputs(models)


@pytest.fixture(scope="module")
def pages(outputs: dict[str, str]) -> dict[str, Page]:
    return parse_pages(outputs)


# ---------------------------------------------------------------- every model has a page and the index lists it


def test_pages_exist_for_every_map(outputs: dict[str, str], models: list[Model]) -> None:
    assert "docs/index.md" in outputs
    for m in models:
        assert f"docs/{m.name}.md" in outputs
    assert len(models) == len(MAPS)


def test_index_has_one_row_per_model(pages: dict[str, Page], models: list[Model]) -> None:
    page = pages["docs/index.md"]
    tables = [t for s in page.sections for t in s.tables]
    assert len(tables) == 1
    header, *rows = tables[0]
    assert header[:2] == ["Model", "Title"]
    assert [r[0] for r in rows] == sorted(m.name for m in models)
    for r in rows:
        m = by_name(models, r[0])
        counts = m.status_counts()
        cells = dict(zip(header, r, strict=True))
        assert cells["Title"] == m.device.title
        assert cells["Registers"].startswith(f"{len(m.registers)} ")
        assert cells["Examples"] == str(len(m.examples))
        assert (cells["Verified"], cells["Errata"], cells["Illegible"]) == (
            str(counts["verified"]), str(counts["erratum"]), str(counts["illegible"]))
        assert f"{m.name}.md" in page.links


# ---------------------------------------------------------------- registers, enums, bit fields, examples


def _rows(section: Section) -> list[list[str]]:
    return [row for table in section.tables for row in table[1:]]


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_every_register_appears_with_its_address(model_id: str, pages: dict[str, Page], models: list[Model]) -> None:
    m = by_name(models, model_id)
    page = pages[f"docs/{model_id}.md"]
    register_rows = [
        row for s in page.sections for t in s.tables if t[0][:5] == ["Address", "Dec", "Modicon", "Param", "Name"]
        for row in t[1:]
    ]
    assert len(register_rows) == len(m.registers)
    for reg in m.registers:
        name = f"{reg.name}[0..{reg.count - 1}]" if reg.is_array else reg.name
        matches = [r for r in register_rows if r[4] == name]
        assert len(matches) == 1, f"{reg.name}: {len(matches)} rows"
        row = matches[0]
        assert row[0].split("-")[0] == f"0x{reg.address:04X}"
        assert row[1].split("-")[0] == str(reg.address)
        assert row[2].split("-")[0] == reg.modicon  # both notations, side by side
        assert row[11] in ("read", "write", "read/write")
        if reg.is_array:
            last = reg.element_address(reg.count - 1)
            assert f"0x{last:04X}" in " ".join(row)
            if reg.count <= 16:
                for i in range(reg.count):
                    assert f"No.{i + reg.first_index} 0x{reg.element_address(i):04X}" in row[-1]  # the manual's number
        if reg.param:
            assert row[3].split(" … ")[0] == reg.param
        if reg.element_param_format:  # ids by rule: first … last (v2 P_0 … P_255)
            assert row[3] == f"{reg.element_param(0)} … {reg.element_param(reg.count - 1)}"
        if reg.page is not None:
            assert f"{reg.page.selector}" in row[-1] and f"= {reg.page.value}" in row[-1]


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_unlisted_addresses_are_not_called_reserved(model_id: str, pages: dict[str, Page], models: list[Model]) -> None:
    """Never guess: a range the manual never lists reads "not listed in the manual", not "reserved"."""
    m = by_name(models, model_id)
    if not m.reserved:  # nothing to call anything: the page has no such section
        with pytest.raises(AssertionError, match="found 0"):
            pages[f"docs/{model_id}.md"].section("Reserved and unlisted addresses")
        return
    section = pages[f"docs/{model_id}.md"].section("Reserved and unlisted addresses")
    header, *rows = section.tables[0]
    assert header[:3] == ["Addresses", "Dec", "In the manual"]
    want = {"reserved": "marked reserved", "unlabeled": "listed without a name", "not_listed": "not listed in the manual"}
    assert [r[2] for r in rows] == [want[r.kind] for r in m.reserved]


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_every_enum_has_a_table(model_id: str, pages: dict[str, Page], models: list[Model]) -> None:
    m = by_name(models, model_id)
    page = pages[f"docs/{model_id}.md"]
    for enum in m.enums:
        section = page.section(f"Enum {enum.name}")
        assert len(section.tables) == 1
        header, *rows = section.tables[0]
        assert header[:4] == ["Value", "Hex", "Name", "Label"]
        assert [(r[0], r[2], r[3]) for r in rows] == [(str(v.value), v.name, v.label) for v in enum.members]


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_every_bitfield_has_a_table_and_a_diagram(model_id: str, pages: dict[str, Page], models: list[Model]) -> None:
    m = by_name(models, model_id)
    page = pages[f"docs/{model_id}.md"]
    for reg in (r for r in m.registers if r.bits):
        section = page.section(f"Bits of {reg.name}")
        assert len(section.tables) == 1
        header, *rows = section.tables[0]
        assert header[:3] == ["Bits", "Mask", "Name"]
        assert [r[2] for r in rows] == [b.name for b in sorted(reg.bits, key=lambda b: b.offset)]
        for b, r in zip(sorted(reg.bits, key=lambda b: b.offset), rows, strict=True):
            assert int(r[1], 16) == b.mask
            assert r[3] == b.label
        diagrams = [content for info, content in section.fences if info == "text"]
        assert len(diagrams) == 1
        lines = diagrams[0].splitlines()
        assert lines[0].split() == [str(b) for b in range(16 * reg.words - 1, -1, -1)]
        for b in reg.bits:
            assert any(line.endswith(f" {b.name}") for line in lines), b.name
        # the marker row marks exactly the bits in use
        marks = lines[1]
        used = {bit for b in reg.bits for bit in range(b.offset, b.offset + b.width)}
        for bit in range(16 * reg.words):
            column = 4 * (16 * reg.words - 1 - bit) + 3
            assert (marks[column] != ".") == (bit in used), f"bit {bit}"


def test_bit_diagram_layout() -> None:
    """A 16-bit field with a 2-bit field: numbers, markers and one ladder line per field."""
    from drivemap.model.nodes import Bit

    m = compile_map(MAPS[0])
    reg = dataclasses.replace(
        m.registers[0],
        bits=(Bit("LOW", 0, 2, "l", None, None), Bit("MID", 4, 1, "m", None, None), Bit("TOP", 15, 1, "t", None, None)),
        type="u16",
    )
    lines = docs.bit_diagram(reg).splitlines()
    assert lines[0].split()[0] == "15" and lines[0].split()[-1] == "0"
    assert lines[1].strip().startswith("x") and lines[1].rstrip().endswith("[===]")
    assert lines[2].rstrip().endswith("+-- 1-0   LOW")
    assert lines[3].rstrip().endswith("MID") and "|" in lines[3]
    assert lines[4].rstrip().endswith("TOP")
    assert "bits 2-3, 5-14" in lines[-1]


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_every_example_appears_with_its_status(model_id: str, pages: dict[str, Page], models: list[Model]) -> None:
    m = by_name(models, model_id)
    page = pages[f"docs/{model_id}.md"]
    overview = page.section("Examples")
    listed = {r[0]: r[2] for r in _rows(overview)}
    assert listed == {ex.name: ex.status for ex in m.examples}
    for ex in m.examples:
        section = page.section(f"Example {ex.name}")
        facts = {r[0]: r[1] for r in _rows(section) if len(r) == 2}
        assert facts["Status"].split(" ")[0] == ex.status
        assert facts["Source"] == ex.source
        fences = [content.rstrip("\n") for info, content in section.fences if info == "text"]
        shown = [f.replace("\\r\\n", "\r\n") for f in fences]
        expected = [t for t in (ex.request, ex.corrected_request, ex.response, ex.corrected_response) if t is not None]
        assert sorted(shown) == sorted(expected)
        # every byte of every frame is annotated: the byte column re-assembles the frame
        annotations = [t for t in section.tables if t[0][0] in ("Bytes", "Characters")]
        assert len(annotations) == len(expected)
        for fence, table in zip(shown, annotations, strict=True):
            column = " ".join(r[0] for r in table[1:])
            if ex.mode == "rtu":
                assert column == fence
            else:
                assert column.replace(" ", "") == ":" + fence[1:-2] + "CRLF"
            fields = [r[1] for r in table[1:]]
            assert fields[0] in ("unit", "start")
            assert ("CRC low byte" in fields and "CRC high byte" in fields) if ex.mode == "rtu" else "LRC" in fields
        for ref, _value in ex.meaning.values:
            assert any(r[0] == ref for r in _rows(section)), ref
        if ex.erratum:
            assert any(ex.erratum == t.removeprefix("Erratum: ") for t in section.text)
        if ex.meaning.exception is not None:
            code = f"0x{ex.meaning.exception:02X}"
            assert any(r[1] == "exception code" and r[2].startswith(code) for t in annotations for r in t[1:])


def test_annotation_of_a_wrong_checksum(models: list[Model], pages: dict[str, Page]) -> None:
    """An erratum frame says which checksum the printed frame should carry."""
    for m in models:
        for ex in m.examples:
            if ex.corrected_response is None or ex.mode != "rtu":
                continue
            printed = docs.annotate(m, ex, ex.response or "", "response", "t")
            fixed = docs.annotate(m, ex, ex.corrected_response, "response", "t")
            assert fixed.verdict.endswith("correct")
            if not printed.verdict.endswith("correct"):
                assert printed.verdict.startswith("CRC wrong")
                assert ex.corrected_response.split(" ")[-2] + " " + ex.corrected_response.split(" ")[-1] in printed.verdict


def test_annotation_of_illegible_and_truncated_frames(models: list[Model]) -> None:
    m = by_name(models, "edx")
    ex = next(e for e in m.examples if e.mode == "rtu" and e.request and e.request.split(" ")[1] == "03")
    text = ex.request
    assert text is not None
    parts = text.split(" ")
    illegible = " ".join(parts[:2] + ["??"] + parts[3:])
    view = docs.annotate(m, ex, illegible, "request", "t")
    assert "illegible" in view.verdict
    assert any(r[2] == "illegible" and "??" in r[0] for r in view.rows)
    assert " ".join(r[0] for r in view.rows) == illegible
    short = " ".join(parts[:3] + parts[-2:])  # address cut short
    view = docs.annotate(m, ex, short, "request", "t")
    assert any("missing" in r[2] for r in view.rows)
    assert ("(missing)", "quantity", "incomplete: 2 byte(s) missing") in view.rows
    assert " ".join(r[0] for r in view.rows if r[0] != "(missing)") == short
