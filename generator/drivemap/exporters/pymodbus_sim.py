"""The ``pymodbus-sim`` exporter: the device image as a configuration of pymodbus's own simulator.

``pymodbus.simulator --json_file ev.pymodbus-sim.json --modbus_server ev --modbus_device ev``
serves the map's registers with their default values (0 where the map gives none, the shown page
on a page selector), the readable reserved words as 0, and refuses every other address with
exception 02h, as a device would. pymodbus's simulator knows one address space: paged registers are
served for one page (``--page``), and writing a page selector does not switch pages there.

The simulator's ``int16`` section stores float bytes (pymodbus 3.16), so signed values are written
as their two's complement in ``uint16``/``uint32`` cells; a value whose word order the simulator
cannot hold goes in as its words (``SECTIONS``).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..model import Model, Register
from ..views import integrations as iv
from ..views.common import header as generated_header
from .base import Exporter, Options

__all__ = ["BLOCKS", "SECTIONS", "PymodbusSimExporter"]

#: (drivemap type, word order) -> the simulator section that holds the raw value as is, or None
#: (written as uint16 words in wire order). Issue 14 adds f32/f64 (float32/float64, high-first,
#: big-endian bytes only), u64/s64 (words), string ("string" when space-padded, else words), bool.
SECTIONS: dict[tuple[str, str | None], str | None] = {
    ("u16", None): "uint16",
    ("s16", None): "uint16",
    ("u32", "high_first"): "uint32",
    ("s32", "high_first"): "uint32",
    ("u32", "low_first"): None,
    ("s32", "low_first"): None,
}
#: The simulator's blocks in the order it lays them out ("shared blocks": false); issue 14 maps
#: its coil/discrete/input tables to "co size"/"di size"/"ir size".
BLOCKS = ("co size", "di size", "ir size", "hr size")
_TYPES = ("bits", "uint16", "uint32", "float32", "float64", "string")
_PARITY = {"none": "N", "even": "E", "odd": "O"}


def _raw(reg: Register, index: int, pages: dict[str, int]) -> int:
    if reg.name in pages:
        return pages[reg.name]
    default = reg.default_at(index)
    if isinstance(default, bool):
        return int(default)
    if default is None or isinstance(default, str):
        return 0
    return int(round((default - reg.offset) / reg.scale))


def wire_words(reg: Register, raw: int) -> list[int]:
    if reg.words == 1:
        return [raw & 0xFFFF]
    value = raw & 0xFFFFFFFF
    high, low = value >> 16, value & 0xFFFF
    return [low, high] if reg.word_order == "low_first" else [high, low]


class PymodbusSimExporter(Exporter):
    name = "pymodbus-sim"
    help = "JSON configuration of pymodbus's simulator (pymodbus.simulator --json_file) serving the device image"
    suffix = ".json"

    def add_arguments(self, parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
        where = parser.add_mutually_exclusive_group()
        where.add_argument("--tcp", default=None, metavar="HOST:PORT", help="serve Modbus TCP here (default 127.0.0.1:5020)")
        where.add_argument("--serial", default=None, metavar="DEV", help="serve on this serial device instead")
        parser.add_argument("--unit", type=int, default=None, help="unit id served (default: 1, or the map's lowest)")
        parser.add_argument("--page", action="append", default=None, metavar="SELECTOR=VALUE",
                            help="the page served at paged addresses (default: the selector's default)")
        iv.add_serial_arguments(parser)

    def render(self, model: Model, options: Options) -> dict[str, str]:
        values = options.values
        sel = iv.select(model, {"unit": values.get("unit"), "page": values.get("page")})
        pages = dict(sel.pages)
        device, size = self._device(model, sel, pages)
        device["setup"]["hr size"] = size
        doc = {
            "drivemap": {
                "note": generated_header(model, options),
                "model": model.name,
                "title": model.device.title,
                "unit": sel.unit,
                "pages": pages,
                "not_served": [f"{name}: {why}" for name, why in sel.omitted],
            },
            "server_list": {model.name: self._server(model, sel.unit, values)},
            "device_list": {model.name: device},
        }
        return {f"{model.name}.pymodbus-sim.json": json.dumps(doc, indent=2, ensure_ascii=False) + "\n"}

    def _server(self, model: Model, unit: int, values: Any) -> dict[str, Any]:
        server: dict[str, Any]
        if values.get("serial"):
            line = iv.serial_settings(model, values)
            server = {"comm": "serial", "port": values["serial"], "framer": line.mode, "baudrate": line.baudrate,
                      "bytesize": line.data_bits, "parity": _PARITY[line.parity], "stopbits": line.stop_bits}
        else:
            host, port = iv.tcp_endpoint(values.get("tcp") or "127.0.0.1:5020")
            server = {"comm": "tcp", "host": host, "port": port, "framer": "socket"}
        server["device_id"] = unit
        server["broadcast_enable"] = model.protocol.broadcast_address == 0
        return server

    def _device(self, model: Model, sel: iv.Selection, pages: dict[str, int]) -> tuple[dict[str, Any], int]:
        sections: dict[str, list[Any]] = {t: [] for t in _TYPES}
        writable: list[Any] = []
        end = 0
        for point in sel.points:
            reg = point.reg
            raw = _raw(reg, point.index, pages)
            section = SECTIONS[(reg.type, reg.word_order)]
            a = point.address
            if section is None:
                for i, word in enumerate(wire_words(reg, raw)):
                    sections["uint16"].append({"addr": a + i, "value": word})
            elif reg.words == 1:
                sections[section].append({"addr": a, "value": raw & 0xFFFF})
            else:
                sections[section].append({"addr": [a, a + reg.words - 1], "value": raw & 0xFFFFFFFF})
            if reg.writable:
                writable.append(a if reg.words == 1 else [a, a + reg.words - 1])
            end = max(end, a + reg.words)
        for res in model.reserved:
            if res.readable is True and (res.page is None or pages.get(res.page.selector) == res.page.value):
                sections["uint16"].append({"addr": [res.start, res.end], "value": 0})
                end = max(end, res.end + 1)
        for items in sections.values():
            items.sort(key=lambda item: item["addr"] if isinstance(item["addr"], int) else item["addr"][0])
        setup = {
            **{block: 0 for block in BLOCKS},
            "shared blocks": False,
            "type exception": True,
            "defaults": {"value": {"bits": 0, "uint16": 0, "uint32": 0, "float32": 0.0, "float64": 0.0, "string": " "},
                         "action": {t: None for t in _TYPES}},
        }
        return {"setup": setup, "invalid": [], "write": writable, **sections, "repeat": []}, end
