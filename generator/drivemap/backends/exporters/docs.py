"""The ``docs`` exporter: one Markdown page per model and an index."""

from __future__ import annotations

from collections.abc import Sequence

from drivemap.backends.exporters.base import Exporter, Options
from drivemap.backends.render import render_template
from drivemap.backends.views import docs
from drivemap.model.nodes import Model

__all__ = ["DocsExporter"]


class DocsExporter(Exporter):
    name = "docs"
    help = "Markdown: <model>.md (registers, frames, errata) and index.md (what `drivemap build` writes to docs)"
    suffix = ".md"
    multi_file = True

    def render(self, model: Model, options: Options) -> dict[str, str]:
        name = f"{model.name}.md"
        return {name: render_template(name, "model.md.jinja", docs.context(model, options))}

    def render_collection(self, models: Sequence[Model], options: Options) -> dict[str, str]:
        return {"index.md": render_template("index.md", "index.md.jinja", docs.index_context(models, options))}
