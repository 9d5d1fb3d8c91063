"""The ``csv`` exporter: one row per register element, for PLC tools and spreadsheets.

Written by Python's ``csv`` module (quoting is its business, so map text never adds a row or a
column). ``table`` is holding/input/coil/discrete, ``modicon`` the six-digit reference with the table's
digit first (coil 0, discrete 1, input 3, holding 4), ``not_available`` the raw values meaning "no
value" (hex, as the register's words), ``scale_register`` the register whose value v scales by 10^v,
``values`` the value set (``value (label) | ...``: the only values a write may send), ``precision`` the
decimals shown, ``display_name`` the element as the manual numbers it (``first_index``; else the name);
``evidence`` and ``origin_*`` repeat the map's evidence level and origin on every row (empty where the map
does not state them), so a sheet says how far it is proven however it is sorted or filtered.
Text cells are flattened to one line, and a text cell that a spreadsheet would run as a
formula (it starts with ``=``, ``+``, ``-``, ``@``) gets a leading apostrophe.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from typing import Any

from drivemap.backends.exporters.base import Exporter, ExporterOptions, OptionError, Options, option
from drivemap.backends.views.common import review_text
from drivemap.backends.views.integrations import comment_safe
from drivemap.model.nodes import Cell, Model
from drivemap.vocab.csv_columns import COLUMNS, ORIGIN_KEYS

__all__ = ["COLUMNS", "MODICON", "CsvExporter"]


#: table -> (Modicon prefix, function code that reads it).
MODICON: dict[str, tuple[int, int]] = {"coil": (0, 0x01), "discrete": (1, 0x02), "input": (3, 0x04),
                                       "holding": (4, 0x03)}

_DELIMITERS = {"comma": ",", "semicolon": ";", "tab": "\t"}


def _text(value: str | None) -> str:
    if value is None:
        return ""
    text = comment_safe(value)
    return "'" + text if text[:1] in ("=", "+", "-", "@") else text


def _value(value: float | str | bool | None) -> str:
    """A default: a number, text (strings) or true/false (coils)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return _text(value)
    return _num(value)


def _num(value: float | None) -> str:
    if value is None:
        return ""
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def modicon(table: str, address: int) -> str:
    """Six-digit Modicon reference (holding 0x0000 -> 400001), one-based as PLC tools count."""
    return f"{MODICON[table][0]}{address + 1:05d}"


def _map_cells(model: Model) -> dict[str, str]:
    """The map-level columns: ``device.evidence`` and ``device.origin``, the same on every row."""
    dev = model.device
    cells = {"evidence": dev.evidence or ""}
    for key in ORIGIN_KEYS:
        cells[f"origin_{key}"] = _text(getattr(dev.origin, key, None) or "") if dev.origin else ""
    return cells


def _row(model: Model, cell: Cell) -> dict[str, str]:
    reg = cell.register
    enum = model.enum(reg.enum) if reg.enum else None
    bits = " | ".join(
        (f"bit {b.offset}" if b.width == 1 else f"bits {b.offset}-{b.offset + b.width - 1}") + f" {b.name}: {b.label}"
        for b in reg.bits
    )
    return {
        "table": reg.table,
        "address_hex": f"0x{cell.address:04X}",
        "address": str(cell.address),
        "modicon": modicon(reg.table, cell.address),
        "name": cell.name,
        "param": reg.element_param(cell.index) or "",
        "group": reg.group,
        "label": _text(reg.label),
        "type": reg.type,
        "words": str(reg.words),
        "word_order": reg.word_order or "",
        "byte_order": "" if reg.bit_table else reg.byte_order,
        "length": str(reg.length) if reg.type == "string" else "",
        "encoding": reg.encoding if reg.type == "string" else "",
        "scale": _num(reg.scale),
        "scale_register": reg.scale_register or "",
        "offset": _num(reg.offset),
        "not_available": " | ".join(f"0x{v & ((1 << (16 * reg.words)) - 1):0{4 * reg.words}X}"
                                    for v in reg.not_available),
        "unit": _text(reg.unit),
        "access": reg.access,
        "min": _num(reg.min),
        "max": _num(reg.max),
        "default": _value(reg.default_at(cell.index)),
        "reflect": reg.reflect,
        "storage": reg.storage,
        "page": f"{reg.page.selector}={reg.page.value}" if reg.page else "",
        "enum": reg.enum or "",
        "enum_labels": _text(" | ".join(f"{v.value}={v.label}" for v in enum.members)) if enum else "",
        "bits": _text(bits),
        "command": "" if reg.command_value is None else str(reg.command_value),
        "description": _text(reg.description),
        "source": _text(reg.source),
        "values": _text(" | ".join(v.text() for v in reg.value_set)),
        "precision": "" if reg.precision is None else str(reg.precision),
        "display_name": _text(reg.display_name(cell.index) if reg.first_index else cell.name),
        "review": _text(review_text(reg)) if reg.review else "",
    }


@dataclass(frozen=True)
class CsvOptions(ExporterOptions):
    delimiter: str = option("comma", choices=sorted(_DELIMITERS), help="field separator")
    bom: bool = option(False, help="start with a UTF-8 byte order mark (for Excel)")


class CsvExporter(Exporter):
    name = "csv"
    help = "CSV register list for PLC tools and spreadsheets (one row per register element)"
    suffix = ".csv"

    options_class = CsvOptions

    def render(self, model: Model, options: Options) -> dict[str, str]:
        own = CsvOptions.from_values(options.values)
        delimiter = own.delimiter or "comma"
        if delimiter not in _DELIMITERS:
            raise OptionError(f"--delimiter: one of {', '.join(sorted(_DELIMITERS))}")
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=COLUMNS, delimiter=_DELIMITERS[delimiter], lineterminator="\n",
                                quoting=csv.QUOTE_MINIMAL)
        writer.writeheader()
        order = {"coil": 0, "discrete": 1, "input": 3, "holding": 4}
        cells: list[Any] = sorted(model.cells(), key=lambda c: (order[c.register.table], c.address,
                                                                c.register.page.value if c.register.page else -1, c.name))
        shared = _map_cells(model)
        for cell in cells:
            writer.writerow(_row(model, cell) | shared)
        return {f"{model.name}.csv": ("\ufeff" if own.bom else "") + out.getvalue()}
