"""The columns of drivemap's register spreadsheet (``drivemap export --format csv``), in order: the csv
exporter writes them and ``drivemap import csv`` recognises a file of drivemap's own by them."""

from __future__ import annotations

__all__ = ["COLUMNS"]

COLUMNS = (
    "table", "address_hex", "address", "modicon", "name", "param", "group", "label", "type", "words", "word_order",
    "byte_order", "length", "encoding", "scale", "scale_register", "offset", "not_available", "unit", "access", "min", "max", "default", "reflect", "storage", "page", "enum", "enum_labels",
    "bits", "command", "description", "source", "values", "precision", "display_name", "review",
)
