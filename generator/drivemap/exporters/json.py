"""The ``json`` exporter: the normalized model, a stable contract (see the README)."""

from __future__ import annotations

import json

from ..export import export
from ..model import Model
from .base import Exporter, Options

__all__ = ["JsonExporter"]


class JsonExporter(Exporter):
    name = "json"
    help = "the normalized model as JSON (the stable export contract)"
    suffix = ".json"

    def render(self, model: Model, options: Options) -> dict[str, str]:
        return {f"{model.name}.json": json.dumps(export(model), indent=2, ensure_ascii=False) + "\n"}
