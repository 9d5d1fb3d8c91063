"""The one diagnostic format: ``path:line:col: error: message``."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

#: One problem found at a place of a map document: (path of keys and indexes, message, options of a located
#: error: ``key``, ``related``, ``note``, ``related_key``), as an exporter's ``validate`` gives it.
Problem = tuple[tuple[str | int, ...], str, dict[str, Any]]


@dataclass(frozen=True)
class Location:
    """A place in a source file (1-based line and column)."""

    path: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.col}"


@dataclass(frozen=True)
class Diagnostic:
    """One message about a source file, with an optional second location."""

    location: Location
    message: str
    severity: str = "error"
    related: tuple[tuple[Location, str], ...] = field(default=())

    def format(self) -> str:
        text = f"{self.location}: {self.severity}: {self.message}"
        for loc, note in self.related:
            text += f"\n{loc}: note: {note}"
        return text

    def sort_key(self) -> tuple[str, int, int, str]:
        loc = self.location
        return (loc.path, loc.line, loc.col, self.message)


class CompileError(Exception):
    """Raised with every error found in one run; the CLI prints them and exits 1."""

    def __init__(self, diagnostics: Iterable[Diagnostic]) -> None:
        self.diagnostics = sorted(diagnostics, key=Diagnostic.sort_key)
        super().__init__("\n".join(d.format() for d in self.diagnostics))
