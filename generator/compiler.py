"""The pipeline: load -> schema -> semantic checks -> immutable model."""

from __future__ import annotations

import os
from pathlib import Path

from . import checks, schema
from .diagnostics import CompileError
from .load import load_file
from .model import Model, build_model

ROOT = Path(__file__).resolve().parent.parent
MAPS_DIR = ROOT / "maps"


def display_path(path: str | os.PathLike[str]) -> str:
    """Paths in messages are relative to the working directory when they can be."""
    p = Path(path)
    try:
        return os.path.relpath(p) if p.is_absolute() and not os.path.relpath(p).startswith("..") else str(p)
    except ValueError:
        return str(p)


def compile_map(path: str | os.PathLike[str]) -> Model:
    """Load, validate and check one map; raise :class:`CompileError` with every error found."""
    shown = display_path(path)
    doc = load_file(shown)
    if not isinstance(doc.data, dict):
        from .diagnostics import Diagnostic

        raise CompileError([Diagnostic(doc.positions.at(()), "a map is a YAML mapping at the top level")])
    errors = schema.validate(doc)
    if errors:
        raise CompileError(errors)
    problems, statuses = checks.check(doc)
    if problems:
        raise CompileError(problems)
    lines = {r["name"]: doc.positions.at(("registers", i)).line for i, r in enumerate(doc.data["registers"])}
    return build_model(shown, doc.data, statuses, lines)  # type: ignore[arg-type]


def map_paths(directory: str | os.PathLike[str] | None = None) -> list[Path]:
    """Every map in ``maps/`` (sorted by name)."""
    folder = Path(directory) if directory is not None else MAPS_DIR
    return sorted(folder.glob("*.yaml"))


def find_map(model: str) -> Path:
    """The map of a model id (``ev`` -> maps/ev.yaml)."""
    candidate = MAPS_DIR / f"{model}.yaml"
    if candidate.exists():
        return candidate
    direct = Path(model)
    if direct.suffix == ".yaml" and direct.exists():
        return direct
    from .diagnostics import Diagnostic, Location

    raise CompileError([Diagnostic(Location(display_path(candidate), 1, 1), f"no map for model {model!r}")])


def load_model(model: str) -> Model:
    """Compile ``maps/<model>.yaml``."""
    return compile_map(find_map(model))
