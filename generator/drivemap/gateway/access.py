"""What the gateway lets a command reach: the per-device ``writable`` list and the link settings rule.

A device accepts commands only for the registers its ``writable`` list names (default: none). An
entry is a register name, or the name of a group of the map: a group stands for its writable
registers **except link settings**, which are writable only when named one by one.

A *link setting* is a register that changes how the device is reached or who may change it: its
Modbus address (node, slave, station, unit id), its serial line (baud rate, parity, stop bits),
its protocol, its password, the register layout it presents (SunSpec model type). The rule reads
the map, never a hand list of registers: a writable register is a link setting when a word of its
name or of its group's name is one of :data:`LINK_WORDS`, or its label, description or notes
contain one of :data:`LINK_PHRASES` (case-insensitive; a note naming the map's own
``protocol.alignment`` key is not about the link). ``tests/gateway/test_gateway_discovery.py`` holds the
rule to every shipped map.
"""

from __future__ import annotations

import re

from drivemap.model.nodes import Model, Register

#: Words of a register's or its group's snake_case name that make it a link setting.
LINK_WORDS = frozenset({
    "baud", "baudrate", "parity", "stopbits", "node", "slave", "station", "password", "passwd", "pin",
    "comm", "rs485", "rs232", "protocol", "modbus", "address", "addr", "model",
})
#: Phrases of a register's label, description or notes that make it a link setting.
LINK_PHRASES = ("baud rate", "baudrate", "parity", "stop bit", "password", "slave address", "slave id",
                "station number", "station address", "node id", "node address", "unit id", "modbus address",
                "device address", "communication address", "protocol")


def _words(name: str | None) -> set[str]:
    return set(re.split(r"[_\W]+", (name or "").lower()))


def link_setting(model: Model, reg: Register) -> bool:
    """Whether ``reg`` is a link setting (see the module's rule)."""
    if _words(reg.name) & LINK_WORDS or _words(reg.group) & LINK_WORDS:
        return True
    text = " ".join(t for t in (reg.label, reg.description, reg.notes) if t).lower()
    text = text.replace("protocol.alignment", "")  # the map's key named in a note says nothing of the link
    return any(p in text for p in LINK_PHRASES)


def group_writables(model: Model, group: str) -> list[str]:
    """The writable registers of ``group`` that a group entry in ``writable`` opens (no link settings)."""
    return [r.name for r in model.group_registers(group) if r.writable and not link_setting(model, r)]
