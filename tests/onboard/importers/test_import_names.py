"""`drivemap import` (csv, homeassistant, esphome): one name policy with `draft` (a name the compiler
refuses, such as `self`, is renamed as draft renames it), duplicate keys refused where they stand, the
Home Assistant import linear in the number of entities. (No import circle among the importers: pyproject's
acyclic_siblings contract, which lint-imports checks for every folder of the package.)"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from drivemap.cli import main
from drivemap.compiler import compile_map
from drivemap.onboard import naming
from drivemap.onboard.draft import naming as draft_naming
from drivemap.onboard.importers.homeassistant import import_homeassistant
from drivemap.onboard.importers.mapdoc import MapDoc

HA_NAMES = """\
modbus:
  - name: hub
    type: tcp
    host: 192.0.2.1
    port: 502
    sensors:
      - name: self
        address: 1
      - name: class
        address: 2
      - name: read
        address: 3
      - name: float
        address: 4
"""

ES_NAMES = """\
esphome:
  name: box
uart:
  baud_rate: 9600
modbus_controller:
  - address: 1
sensor:
  - platform: modbus_controller
    name: self
    register_type: holding
    address: 1
  - platform: modbus_controller
    name: class
    register_type: holding
    address: 2
"""


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_draft_and_import_share_one_name_policy() -> None:
    assert draft_naming.snake is naming.snake and draft_naming.upper is naming.upper
    assert naming.refused("self") == "a client attribute" and naming.refused("class") == "a Python keyword"
    assert naming.refused("float") is not None and naming.refused("flow") is None
    assert [naming.register_name(n) for n in ("self", "class", "float", "flow")] == [
        "self_reg", "class_value", "float_reg", "flow"]


@pytest.mark.parametrize(("fmt", "text", "expected"), [
    ("homeassistant", HA_NAMES, {"self_reg", "class_value", "read_reg", "float_reg"}),
    ("esphome", ES_NAMES, {"self_reg", "class_value"}),
    ("csv", "name,address,type\nself,1,u16\nclass,2,u16\nread,3,u16\n", {"self_reg", "class_value", "read_reg"}),
])
def test_refused_names_are_renamed_and_the_map_builds(fmt: str, text: str, expected: set[str], tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / ("source.csv" if fmt == "csv" else "source.yaml")
    source.write_text(text, encoding="utf-8")
    target = tmp_path / "dev.yaml"
    extra = ["--table", "holding"] if fmt == "csv" else []
    code, _, err = run(capsys, "import", fmt, str(source), "-o", str(target), *extra)
    assert code == 0, err
    model = compile_map(target)  # with the python and docs exporters' name checks, as build runs them
    assert {r.name for r in model.registers} == expected


def test_duplicate_keys_are_refused_where_they_stand(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "dup.yaml"
    source.write_text("modbus:\n  - name: hub\n    type: tcp\n    sensors:\n      - name: a\n        address: 1\n"
                      "        address: 2\n", encoding="utf-8")
    code, out, err = run(capsys, "import", "homeassistant", str(source), "-o", str(tmp_path / "hub.yaml"))
    assert code == 1 and not (tmp_path / "hub.yaml").exists()
    assert "dup.yaml:7:9: error: the key 'address' is given twice in this mapping (first on line 6)" in err


def test_an_entity_repeated_by_an_alias_is_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "alias.yaml"
    source.write_text("modbus:\n  - name: hub\n    type: tcp\n    sensors:\n      - &a\n        name: x\n"
                      "        address: 1\n" + "      - *a\n" * 50_000, encoding="utf-8")
    start = time.perf_counter()
    code, _, err = run(capsys, "import", "homeassistant", str(source), "-o", str(tmp_path / "hub.yaml"))
    assert code == 1 and "alias.yaml:5:9: error: sensors: the entity 'x' is listed again by a YAML alias" in err
    assert err.count("error:") == 1
    assert time.perf_counter() - start < 60  # was: no output after 400 s (100,000 aliases)


def _hub(n: int, path: Path) -> Path:
    lines = ["modbus:", "  - name: big", "    type: tcp", "    sensors:"]
    for i in range(n):  # every 4th name repeats: renamed name_2, name_3 ... (a counter, not a search)
        lines += [f"      - name: s{i if i % 4 else 0}", f"        address: {i}", "        scale: 0.1"]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _seconds(n: int, tmp_path: Path) -> float:
    path = _hub(n, tmp_path / f"hub{n}.yaml")
    best = float("inf")
    for _ in range(2):
        doc = MapDoc("big", "big", "test", "hub.yaml")
        start = time.perf_counter()
        import_homeassistant(doc, [path])
        doc.text()
        best = min(best, time.perf_counter() - start)
        assert len(doc.registers) == n
    return best


def test_home_assistant_import_is_linear_in_the_entities(tmp_path: Path) -> None:
    """8 times the entities cost about 8 times the time (was 64: quadratic); a generous factor 3."""
    small, large = _seconds(1000, tmp_path), _seconds(8000, tmp_path)
    assert large / small < 8 * 3, (small, large)
