"""The loader: libyaml (when PyYAML has it) and the pure-Python path give the same data and positions."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from drivemap.frontend import load

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted((ROOT / "maps").glob("*.yaml")) + [ROOT / "generator" / "drivemap" / "backends" / "templates" / "new_map.yaml.jinja"]


@pytest.mark.skipif(not getattr(yaml, "__with_libyaml__", False), reason="PyYAML built without libyaml: one path only")
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_fast_and_python_paths_agree(path: Path) -> None:
    text = path.read_text(encoding="utf-8").replace("{{ model }}", "scaffold")
    fast_node = load._compose_fast(text)
    assert fast_node is not None
    fast = load._Builder(str(path))
    fast_data = fast.build(fast_node, ())
    slow = load._Builder(str(path))
    slow_data = slow.build(load._compose_python(text, str(path)), ())  # type: ignore[arg-type]
    assert fast_data == slow_data
    assert fast.positions.values == slow.positions.values
    assert fast.positions.keys == slow.positions.keys


@pytest.mark.parametrize("text", ["a: &x 1\nb: *x\n", "a: [1, *y]\n", "- &a [1]\n"])
def test_fast_path_never_expands_aliases(text: str) -> None:
    assert load._compose_fast(text) is None
    with pytest.raises(load.CompileError):
        load.load_text(text, "t.yaml")
