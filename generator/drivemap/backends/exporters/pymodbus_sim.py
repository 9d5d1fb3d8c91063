"""The ``pymodbus-sim`` exporter: the device image as a configuration of pymodbus's own simulator.

``pymodbus.simulator --json_file ev.pymodbus-sim.json --modbus_server ev --modbus_device ev``
serves the map's registers with their default values (0 where the map gives none, the shown page
on a page selector), the readable reserved words as 0, and refuses every other address with
exception 02h, as a device would. pymodbus's simulator knows one address space: paged registers are
served for one page (``--page``), and writing a page selector does not switch pages there.

The values are the image drivemap's simulator starts with: defaults (a value the map allows where
it gives none), scale factors, not-available values, and then the model's behaviour's power-up (ev:
the RAM copies loaded from EEPROM), exactly what ``drivemap simulate`` serves before any request.
What the export cannot carry is the behaviour itself (ramps, the status bits a write changes,
pages switching): pymodbus's simulator serves the start-up image as a fixed store. Tables: coils and discrete inputs go in ``bits`` cells (16 per cell), input and holding
registers in register cells, each table's block after the blocks before it (co, di, ir, hr: the
simulator's layout with "shared blocks": false, so the addresses here are offset by the sizes of
the blocks before). The simulator's ``int16`` section stores float bytes (pymodbus 3.16), so signed
values are written as their two's complement in ``uint16``/``uint32`` cells; f32/f64 in the standard
layout (high word and high byte first) go in ``float32``/``float64``; any other word or byte order,
64-bit integers and strings go in as their wire words (``SECTIONS``, :func:`section`).
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any

from drivemap.backends.exporters.base import Exporter, Options, option
from drivemap.backends.options import SerialOptions
from drivemap.backends.views import integrations as iv
from drivemap.backends.views.common import header as generated_header
from drivemap.backends.views.common import provenance, review_lines
from drivemap.model.nodes import Model, Register
from drivemap.model.spec import spec_from_model
from drivemap.runtime.sim.simulator import Simulator
from drivemap.runtime.sim.unit import wire_words

__all__ = ["BLOCKS", "SECTIONS", "PymodbusSimExporter"]

#: drivemap type -> the simulator section that holds the value as pymodbus lays it out (big-endian
#: bytes, high word first), or None: written as uint16 words in wire order. Strings always go in as
#: words: the simulator's "string" cell refuses a read that continues past the string (type exception).
SECTIONS: dict[str, str | None] = {
    "u16": "uint16", "s16": "uint16", "bool": "uint16",
    "u32": "uint32", "s32": "uint32",
    "f32": "float32", "f64": "float64",
    "u64": None, "s64": None, "string": None,
}
#: The simulator's blocks in the order it lays them out ("shared blocks": false): coils, discrete
#: inputs, input registers, holding registers; each table's addresses are offset by the sizes of the
#: blocks before it (bit tables: 16 bits per cell).
BLOCKS = ("co size", "di size", "ir size", "hr size")
_BLOCK_OF = {"coil": "co size", "discrete": "di size", "input": "ir size", "holding": "hr size"}
_TYPES = ("bits", "uint16", "uint32", "float32", "float64", "string")
_PARITY = {"none": "N", "even": "E", "odd": "O"}


def section(reg: Register) -> str | None:
    """Where a register's value goes (None: as words)."""
    if reg.bit_table:
        return "bits"
    if reg.byte_order != "high_first" or (reg.words > 1 and reg.word_order == "low_first"):
        return None
    return SECTIONS[reg.type]


def _image(model: Model, unit: int, pages: dict[str, int]) -> tuple[Any, dict[str, int]]:
    """The raw value of every element as drivemap's simulator starts (defaults, scale factors,
    not-available values, the behaviour's power-up), the shown page on each selector."""
    from drivemap.runtime.sim.behaviours import behaviour_for

    spec = spec_from_model(model)
    state = Simulator(spec, [unit], behaviour=behaviour_for(model.name)).unit(unit)
    raws = dict(state.values)
    raws.update(pages)
    return spec, raws


@dataclass(frozen=True)
class PymodbusSimOptions(SerialOptions):
    tcp: str | None = option(metavar="HOST:PORT", exclusive="where", help="serve Modbus TCP here (default 127.0.0.1:5020)")
    serial: str | None = option(metavar="DEV", exclusive="where", help="serve on this serial device instead")
    unit: int | None = option(help="unit id served (default: 1, or the map's lowest)")
    page: tuple[str, ...] | None = option(
        metavar="SELECTOR=VALUE", help="the page served at paged addresses (default: the selector's default)")


class PymodbusSimExporter(Exporter):
    name = "pymodbus-sim"
    help = "JSON configuration of pymodbus's simulator (pymodbus.simulator --json_file) serving the device image"
    suffix = ".json"

    options_class = PymodbusSimOptions

    def render(self, model: Model, options: Options) -> dict[str, str]:
        own = PymodbusSimOptions.from_values(options.values)
        sel = iv.select(model, {"unit": own.unit, "page": own.page})
        pages = dict(sel.pages)
        device = self._device(model, sel, pages)
        doc = {
            "drivemap": {
                "note": generated_header(model, options),
                "model": model.name,
                "title": model.device.title,
                "provenance": provenance(model),
                **({"review": review_lines(model)} if any(r.review for r in model.registers) else {}),
                "unit": sel.unit,
                "pages": pages,
                "not_served": [f"{name}: {why}" for name, why in sel.omitted],
            },
            "server_list": {model.name: self._server(model, sel.unit, own)},
            "device_list": {model.name: device},
        }
        return {f"{model.name}.pymodbus-sim.json": json.dumps(doc, indent=2, ensure_ascii=False) + "\n"}

    def _server(self, model: Model, unit: int, own: PymodbusSimOptions) -> dict[str, Any]:
        server: dict[str, Any]
        if own.serial:
            line = iv.serial_settings(model, own.values())
            server = {"comm": "serial", "port": own.serial, "framer": line.mode, "baudrate": line.baudrate,
                      "bytesize": line.data_bits, "parity": _PARITY[line.parity], "stopbits": line.stop_bits}
        else:
            host, port = iv.tcp_endpoint(own.tcp or "127.0.0.1:5020")
            server = {"comm": "tcp", "host": host, "port": port, "framer": "socket"}
        server["device_id"] = unit
        server["broadcast_enable"] = model.protocol.broadcast_address == 0
        return server

    def _device(self, model: Model, sel: iv.Selection, pages: dict[str, int]) -> dict[str, Any]:
        spec, raws = _image(model, sel.unit, pages)
        sections: dict[str, list[Any]] = {t: [] for t in _TYPES}
        writable: list[Any] = []
        ends = dict.fromkeys(_BLOCK_OF, 0)
        words: dict[str, dict[int, int]] = {t: {} for t in _BLOCK_OF}  # table -> word address -> value
        bits: dict[str, dict[int, int]] = {"coil": {}, "discrete": {}}   # table -> cell -> 16 bits
        for point in sel.points:
            reg = point.reg
            raw = raws[point.cell.name]
            a = point.address
            if reg.bit_table:
                cell = bits[reg.table].setdefault(a // 16, 0)
                bits[reg.table][a // 16] = cell | ((raw & 1) << (a % 16))
                ends[reg.table] = max(ends[reg.table], a // 16 + 1)
                if reg.writable:
                    writable.append((reg.table, a // 16, 1))
                continue
            for i, word in enumerate(wire_words(spec.register(reg.name), raw)):
                words[reg.table][a + i] = word
            if reg.writable:
                writable.append((reg.table, a, reg.words))
            ends[reg.table] = max(ends[reg.table], a + reg.words)
        for res in model.reserved:
            if res.readable is True and (res.page is None or pages.get(res.page.selector) == res.page.value) \
                    and res.table not in bits:
                for w in range(res.start, res.end + 1):
                    words[res.table].setdefault(w, 0)
                ends[res.table] = max(ends[res.table], res.end + 1)
        sizes = {_BLOCK_OF[t]: ends[t] for t in _BLOCK_OF}
        base = {"coil": 0, "discrete": ends["coil"], "input": ends["coil"] + ends["discrete"],
                "holding": ends["coil"] + ends["discrete"] + ends["input"]}
        for table, cells in bits.items():
            for cell, value in sorted(cells.items()):
                sections["bits"].append({"addr": base[table] + cell, "value": value})
        _register_sections(sel, words, base, sections)
        for items in sections.values():
            items.sort(key=lambda item: item["addr"] if isinstance(item["addr"], int) else item["addr"][0])
        write = _runs(sorted({base[t] + a + i for t, a, n in writable for i in range(n)}))
        setup = {
            **sizes,
            "shared blocks": False,
            "type exception": True,
            "defaults": {"value": {"bits": 0, "uint16": 0, "uint32": 0, "float32": 0.0, "float64": 0.0, "string": " "},
                         "action": {t: None for t in _TYPES}},
        }
        return {"setup": setup, "invalid": [], "write": write, **sections, "repeat": []}


def _register_sections(sel: iv.Selection, words: dict[str, dict[int, int]], base: dict[str, int],
                       sections: dict[str, list[Any]]) -> None:
    """Each register's words into the section of its type (uint16, uint32, float32 ...), at its
    address in the device block; readable reserved words as uint16."""
    taken: set[tuple[str, int]] = set()
    for point in sel.points:
        reg = point.reg
        if reg.bit_table:
            continue
        kind, a = section(reg), point.address
        taken.update((reg.table, a + i) for i in range(reg.words))
        at = base[reg.table] + a
        if kind is None:
            for i in range(reg.words):
                sections["uint16"].append({"addr": at + i, "value": words[reg.table][a + i]})
        elif kind in ("float32", "float64"):
            data = b"".join(words[reg.table][a + i].to_bytes(2, "big") for i in range(reg.words))
            value = struct.unpack(">f" if kind == "float32" else ">d", data)[0]
            sections[kind].append({"addr": [at, at + reg.words - 1], "value": value})
        elif reg.words == 1:
            sections[kind].append({"addr": at, "value": words[reg.table][a]})
        else:
            value = 0
            for i in range(reg.words):
                value = (value << 16) | words[reg.table][a + i]
            sections[kind].append({"addr": [at, at + reg.words - 1], "value": value})
    for table, cells in words.items():  # readable reserved words
        for w, value in sorted(cells.items()):
            if (table, w) not in taken:
                sections["uint16"].append({"addr": base[table] + w, "value": value})


def _runs(addresses: list[int]) -> list[int | list[int]]:
    """Writable addresses as pymodbus's simulator lists them: a lone address, or [first, last] of a run
    (one canonical form, whatever registers the words belong to, so an import of the file exports it again)."""
    runs: list[list[int]] = []
    for address in addresses:
        if runs and address == runs[-1][1] + 1:
            runs[-1][1] = address
        else:
            runs.append([address, address])
    return [first if first == last else [first, last] for first, last in runs]
