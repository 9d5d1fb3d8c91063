"""The pipeline: load -> schema -> semantic checks -> immutable model."""

from __future__ import annotations

import os
from pathlib import Path

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend import checks, schema
from drivemap.frontend.load import MAX_REGISTERS, Document, load_file, load_text
from drivemap.frontend.project import Project, display, load_project
from drivemap.model.build import build_model
from drivemap.model.nodes import Model

#: The seed maps shipped with drivemap (ev, vfd1000, v2, edx): a model id that the project does
#: not have is looked up here.
BUNDLED_MAPS = Path(__file__).resolve().parent / "data" / "maps"


def display_path(path: str | os.PathLike[str]) -> str:
    """Paths in messages are relative to the working directory when they can be."""
    return display(path)


def compile_map(path: str | os.PathLike[str]) -> Model:
    """Load, validate and check one map; raise :class:`CompileError` with every error found."""
    shown = display_path(path)
    return _compile_document(load_file(shown), shown)


def compile_text(text: str, shown: str) -> Model:
    """:func:`compile_map` of a map's text (``shown`` is the path its messages name)."""
    return _compile_document(load_text(text, shown), shown)


def _compile_document(doc: Document, shown: str) -> Model:
    if not isinstance(doc.data, dict):
        raise CompileError([Diagnostic(doc.positions.at(()), "a map is a YAML mapping at the top level")])
    registers = doc.data.get("registers")
    if isinstance(registers, list) and len(registers) > MAX_REGISTERS:
        raise CompileError([Diagnostic(doc.positions.at(("registers", MAX_REGISTERS)),
                                       f"more than {MAX_REGISTERS:,} registers: map refused before validation "
                                       "(bounded time and memory; docs/limits.md)")])
    errors = schema.validate(doc)
    if errors:
        raise CompileError(errors)
    problems, statuses = checks.check(doc)
    if problems:
        raise CompileError(problems)
    lines = {r["name"]: doc.positions.at(("registers", i)).line for i, r in enumerate(doc.data["registers"])}
    return build_model(shown, doc.data, statuses, lines)  # type: ignore[arg-type]


def map_paths() -> list[Path]:
    """Every map of the working directory's project (sorted by name)."""
    return load_project().map_files()


def bundled_maps() -> list[Path]:
    """The seed maps that ship with drivemap (sorted by name)."""
    return sorted(BUNDLED_MAPS.glob("*.yaml")) if BUNDLED_MAPS.is_dir() else []


def looks_like_path(text: str) -> bool:
    return text.endswith((".yaml", ".yml")) or "/" in text or os.sep in text


def resolve_map(name: str, project: Project) -> Path:
    """The map of ``name``: a path to a map file, else the project's map of that model id, else
    the seed map of that id shipped with drivemap."""
    if looks_like_path(name):
        path = Path(name)
        if path.is_file():
            return path
        raise CompileError([Diagnostic(Location(display(path), 1, 1), "no such map file")])
    found = project.find_map(name)
    if found is None:
        found = next((p for p in bundled_maps() if p.stem == name), None)
    if found is None:
        known = sorted({p.stem for p in project.map_files()})
        hint = f" (the project has: {', '.join(known)})" if known else " (the project has no maps)"
        where = display(project.maps_folder() / f"{name}.yaml")
        raise CompileError([Diagnostic(Location(where, 1, 1), f"no map for model {name!r}{hint}")])
    return found


def load_model(name: str, project: Project | None = None) -> Model:
    """Compile the map of a model id or path (see :func:`resolve_map`)."""
    return compile_map(resolve_map(name, project or load_project()))
