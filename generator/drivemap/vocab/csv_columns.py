"""The columns of drivemap's register spreadsheet (``drivemap export --format csv``), in order: the csv
exporter writes them and ``drivemap import csv`` recognises a file of drivemap's own by them.

The map-level columns (``evidence`` and the ``origin_*`` ones) repeat the map's ``device.evidence`` and
``device.origin`` on every row: a CSV has no header block, and a sheet filtered or sorted by a user still
says where each row comes from and how far it is proven. Sheets exported before these columns existed
(:data:`REGISTER_COLUMNS` only) are still drivemap's own.
"""

from __future__ import annotations

__all__ = ["COLUMNS", "MAP_COLUMNS", "ORIGIN_KEYS", "REGISTER_COLUMNS"]

REGISTER_COLUMNS = (
    "table", "address_hex", "address", "modicon", "name", "param", "group", "label", "type", "words", "word_order",
    "byte_order", "length", "encoding", "scale", "scale_register", "offset", "not_available", "unit", "access", "min",
    "max", "default", "reflect", "storage", "page", "enum", "enum_labels", "bits", "command", "description", "source",
    "values", "precision", "display_name", "review",
)

#: ``device.origin``'s keys, each written as the column ``origin_<key>``.
ORIGIN_KEYS = ("project", "path", "commit", "licence", "format")

MAP_COLUMNS = ("evidence", *(f"origin_{key}" for key in ORIGIN_KEYS))

COLUMNS = (*REGISTER_COLUMNS, *MAP_COLUMNS)
