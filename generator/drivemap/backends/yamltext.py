"""YAML for the integration exporters, written by PyYAML (never by string templates).

Every value, map text included, goes through PyYAML's safe emitter, which quotes whatever would
otherwise read as something else (``!!python/...``, ``#``, ``{{ }}``, ``yes``, line breaks), so
map text can never change the structure of the document. The only text outside the emitter is the
comment header, whose lines pass :func:`~drivemap.vocab.escape.comment_safe`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import yaml

from drivemap.vocab.escape import comment_safe

__all__ = ["Hex", "Literal", "LiteralMap", "Secret", "dump", "header"]


class Hex(int):
    """An int written as ``0x0000`` (register addresses, masks)."""

    width = 4


class Literal(str):
    """ESPHome text taken as is: ``!literal`` keeps its substitution pass (``$name``, ``${...}``) away."""


class LiteralMap(dict):  # type: ignore[type-arg]
    """A mapping ESPHome takes as is, keys included (``!literal`` on the whole mapping)."""


class Secret(str):
    """``!secret NAME`` (ESPHome and Home Assistant read it from secrets.yaml)."""


class _Dumper(yaml.SafeDumper):
    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        # lists indented under their key, as Home Assistant's and ESPHome's documentation write them
        super().increase_indent(flow, False)


def _hex(dumper: yaml.SafeDumper, value: Hex) -> yaml.ScalarNode:
    return dumper.represent_scalar("tag:yaml.org,2002:int", f"0x{int(value):0{value.width}X}")


def _tagged(tag: str) -> Any:
    def represent(dumper: yaml.SafeDumper, value: str) -> yaml.ScalarNode:
        return dumper.represent_scalar(tag, str(value), style="'" if tag == "!literal" else None)

    return represent


_Dumper.add_representer(Hex, _hex)
_Dumper.add_representer(Literal, _tagged("!literal"))
_Dumper.add_representer(Secret, _tagged("!secret"))
_Dumper.add_representer(LiteralMap, lambda dumper, value: dumper.represent_mapping("!literal", dict(value)))


def dump(data: Any) -> str:
    """``data`` as block YAML: keys in the given order, UTF-8 text kept, no line folding."""
    text: str = yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, default_flow_style=False,
                          width=1 << 16, indent=2)
    return text


def header(lines: Iterable[str]) -> str:
    """Comment lines (map text in them is flattened to one line each)."""
    return "".join(f"# {comment_safe(line)}".rstrip() + "\n" for line in lines)
