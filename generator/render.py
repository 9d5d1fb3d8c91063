"""Rendering: one Jinja template per output, values reach code through repr-style filters."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import jinja2

from .model import Model

TEMPLATES = Path(__file__).resolve().parent / "templates"


def _py(value: Any) -> str:
    """A Python literal for any map value: text from a map can never become code."""
    return repr(value)


def _hex(value: int, width: int = 4) -> str:
    return f"0x{value:0{width}X}"


def _md(value: Any) -> str:
    """Text for a Markdown table cell: pipes, newlines and HTML are neutralised."""
    if value is None:
        return "—"
    text = str(value)
    for old, new in (("&", "&amp;"), ("\\", "\\\\"), ("|", "\\|"), ("<", "&lt;"), (">", "&gt;"), ("\r", " "), ("\n", " "),
                     ("`", "\\`"), ("*", "\\*"), ("_", "\\_"), ("[", "\\["), ("]", "\\]")):
        text = text.replace(old, new)
    return text


def _doc(value: Any) -> str:
    """Text safe inside a triple-quoted docstring (rendered with repr-escapes, no quotes)."""
    text = str(value)
    return repr(text)[1:-1].replace('"""', '\\"\\"\\"')


def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(TEMPLATES)),
        undefined=jinja2.StrictUndefined,
        autoescape=False,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["py"] = _py
    env.filters["hex"] = _hex
    env.filters["md"] = _md
    env.filters["doc"] = _doc
    return env


def scaffold(model: str) -> str:
    return environment().get_template("new_map.yaml.jinja").render(model=model)


def render_all(models: list[Model]) -> dict[str, str]:
    """Every generated file: relative path -> text."""
    from . import views

    env = environment()
    out: dict[str, str] = {}
    for per_model in (True, False):
        for rel, template, build in views.TARGETS:
            if ("{model}" in rel) != per_model:
                continue
            for model in models if per_model else [None]:
                context = build(model, models)  # type: ignore[arg-type]
                name = rel.format(model=model.name) if model is not None else rel
                out[name] = views.postprocess(name, env.get_template(template).render(**context))
    return out


def write_outputs(outputs: dict[str, str], root: Path) -> int:
    """Write files atomically; remove generated files no target produces any more."""
    changed = 0
    for rel, text in sorted(outputs.items()):
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.exists() and path.read_text(encoding="utf-8") == text:
            continue
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        os.replace(tmp, path)
        changed += 1
    for stale in _extra_files(outputs, root):
        stale.unlink()
        changed += 1
    return changed


def _generated_files(root: Path) -> Iterable[Path]:
    for path in root.rglob("*"):
        if path.is_file() and "__pycache__" not in path.parts and path.suffix in (".py", ".md", ".typed"):
            yield path


def _extra_files(outputs: dict[str, str], root: Path) -> list[Path]:
    known = {(root / rel).resolve() for rel in outputs}
    return [p for p in _generated_files(root) if p.resolve() not in known]


def stale_files(outputs: dict[str, str], root: Path) -> list[tuple[str, str]]:
    """(path, why) for every file that differs from what build would write."""
    stale = []
    for rel, text in sorted(outputs.items()):
        path = root / rel
        if not path.exists():
            stale.append((rel, "missing"))
        elif path.read_text(encoding="utf-8") != text:
            stale.append((rel, "differs"))
    for extra in _extra_files(outputs, root):
        stale.append((str(extra.relative_to(root)), "not produced by any map"))
    return stale
