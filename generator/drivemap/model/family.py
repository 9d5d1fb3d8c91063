"""Model nodes of a map's identity (which device it describes) and of its family (which map it extends)."""

from __future__ import annotations

from dataclasses import dataclass, field

from drivemap.model.source import SourceRef
from drivemap.runtime.spec import IdentitySpec
from drivemap.runtime.types import expected_text

#: The ways an identity check compares (``identity[].<kind>`` in a map).
IDENTITY_KINDS = ("equals", "one_of", "prefix", "pattern")


@dataclass(frozen=True)
class IdentityCheck(IdentitySpec):
    """A register and the value(s) that identify the device or family (``kind``: see IDENTITY_KINDS):
    the runtime's :class:`IdentitySpec` and the map's notes."""

    notes: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def expected(self) -> str:
        """The expected value(s) as docs and messages show them."""
        return expected_text(self.kind, self.values)


@dataclass(frozen=True)
class Variant:
    """What a map that extends another changes: the chain of maps it extends (nearest first) and
    one line per change (register added, overridden, removed, ...)."""

    extends: tuple[str, ...]
    changes: tuple[str, ...]


__all__ = ["IDENTITY_KINDS", "IdentityCheck", "Variant"]
