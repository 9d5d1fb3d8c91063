"""Hostile free text in a map must come out literally, never as code or markup.

A map whose titles, labels, notes and sources carry quotes, triple quotes, backslashes,
newlines, Jinja delimiters, HTML, Markdown pipes and Python code is compiled; the generated
client, simulator and docs must import, type-check and render, show the text literally, and
nothing in the text may run (each payload would create a marker file if it ever executed).
"""

from __future__ import annotations

import importlib
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
import yaml

from drivemap.build import render_tree, write_tree
from drivemap.compiler import compile_map

ROOT = Path(__file__).resolve().parents[2]


def payloads(marker: Path) -> list[str]:
    code = f"__import__('pathlib').Path({str(marker)!r}).touch()"
    return [
        f"'; {code}; '",
        f'"""; {code}; """',
        f"\\\\'\\n{code}\\n#",
        "{{ 7*7 }} {% for x in range(3) %}loop{% endfor %}",
        f"</script><script>{code}</script><b>bold</b>",
        "| a | b |\n|---|---|\n| injected | row |",
        f"line one\nline two\r\n\t{code}",
        f"{{{{ self.__init__.__globals__ }}}} {code}",
    ]


def hostile_map(marker: Path) -> tuple[dict[str, object], list[str]]:
    scaffold = ROOT / "generator" / "drivemap" / "backends" / "templates" / "new_map.yaml.jinja"
    base = yaml.safe_load(scaffold.read_text(encoding="utf-8").replace("{{ model }}", "hostile"))
    texts = payloads(marker)
    base["device"]["title"] = texts[0]
    base["device"]["notes"] = texts[1]
    base["device"]["coverage"] = texts[6]
    base["device"]["vendor"] = texts[4]
    base["device"]["manual"]["document"] = texts[3]
    base["enums"]["RunState"]["values"][0]["label"] = texts[2]
    base["enums"]["RunState"]["values"][1]["label"] = texts[5]
    base["enums"]["RunState"]["notes"] = texts[7]
    for i, reg in enumerate(base["registers"]):
        reg["notes"] = texts[i % len(texts)]
        reg["label"] = texts[(i + 3) % len(texts)]
        reg["description"] = texts[(i + 5) % len(texts)]
        reg["source"] = texts[(i + 1) % len(texts)]
    base["registers"][0]["bits"][0]["label"] = texts[1]
    base["registers"][1]["unit"] = texts[0]
    base["protocol"]["exceptions"][0]["meaning"] = texts[1]
    base["known_issues"][0]["printed"] = texts[5]
    base["identity"][0]["source"] = texts[3]
    base["known_issues"][0]["reason"] = texts[2]
    base["examples"][0]["title"] = texts[4]
    base["examples"][0]["notes"] = texts[6]
    base["groups"][0]["title"] = texts[5]
    return base, texts


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[str]]:
    work = tmp_path_factory.mktemp("inject")
    marker = work / f"executed-{uuid.uuid4().hex}"
    data, texts = hostile_map(marker)
    (work / "maps").mkdir()
    map_path = work / "maps" / "hostile.yaml"
    map_path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")
    model = compile_map(map_path)
    out = work / "pkg" / "generated_hostile"
    write_tree(out, render_tree([model]))
    assert not marker.exists(), "rendering executed map text"
    return out, marker, texts


def test_generated_python_imports_and_runs_nothing(built: tuple[Path, Path, list[str]]) -> None:
    out, marker, texts = built
    sys.path.insert(0, str(out.parent))
    try:
        modules = sorted(p.stem for p in (out / "hostile").glob("*.py") if p.stem != "__init__")
        assert "spec" in modules
        for name in ["generated_hostile.hostile"] + [f"generated_hostile.hostile.{m}" for m in modules]:
            module = importlib.import_module(name)
            assert module is not None
        spec = importlib.import_module("generated_hostile.hostile.spec").SPEC
        assert spec.device.title == texts[0]  # the text survives literally
        for module_name in modules:
            mod = importlib.import_module(f"generated_hostile.hostile.{module_name}")
            for attr in dir(mod):
                obj = getattr(mod, attr)
                doc = getattr(obj, "__doc__", None)
                assert doc is None or isinstance(doc, str)
    finally:
        sys.path.remove(str(out.parent))
        for key in [k for k in sys.modules if k.startswith("generated_hostile")]:
            del sys.modules[key]
    assert not marker.exists(), "importing generated code executed map text"


def test_generated_python_type_checks_and_lints(built: tuple[Path, Path, list[str]]) -> None:
    out, marker, _ = built
    mypy = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--no-incremental", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert mypy.returncode == 0, mypy.stdout + mypy.stderr
    ruff = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", str(out)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert ruff.returncode == 0, ruff.stdout + ruff.stderr
    assert not marker.exists()


def test_docs_render_text_literally(built: tuple[Path, Path, list[str]]) -> None:
    out, _, _ = built
    page = out / "docs" / "hostile.md"
    if not page.exists():
        pytest.fail("docs target missing: generated/docs/<model>.md was not rendered")
    text = page.read_text(encoding="utf-8")
    from markdown_it import MarkdownIt

    html = MarkdownIt("commonmark").enable("table").render(text)
    assert "<script>" not in html and "<b>bold</b>" not in html
    assert "loop loop" not in text and "49" not in text.split("{{ 7*7 }}")[0][-3:]
    assert "{{ 7*7 }}" in text or "{{ 7\\*7 }}" in text
    # a pipe in map text never adds a table column: every table row has the header's cell count
    tokens = MarkdownIt("commonmark").enable("table").parse(text)
    depth_cells: list[int] = []
    cells = 0
    header = None
    for tok in tokens:
        if tok.type == "table_open":
            header = None
        elif tok.type == "tr_open":
            cells = 0
        elif tok.type in ("th_open", "td_open"):
            cells += 1
        elif tok.type == "tr_close":
            if header is None:
                header = cells
            depth_cells.append(cells)
            assert cells == header
    assert depth_cells
