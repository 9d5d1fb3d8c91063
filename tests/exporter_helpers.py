"""Shared pieces of the exporter tests: per-map options, a hostile map, loaders for the outputs."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import yaml

from drivemap.backends.exporters import available
from drivemap.backends.exporters.base import Options
from drivemap.compiler import compile_map
from drivemap.model.nodes import Model

ROOT = Path(__file__).resolve().parent.parent
MAPS = sorted(p.stem for p in (ROOT / "maps").glob("*.yaml"))
INTEGRATIONS = ("homeassistant", "esphome", "pymodbus-sim", "csv")

#: what the maps leave open on their serial line (no guessing: every export names it)
SERIAL: dict[str, dict[str, Any]] = {
    "ev": {"baudrate": 9600, "method": "rtu"},
    "vfd1000": {"baudrate": 9600, "parity": "none", "stopbits": 1},
    "v2": {"baudrate": 9600, "parity": "none", "stopbits": 1},
    "edx": {"baudrate": 9600, "parity": "none", "stopbits": 1, "method": "rtu"},
    "fronius_symo_hybrid": {"baudrate": 9600, "parity": "none", "stopbits": 1},
    "wattnode_wnc": {"baudrate": 9600},
    "delta_vfd_el_w": {"baudrate": 9600, "parity": "none", "stopbits": 1, "method": "rtu"},
    "delta_vfd_f": {"baudrate": 9600, "parity": "none", "stopbits": 1, "method": "rtu"},
}
#: the synthetic map that uses every construct of the map language (coils, discretes, f64, strings,
#: low-first bytes, scale registers...): exported as well as the maps of maps/
ALLKINDS = ROOT / "tests" / "maps" / "allkinds.yaml"


def load(name: str) -> Model:
    """A map of maps/ by name, or the synthetic ``allkinds``."""
    from drivemap.compiler import load_model

    return compile_map(ALLKINDS) if name == "allkinds" else load_model(name)

HOSTILE = (
    "it's \"quoted\" {{ states('sensor.x') }} {% raw %}x{% endraw %} !!python/object/apply:os.system ['id'] "
    "# not a comment\nsecond: line\r\n- item ${unit} $name <% x %> \\u0041 ' ] } =1+1 \u2028 tail"
)


class _Loader(yaml.SafeLoader):
    """Reads ESPHome's !secret / !literal as plain text (what the tool sees after its own loader)."""


_Loader.add_constructor("!secret", lambda loader, node: f"<secret {loader.construct_scalar(node)}>")
_Loader.add_constructor("!literal", lambda loader, node: loader.construct_mapping(node)
                        if isinstance(node, yaml.MappingNode) else loader.construct_scalar(node))


def load_yaml(text: str) -> Any:
    return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass


def options(model: str, fmt: str, **extra: Any) -> dict[str, Any]:
    """The option values of one export (as ``drivemap export`` would parse them)."""
    exporter = available()[fmt]()
    import argparse

    parser = argparse.ArgumentParser(add_help=False)
    exporter.add_arguments(parser)
    values = vars(parser.parse_args([]))
    if fmt in ("homeassistant", "esphome"):
        values.update(SERIAL.get(model, {}))
        if fmt == "esphome":
            values.pop("method", None)
    values.update(extra)
    return values


def render(model: Model, fmt: str, **extra: Any) -> str:
    exporter = available()[fmt]()
    files = exporter.render(model, Options(root=ROOT, values=options(model.name, fmt, **extra)))
    assert len(files) == 1
    return next(iter(files.values()))


def parse(fmt: str, text: str) -> Any:
    if fmt == "pymodbus-sim":
        return json.loads(text)
    if fmt == "csv":
        import csv
        import io

        return list(csv.DictReader(io.StringIO(text)))
    return load_yaml(text)


def hostile_map(tmp: Path, model: str = "ev") -> Path:
    """The map with hostile text in every free-text field an export can carry."""
    data = yaml.safe_load((ROOT / "maps" / f"{model}.yaml").read_text(encoding="utf-8"))
    data["device"]["title"] = HOSTILE
    for enum in data.get("enums", {}).values():
        for i, value in enumerate(enum["values"]):
            value["label"] = f"{HOSTILE} #{i}"
    for reg in data["registers"]:
        reg["description"] = HOSTILE
        reg["source"] = HOSTILE
        if reg.get("label"):
            reg["label"] = HOSTILE
        for bit in reg.get("bits", ()):
            bit["label"] = HOSTILE
    path = tmp / f"{model}.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")
    return path


def compile_hostile(tmp: Path, model: str = "ev") -> Model:
    return compile_map(hostile_map(tmp, model))


def shape(value: Any) -> Any:
    """The structure of a document with its strings blanked (map text may change strings only;
    keys that are not identifiers, such as ESPHome's option labels, count as strings)."""
    if isinstance(value, dict):
        return [(k if re.fullmatch(r"[a-z_][a-z0-9_ ]*", str(k)) else "<key>", shape(v)) for k, v in value.items()]
    if isinstance(value, list):
        return [shape(v) for v in value]
    return "<str>" if isinstance(value, str) else value
