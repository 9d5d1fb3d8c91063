"""Generated Markdown docs: every page parses as CommonMark and shows the whole model.

The pages are rendered in memory from the same compiled models ``drivemap build`` uses, parsed with
markdown-it-py, and checked structurally (tables, headings, fences, links). The usage snippet on
each page is executed against that model's simulator over TCP.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from markdown_it import MarkdownIt
from markdown_it.token import Token

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.docs import DocsExporter
from drivemap.backends.render import _md, environment
from drivemap.backends.views import docs
from drivemap.build import render_tree, write_tree
from drivemap.compiler import compile_map, map_paths
from drivemap.diagnostics import CompileError
from drivemap.model.nodes import Model
from tests.waits import free_port, wait_port

ROOT = Path(__file__).resolve().parent.parent
GENERATED = ROOT / "generated"
MAPS = map_paths()


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def models() -> list[Model]:
    compiled = []
    for path in MAPS:
        try:
            compiled.append(compile_map(path))
        except CompileError as exc:
            pytest.fail(f"{path} does not compile:\n" + "\n".join(d.format() for d in exc.diagnostics))
    return compiled


@pytest.fixture(scope="module")
def outputs(models: list[Model]) -> dict[str, str]:
    """The docs pages, rendered through their registered targets exactly as ``drivemap build`` does."""
    return {f"docs/{rel}": text for rel, text in DocsExporter().render_all(models, Options()).items()}


@pytest.fixture(scope="module")
def target_paths(models: list[Model]) -> set[str]:
    """Every file ``drivemap build`` writes under generated/ (links may point at any of them)."""
    return set(render_tree(models))


def by_name(models: list[Model], name: str) -> Model:
    return next(m for m in models if m.name == name)


MODEL_IDS = [p.stem for p in MAPS]


# ---------------------------------------------------------------- a small structural view of a page


@dataclass
class Section:
    level: int
    title: str
    tables: list[list[list[str]]] = field(default_factory=list)  # table -> rows (header first) -> cells
    fences: list[tuple[str, str]] = field(default_factory=list)  # (info, content)
    text: list[str] = field(default_factory=list)  # inline text of paragraphs, list items, cells


@dataclass
class Page:
    source: str
    tokens: list[Token]
    sections: list[Section]
    links: list[str]

    def section(self, title: str) -> Section:
        hits = [s for s in self.sections if s.title == title]
        assert len(hits) == 1, f"expected one heading {title!r}, found {len(hits)}"
        return hits[0]

    def slugs(self) -> set[str]:
        """Heading anchors as GitHub derives them (independent of the view's own slug function)."""
        seen: dict[str, int] = {}
        out = set()
        for s in self.sections:
            if s.level == 0:
                continue
            base = re.sub(r"[^\w\- ]", "", s.title.strip().lower()).replace(" ", "-")
            n = seen.get(base, 0)
            out.add(base if n == 0 else f"{base}-{n}")
            seen[base] = n + 1
        return out


def inline_text(token: Token) -> str:
    return "".join(c.content for c in token.children or [] if c.type in ("text", "code_inline", "softbreak"))


def parse(source: str) -> Page:
    md = MarkdownIt("commonmark").enable("table")
    tokens = md.parse(source)
    sections = [Section(0, "")]
    links: list[str] = []
    table: list[list[str]] | None = None
    row: list[str] | None = None
    in_heading = False
    for i, tok in enumerate(tokens):
        current = sections[-1]
        if tok.type == "heading_open":
            in_heading = True
        elif tok.type == "heading_close":
            in_heading = False
        elif tok.type == "table_open":
            table = []
        elif tok.type == "table_close":
            assert table is not None
            current.tables.append(table)
            table = None
        elif tok.type == "tr_open":
            row = []
        elif tok.type == "tr_close":
            assert table is not None and row is not None
            table.append(row)
            row = None
        elif tok.type == "fence":
            current.fences.append((tok.info.strip(), tok.content))
        elif tok.type == "inline":
            text = inline_text(tok)
            if in_heading:
                level = int(tokens[i - 1].tag[1])
                sections.append(Section(level, text))
            elif row is not None:
                row.append(text)
                current.text.append(text)
            else:
                current.text.append(text)
            for child in tok.children or []:
                if child.type == "link_open":
                    links.append(str(child.attrs["href"]))
    return Page(source, tokens, sections, links)


@pytest.fixture(scope="module")
def pages(outputs: dict[str, str]) -> dict[str, Page]:
    return {name: parse(text) for name, text in outputs.items() if name.startswith("docs/")}


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


# ---------------------------------------------------------------- links, leaks, escaping


@pytest.mark.parametrize("name", [f"docs/{i}.md" for i in MODEL_IDS] + ["docs/index.md"])
def test_every_relative_link_resolves(name: str, pages: dict[str, Page], target_paths: set[str]) -> None:
    page = pages[name]
    assert page.links
    here = Path(name).parent
    for href in page.links:
        if re.match(r"^[a-z]+:", href):
            continue
        target, _, anchor = href.partition("#")
        if target:
            rel = os.path.normpath(here / target)
            on_disk = (GENERATED / rel).resolve()
            assert rel in target_paths or on_disk.exists(), f"{name}: link {href!r} resolves to nothing"
            if anchor:
                assert rel in pages and anchor in pages[rel].slugs(), f"{name}: {href!r}"
        else:
            assert anchor in page.slugs(), f"{name}: anchor {href!r} has no heading"


def _map_strings(path: Path) -> list[str]:
    out: list[str] = []

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                out.append(str(k))
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)
        elif isinstance(node, str):
            out.append(node)

    walk(yaml.safe_load(path.read_text(encoding="utf-8")))
    return out


LEAKS = re.compile(r"\bNone\b|\bnan\b|\bUndefined\b|\{\{|\}\}|\{%|%\}|\{#|#\}|\bnull\b")


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_no_placeholder_or_none_leaks(model_id: str, outputs: dict[str, str], pages: dict[str, Page]) -> None:
    text = outputs[f"docs/{model_id}.md"]
    # the docs say on purpose what a not-available value reads as in Python (Optional -> None)
    text = text.replace("(the client reads None)", "")
    # text that comes from the map may legitimately say "None" (e.g. "Parity: None"): take it out first
    strings = sorted({_md(s) for s in _map_strings(ROOT / "maps" / f"{model_id}.yaml")}, key=len, reverse=True)
    for s in strings:
        if len(s) > 2:
            text = text.replace(s, "")
    leaks = LEAKS.findall(text)
    assert not leaks, f"placeholder leaks in docs/{model_id}.md: {leaks}"
    page = pages[f"docs/{model_id}.md"]
    for section in page.sections:
        for table in section.tables:
            width = len(table[0])
            for row in table[1:]:
                assert len(row) == width
                assert all(cell.strip() for cell in row), f"empty cell in {section.title!r}: {row}"
    index = outputs["docs/index.md"]
    assert not re.search(r"\{\{|\{%|\bNone\b", index)


def test_map_text_cannot_break_tables_or_inject_html(models: list[Model]) -> None:
    """Hostile text in every kind of map string stays inside its cell and never becomes HTML."""
    m = models[0]
    evil = "a | b <script>alert(1)</script> `x` *y* _z_ [l](http://e) \\ \n# H\n| c |"
    reg = dataclasses.replace(m.registers[0], label=evil, notes=evil, description=evil, unit=evil, source=evil)
    regs = (reg,) + m.registers[1:]
    device = dataclasses.replace(m.device, title=evil, coverage=evil, notes=evil)
    examples = tuple(dataclasses.replace(e, title=evil, notes=evil, source=evil) for e in m.examples)
    hostile = dataclasses.replace(m, registers=regs, device=device, examples=examples,
                                  _by_name={r.name: r for r in regs})
    text = environment().get_template("model.md.jinja").render(**docs.context(hostile, Options()))
    page = parse(text)
    html = [t for t in page.tokens if t.type in ("html_block", "html_inline")]
    assert [t.content.strip() for t in html] == [f"<!-- {docs.header(hostile, Options())} -->"]
    for t in page.tokens:
        for child in t.children or []:
            assert child.type != "html_inline"
            if child.type == "link_open":
                assert not str(child.attrs["href"]).startswith("http://e")
    original = parse(environment().get_template("model.md.jinja").render(**docs.context(m, Options())))
    assert [len(t) for s in page.sections for t in s.tables] == [len(t) for s in original.sections for t in s.tables]
    flat = evil.replace("\n", " ")
    assert [s.title for s in page.sections if s.level <= 2] == [
        f"{m.name}: {flat}" if s.level == 1 else s.title for s in original.sections if s.level <= 2
    ]
    register_rows = [row for s in page.sections for t in s.tables
                     if t[0][:5] == ["Address", "Dec", "Modicon", "Param", "Name"] for row in t[1:]]
    assert any(row[5] == evil.replace("\n", " ") for row in register_rows)


# ---------------------------------------------------------------- the usage snippet runs against the simulator


def _free_port() -> int:
    return free_port()


def _wait_for_port(port: int, proc: subprocess.Popen[bytes], timeout: float = 20.0) -> None:
    wait_port(port, timeout, proc)


@pytest.fixture(scope="module")
def built_tree(tmp_path_factory: pytest.TempPathFactory, models: list[Model]) -> Path:
    """A fresh generated/ tree (client, simulator, spec) so the snippet runs what this code generates."""
    root = tmp_path_factory.mktemp("docs_snippets")
    write_tree(root / "generated", render_tree(models))
    return root


@pytest.mark.parametrize("model_id", MODEL_IDS)
def test_snippet_runs_against_the_simulator(model_id: str, pages: dict[str, Page], target_paths: set[str],
                                            request: pytest.FixtureRequest) -> None:
    assert f"{model_id}/client.py" in target_paths, (
        "the generated client (generator/drivemap/backends/views/client.py) is missing: the page's snippet cannot run")
    built_tree: Path = request.getfixturevalue("built_tree")
    section = pages[f"docs/{model_id}.md"].section("How to use it")
    shells = [c for info, c in section.fences if info == "sh"]
    pythons = [c for info, c in section.fences if info == "python"]
    assert len(shells) == 1 and len(pythons) == 1
    port = _free_port()
    address = f"{docs.SNIPPET_HOST}:{docs.SNIPPET_PORT}"
    argv = shlex.split(shells[0].strip())
    assert argv[:2] == ["drivemap", "simulate"] and address in argv
    argv = [sys.executable, "-m", "drivemap"] + [a.replace(address, f"127.0.0.1:{port}") for a in argv[1:]]
    code = pythons[0]
    assert f"port={docs.SNIPPET_PORT}" in code
    code = code.replace(f"port={docs.SNIPPET_PORT}", f"port={port}")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(argv, cwd=built_tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_for_port(port, proc)
        run = subprocess.run([sys.executable, "-c", code], cwd=built_tree, env=env, capture_output=True,
                             text=True, timeout=60)
        assert run.returncode == 0, f"snippet failed:\n{code}\n--- stderr ---\n{run.stderr}"
        printed = [line for line in run.stdout.splitlines() if line.strip()]
        assert len(printed) == code.count("print("), run.stdout
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
