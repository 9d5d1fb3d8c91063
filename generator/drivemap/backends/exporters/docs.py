"""The ``docs`` exporter: one Markdown page per model and an index."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from drivemap.backends.exporters.base import Exporter, Options, Problem
from drivemap.model.nodes import Model
from drivemap.vocab import namecheck

__all__ = ["DocsExporter"]


class DocsExporter(Exporter):
    name = "docs"
    help = "Markdown: <model>.md (registers, frames, errata) and index.md (what `drivemap build` writes to docs)"
    suffix = ".md"
    multi_file = True

    def validate(self, model: Model, options: Options | None = None) -> Iterable[Problem]:
        """Headings whose anchors collide on the model's page, and a model id the index file takes."""
        return namecheck.docs_problems(model)

    def render(self, model: Model, options: Options) -> dict[str, str]:
        from drivemap.backends.render import render_template  # Jinja only when rendering
        from drivemap.backends.views import docs

        name = f"{model.name}.md"
        return {name: render_template(name, "model.md.jinja", docs.context(model, options))}

    def render_collection(self, models: Sequence[Model], options: Options) -> dict[str, str]:
        from drivemap.backends.render import render_template
        from drivemap.backends.views import docs

        return {"index.md": render_template("index.md", "index.md.jinja", docs.index_context(models, options))}
