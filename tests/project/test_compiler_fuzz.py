"""Property-based fuzzing of the compiler: a mutated map builds or reports located errors.

Nothing else may escape: no traceback, no exception other than CompileError, every
diagnostic of the form ``path:line:col: error: ...``.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivemap.build import render_tree
from drivemap.compiler import compile_map
from drivemap.diagnostics import CompileError

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted((ROOT / "maps").glob("*.yaml"))
LOCATED = re.compile(r"^\S+:\d+:\d+: error: .+")

junk = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=20),
    st.lists(st.integers(min_value=-5, max_value=70000), max_size=3),
    st.dictionaries(st.text(max_size=5), st.integers(), max_size=2),
)


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            out.extend(_paths(value, prefix + (key,)))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out.extend(_paths(value, prefix + (i,)))
    return out


def _mutate(data: Any, path: tuple[Any, ...], action: int, value: Any) -> Any:
    if not path:
        return value if action == 0 else data
    parent = data
    for part in path[:-1]:
        parent = parent[part]
    last = path[-1]
    if action == 0:
        parent[last] = value
    elif action == 1 and isinstance(parent, dict):
        del parent[last]
    elif action == 1 and isinstance(parent, list):
        parent.pop(last)
    elif action == 2 and isinstance(parent, list):
        parent.append(copy.deepcopy(parent[last]))
    elif action == 3 and isinstance(parent, dict):
        parent["unexpected_" + str(last)] = value
    return data


_originals = {p: yaml.safe_load(p.read_text(encoding="utf-8")) for p in MAPS}
_paths_of = {p: _paths(d) for p, d in _originals.items()}


@pytest.mark.parametrize("map_path", MAPS, ids=[p.stem for p in MAPS])
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_mutated_map_builds_or_reports_located_errors(map_path: Path, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject) -> None:
    doc = copy.deepcopy(_originals[map_path])
    for _ in range(data.draw(st.integers(min_value=1, max_value=3))):
        paths = _paths(doc)
        path = data.draw(st.sampled_from(paths))
        doc = _mutate(doc, path, data.draw(st.integers(min_value=0, max_value=3)), data.draw(junk))
    out = tmp_path_factory.mktemp("fuzz") / map_path.name
    out.write_text(yaml.safe_dump(doc, allow_unicode=True, sort_keys=False), encoding="utf-8")
    try:
        model = compile_map(out)
    except CompileError as exc:
        assert exc.diagnostics
        for diag in exc.diagnostics:
            assert LOCATED.match(diag.format()), diag.format()
    else:
        # it built: it must render too
        assert render_tree([model])


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=300))
def test_arbitrary_text_never_crashes(tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    out = tmp_path_factory.mktemp("fuzz") / "x.yaml"
    out.write_text(text, encoding="utf-8", errors="surrogatepass")
    with pytest.raises(CompileError) as info:
        compile_map(out)
    for diag in info.value.diagnostics:
        assert LOCATED.match(diag.format()), diag.format()
