"""What every exporter and every view shares, below both: the options an exporter is run with
(:class:`Options`: the project's settings and its own options) and the error of an unusable option."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.model.nodes import Model

__all__ = ["OptionError", "Options"]


class OptionError(ValueError):
    """An exporter option that cannot be used (``drivemap export`` reports it as a usage error,
    ``drivemap build`` at the ``[[tool.drivemap.exports]]`` entry that gave it)."""


@dataclass(frozen=True)
class Options:
    """What an exporter knows besides the model: the project's settings and its own options.

    ``package`` is the generated package's import name, ``root`` the project root, ``out`` and
    ``docs`` the folders of the generated package and docs; ``values`` holds the exporter's own
    command-line options (``add_arguments``) by their ``dest`` names.
    """

    package: str = "generated"
    root: Path = field(default_factory=Path.cwd)
    out: Path = field(default_factory=lambda: Path.cwd() / "generated")
    docs: Path = field(default_factory=lambda: Path.cwd() / "generated" / "docs")
    values: Mapping[str, Any] = field(default_factory=dict)

    def source(self, model: Model) -> str:
        """The map's path relative to the project root (posix), or its file name outside it.

        Generated headers use this, so output does not depend on the working directory.
        """
        full = Path(model.path).resolve()
        try:
            return full.relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return full.name

    def get(self, key: str, default: Any = None) -> Any:
        value = self.values.get(key, default)
        return default if value is None else value
