"""How live values are shown: one row per register element, as a rich table, JSON or CSV."""

from __future__ import annotations

import csv
import dataclasses
import enum
import io
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from rich.console import Console
from rich.table import Table

from drivemap.device.target import Target
from drivemap.live.values import to_text
from drivemap.model.nodes import Register
from drivemap.runtime.client.values.display import display_text
from drivemap.runtime.errors import ScaleUnavailable

COLUMNS = ("name", "value", "unit", "meaning", "raw", "address", "param")


@dataclass(frozen=True)
class Row:
    """One register element as read."""

    name: str
    register: Register
    index: int
    raw: int | None
    value: Any
    #: why the value is None although the raw value was read (not available, no scale factor)
    why: str | None = None

    @property
    def address(self) -> int:
        return self.register.element_address(self.index)

    def value_text(self) -> str:
        """The value as people read it: the map's precision, else the shortest exact text
        (:func:`drivemap.runtime.client.values.display.display_text`)."""
        if self.raw is None:
            return ""
        if self.value is None:
            return "n/a"
        if isinstance(self.value, (int, float)) and not isinstance(self.value, (bool, enum.Enum)):
            return display_text(self.value, self.register.precision, single=_single(self.register))
        return to_text(self.value)

    def meaning(self, target: Target) -> str:
        if self.raw is None:
            return ""
        return self.why if self.why is not None else meaning(target, self.register, self.value)

    def raw_text(self) -> str:
        if self.raw is None:
            return ""
        if self.register.bit_table:
            return str(self.raw)
        digits = 4 * self.register.words
        text = f"0x{self.raw & ((1 << (4 * digits)) - 1):0{digits}X}"
        return text if digits <= 16 else text[:18] + "…"  # a long string: its first 8 bytes

    def address_text(self) -> str:
        """``0x0010`` (holding), ``input 0x0010`` for the other tables (each its own address space)."""
        table = self.register.table
        return f"0x{self.address:04X}" if table == "holding" else f"{table} 0x{self.address:04X}"

    def cells(self, target: Target) -> dict[str, str]:
        return {
            "name": self.name, "value": self.value_text(), "unit": self.register.unit or "",
            "meaning": self.meaning(target), "raw": self.raw_text(), "address": self.address_text(),
            "param": self.register.element_param(self.index) or "",
        }

    def json(self, target: Target) -> dict[str, Any]:
        return {
            "name": self.name,
            "value": json_value(self.value, _single(self.register)) if self.raw is not None else None,
            "unit": self.register.unit, "meaning": self.meaning(target) or None, "raw": self.raw,
            "address": self.address, "table": self.register.table,
            "param": self.register.element_param(self.index),
        }


def _single(reg: Register) -> bool:
    """Whether the register's value is an f32 as read (shown as the shortest text of that f32)."""
    return reg.type == "f32" and reg.scale == 1 and reg.offset == 0


def meaning(target: Target, reg: Register, value: Any) -> str:
    """The label of the value in the value set or enum, or the labels of the bits that are set."""
    if reg.values and value is not None:
        label = next((v.label for v in reg.value_set if v.value == value), None)
        return label if label is not None else ("" if any(v.value == value for v in reg.value_set)
                                                else "not a value of the map")
    if reg.enum is not None and isinstance(value, enum.Enum):
        labels = {v.value: v.label for v in target.model.enum(reg.enum).members}
        return labels.get(value.value, "not a value of the map")
    if isinstance(value, enum.IntFlag):
        return ", ".join(b.label for b in reg.bits if int(value) & b.mask)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return "; ".join(_field_label(target, reg, f.name, getattr(value, f.name)) for f in dataclasses.fields(value))
    return ""


def _field_label(target: Target, reg: Register, attribute: str, value: Any) -> str:
    bit = next((b for b in reg.bits if b.name.lower() == attribute), None)
    if bit is not None and bit.enum is not None and isinstance(value, enum.Enum):
        labels = {v.value: v.label for v in target.model.enum(bit.enum).members}
        return f"{attribute} {labels.get(value.value, value.name)}"
    return f"{attribute} {to_text(value)}"


def json_value(value: Any, single: bool = False) -> Any:
    """``value`` for JSON; an f32 as the shortest decimal that reads back as the same f32."""
    if single and isinstance(value, float) and not isinstance(value, bool):
        text = display_text(value, single=True)
        return float(text) if text not in ("nan", "inf", "-inf") else value
    if isinstance(value, enum.IntFlag):
        return [m.name for m in type(value) if m.name and m in value]
    if isinstance(value, enum.Enum):
        return value.name
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return value


def rows_of(target: Target, cells: Iterable[tuple[Register, int]], raws: dict[tuple[str, int], int]) -> list[Row]:
    """Rows for the cells read (``raws``: raw value per key; a missing key is an empty row)."""
    rows = []
    for reg, index in cells:
        raw = raws.get((reg.name, index))
        value, why = decode(target, reg, raw, raws) if raw is not None else (None, None)
        rows.append(Row(reg.element_name(index), reg, index, raw, value, why))
    return rows


def decode(target: Target, reg: Register, raw: int, raws: dict[tuple[str, int], int]) -> tuple[Any, str | None]:
    """(engineering value, why it is None): a scale-register value is scaled by the factor read with
    it (never by a stale one); a not-available raw value reads None."""
    codec = target.codecs[reg.name]
    if raw in reg.not_available:
        return None, "not available"
    try:
        if codec.scale_key is not None:
            return codec.decode_scaled(raw, raws.get(codec.scale_key)), None
        return codec.decode(raw), None
    except ScaleUnavailable as exc:
        return None, str(exc)


def table(target: Target, rows: Sequence[Row], title: str | None = None,
          styles: dict[str, str] | None = None) -> Table:
    """The rich table of ``rows`` (``styles``: a row style per element name)."""
    out = Table(title=title, title_justify="left", header_style="bold")
    for column in COLUMNS:
        out.add_column(column, justify="right" if column in ("value", "raw") else "left",
                       overflow="fold" if column == "meaning" else "ellipsis", no_wrap=column != "meaning")
    for row in rows:
        cells = row.cells(target)
        out.add_row(*(cells[c] for c in COLUMNS), style=(styles or {}).get(row.name))
    return out


def console(width: int | None = None) -> Console:
    """A console on stdout (no colours when stdout is not a terminal; then 200 columns unless
    ``COLUMNS`` says otherwise, so piped tables are not squeezed)."""
    import os
    import sys

    if width is None and not sys.stdout.isatty() and "COLUMNS" not in os.environ:
        width = 200
    return Console(width=width, highlight=False, soft_wrap=False)


def to_json(target: Target, rows: Sequence[Row], extra: dict[str, Any] | None = None) -> str:
    doc = {"model": target.model.name, **(extra or {}), "registers": [r.json(target) for r in rows]}
    return json.dumps(doc, ensure_ascii=False, indent=2)


def to_csv(target: Target, rows: Sequence[Row]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        cells = row.cells(target)
        writer.writerow([cells[c] for c in COLUMNS])
    return buffer.getvalue()
