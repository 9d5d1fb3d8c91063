"""View models: everything a template needs, computed in Python so templates stay logic-free.

``TARGETS`` lists every generated file: (path under generated/, template, context builder).
Per-model paths contain ``{model}``; the others are rendered once for all models.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..model import Model
from . import common, spec

Builder = Callable[[Model, list[Model]], dict[str, Any]]

TARGETS: list[tuple[str, str, Builder]] = [
    ("__init__.py", "generated_init.py.jinja", common.root_context),
    ("py.typed", "py.typed.jinja", common.root_context),
    ("{model}/spec.py", "spec.py.jinja", spec.context),
]


def _register_optional_targets() -> None:
    """Targets whose view modules exist (client, simulator, docs are added by their own modules)."""
    import importlib

    for module, entries in (
        ("client", [("{model}/__init__.py", "package_init.py.jinja"), ("{model}/client.py", "client.py.jinja")]),
        ("simulator", [("{model}/simulator.py", "simulator.py.jinja")]),
        ("docs", [("docs/{model}.md", "model.md.jinja"), ("docs/index.md", "index.md.jinja")]),
    ):
        try:
            mod = importlib.import_module(f"{__name__}.{module}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{module}":
                raise
            continue
        for path, template in entries:
            builder = getattr(mod, "index_context" if path == "docs/index.md" else "context")
            TARGETS.append((path, template, builder))


_register_optional_targets()


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
