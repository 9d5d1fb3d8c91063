"""``drivemap import pymodbus-sim``: a pymodbus simulator configuration (``pymodbus.simulator --json_file``).

What the file states becomes the map: the tables (the ``co``/``di``/``ir``/``hr`` blocks laid out one
after the other, or one shared block: holding registers), each cell's address and the type pymodbus
declares for it (``uint16`` -> u16, ``uint32`` -> u32, ``float32`` -> f32, ``float64`` -> f64 in the
order pymodbus serves them: high word first; ``string`` -> string; ``bits`` -> 16 coils or discrete
inputs per cell, a u16 in a register block), the value it serves at power-up as the default, write
access from ``write``, the served unit, serial line and broadcast. pymodbus's cells carry no names: a
register is named after its table and address (``holding_256``). Nothing else is guessed: signedness
(pymodbus keeps signed values as their two's complement), scale, unit, word order of words served as
plain ``uint16`` cells (a wider value written as one range is listed), enums and ranges stay out and
are listed for review.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.jsonsrc import field, load_json, objects
from drivemap.onboard.importers.mapdoc import MapDoc
from drivemap.onboard.importers.yamlsrc import Node, located

__all__ = ["import_pymodbus_sim"]

_BLOCKS = (("co size", "coil"), ("di size", "discrete"), ("ir size", "input"), ("hr size", "holding"))
#: pymodbus cell type -> (drivemap type, words per value)
_CELLS = {"uint16": ("u16", 1), "uint32": ("u32", 2), "float32": ("f32", 2), "float64": ("f64", 4)}
_TITLES = {"coil": "Coils", "discrete": "Discrete inputs", "input": "Input registers", "holding": "Holding registers"}
_PARITY = {"N": "none", "E": "even", "O": "odd"}
_NOT_STATED = ("a pymodbus simulator configuration states no register names, signedness, scale, unit, enums, "
               "ranges or protocol facts: the registers are named by table and address; review each one")


def import_pymodbus_sim(doc: MapDoc, path: Path) -> str | None:
    """Fill ``doc`` from the configuration ``path``; the model id it names (drivemap's note), else None."""
    data = load_json(path)
    devices = field(path, data, "device_list", "object", "the configuration")
    if len(devices) != 1:
        raise located(path, devices, f"device_list has {len(devices)} devices ({', '.join(devices) or 'none'}): "
                                     "import a configuration of one device")
    name, device = next(iter(devices.items()))
    note = field(path, data, "drivemap", "object", "the configuration", default=Node())
    doc.title = field(path, note, "title", "str", "drivemap", default=f"pymodbus simulator device {name}")
    _server(path, doc, data, name)
    tables = _tables(path, field(path, device, "setup", "object", f"device {name}"))
    if len(tables) == 1:
        doc.review.notes.append("shared blocks: the simulator serves each word in every table; imported as holding "
                                "registers (which tables the device really has is not stated)")
    writable, ranges = _writable(path, device)
    cells: list[tuple[str, int, dict[str, Any]]] = []
    for kind in ("bits", "uint16", "uint32", "float32", "float64", "string"):
        for item in objects(path, device, kind, f"device {name}"):
            cells += _cell(path, kind, item, tables, _default(path, device, kind))
    cells.sort(key=lambda c: (c[0], c[1]))
    if any(table in ("coil", "discrete") for table, _, _ in cells):
        doc.review.notes.append("each bits cell holds 16 coils or discrete inputs, all imported: which of them the "
                                "device has is not stated (a writable cell makes all 16 writable)")
    taken: dict[tuple[str, int], int] = {}
    spans = {(c[2]["_cells"][0], c[2]["_cells"][-1]) for c in cells}
    for table, address, reg in cells:
        _place(path, doc, table, address, reg, writable, taken)
    for first, last in sorted(ranges - spans):
        doc.review.notes.append(f"cells {first}..{last} are written as one value: its type and word order are not "
                                "stated (imported as the cells' own types)")
    for key in ("invalid", "repeat"):
        if field(path, device, key, "list", f"device {name}", default=[]):
            doc.review.skipped.append(f"{key}: pymodbus's {key} entries are not map facts (not imported)")
    doc.review.notes.append(_NOT_STATED)
    model = field(path, note, "model", "str", "drivemap", default=None, nullable=True)
    return str(model) if model else None


def _server(path: Path, doc: MapDoc, data: Any, name: str) -> None:
    """The served unit, broadcast and serial line of the device's server (the one of its name, or the only one)."""
    servers = field(path, data, "server_list", "object", "the configuration", default={})
    server = servers.get(name) if name in servers else next(iter(servers.values())) if len(servers) == 1 else None
    if server is None:
        doc.review.notes.append("no server of this device: its unit id and line are not stated")
        return
    unit = field(path, server, "device_id", "int", "server", default=None, nullable=True)
    if unit is not None and unit != 1:
        doc.review.notes.append(f"export again with --unit {unit} (the served device id)")
    if field(path, server, "broadcast_enable", "bool", "server", default=False):
        doc.broadcast_address = 0
    comm = field(path, server, "comm", "str", "server", default="tcp")
    if comm == "serial":
        framer = field(path, server, "framer", "str", "server", default="rtu")
        baud = field(path, server, "baudrate", "int", "server", default=None, nullable=True)
        bits, stop = (v if type(v) is int else None for v in (server.get("bytesize"), server.get("stopbits")))
        parity = _PARITY.get(str(server.get("parity")))
        doc.port = {"name": "serial", "modes": [framer if framer in ("rtu", "ascii") else "rtu"], "default_mode": None,
                    "baudrates": [baud] if baud else [], "default_baudrate": baud,
                    "parity": [parity] if parity else [], "default_parity": parity,
                    "data_bits": [bits] if bits in (7, 8) else [], "stop_bits": [stop] if stop in (1, 2) else [],
                    "default_stop_bits": stop if stop in (1, 2) else None, "set_by": "unknown", "source": doc.source,
                    "notes": "The line the simulator serves (what one configuration uses)."}
        doc.review.notes.append(f"export again with --serial {server.get('port')} (the served serial port)")
    elif comm == "tcp":
        host, port = server.get("host", "127.0.0.1"), server.get("port", 5020)
        if (host, port) != ("127.0.0.1", 5020):
            doc.review.notes.append(f"export again with --tcp {host}:{port} (the served address is not a map fact)")


def _tables(path: Path, setup: Any) -> list[tuple[int, int, str]]:
    """The blocks as (first cell, end cell, table); one holding block when they are shared."""
    sizes = [(field(path, setup, key, "int", "setup", default=0), table) for key, table in _BLOCKS]
    shared = field(path, setup, "shared blocks", "bool", "setup", default=True)
    for size, table in sizes:
        if not 0 <= size <= (0x1000 if table in ("coil", "discrete") and not shared else 0x10000):
            raise located(path, setup, f"setup: the {table} block size {size} is not one of a Modbus table "
                                       "(0..65536 words, 0..4096 cells of 16 bits)")
    if shared:
        return [(0, max(size for size, _ in sizes), "holding")]
    out, base = [], 0
    for size, table in sizes:
        out.append((base, base + size, table))
        base += size
    return out


def _locate(path: Path, item: Any, cell: int, tables: list[tuple[int, int, str]]) -> tuple[str, int]:
    for start, end, table in tables:
        if start <= cell < end:
            return table, cell - start
    raise located(path, item, f"cell {cell} lies outside the blocks the setup sizes")


def _writable(path: Path, device: Any) -> tuple[set[int], set[tuple[int, int]]]:
    """The cells ``write`` lists, and its ranges wider than one cell."""
    cells: set[int] = set()
    ranges: set[tuple[int, int]] = set()
    for item in field(path, device, "write", "list", "device", default=[]):
        first, last = _span(path, device, item)
        cells.update(range(first, last + 1))
        if last > first:
            ranges.add((first, last))
    return cells, ranges


def _span(path: Path, where: Any, addr: Any) -> tuple[int, int]:
    if isinstance(addr, int) and not isinstance(addr, bool) and addr >= 0:
        return addr, addr
    if isinstance(addr, list) and len(addr) == 2 and all(isinstance(a, int) and not isinstance(a, bool) for a in addr) \
            and 0 <= addr[0] <= addr[1]:
        return addr[0], addr[1]
    raise located(path, where, f"addr {addr!r}: a cell number or [first, last]")


def _default(path: Path, device: Any, kind: str) -> Any:
    """The value pymodbus gives a cell of ``kind`` without one (setup.defaults.value), None if unstated."""
    defaults = field(path, device["setup"], "defaults", "object", "setup", default={})
    return field(path, defaults, "value", "object", "setup.defaults", default={}).get(kind)


def _cell(path: Path, kind: str, item: Node, tables: list[tuple[int, int, str]],
          fallback: Any) -> list[tuple[str, int, dict[str, Any]]]:
    """The registers of one section entry: (table, address, register) with its cells."""
    first, last = _span(path, item, item.get("addr"))
    value = item.get("value", fallback)
    table, address = _locate(path, item, first, tables)
    if _locate(path, item, last, tables)[0] != table:
        raise located(path, item, f"addr {first}..{last} crosses from the {table} block into the next")
    if kind == "string":
        if not isinstance(value, str):
            raise located(path, item, "a string cell's value is text")
        return [(table, address, {"type": "string", "length": last - first + 1, "default": value.rstrip(" \x00"),
                                  "_cells": range(first, last + 1)})]
    if kind == "bits" and table in ("coil", "discrete"):
        word = _integer(path, item, value, 0xFFFF)
        return [(table, address * 16 + b, {"type": "bool", "default": bool(word >> b & 1), "_cells": range(first, first + 1)})
                for b in range(16)] if first == last else _too_wide(path, item)
    rtype, words = _CELLS.get(kind, ("u16", 1))
    if (last - first + 1) % words:
        raise located(path, item, f"addr {first}..{last}: a {kind} value takes {words} cells")
    out = []
    for at in range(first, last + 1, words):
        reg: dict[str, Any] = {"type": rtype, "_cells": range(at, at + words)}
        if words > 1:
            reg["word_order"] = "high_first"
        reg["default"] = _value(path, item, rtype, value)
        out.append((table, address + at - first, reg))
    return out


def _too_wide(path: Path, item: Node) -> list[tuple[str, int, dict[str, Any]]]:
    raise located(path, item, "a bits entry of a coil or discrete block gives one cell")


def _integer(path: Path, item: Node, value: Any, top: int) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= top:
        raise located(path, item, f"value {value!r}: an integer 0..{top} was expected")
    return value


def _value(path: Path, item: Node, rtype: str, value: Any) -> Any:
    if rtype == "u16":
        return _integer(path, item, value, 0xFFFF)
    if rtype == "u32":
        return _integer(path, item, value, 0xFFFFFFFF)
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise located(path, item, f"value {value!r}: a number was expected")
    if rtype == "f32":  # what pymodbus stores: the nearest float32
        return struct.unpack(">f", struct.pack(">f", value))[0]
    return float(value)


def _place(path: Path, doc: MapDoc, table: str, address: int, reg: dict[str, Any], writable: set[int],
           taken: dict[tuple[str, int], int]) -> None:
    cells = reg.pop("_cells")
    words = 1 if table in ("coil", "discrete") else len(cells)
    for a in range(address, address + words):
        if (table, a) in taken:
            raise located(path, Node(), f"{table} address {a} is given twice")
        taken[(table, a)] = 1
    written = [c in writable for c in cells]
    access = "rw" if all(written) and table in ("coil", "holding") else "r"
    if any(written) and access == "r":
        doc.review.notes.append(f"{table}_{address}: listed in write, but only part of it or in a read-only table")
    name = doc.name(f"{table}_{address}")
    doc.add({"name": name, "table": table, "address": address, **reg, "access": access,
             "group": doc.group(table, _TITLES[table]),
             "source": doc.source})
