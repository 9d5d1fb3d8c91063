"""The context of one ESPHome device being imported, shared by :mod:`.esphome` and :mod:`.es_entities`."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.mapdoc import MapDoc, safe

__all__ = ["PARITY", "PLATFORMS", "TABLES", "VALUE_TYPES", "Ctx"]

PLATFORMS = ("sensor", "binary_sensor", "number", "select", "switch", "text_sensor")
TABLES = {"holding": "holding", "read": "input", "coil": "coil", "discrete_input": "discrete"}
VALUE_TYPES = {"U_WORD": ("u16", None), "S_WORD": ("s16", None), "U_DWORD": ("u32", "high_first"),
               "U_DWORD_R": ("u32", "low_first"), "S_DWORD": ("s32", "high_first"), "S_DWORD_R": ("s32", "low_first"),
               "FP32": ("f32", "high_first"), "FP32_R": ("f32", "low_first"), "U_QWORD": ("u64", "high_first"),
               "U_QWORD_R": ("u64", "low_first"), "S_QWORD": ("s64", "high_first"), "S_QWORD_R": ("s64", "low_first")}
PARITY = {"NONE": "none", "EVEN": "even", "ODD": "odd"}
RAW_NOTE = re.compile(r"text_sensor with the wire bytes as hex \(ESPHome has no value_type for them\): (.*)")
RAW_ITEM = re.compile(r"^(\S+) \((\w+), word order ([\w-]+), byte order (\w+)\)$")


@dataclass
class Ctx:
    doc: MapDoc
    path: Path
    prefix: str
    base: int
    regs: dict[str, dict[str, Any]] = field(default_factory=dict)
    raw_types: dict[str, tuple[str, str | None, str]] = field(default_factory=dict)
    factors: dict[str, str] = field(default_factory=dict)
    intervals: dict[str, int] = field(default_factory=dict)
    #: modbus_controller id -> (its device address, its update_interval in s): ESPHome 2026.9+ polls slower
    #: entities through more controllers of one device (drivemap's export names them device_<n>x)
    controllers: dict[str, tuple[object, int]] = field(default_factory=dict)
    #: entities read across a hole before them (``reuse_previous_range: true``, 2026.9+): (register_type, address, node)
    joins: list[tuple[str, int, Any]] = field(default_factory=list)
    #: (register_type, address) -> the controller that polls it: each controller's reads are its own
    batch_owner: dict[tuple[str, int], str] = field(default_factory=dict)
    #: polled entities as (table, address) -> (words, starts a new read): drivemap's batching
    batches: dict[tuple[str, int], tuple[int, bool]] = field(default_factory=dict)
    #: entities with a bitmask by (table, address): one register of bit fields (:mod:`.es_bits`)
    masked: dict[tuple[str, int], list[tuple[str, Any]]] = field(default_factory=dict)

    def key(self, name: str) -> tuple[str, str | None]:
        """(register name, suffix after it: a bit, an enum value or 'label') of an entity name."""
        rest = name[len(self.prefix) + 1:] if name.startswith(self.prefix + " ") else name
        head, sep, tail = rest.partition(" ")
        if sep and re.fullmatch(r"[a-z][a-z0-9_]*", head) and (tail == "label" or re.fullmatch(r"[A-Z][A-Z0-9_]*", tail)):
            return head, tail
        return safe(rest), None
