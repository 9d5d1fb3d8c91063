"""The ``json`` exporter: the normalized model, a stable contract (see the README)."""

from __future__ import annotations

import json
import re

from drivemap.backends.export import export
from drivemap.backends.exporters.base import Exporter, Options
from drivemap.model.nodes import Model

__all__ = ["JsonExporter"]

_LONE_SURROGATE = re.compile("[\ud800-\udfff]")


class JsonExporter(Exporter):
    name = "json"
    help = "the normalized model as JSON (the stable export contract)"
    suffix = ".json"

    def render(self, model: Model, options: Options) -> dict[str, str]:
        text = json.dumps(export(model), indent=2, ensure_ascii=False) + "\n"
        # a lone surrogate (a map may hold one, as "\ud800") cannot be stored as UTF-8: JSON escapes it
        return {f"{model.name}.json": _LONE_SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", text)}
