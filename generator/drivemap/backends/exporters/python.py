"""The ``python`` exporter: the typed client package (spec, client, simulator) of each model."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from drivemap.backends.exporters.base import Exporter, Options, Problem
from drivemap.model.nodes import Model
from drivemap.vocab import namecheck

__all__ = ["PythonExporter"]


class PythonExporter(Exporter):
    name = "python"
    help = "typed Python package: <model>/spec.py, client.py, simulator.py (what `drivemap build` writes to out)"
    multi_file = True

    def validate(self, model: Model, options: Options | None = None) -> Iterable[Problem]:
        """The map's names against each other and against what the generated package defines."""
        return namecheck.python_problems(model)

    def render(self, model: Model, options: Options) -> dict[str, str]:
        from drivemap.backends.render import render_template  # Jinja only when rendering
        from drivemap.backends.views import client, simulator, spec

        m = model.name
        return {
            f"{m}/__init__.py": render_template(f"{m}/__init__.py", "package_init.py.jinja", client.context(model, options)),
            f"{m}/client.py": render_template(f"{m}/client.py", "client.py.jinja", client.context(model, options)),
            f"{m}/spec.py": render_template(f"{m}/spec.py", "spec.py.jinja", spec.context(model, options)),
            f"{m}/simulator.py": render_template(f"{m}/simulator.py", "simulator.py.jinja",
                                                 simulator.context(model, options)),
        }

    def render_collection(self, models: Sequence[Model], options: Options) -> dict[str, str]:
        from drivemap.backends.render import render_template
        from drivemap.backends.views import common

        context = common.root_context(models, options)
        return {
            "__init__.py": render_template("__init__.py", "generated_init.py.jinja", context),
            "py.typed": render_template("py.typed", "py.typed.jinja", context),
        }

