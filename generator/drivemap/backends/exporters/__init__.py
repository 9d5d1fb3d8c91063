"""Exporters: the built-in ones and every plugin registered under ``drivemap.exporters``."""

from __future__ import annotations

import importlib.metadata
import sys

from drivemap.backends.exporters.base import Exporter, OptionError, Options

__all__ = ["BUILTIN", "Exporter", "OptionError", "Options", "available", "get", "load"]

#: The built-in exporters (also registered as entry points of the drivemap distribution).
BUILTIN: dict[str, str] = {
    "python": "drivemap.backends.exporters.python:PythonExporter",
    "docs": "drivemap.backends.exporters.docs:DocsExporter",
    "json": "drivemap.backends.exporters.json:JsonExporter",
    "homeassistant": "drivemap.backends.exporters.homeassistant:HomeAssistantExporter",
    "esphome": "drivemap.backends.exporters.esphome:EsphomeExporter",
    "pymodbus-sim": "drivemap.backends.exporters.pymodbus_sim:PymodbusSimExporter",
    "csv": "drivemap.backends.exporters.csv:CsvExporter",
}


def _load(reference: str) -> type[Exporter]:
    module, _, attr = reference.partition(":")
    obj = getattr(importlib.import_module(module), attr)
    if not (isinstance(obj, type) and issubclass(obj, Exporter)):
        raise TypeError(f"{reference} is not a drivemap Exporter subclass")
    if obj.multi_device and not callable(getattr(obj, "render_line", None)):
        raise TypeError(f"{reference} declares multi_device but has no render_line(devices, options)")
    return obj


def available() -> dict[str, type[Exporter]]:
    """Every exporter by name: built-ins first, then installed plugins (sorted by name)."""
    found: dict[str, type[Exporter]] = {name: _load(ref) for name, ref in BUILTIN.items()}
    for entry in importlib.metadata.entry_points(group="drivemap.exporters"):
        if entry.name in found:
            if entry.value != BUILTIN.get(entry.name):
                print(f"drivemap: warning: exporter plugin {entry.name!r} ({entry.value}) is shadowed by the built-in",
                      file=sys.stderr)
            continue
        try:
            found[entry.name] = _load(entry.value)
        except Exception as exc:  # a broken plugin must not break drivemap
            print(f"drivemap: warning: exporter plugin {entry.name!r} ({entry.value}) cannot be loaded: {exc}",
                  file=sys.stderr)
    return dict(sorted(found.items()))


def load(name: str) -> type[Exporter] | None:
    """The exporter ``name`` (a built-in, else an installed plugin), importing no other exporter; None if unknown."""
    if name in BUILTIN:
        return _load(BUILTIN[name])
    entry = next((e for e in importlib.metadata.entry_points(group="drivemap.exporters") if e.name == name), None)
    return available().get(name) if entry is not None else None


def get(name: str) -> Exporter | None:
    cls = available().get(name)
    return cls() if cls is not None else None
