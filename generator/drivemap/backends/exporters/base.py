"""The exporter plugin interface: every output drivemap writes goes through it.

An exporter turns the immutable :class:`~drivemap.model.nodes.Model` into files (relative path ->
text). drivemap's own outputs (the typed Python package, the Markdown docs, the JSON contract) are
exporters exactly like a third party's, which registers its class under the entry-point group
``drivemap.exporters`` in its own distribution::

    [project.entry-points."drivemap.exporters"]
    mytool = "mypackage.export:MyToolExporter"

and is then listed by ``drivemap export --list`` and run by ``drivemap export MODEL --format mytool``.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
from typing import ClassVar, Protocol, runtime_checkable

from drivemap.backends.common import OptionError, Options
from drivemap.backends.options import ExporterOptions, NoOptions, option
from drivemap.diagnostics import Problem
from drivemap.model.nodes import Model

__all__ = ["Exporter", "ExporterOptions", "MultiDevice", "OptionError", "Options", "Problem", "option"]


@runtime_checkable
class MultiDevice(Protocol):
    """An exporter that writes several devices sharing one line into one output (``drivemap export
    MODEL:UNIT MODEL:UNIT ...``; Home Assistant: one hub per serial port). An exporter class declares it
    with ``multi_device = True``; loading a plugin that declares it without ``render_line`` fails."""

    def render_line(self, devices: Sequence[tuple[Model, int | None]], options: Options) -> dict[str, str]: ...


class Exporter:
    """Base class of exporters. Subclasses set ``name`` and ``help`` and implement ``render``.

    ``suffix`` is the extension of a single-file output (``drivemap export -o`` names the file);
    ``multi_file`` exporters write a folder (``-o DIR``).

    ``options_class`` declares the exporter's own options: a frozen dataclass of
    :class:`~drivemap.backends.options.ExporterOptions` whose fields are made by
    :func:`~drivemap.backends.options.option`. drivemap reads it from ``drivemap export``'s command
    line and from a committed export's ``options`` table with the same names and checks, and the
    exporter reads it typed: ``self.options_class.from_values(options.values)``.
    """

    name: ClassVar[str] = ""
    help: ClassVar[str] = ""
    suffix: ClassVar[str] = ""
    multi_file: ClassVar[bool] = False
    #: writes several devices of one line into one output (:class:`MultiDevice`: implements ``render_line``)
    multi_device: ClassVar[bool] = False
    #: this exporter's options (see the class docstring)
    options_class: ClassVar[type[ExporterOptions]] = NoOptions

    def add_arguments(self, parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
        """Add this exporter's own options to ``drivemap export``'s parser: ``options_class``'s.

        A plugin may instead override this and read its options from ``Options.values`` by their
        ``dest`` names; a committed export's ``options`` table is then read through this parser."""
        self.options_class.add_arguments(parser)

    def validate(self, model: Model, options: Options | None = None) -> Iterable[Problem]:
        """Exporter-side checks of a map that passed the front end (schema and semantic checks), on its
        compiled model: the names and values this output could not hold (the python exporter: generated
        names; docs: heading anchors). Nothing is rendered here.

        Yields ``(path, message, options)``: ``path`` is the YAML path of the node concerned, taken from
        the node's ``src`` (:class:`~drivemap.model.source.SourceRef`; ``reg.src.yaml_path + ("name",)``),
        and ``options`` those of a located error (``key``, ``related``, ``note``, ``related_key``). The
        pipeline (:func:`drivemap.compiler.compile_map`) places each in the map's file. None by default.
        A plugin whose ``validate`` still takes the YAML document (first parameter ``document``) is given
        it, with a deprecation warning, until drivemap 0.4."""
        return ()

    def render(self, model: Model, options: Options) -> dict[str, str]:
        """Files of one model: relative path -> text (deterministic: same model, same bytes)."""
        raise NotImplementedError

    def render_collection(self, models: Sequence[Model], options: Options) -> dict[str, str]:
        """Files about all the models together (an index, a package ``__init__``); none by default."""
        return {}

    def render_all(self, models: Sequence[Model], options: Options) -> dict[str, str]:
        files: dict[str, str] = {}
        for model in models:
            files.update(self.render(model, options))
        files.update(self.render_collection(models, options))
        return files
