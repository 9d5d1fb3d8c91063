"""The pipeline: load -> schema -> semantic checks -> immutable model.

The compiler is the front end and the model: it imports no back end. A verb that writes an output
asks for that output's own checks by handing them in (``checks``: anything with an exporter's
``validate(model)``, run on the located model once the front end has passed; ``build`` and ``check`` hand in the python and docs exporters, ``export``
the exporter it runs, ``drivemap validate --exporter NAME`` the ones named); by default none run.
"""

from __future__ import annotations

import hashlib
import inspect
import os
import stat
import sys
import time
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Protocol, TextIO

from drivemap import cache
from drivemap.diagnostics import CompileError, Diagnostic, Location, Problem
from drivemap.frontend import family, formats
from drivemap.frontend.load import MAX_MAP_BYTES, MAX_REGISTERS, Document, load_file, load_text
from drivemap.frontend.project import SHIPPED_MAPS, Project, catalogue_maps, display, load_project, shipped_maps
from drivemap.model.nodes import Model

#: The maps shipped with drivemap (and its catalogue below ``catalogue/``): a model id that the project
#: does not have is looked up here.
BUNDLED_MAPS = SHIPPED_MAPS


def display_path(path: str | os.PathLike[str]) -> str:
    """Paths in messages are relative to the working directory when they can be."""
    return display(path)


class MapCheck(Protocol):
    """An output's own checks of a map that passed the front end (an exporter's ``validate``)."""

    def validate(self, model: Model, options: Any = None) -> Iterable[Problem]: ...


def compile_map(path: str | os.PathLike[str], checks: Sequence[MapCheck] = ()) -> Model:
    """Load, validate and check one map (and run each of ``checks``, an output's own checks: none by
    default); raise :class:`CompileError` with every error found."""
    shown = display_path(path)
    return compile_document(load_file(shown), checks)


def compile_cached(path: str | os.PathLike[str], checks: Sequence[MapCheck] = ()) -> Model:
    """:func:`compile_map`, reusing the model compiled before from the same bytes (of the map and
    of every map it extends), shown under the same path, with the same checks, by the same
    drivemap (:mod:`drivemap.cache`). A map that does not compile is never cached (its errors are
    raised anew); warnings a compile gave are given again when its model comes from the cache.
    """
    chosen = tuple(checks)
    shown = display_path(path)
    names = sorted(f"{type(e).__module__}.{type(e).__qualname__}" for e in chosen)
    if not cache.enabled() or any(not n.startswith("drivemap.") for n in names):
        return compile_map(shown, chosen)  # a plugin's checks may change without drivemap's version
    try:
        st = os.stat(shown)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_MAP_BYTES:
            raise OSError
        with open(shown, "rb") as handle:
            raw = handle.read(MAX_MAP_BYTES + 1)
    except OSError:
        return compile_map(shown, chosen)  # it raises the located error
    entry = cache.key("model", shown, os.path.realpath(shown), "\0".join(names), raw)
    hit = cache.load("model", entry)
    if hit is not None and _fresh(hit):
        deps, cached, given = hit
        _warn_again(given)
        _remember(cached, entry, deps)
        return cached  # type: ignore[no-any-return]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return compile_map(shown, chosen)  # it raises the located error
    started = time.time()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        failed: CompileError | None = None
        try:
            model = compile_document(load_text(text, shown), chosen)  # the bytes of the key, not a second read
        except CompileError as exc:
            failed = exc
    given = [(str(w.message), w.category, w.filename, w.lineno) for w in caught]
    if failed is not None:
        _warn_again(given)
        raise failed
    deps = tuple((os.path.realpath(p), _digest(p)) for p in (model.variant.extends if model.variant else ()))
    if all(d and _settled(p, started) for p, d in deps):  # an extended map changed while it was read: not stored
        cache.store("model", entry, (deps, model, given))
        _remember(model, entry, deps)
    _warn_again(given)
    return model


def _remember(model: Model, entry: str, deps: tuple[tuple[str, str], ...]) -> None:
    """Give the model the key of everything it was compiled from (``Model.cache_key``, set once here)."""
    object.__setattr__(model, "cache_key", cache.key(entry, *(d for _, d in deps)))


def content_key(model: Model) -> str | None:
    """A key of everything ``model`` was compiled from (the map's bytes and path, the maps it
    extends, the checks, drivemap's code), when :func:`compile_cached` gave it; else None."""
    return model.cache_key


def _digest(path: str) -> str:
    try:
        with open(path, "rb") as handle:
            return hashlib.sha256(handle.read()).hexdigest()
    except OSError:
        return ""


def _settled(path: str, started: float) -> bool:
    try:
        return os.stat(path).st_mtime < started - 1.0
    except OSError:
        return False


def _fresh(hit: object) -> bool:
    """A cached (extended maps, model, warnings) whose extended maps still hold the bytes it was built from."""
    if not (isinstance(hit, tuple) and len(hit) == 3 and isinstance(hit[1], Model) and isinstance(hit[0], tuple)
            and isinstance(hit[2], list)):
        return False
    return all(isinstance(d, tuple) and len(d) == 2 and _digest(d[0]) == d[1] for d in hit[0])


def _warn_again(given: list[tuple[str, type[Warning], str, int]]) -> None:
    for message, category, filename, lineno in given:
        warnings.warn_explicit(message, category, filename, lineno)


def compile_text(text: str, path: str | os.PathLike[str], checks: Sequence[MapCheck] = ()) -> Model:
    """:func:`compile_map` of ``text`` as if it were the content of ``path`` (nothing is read but
    the maps it extends)."""
    return compile_document(load_text(text, display_path(path)), checks)


def compile_document(doc: Document, checks: Sequence[MapCheck] = ()) -> Model:
    """Validate and check a loaded map (and the maps it extends), with ``checks`` (outputs' own
    checks); the model."""
    from drivemap.frontend import checks as semantic  # here: a model from the cache needs neither (nor jsonschema)
    from drivemap.frontend import schema
    from drivemap.model.build import build_model

    shown = doc.path
    if not isinstance(doc.data, dict):
        raise CompileError([Diagnostic(doc.positions.at(()), "a map is a YAML mapping at the top level")])
    registers = doc.data.get("registers")
    if isinstance(registers, list) and len(registers) > MAX_REGISTERS:
        raise CompileError([Diagnostic(doc.positions.at(("registers", MAX_REGISTERS)),
                                       f"more than {MAX_REGISTERS:,} registers: map refused before validation "
                                       "(bounded time and memory; docs/limits.md)")])
    version = formats.upgrade(doc)
    doc, variant = family.resolve(doc)
    errors = schema.validate(doc)
    if errors:
        raise CompileError(family.note_overrides(doc, errors))
    problems, statuses = semantic.check(doc)
    if problems:
        raise CompileError(family.note_overrides(doc, problems))
    lines = {r["name"]: doc.positions.at(("registers", i)).line for i, r in enumerate(doc.data["registers"])}
    model = build_model(shown, doc.data, statuses, lines, doc.positions.at)  # type: ignore[arg-type]
    model = replace(model, format_version=version or formats.CURRENT, variant=variant)
    for check in checks:  # outputs' own checks walk the located model; their YAML paths are placed in the map
        problems += semantic.located(doc, run_check(check, model, doc.data))
    if problems:
        raise CompileError(family.note_overrides(doc, problems))
    return model


def run_check(check: MapCheck, model: Model, document: Mapping[str, Any]) -> Iterable[Problem]:
    """``check.validate(model)``; a plugin written against drivemap 0.2 or before, whose ``validate`` takes the
    YAML document (its first parameter named ``document``), gets the document and a deprecation warning
    (removal: drivemap 0.4)."""
    params = list(inspect.signature(check.validate).parameters)
    if params[:1] == ["document"]:
        warnings.warn(f"{type(check).__name__}.validate(document) reads the YAML dict: take the model instead "
                      "(validate(self, model, options=None)); the dict form goes in drivemap 0.4",
                      DeprecationWarning, stacklevel=2)
        return check.validate(document)  # type: ignore[arg-type]
    return check.validate(model)


def map_paths() -> list[Path]:
    """Every map of the working directory's project (sorted by name)."""
    return load_project().map_files()


def bundled_maps() -> list[Path]:
    """The seed maps that ship with drivemap (sorted by name; the catalogue: :func:`catalogue_maps`)."""
    return shipped_maps()


def looks_like_path(text: str) -> bool:
    return text.endswith((".yaml", ".yml")) or "/" in text or os.sep in text


def resolve_map(name: str, project: Project, notes: TextIO | None = None) -> Path:
    """The map of ``name``: a path to a map file, else the project's map of that model id, else
    the seed map of that id shipped with drivemap.

    Which file is used is said on ``notes`` (stderr by default) whenever it is not the project's: a
    note for a shipped map, and a warning naming both when the project's map and a shipped map of
    the same id differ (the project's wins), so a register name that is "not there" is never a mystery.
    """
    if looks_like_path(name):
        path = Path(name)
        if path.is_file():
            return path
        raise CompileError([Diagnostic(Location(display(path), 1, 1), "no such map file")])
    found = project.find_map(name) or next((p for p in project.excluded_files() if p.stem == name), None)
    shipped = next((p for p in bundled_maps() if p.stem == name), None)
    kind = "the map shipped with drivemap"
    if shipped is None:
        shipped, kind = next((p for p in catalogue_maps() if p.stem == name), None), "the catalogue map"
    if found is not None and shipped is not None and _differ(found, shipped):
        _say(project, notes, Diagnostic(Location(display(found), 1, 1),
                               f"the project's map of {name!r} overrides {kind} of the same id ({shipped}); "
                               "using the project's", severity="warning").format())
    if found is None and shipped is not None:
        where = ", ".join(display(m) for m in project.maps)
        _say(project, notes, f"drivemap: note: {name!r} is not a map of the project ({where}); using {kind}: {shipped}")
        found = shipped
    if found is None:
        known = sorted({p.stem for p in project.map_files()})
        hint = f" (the project has: {', '.join(known)})" if known else " (the project has no maps)"
        where = display(project.maps_folder() / f"{name}.yaml")
        raise CompileError([Diagnostic(Location(where, 1, 1), f"no map for model {name!r}{hint}; `drivemap list` "
                                                              "shows the shipped and catalogue maps")])
    return found


def _say(project: Project, notes: TextIO | None, text: str) -> None:
    """Print a note about which map is used, once per project (a verb may resolve a model twice)."""
    if notes is None and text in project.said:
        return
    project.said.add(text)
    print(text, file=notes if notes is not None else sys.stderr)


def _differ(a: Path, b: Path) -> bool:
    try:
        return a.resolve() != b.resolve() and a.read_bytes() != b.read_bytes()
    except OSError:
        return True


def load_model(name: str, project: Project | None = None) -> Model:
    """Compile the map of a model id or path (see :func:`resolve_map`)."""
    return compile_map(resolve_map(name, project or load_project()))
