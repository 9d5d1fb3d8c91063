"""The reserved names are derived from what the templates produce, and cover what they produce.

:func:`drivemap.vocab.reserved.reserved` renders a probe map and reads the output back. These tests read
the generated packages of the seed maps (other maps than the probe, other features) and check that
every name they bind, every builtin their classes annotate with and every attribute their clients
have is in the derived sets, so a map name equal to any of them is refused by ``validate``
(the golden maps in ``tests/bad_maps`` show the messages).
"""

from __future__ import annotations

import ast
import builtins
import importlib
from pathlib import Path

import pytest

from drivemap.backends.python.names import exception_classes
from drivemap.compiler import compile_map, map_paths
from drivemap.runtime.client.transport.bus import Bus
from drivemap.vocab.reserved import reserved

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ROOT / "generated" / "drivemap_models"
MODELS = {p.stem: compile_map(p) for p in map_paths()}


def _module_names(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names


@pytest.mark.parametrize("model", sorted(MODELS))
def test_every_name_a_generated_module_binds_is_reserved(model: str) -> None:
    m = MODELS[model]
    own = {e.name for e in m.enums} | {r.bits_class for r in m.registers if r.bits_class}
    own |= set(exception_classes([(e.name, e.code) for e in m.protocol.exceptions]))
    bound = _module_names(GENERATED / model / "client.py") | _module_names(GENERATED / model / "__init__.py")
    fixed = {n for n in bound if n not in own and not n.startswith("_codec_")}
    assert fixed <= reserved().module, sorted(fixed - reserved().module)
    assert not own & reserved().module  # and the seed maps' own names are all free


@pytest.mark.parametrize("model", sorted(MODELS))
def test_every_builtin_the_generated_classes_annotate_with_is_reserved(model: str) -> None:
    tree = ast.parse((GENERATED / model / "client.py").read_text(encoding="utf-8"))
    used = set()
    for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
        for node in ast.walk(cls):
            if isinstance(node, ast.AnnAssign):
                used |= {n.id for n in ast.walk(node.annotation) if isinstance(n, ast.Name) and hasattr(builtins, n.id)}
    assert used <= reserved().annotation, sorted(used - reserved().annotation)
    assert {"int", "float", "tuple", "bool"} <= reserved().annotation


@pytest.mark.parametrize("model", sorted(MODELS))
def test_every_attribute_of_a_generated_client_is_reserved(model: str) -> None:
    package = importlib.import_module(f"drivemap_models.{model}")
    bus = Bus.tcp("127.0.0.1", 1)
    try:
        client = package.Client(bus, unit=package.SPEC.protocol.unit_min or 1)
        client.plan()  # fills the per-class caches (attributes set on first use)
        client._drivemap.snapshot({})
        attributes = {n for n in dir(client) if not n.startswith("__")}
    finally:
        bus.close()
    attributes -= {r.name for r in MODELS[model].registers}
    assert attributes <= reserved().client, sorted(attributes - reserved().client)


def test_fixed_outputs_and_headings_come_from_the_exporters_and_template() -> None:
    outputs = {name: (per_model, once) for name, per_model, once in reserved().outputs}
    assert outputs["docs"] == (frozenset({"{model}.md"}), frozenset({"index.md"}))
    assert "__init__.py" in outputs["python"][1] and "{model}/client.py" in outputs["python"][0]
    assert {"registers", "enums", "bit-fields", "examples", "contents"} <= reserved().headings


def test_reserved_data_is_what_the_templates_produce() -> None:
    """The python back end's reserved names are data; they must equal what rendering a probe map gives.

    When a template or runtime change binds a new name, this fails until
    ``python tests/reserved_probe.py > generator/drivemap/vocab/reserved.py`` is run.
    """
    import dataclasses

    from tests import reserved_probe

    probe = reserved_probe.reserved()
    assert dataclasses.astuple(probe) == dataclasses.astuple(reserved()), reserved_probe.module_text(probe)
