"""Generated Markdown docs, continued (tests/backends/exporters/test_docs.py checks what each page shows): every relative
link resolves, no placeholder or ``None`` leaks, map text cannot break a table or inject HTML, and the
usage snippet on each page runs against that model's simulator over TCP.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from drivemap.backends.exporters.base import Options
from drivemap.backends.render import _md, environment
from drivemap.backends.views import docs
from drivemap.build import render_tree, write_tree
from drivemap.model.nodes import Model
from tests.docs_pages import GENERATED, MODEL_IDS, ROOT, Page, compile_models, parse, parse_pages, render_outputs
from tests.waits import free_port, wait_port


@pytest.fixture(scope="module")
def models() -> list[Model]:
    return compile_models()


@pytest.fixture(scope="module")
def outputs(models: list[Model]) -> dict[str, str]:
    return render_outputs(models)


@pytest.fixture(scope="module")
def target_paths(models: list[Model]) -> set[str]:
    """Every file ``drivemap build`` writes under generated/ (links may point at any of them)."""
    return set(render_tree(models))


@pytest.fixture(scope="module")
def pages(outputs: dict[str, str]) -> dict[str, Page]:
    return parse_pages(outputs)


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
    hostile = dataclasses.replace(m, registers=regs, device=device, examples=examples)
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
