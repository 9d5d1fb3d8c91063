"""An exporter's own checks run on the compiled, located model (``Exporter.validate(model, options)``),
after the front end has passed; their YAML paths come from the model nodes' ``src`` and are placed in the
map's file. A plugin written against the old form (``validate(document)``) still works, with a warning."""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pytest

from drivemap.backends.exporters.base import Exporter, Options, Problem
from drivemap.compiler import compile_map
from drivemap.diagnostics import CompileError
from drivemap.model.nodes import Model

ROOT = Path(__file__).resolve().parents[3]


class _ModelCheck(Exporter):
    name = "modelcheck"
    seen: list[Model] = []

    def validate(self, model: Model, options: Options | None = None) -> Iterable[Problem]:
        self.seen.append(model)
        reg = model.registers[3]
        assert reg.src is not None
        yield (*reg.src.yaml_path, "name"), f"the check saw {reg.name} on line {reg.src.line}", {}


class _OldCheck(Exporter):
    name = "oldcheck"

    def validate(self, document: Mapping[str, Any]) -> Iterable[Problem]:  # type: ignore[override]
        assert isinstance(document, Mapping) and "registers" in document
        yield ("registers", 0, "name"), "old-style check", {}


def test_exporter_checks_walk_the_located_model() -> None:
    with pytest.raises(CompileError) as caught:
        compile_map(ROOT / "maps" / "sdm630.yaml", [_ModelCheck()])
    (diag,) = caught.value.diagnostics
    model = _ModelCheck.seen[-1]
    reg = model.registers[3]
    assert isinstance(model, Model) and reg.src is not None
    assert diag.location.path.endswith("maps/sdm630.yaml") and diag.location.line == reg.src.line
    assert diag.message == f"the check saw {reg.name} on line {reg.src.line}"
    # the name's own place: the line of `- name: ...` in the map
    lines = (ROOT / "maps" / "sdm630.yaml").read_text(encoding="utf-8").splitlines()
    assert f"name: {reg.name}" in lines[diag.location.line - 1]


def test_an_old_style_plugin_gets_the_document_and_a_warning() -> None:
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with pytest.raises(CompileError) as caught:
            compile_map(ROOT / "maps" / "sdm630.yaml", [_OldCheck()])
    assert [d.message for d in caught.value.diagnostics] == ["old-style check"]
    assert any(issubclass(w.category, DeprecationWarning) and "drivemap 0.4" in str(w.message) for w in said)
