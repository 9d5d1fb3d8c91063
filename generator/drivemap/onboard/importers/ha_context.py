"""The context of one Home Assistant hub being imported, shared by :mod:`.homeassistant` and the modules
that read its entities (:mod:`.ha_entities`) and templates (:mod:`.ha_templates`)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.mapdoc import MapDoc, safe
from drivemap.onboard.importers.yamlsrc import Node, located

__all__ = ["LEGACY", "PARITY", "SIZED", "TABLES", "Ctx"]

SIZED = {"int16": "s16", "uint16": "u16", "int32": "s32", "uint32": "u32", "int64": "s64", "uint64": "u64",
         "float32": "f32", "float64": "f64"}
LEGACY = {("int", 1): "s16", ("int", 2): "s32", ("int", 4): "s64", ("uint", 1): "u16", ("uint", 2): "u32",
          ("uint", 4): "u64", ("float", 2): "f32", ("float", 4): "f64"}
TABLES = {"holding": "holding", "input": "input", "coil": "coil", "discrete_input": "discrete"}
PARITY = {"N": "none", "E": "even", "O": "odd"}
_ELEMENT = re.compile(r"^([a-z][a-z0-9_]*) (\d+)$")


@dataclass
class Ctx:
    """One hub being imported: its registers by name (arrays as {index: register}), the entity ids."""

    doc: MapDoc
    path: Path
    prefix: str
    regs: dict[str, dict[int, dict[str, Any]]] = field(default_factory=dict)
    entities: dict[str, tuple[str, int]] = field(default_factory=dict)
    units: set[int] = field(default_factory=set)
    intervals: dict[str, int] = field(default_factory=dict)
    seen: set[int] = field(default_factory=set)  #: the entity mappings read (an alias repeats one)

    def split(self, text: str) -> tuple[str, int, bool]:
        """(register name, element index, is it a '<name> raw' sensor) of an entity name."""
        rest = text[len(self.prefix) + 1:] if text.startswith(self.prefix + " ") else text
        raw = rest.endswith(" raw")
        rest = rest[:-4] if raw else rest
        match = _ELEMENT.match(rest)
        if match:
            return match.group(1), int(match.group(2)), raw
        return safe(rest), 0, raw

    def put(self, entry: Node, reg: dict[str, Any], entity: str | None = None) -> None:
        name, index, _ = self.split(str(entry.get("name", "")))
        if not name or name == "register":
            raise located(self.path, entry, "an entity without a name")
        elements = self.regs.get(name)
        if (elements is not None and index in elements) or (elements is None and self.doc.taken(name)):
            name = self.doc.name(name)  # a second entity of the same name: a register of its own
            elements = None
        if elements is None:
            elements = self.regs[name] = {}
        self.doc.claim(name)
        elements[index] = reg
        reg.setdefault("_file", (entry.file or self.path).name)
        reg.setdefault("_node", entry)
        text = str(entry.get("name", ""))
        slug = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")
        self.entities[f"{entity or 'sensor'}.{slug}"] = (name, index)
        plain = re.sub(r"[^a-z0-9]+", "_", text.removesuffix(" raw").lower()).strip("_")
        for i in range(1, reg.get("count", 1)):  # the elements of a virtual_count array
            self.entities[f"{entity or 'sensor'}.{plain}_{i}"] = (name, index)
        unit = entry.get("device_address", entry.get("slave"))
        if isinstance(unit, int):
            self.units.add(unit)
