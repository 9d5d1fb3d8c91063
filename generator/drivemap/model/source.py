"""Where a model node stands in its map."""

from __future__ import annotations

from dataclasses import dataclass

from drivemap.diagnostics import Location

#: A path into the map's YAML: keys and list indexes from the top (``("registers", 3, "scale")``).
YamlPath = tuple[str | int, ...]


@dataclass(frozen=True)
class SourceRef:
    """The file, 1-based line and column, and YAML path of the item a model node was built from (the
    base map's file for what a variant inherits). Exporters locate their diagnostics with it."""

    path: str
    line: int
    column: int
    yaml_path: YamlPath

    def location(self) -> Location:
        return Location(self.path, self.line, self.column)

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.column}"


__all__ = ["SourceRef", "YamlPath"]
