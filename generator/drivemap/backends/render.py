"""Rendering: one Jinja template per output, values reach code through repr-style filters."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import jinja2

from drivemap.vocab import escape

TEMPLATES = Path(__file__).resolve().parent / "templates"


def _py(value: Any) -> str:
    """A Python literal for any map value: text from a map can never become code (:mod:`.escape`)."""
    return escape.py_literal(value)


def _hex(value: int, width: int = 4) -> str:
    return f"0x{value:0{width}X}"


def _md(value: Any) -> str:
    """Text for Markdown inline text and table cells (:func:`.escape.md_text`)."""
    return escape.md_text(value)


def _doc(value: Any) -> str:
    """Text safe inside a triple-quoted docstring (:func:`.escape.py_docstring`)."""
    return escape.py_docstring(value)


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
    env.filters["mdcomment"] = escape.md_comment
    return env


def scaffold(model: str, schema_ref: str = "../schemas/drivemap.schema.json") -> str:
    """The text of ``drivemap new``'s map (``schema_ref``: the ``$schema`` path as seen from the map)."""
    return environment().get_template("new_map.yaml.jinja").render(model=model, schema_ref=schema_ref)


@lru_cache(maxsize=1)
def _shared_environment() -> jinja2.Environment:
    return environment()


def render_template(name: str, template: str, context: dict[str, Any]) -> str:
    """Render one output file ``name`` from ``template`` and normalise its whitespace."""
    return postprocess(name, _shared_environment().get_template(template).render(**context))


def postprocess(name: str, text: str) -> str:
    """Normalise whitespace so output is byte-stable: no trailing spaces, one final newline."""
    lines = [line.rstrip() for line in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    if name.endswith(".py"):
        cleaned: list[str] = []
        blank = 0
        for line in lines:
            blank = blank + 1 if not line else 0
            if blank <= 2:
                cleaned.append(line)
        lines = cleaned
    return "\n".join(lines) + "\n" if lines else ""
