"""The sources of ``drivemap import sunspec``: model JSON files (one model or a list) and model numbers.

Each argument is ``FILE.json`` or a SunSpec model number (from pysunspec2's models: needs
``drivemap[sunspec]``), optionally ``:L`` with the model's length (required for models with a
repeating group). The models are laid out in the order given, from ``--base``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from drivemap.device.target import locate_error
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.importers.mapdoc import MapDoc
from drivemap.onboard.importers.sunspec import SunSpecError, add_models, load_model_def

__all__ = ["import_sunspec"]


def import_sunspec(doc: MapDoc, tokens: list[str], base: int) -> None:
    if not 0 <= base <= 0xFFFD:
        raise locate_error(str(base), f"--base {base}: the address of 'SunS' is 0..65533")
    defs: list[tuple[dict[str, Any], int | None, str]] = []
    for token in tokens:
        source, length = _split(token)
        if source.isdigit():
            try:
                model = load_model_def(int(source))
            except SunSpecError as exc:
                raise locate_error(token, f"model {source}: needs drivemap[sunspec] ({exc})") from None
            if model is None:
                raise locate_error(token, f"SunSpec model {source} is not among the installed definitions")
            defs.append((model, length, f"model_{source}.json"))
        else:
            defs.extend((m, length, Path(source).name) for m in _file(Path(source)))
    doc.max_quantity[3] = None
    if any(p.get("access") == "RW" for m, _, _ in defs for p in m["group"].get("points", [])):
        doc.max_quantity[16] = None  # SunSpec writes with 10h
    try:
        add_models(doc, defs, base)
    except SunSpecError as exc:
        raise locate_error(tokens[0], str(exc)) from None


def _split(token: str) -> tuple[str, int | None]:
    head, sep, tail = token.rpartition(":")
    if sep and tail.isdigit():
        return head, int(tail)
    return token, None


def _file(path: Path) -> list[dict[str, Any]]:
    shown = display(path)
    try:
        data: Any = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise CompileError([Diagnostic(Location(shown, 1, 1), f"cannot read: {exc.strerror or exc}")]) from None
    except json.JSONDecodeError as exc:
        raise CompileError([Diagnostic(Location(shown, exc.lineno, exc.colno), f"not JSON: {exc.msg}")]) from None
    except UnicodeDecodeError:
        raise CompileError([Diagnostic(Location(shown, 1, 1), "not UTF-8 text")]) from None
    models = data if isinstance(data, list) else [data]
    for i, model in enumerate(models):
        if not isinstance(model, dict) or not isinstance(model.get("id"), int) or not isinstance(model.get("group"), dict):
            where = f"item {i + 1}: " if isinstance(data, list) else ""
            raise CompileError([Diagnostic(Location(shown, 1, 1), f"{where}not a SunSpec model definition "
                                           "(a JSON object with 'id' and 'group', as pysunspec2's models/json)")])
    return models
