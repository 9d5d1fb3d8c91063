"""Synthetic maps of N registers for the compiler-scaling benchmark.

The map is the ``drivemap new`` scaffold (every construct of the format, one verified example)
plus synthetic registers at 0x1000 upwards, cycling through the kinds real maps use: scaled
u16 parameters with range, default, EEPROM storage and a parameter id; signed scaled monitors;
32-bit counters; enum registers; bit-field registers; and every 25th register a 4-element array.
Every 50 registers there is a 4-word gap, declared as a reserved range (readable true, false and
null in turn), so the planner and the checks see realistic structure. When the holding table's
65,536 addresses are used up (about 45,000 registers), the map goes on in the input table with
read-only kinds, so no address overflows.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from common import ROOT  # noqa: F401  (puts the repository on sys.path)

SCAFFOLD_REGISTERS = 7  # registers of the scaffold itself


def synthetic_map(model: str, registers: int) -> dict[str, Any]:
    from drivemap.backends.render import scaffold

    doc: dict[str, Any] = yaml.safe_load(scaffold(model))
    doc["device"]["coverage"] = f"Synthetic benchmark map with {registers} registers."
    regs: list[dict[str, Any]] = doc["registers"][:registers] if registers < SCAFFOLD_REGISTERS else doc["registers"]
    reserved: list[dict[str, Any]] = doc.setdefault("reserved", [])
    address = 0x1000
    table = "holding"
    groups = [g["name"] for g in doc["groups"]]
    readable_cycle: list[bool | None] = [True, False, None]
    for i in range(registers - len(regs)):
        if address + 8 > 0x10000:  # the holding table is full: go on in the input table (its own 65,536 words)
            if table == "input":
                raise ValueError(f"{registers} synthetic registers do not fit two tables of 65,536 words")
            table, address = "input", 0x100  # above the scaffold's input registers
        if i and i % 50 == 0:
            gap: dict[str, Any] = {"start": address, "end": address + 3, "readable": readable_cycle[(i // 50) % 3],
                                   "writable": False, "source": "manual §9"}
            if table == "input":
                gap["table"] = "input"
            reserved.append(gap)
            address += 4
        kind = i % 5 if table == "holding" else 1 + i % 2  # input registers: read-only kinds only
        reg: dict[str, Any] = {"name": f"reg_{i:05d}", "address": address, "group": groups[i % len(groups)],
                               "source": f"manual §{6 + i % 3}"}
        if table == "input":
            reg["table"] = "input"
        words = 1
        if kind == 0:
            reg.update(access="rw", param=f"P.{i:05d}", scale=0.1, unit="Hz", min=0, max=400.0, default=50.0,
                       storage="eeprom", write_delay_ms=20, reflect="configuration")
        elif kind == 1:
            reg.update(access="r", type="s16", scale=0.01, unit="A")
        elif kind == 2:
            reg.update(access="r", type="u32", word_order="high_first", unit="h")
            words = 2
        elif kind == 3:
            reg.update(access="rw", enum="RunState", storage="ram", reflect="immediate")
        else:
            reg.update(access="rw", storage="ram", reflect="immediate", bits=[
                {"name": "RUN", "offset": 0, "label": "1: run"},
                {"name": "DIRECTION", "offset": 1, "label": "1: reverse"},
                {"name": "MODE", "offset": 4, "width": 2, "label": "mode", "enum": "RunState"},
            ])
        if i % 25 == 24 and kind != 2:
            reg.update(count=4, stride=1)
            words = 4
            reg.pop("default", None)
        regs.append(reg)
        address += words
    doc["registers"] = regs
    return doc


def write_synthetic(folder: Path, registers: int) -> Path:
    model = f"syn{registers}"
    path = folder / f"{model}.yaml"
    text = yaml.safe_dump(synthetic_map(model, registers), sort_keys=False, allow_unicode=True, width=120)
    path.write_text("# yaml-language-server: $schema=../schemas/drivemap.schema.json\n" + text, encoding="utf-8")
    return path
