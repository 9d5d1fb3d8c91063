"""Semantic checks of registers and reserved ranges: where they are, what type they have, what they may say.

Each table (holding, input, coil, discrete) is its own address space: overlaps, reserved ranges
and read blocks are checked per table. Every error is located at the key that is wrong.
"""

from __future__ import annotations

import math
import string
from typing import Any

from drivemap.diagnostics import Diagnostic
from drivemap.frontend.load import Document, PathT
from drivemap.model import modicon
from drivemap.model.nodes import (
    BIT_TABLES,
    FLOAT_MAX,
    FLOAT_TYPES,
    INTEGER_TYPES,
    READ_CODES,
    TYPE_BOUNDS,
    default_type,
    normalize_raw,
    type_words,
)

#: Keys that mean nothing for a bool or a string register.
_NOT_FOR_BOOL = ("scale", "offset", "scale_register", "not_available", "enum", "bits", "word_order", "byte_order",
                 "length", "encoding", "min", "max")
_NOT_FOR_STRING = ("scale", "offset", "scale_register", "not_available", "enum", "bits", "min", "max")
#: Write function codes per writable table (either one will do).
WRITE_CODES: dict[str, tuple[int, ...]] = {"holding": (0x06, 0x10), "coil": (0x05, 0x0F)}
#: Modbus limits of one read per table when the map gives no max_quantity.
READ_LIMITS: dict[str, int] = {"holding": 125, "input": 125, "coil": 2000, "discrete": 2000}

Cell = tuple[str, int, str, int, "tuple[str, int] | None"]
"""(table, address, register name, register index, page) of one word of one register element."""


def table_name(table: str) -> str:
    """``an input``, ``a holding``: the table name with its article."""
    return ("an " if table[0] in "aeiou" else "a ") + table


class CheckerBase:
    """What every check needs: the document, its data and the list of diagnostics."""

    def __init__(self, doc: Document) -> None:
        self.doc = doc
        self.data: dict[str, Any] = doc.data
        self.diagnostics: list[Diagnostic] = []
        self.register_names: dict[str, int] = {}
        #: register index -> (table, address), for every register whose location is valid
        self.locations: dict[int, tuple[str, int]] = {}

    def error(self, where: PathT, message: str, *, key: bool = False, related: PathT | None = None,
              note: str = "first defined here", related_key: bool = False) -> None:
        rel = ((self.doc.positions.at(related, key=related_key), note),) if related is not None else ()
        self.diagnostics.append(Diagnostic(self.doc.positions.at(where, key=key), message, related=rel))

    def where_address(self, index: int) -> PathT:
        """The key that gives a register's address: ``address`` if present, else ``register``."""
        reg = self.data["registers"][index]
        return ("registers", index, "address" if "address" in reg or "register" not in reg else "register")

    def table_of(self, index: int) -> str:
        return self.locations.get(index, ("holding", 0))[0]

    def type_of(self, index: int) -> str:
        reg = self.data["registers"][index]
        return str(reg.get("type", default_type(self.table_of(index))))


class RegisterChecks(CheckerBase):
    # ---------------------------------------------------------------- location
    def locate(self, index: int, reg: dict[str, Any]) -> None:
        """Resolve ``register`` (Modicon) or ``table`` + ``address``; refuse contradictions."""
        where: PathT = ("registers", index)
        number, table, address = reg.get("register"), reg.get("table"), reg.get("address")
        if number is None:
            if address is None:
                self.error(where, f"register {reg['name']!r} needs an address (or a Modicon register number)")
                return
            self.locations[index] = (table or "holding", address)
            return
        try:
            found, at = modicon.parse(number)
        except modicon.ModiconError as exc:
            self.error(where + ("register",), str(exc))
            return
        ok = True
        if table is not None and table != found:
            self.error(where + ("register",), f"register {number} is {table_name(found)} number "
                       f"({modicon.TABLE_DIGIT[found]}xxxx) but table says {table}", related=where + ("table",),
                       note="table is given here")
            ok = False
        if address is not None and address != at:
            self.error(where + ("address",), f"address {address:#06x} contradicts register {number}, which is "
                       f"{found} address {at:#06x} (Modicon numbers are 1-based: {modicon.number(found, 0)} is "
                       "address 0)", related=where + ("register",), note="the Modicon number is given here")
            ok = False
        if ok:
            self.locations[index] = (found, at)

    # ---------------------------------------------------------------- types and values
    def check_type_keys(self, reg: dict[str, Any], where: PathT, table: str) -> str:
        """Keys that do not fit the register's type or table; returns the type."""
        rtype = str(reg.get("type", default_type(table)))
        if table in BIT_TABLES and rtype != "bool":
            self.error(where + ("type",), f"a {table} register is one bit: its type is bool, not {rtype}")
        if table in ("input", "discrete") and "w" in reg.get("access", "r"):
            self.error(where + ("access",), f"{table} registers are read-only (no Modbus function writes them); "
                       "access must be r")
        self._keys_of_type(reg, where, rtype)
        words = type_words(rtype, reg.get("length", 1))
        if words > 1 and rtype != "string" and "word_order" not in reg and "word_order" not in reg.get("review", ()):
            self.error(where + ("type",), f"{rtype} register needs word_order (high_first or low_first), or "
                       "review: [word_order] where its source leaves the order open")
        if words == 1 and "word_order" in reg and rtype != "bool":
            self.error(where + ("word_order",), "word_order only applies to multi-word types")
        if rtype in FLOAT_TYPES:
            for key in ("enum", "bits"):
                if reg.get(key):
                    self.error(where + (key,), f"an {rtype} register cannot have {key}"
                               + (" (list its allowed values with 'values:' instead)" if key == "enum" else ""),
                               key=True)
        if reg.get("scale_register"):
            self._scale_register_keys(reg, where, rtype)
        for j, value in enumerate(reg.get("not_available", ()) if rtype not in ("bool", "string") else ()):
            if normalize_raw(rtype, table, 1, value) is None:
                self.error(where + ("not_available", j), f"not_available value {value} does not fit {rtype}")
        return rtype

    def _keys_of_type(self, reg: dict[str, Any], where: PathT, rtype: str) -> None:
        """Keys only some types take: none of bool's and string's refused keys, length and encoding only for text."""
        if rtype == "bool":
            for key in _NOT_FOR_BOOL:
                if key in reg:
                    self.error(where + (key,), f"{key} does not apply to a bool register", key=True)
        elif rtype == "string":
            if "length" not in reg:
                self.error(where + ("type",), "a string register needs length (its size in registers)")
            for key in _NOT_FOR_STRING:
                if key in reg:
                    self.error(where + (key,), f"{key} does not apply to a string register", key=True)
        else:
            for key in ("length", "encoding"):
                if key in reg:
                    self.error(where + (key,), f"{key} is only for type string", key=True)

    def _scale_register_keys(self, reg: dict[str, Any], where: PathT, rtype: str) -> None:
        if rtype not in INTEGER_TYPES | {"bool", "string"}:
            self.error(where + ("scale_register",), f"scale_register needs an integer type, not {rtype}")
        elif reg.get("enum") or reg.get("bits"):
            self.error(where + ("scale_register",), "a register with a scale register cannot have an enum or bits")
        elif reg.get("broadcast"):
            self.error(where + ("broadcast",), "a register with a scale register cannot be written by broadcast "
                       "(its factor is read before every write)")

    def check_default_types(self, reg: dict[str, Any], where: PathT, rtype: str) -> None:
        default = reg.get("default")
        values = default if isinstance(default, list) else [default]
        for j, value in enumerate(values):
            dwhere = where + (("default", j) if isinstance(default, list) else ("default",))
            if value is None:
                continue
            if rtype == "string":
                if not isinstance(value, str):
                    self.error(dwhere, "the default of a string register is text")
                elif len(value.encode(reg.get("encoding", "ascii"), errors="replace")) > 2 * reg.get("length", 1):
                    self.error(dwhere, f"default {value!r} is longer than the field ({2 * reg.get('length', 1)} bytes)")
                elif reg.get("encoding", "ascii") == "ascii" and not value.isascii():
                    self.error(dwhere, f"default {value!r} is not ASCII")
            elif rtype == "bool":
                if isinstance(value, str) or value not in (0, 1):
                    self.error(dwhere, "the default of a bool register is true or false")
            elif isinstance(value, (bool, str)):
                self.error(dwhere, f"the default of a {rtype} register is a number")

    def numeric_bounds(self, reg: dict[str, Any], rtype: str) -> tuple[float, float] | None:
        """Raw bounds the engineering min/max/default must fit (None: not checkable here)."""
        if rtype in FLOAT_TYPES:
            return -FLOAT_MAX[rtype], FLOAT_MAX[rtype]
        if rtype in INTEGER_TYPES and not reg.get("scale_register"):
            return TYPE_BOUNDS[rtype]
        return None

    def check_register_values(self, index: int, reg: dict[str, Any]) -> None:
        where: PathT = ("registers", index)
        table, base = self.locations.get(index, (str(reg.get("table", "holding")), 0))
        rtype = self.check_type_keys(reg, where, table)
        self.check_default_types(reg, where, rtype)
        words = type_words(rtype, reg.get("length", 1))
        count = reg.get("count", 1)
        stride = reg.get("stride", 1)
        if count > 1 and stride < words:
            self.error(where + ("stride",), f"stride {stride} is smaller than the register width ({words} words)")
        last = base + (count - 1) * stride + words - 1
        if last > 0xFFFF:
            self.error(self.where_address(index), f"register extends past address 0xFFFF (to {last:#x})")
        if "stride" in reg and count == 1:
            self.error(where + ("stride",), "stride without count")
        if "element_params" in reg and len(reg["element_params"]) != count:
            self.error(where + ("element_params",),
                       f"element_params has {len(reg['element_params'])} entries, count is {count}")
        if "element_param_format" in reg:
            self.check_element_param_format(reg, where, base)
        if reg.get("enum") and reg.get("bits"):
            self.error(where + ("enum",), "a register has either an enum or bits, not both")
        if reg.get("enum") and (reg.get("scale", 1) != 1 or reg.get("offset", 0) != 0):
            self.error(where + ("enum",), "an enum register cannot be scaled")
        if reg.get("command") and "w" not in reg.get("access", "r"):
            self.error(where + ("command",), "a command register must be writable")
        if reg.get("write_delay_ms") is not None and reg.get("storage") not in ("eeprom",):
            self.error(where + ("write_delay_ms",), "write_delay_ms is for storage: eeprom")
        if rtype not in ("bool", "string"):
            self.check_numbers(reg, where, rtype)
        self.check_bits(reg, where, 16 * words)

    def check_numbers(self, reg: dict[str, Any], where: PathT, rtype: str) -> None:
        """min, max, default and enum values against the type, the scale and each other."""
        scale = reg.get("scale", 1)
        offset = reg.get("offset", 0)
        bounds = self.numeric_bounds(reg, rtype)

        def raw_of(value: float) -> float:
            return float((value - offset) / scale)

        def fits(value: float) -> bool:
            raw = raw_of(value)
            return bounds is None or bounds[0] - 1e-9 <= raw <= bounds[1] + 1e-9

        enum_values = self._register_enum(reg, where, rtype) if reg.get("enum") else None
        lo, hi = reg.get("min"), reg.get("max")
        for key, value in (("min", lo), ("max", hi)):
            if value is not None and not fits(value):
                self.error(where + (key,), f"{key} {value} does not fit type {rtype} at scale {scale}")
        if lo is not None and hi is not None and lo > hi:
            self.error(where + ("min",), f"min {lo} is greater than max {hi}")
        default = reg.get("default")
        defaults = default if isinstance(default, list) else [default]
        if isinstance(default, list) and len(default) != reg.get("count", 1):
            self.error(where + ("default",), f"default lists {len(default)} values, count is {reg.get('count', 1)}")
        for j, value in enumerate(defaults):
            if value is None or isinstance(value, (bool, str)):
                continue
            dwhere = where + (("default", j) if isinstance(default, list) else ("default",))
            whole = rtype in INTEGER_TYPES and not reg.get("scale_register")
            if not fits(value):
                self.error(dwhere, f"default {value} does not fit type {rtype} at scale {scale}")
            elif (lo is not None and value < lo - 1e-9) or (hi is not None and value > hi + 1e-9):
                self.error(dwhere, f"default {value} is outside the range {lo}..{hi}")
            elif whole and not math.isclose(raw_of(value), round(raw_of(value)), abs_tol=1e-6):
                self.error(dwhere, f"default {value} is not a multiple of the scale {scale}")
            elif enum_values is not None and round(raw_of(value)) not in enum_values:
                self.error(dwhere, f"default {value} is not a value of enum {reg['enum']}")

    def _register_enum(self, reg: dict[str, Any], where: PathT, rtype: str) -> list[int] | None:
        """The values of the register's enum (None: no such enum), each checked against the type."""
        enum_values = self._enum_values(reg["enum"])
        if enum_values is None:
            self.error(where + ("enum",), f"unknown enum {reg['enum']!r}")
        elif rtype in TYPE_BOUNDS:
            lo_raw, hi_raw = TYPE_BOUNDS[rtype]
            for v in enum_values:
                if not lo_raw <= v <= hi_raw:
                    self.error(where + ("enum",), f"enum {reg['enum']} value {v} does not fit type {rtype}")
        return enum_values

    def _enum_values(self, name: str) -> list[int] | None:
        enum = self.data.get("enums", {}).get(name)
        return [v["value"] for v in enum["values"]] if enum else None

    def check_bits(self, reg: dict[str, Any], where: PathT, bits_total: int) -> None:
        used: dict[int, int] = {}
        names: dict[str, int] = {}
        for j, bit in enumerate(reg.get("bits", [])):
            bwhere = where + ("bits", j)
            width = bit.get("width", 1)
            if bit["offset"] + width > bits_total:
                self.error(bwhere + ("offset",), f"bit field {bit['name']} (bits {bit['offset']}.."
                           f"{bit['offset'] + width - 1}) is wider than the {bits_total}-bit register")
                continue
            if bit["name"] in names:
                self.error(bwhere + ("name",), f"duplicate bit name {bit['name']!r}",
                           related=where + ("bits", names[bit["name"]]))
            names.setdefault(bit["name"], j)
            for b in range(bit["offset"], bit["offset"] + width):
                if b in used:
                    self.error(bwhere + ("offset",), f"bit field {bit['name']} overlaps bit {b} of another field",
                               related=where + ("bits", used[b]))
                    break
                used[b] = j
            if bit.get("enum"):
                values = self._enum_values(bit["enum"])
                if values is None:
                    self.error(bwhere + ("enum",), f"unknown enum {bit['enum']!r}")
                elif any(not 0 <= v < (1 << width) for v in values):
                    self.error(bwhere + ("enum",), f"enum {bit['enum']} has values that do not fit {width} bits")

    # ---------------------------------------------------------------- addresses
    def cells(self) -> list[Cell]:
        """(table, address, name, register index, page) for every word of every located register."""
        out: list[Cell] = []
        for i, reg in enumerate(self.data["registers"]):
            if i not in self.locations:
                continue
            table, address = self.locations[i]
            words = type_words(self.type_of(i), reg.get("length", 1))
            page = (reg["page"]["selector"], reg["page"]["value"]) if reg.get("page") else None
            for k in range(reg.get("count", 1)):
                base = address + k * reg.get("stride", 1)
                for w in range(words):
                    out.append((table, base + w, reg["name"], i, page))
        return out

    def check_overlaps(self) -> None:
        seen: dict[tuple[str, int], list[tuple[str, int, tuple[str, int] | None]]] = {}
        for table, address, name, index, page in self.cells():
            for other_name, other_index, other_page in seen.get((table, address), []):
                if other_index == index:
                    self.error(("registers", index, "stride"), f"elements of {name!r} overlap at {address:#06x}")
                    break
                if page and other_page and page[0] == other_page[0] and page[1] != other_page[1]:
                    continue
                where = f"{table} address" if table != "holding" else "address"
                self.error(self.where_address(index), f"register {name!r} overlaps {other_name!r} at {where} "
                           f"{address:#06x}", related=self.where_address(other_index),
                           note=f"{other_name!r} is defined here")
                break
            seen.setdefault((table, address), []).append((name, index, page))

    def check_element_param_format(self, reg: dict[str, Any], where: PathT, address: int) -> None:
        """Only {index} and {address}, an array, not with element_params; element 0 gives param."""
        fmt = reg["element_param_format"]
        fwhere = where + ("element_param_format",)
        try:
            fields = {name for _, name, _spec, _conv in string.Formatter().parse(fmt) if name is not None}
            bad = fields - {"index", "address"}
            first = fmt.format(index=0, address=address) if not bad else None
        except (ValueError, KeyError, IndexError) as exc:
            self.error(fwhere, f"element_param_format {fmt!r} is not a valid format: {exc}")
            return
        if bad:
            self.error(fwhere, f"element_param_format may use only {{index}} and {{address}}, not {sorted(bad)}")
        elif reg.get("count", 1) < 2:
            self.error(fwhere, "element_param_format is for arrays (count > 1)")
        elif "element_params" in reg:
            self.error(fwhere, "give element_params or element_param_format, not both")
        elif reg.get("param") is not None and first != reg["param"]:
            self.error(fwhere, f"element_param_format gives {first!r} for element 0, but param is {reg['param']!r}")

    def check_reserved(self) -> None:
        cells: dict[tuple[str, int], list[tuple[str, int, tuple[str, int] | None]]] = {}
        for table, address, name, index, page in self.cells():
            cells.setdefault((table, address), []).append((name, index, page))
        for i, item in enumerate(self.data.get("reserved", [])):
            if item["start"] > item["end"]:
                self.error(("reserved", i, "start"), "reserved range start is after its end")
                continue
            table = item.get("table", "holding")
            rpage = (item["page"]["selector"], item["page"]["value"]) if item.get("page") else None
            for address in range(item["start"], item["end"] + 1):
                hit = [c for c in cells.get((table, address), [])
                       if not (rpage and c[2] and c[2][0] == rpage[0] and c[2][1] != rpage[1])]
                if hit:
                    name, index, _ = hit[0]
                    where = "" if table == "holding" else f"{table} address "
                    self.error(("reserved", i, "start"), f"reserved range overlaps register {name!r} at {where}{address:#06x}",
                               related=self.where_address(index), note=f"{name!r} is defined here")
                    break

    # ---------------------------------------------------------------- cross-register rules
    def check_scale_registers(self) -> None:
        regs = self.data["registers"]
        for i, reg in enumerate(regs):
            name = reg.get("scale_register")
            if not name:
                continue
            where: PathT = ("registers", i, "scale_register")
            if name not in self.register_names:
                self.error(where, f"scale register {name!r} is not a register of this map")
                continue
            j = self.register_names[name]
            other = regs[j]
            if j == i:
                self.error(where, "a register cannot be its own scale register")
            elif self.type_of(j) not in INTEGER_TYPES:
                self.error(where, f"scale register {name!r} must have an integer type, not {self.type_of(j)}")
            elif "r" not in other.get("access", "r"):
                self.error(where, f"scale register {name!r} must be readable")
            elif other.get("count", 1) > 1:
                self.error(where, f"scale register {name!r} must not be an array")
            elif any(key in other for key in ("scale", "offset", "scale_register", "enum", "bits")):
                self.error(where, f"scale register {name!r} must hold a plain power of ten "
                           "(no scale, offset, scale_register, enum or bits)")
            elif other.get("page") and other.get("page") != reg.get("page"):
                self.error(where, f"scale register {name!r} is on another page")

    def check_read_blocks(self) -> None:
        """``min_read`` blocks: at least the register, readable throughout, within the read limit."""
        regs = self.data["registers"]
        codes = {fc["code"]: fc for fc in self.data["protocol"]["function_codes"]}
        cells: dict[tuple[str, int], list[int]] = {}
        for table, address, _name, index, _page in self.cells():
            cells.setdefault((table, address), []).append(index)
        for i, reg in enumerate(regs):
            size = reg.get("min_read")
            if size is None or i not in self.locations:
                continue
            where: PathT = ("registers", i, "min_read")
            table, start = self.locations[i]
            words = type_words(self.type_of(i), reg.get("length", 1))
            fc = codes.get(READ_CODES[table])
            limit = (fc or {}).get("max_quantity") or READ_LIMITS[table]
            if size < words:
                self.error(where, f"min_read {size} is smaller than the register ({words} words)")
            elif size > limit:
                self.error(where, f"min_read {size} is more than one read may carry ({limit})")
            elif start + size > 0x10000:
                self.error(where, f"the block of min_read {size} extends past address 0xFFFF")
            elif "r" not in reg.get("access", "r") or reg.get("page"):
                self.error(where, "min_read needs a readable register without a page")
            else:
                self._check_block_contents(where, table, start, size, cells)

    def _check_block_contents(self, where: PathT, table: str, start: int, size: int,
                              cells: dict[tuple[str, int], list[int]]) -> None:
        regs = self.data["registers"]
        for address in range(start, start + size):
            for index in cells.get((table, address), []):
                other = regs[index]
                if "r" not in other.get("access", "r") or other.get("page"):
                    self.error(where, f"the block of min_read {size} covers {other['name']!r}, which is "
                               f"{'write-only' if 'r' not in other['access'] else 'paged'}")
                    return
        for item in self.data.get("reserved", []):
            if item.get("table", "holding") == table and item["start"] < start + size and item["end"] >= start \
                    and item.get("readable") is not True:
                self.error(where, f"the block of min_read {size} covers reserved {item['start']:#06x}..{item['end']:#06x}, "
                           "which the map does not mark readable")
                return

    def check_table_functions(self) -> None:
        """Every table in use has its function codes in protocol.function_codes (one error per table and kind)."""
        codes = {fc["code"] for fc in self.data["protocol"]["function_codes"]}
        reported: set[tuple[str, str]] = set()
        for i, reg in enumerate(self.data["registers"]):
            if i not in self.locations:
                continue
            table = self.locations[i][0]
            kind_where: PathT = ("registers", i, "table" if "table" in reg else "access")
            read = READ_CODES[table]
            if "r" in reg.get("access", "r") and read not in codes and (table, "r") not in reported:
                reported.add((table, "r"))
                self.error(kind_where, f"{table} registers are read with {read:02X}h, which "
                           f"protocol.function_codes does not list (first: {reg['name']!r})")
            writes = WRITE_CODES.get(table, ())
            if "w" in reg.get("access", "r") and writes and not codes & set(writes) and (table, "w") not in reported:
                reported.add((table, "w"))
                self.error(kind_where, f"{table} registers are written with "
                           f"{' or '.join(f'{c:02X}h' for c in writes)}, which protocol.function_codes does not "
                           f"list (first: {reg['name']!r})")


__all__ = ["CheckerBase", "READ_LIMITS", "RegisterChecks", "WRITE_CODES", "table_name"]
