"""Every model node carries where the map states it (file, line, column, YAML path)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import pytest

from drivemap.compiler import compile_map
from drivemap.model.source import SourceRef
from tests.frontend.test_family import family, run  # noqa: F401 - the fixture

ROOT = Path(__file__).resolve().parents[2]


def _nodes(value: object) -> Iterator[object]:
    """Every dataclass node reachable from ``value`` that declares a ``src`` field."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if any(f.name == "src" for f in dataclasses.fields(value)):
            yield value
        for f in dataclasses.fields(value):
            if f.name != "src":
                yield from _nodes(getattr(value, f.name))
    elif isinstance(value, tuple):
        for item in value:
            yield from _nodes(item)


@pytest.mark.parametrize("name", ["ev", "sdm630", "fronius_symo_hybrid", "edx"])
def test_every_node_is_located(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    model = compile_map(f"maps/{name}.yaml", [])
    nodes = list(_nodes(model))
    assert len(nodes) > len(model.registers)
    missing = [type(n).__name__ for n in nodes if getattr(n, "src", None) is None]
    assert missing == []
    lines = (ROOT / "maps" / f"{name}.yaml").read_text(encoding="utf-8").splitlines()
    for i, reg in enumerate(model.registers):
        src = reg.src
        assert isinstance(src, SourceRef)
        assert (src.path, src.yaml_path) == (f"maps/{name}.yaml", ("registers", i))
        assert lines[src.line - 1][src.column - 1:].lstrip("{").startswith("name:"), (reg.name, src)
        assert src.line == reg.line
        for j, bit in enumerate(reg.bits):
            assert bit.src is not None and bit.src.yaml_path == ("registers", i, "bits", j)
            assert bit.src.line > src.line
    for enum in model.enums:
        assert enum.src is not None and enum.src.yaml_path == ("enums", enum.name)


def test_a_variant_locates_what_it_inherits_in_its_base(family: Path) -> None:  # noqa: F811
    xl = compile_map("maps/acme_xl.yaml", [])
    where = {r.name: r.src.path for r in xl.registers if r.src is not None}
    assert len(where) == len(xl.registers)
    assert where["motor_temperature"] == where["frequency_command"] == "maps/acme_xl.yaml"  # added, overridden
    assert where["run_state"] == where["output_current"] == "maps/acme.yaml"  # inherited
    assert xl.src is not None and xl.src.path == "maps/acme_xl.yaml"


def test_a_source_ref_is_not_part_of_equality(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two compiles of one map are equal whatever their positions (a cached model compares equal)."""
    monkeypatch.chdir(ROOT)
    a = compile_map("maps/ev.yaml", [])
    b = dataclasses.replace(a.registers[0], src=SourceRef("elsewhere.yaml", 1, 1, ()))
    assert b == a.registers[0]


def test_where_a_node_stands_is_no_part_of_the_json_contract(monkeypatch: pytest.MonkeyPatch) -> None:
    from drivemap.backends.export import export

    monkeypatch.chdir(ROOT)

    def keys(value: object) -> set[str]:
        if isinstance(value, dict):
            return set(value) | {k for v in value.values() for k in keys(v)}
        if isinstance(value, list):
            return {k for v in value for k in keys(v)}
        return set()

    for name in ("ev", "vfd1000", "fronius_symo_hybrid"):
        found = keys(export(compile_map(f"maps/{name}.yaml", [])))
        assert not found & {"src", "cache_key", "yaml_path"}, name
