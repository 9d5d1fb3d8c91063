"""Shared by tests/backends/exporters/test_docs.py and tests/backends/exporters/test_docs_links.py: the maps, their docs pages rendered in
memory exactly as ``drivemap build`` renders them, and a small structural view of a page (CommonMark,
parsed with markdown-it-py: sections with their tables, fences and text, and the page's links)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from markdown_it import MarkdownIt
from markdown_it.token import Token

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.docs import DocsExporter
from drivemap.compiler import compile_map, map_paths
from drivemap.diagnostics import CompileError
from drivemap.model.nodes import Model

ROOT = Path(__file__).resolve().parent.parent
GENERATED = ROOT / "generated"
MAPS = map_paths()
MODEL_IDS = [p.stem for p in MAPS]


def compile_models() -> list[Model]:
    """Every map compiled; a map that does not compile fails the test with its diagnostics."""
    compiled = []
    for path in MAPS:
        try:
            compiled.append(compile_map(path))
        except CompileError as exc:
            pytest.fail(f"{path} does not compile:\n" + "\n".join(d.format() for d in exc.diagnostics))
    return compiled


def render_outputs(models: list[Model]) -> dict[str, str]:
    """The docs pages, rendered through their registered targets exactly as ``drivemap build`` does."""
    return {f"docs/{rel}": text for rel, text in DocsExporter().render_all(models, Options()).items()}


def by_name(models: list[Model], name: str) -> Model:
    return next(m for m in models if m.name == name)


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



def parse_pages(outputs: dict[str, str]) -> dict[str, Page]:
    return {name: parse(text) for name, text in outputs.items() if name.startswith("docs/")}
