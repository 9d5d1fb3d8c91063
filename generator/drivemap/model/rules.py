"""Model nodes of a register's value set and of the protocol's alignment rules.

Kept apart from :mod:`drivemap.model.nodes` (which re-exports them) so each module stays short.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from drivemap.model.modicon import Table
from drivemap.model.source import SourceRef
from drivemap.runtime.spec import AlignmentSpec


@dataclass(frozen=True)
class AllowedValue:
    """One value of a register's value set (``values:``): an engineering value and its label."""

    value: float | str
    label: str | None
    notes: str | None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def text(self) -> str:
        """``5`` or ``5 (5 min)``: the value (as the map writes it) and its label."""
        value = self.value
        shown = str(int(value)) if isinstance(value, float) and value.is_integer() else str(value)
        return shown + (f" ({self.label})" if self.label else "")


@dataclass(frozen=True, kw_only=True)
class Alignment(AlignmentSpec):
    """A rule on the requests to ``table`` words ``start``..``end`` (``protocol.alignment``): the
    runtime's :class:`AlignmentSpec` (``exception``: the rule's code, else the illegal_address
    policy's, else 02h) and the map's notes."""

    table: Table
    notes: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def text(self) -> str:
        """The rule in words, for docs and messages."""
        block = f"{self.table} 0x{self.start:04X}..0x{self.end:04X}"
        if (self.start, self.end) == (0, 0xFFFF):
            block = f"every {self.table} register"
        parts = []
        if self.start_multiple > 1:
            parts.append(f"start address a multiple of {self.start_multiple}")
        if self.quantity_multiple > 1:
            parts.append(f"quantity a multiple of {self.quantity_multiple}")
        if self.min_quantity > 1:
            parts.append(f"at least {self.min_quantity} registers")
        if self.whole_values:
            parts.append("multi-word values whole")
        what = " and ".join(self.operations)
        return (f"{what} requests to {block}: " + (", ".join(parts) or "no constraint")
                + f"; otherwise exception {self.exception:02X}h")


__all__ = ["Alignment", "AllowedValue"]
