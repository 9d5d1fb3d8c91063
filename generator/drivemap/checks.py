"""Semantic checks on a document that passed the schema.

Each check reports a located :class:`Diagnostic`; all of a file's errors are collected in one run.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from . import examplevalues, frames, namecheck
from .diagnostics import Diagnostic
from .load import Document, PathT
from .model import TYPE_BOUNDS, camel, is_keyword
from .names import FIXED_NAMES

#: Attribute names of the generated clients that a register may not take.
CLIENT_ATTRIBUTES = frozenset(
    {
        "read", "write", "read_all", "read_by_name", "write_by_name", "read_modify_write", "close",
        "stats", "bus", "unit", "pending_configuration", "pending_power_cycle", "apply_configuration",
        "registers", "accessor", "tcp", "serial", "rtu_over_tcp", "broadcast", "model", "page_policy",
        "connect", "plan", "loopback", "write_many", "self", "cls",
    }
)

STANDARD_EXCEPTIONS = frozenset({1, 2, 3, 4, 5, 6, 8, 10, 11})
OPERATION_CODES = {"read": (3, 4), "write": (6,), "write_multiple": (16,), "loopback": (8,)}


class Checker:
    def __init__(self, doc: Document) -> None:
        self.doc = doc
        self.data: dict[str, Any] = doc.data
        self.diagnostics: list[Diagnostic] = []
        self.statuses: dict[str, str] = {}
        self.register_names: dict[str, int] = {}

    def error(self, where: PathT, message: str, *, key: bool = False, related: PathT | None = None,
              note: str = "first defined here", related_key: bool = False) -> None:
        rel = ((self.doc.positions.at(related, key=related_key), note),) if related is not None else ()
        self.diagnostics.append(Diagnostic(self.doc.positions.at(where, key=key), message, related=rel))

    # --------------------------------------------------------------------- all
    def run(self) -> list[Diagnostic]:
        self.check_device()
        self.check_enums()
        self.check_registers()
        self.check_protocol()
        self.check_reserved()
        self.check_known_issues()
        self.check_examples()
        self.check_generated_names()
        self.check_reserved_pages()
        self.check_example_values()
        return self.diagnostics

    def check_reserved_pages(self) -> None:
        """A reserved range's page selector is a register, as a register's is."""
        for i, item in enumerate(self.data.get("reserved", [])):
            page = item.get("page")
            if page and page["selector"] not in self.register_names:
                self.error(("reserved", i, "page", "selector"), f"page selector {page['selector']!r} is not a register")

    def check_example_values(self) -> None:
        """``meaning.values`` and ``preset`` against what the example's frames carry (:mod:`.examplevalues`)."""
        for where, message, options in examplevalues.problems(self.data):
            self.error(where, message, **options)

    def check_generated_names(self) -> None:
        """Generated names against each other and against what the generated code holds (:mod:`.namecheck`)."""
        for where, message, options in namecheck.problems(self.data, CLIENT_ATTRIBUTES):
            self.error(where, message, **options)

    def check_device(self) -> None:
        model = self.data["device"]["model"]
        stem = Path(self.doc.path).stem
        if stem != model:
            self.error(("device", "model"), f"model id {model!r} must equal the file name {stem!r}")
        if is_keyword(model):
            self.error(("device", "model"), f"model id {model!r} is a Python keyword")

    def check_enums(self) -> None:
        classes: dict[str, PathT] = {}
        for name in self.data.get("enums", {}):
            if name in FIXED_NAMES:
                self.error(("enums", name), f"enum name {name!r} is taken by the generated client package", key=True)
            classes[name] = ("enums", name)
        for i, reg in enumerate(self.data["registers"]):
            if reg.get("bits"):
                cls = reg.get("flags_name") or camel(reg["name"])
                where: PathT = ("registers", i, "flags_name" if reg.get("flags_name") else "name")
                if cls in FIXED_NAMES:
                    self.error(where, f"bit-field class name {cls!r} is taken by the generated client package")
                elif cls in classes:
                    self.error(where, f"bit-field class name {cls!r} clashes with another class of this map",
                               related=classes[cls], note="the other class is defined here",
                               related_key=classes[cls][0] == "enums")
                classes.setdefault(cls, where)
        for name, enum in self.data.get("enums", {}).items():
            seen_v: dict[int, int] = {}
            seen_n: dict[str, int] = {}
            for i, item in enumerate(enum["values"]):
                where = ("enums", name, "values", i)
                if item["value"] in seen_v:
                    self.error(where + ("value",), f"enum {name}: value {item['value']} listed twice",
                               related=("enums", name, "values", seen_v[item["value"]]))
                seen_v.setdefault(item["value"], i)
                if item["name"] in seen_n:
                    self.error(where + ("name",), f"enum {name}: member name {item['name']!r} listed twice",
                               related=("enums", name, "values", seen_n[item["name"]]))
                seen_n.setdefault(item["name"], i)
                if is_keyword(item["name"]):
                    self.error(where + ("name",), f"enum member {item['name']!r} is a Python keyword")

    # --------------------------------------------------------------- registers
    def _enum_values(self, name: str) -> list[int] | None:
        enum = self.data.get("enums", {}).get(name)
        return [v["value"] for v in enum["values"]] if enum else None

    def check_registers(self) -> None:
        groups = {g["name"] for g in self.data.get("groups", [])}
        regs = self.data["registers"]
        for i, reg in enumerate(regs):
            where: PathT = ("registers", i)
            name = reg["name"]
            if name in self.register_names:
                self.error(where + ("name",), f"duplicate register name {name!r}",
                           related=("registers", self.register_names[name], "name"))
                continue
            self.register_names[name] = i
            if is_keyword(name):
                self.error(where + ("name",), f"register name {name!r} is a Python keyword")
            elif name in CLIENT_ATTRIBUTES:
                self.error(where + ("name",), f"register name {name!r} clashes with a client attribute")
            elif name.startswith("_") or "__" in name:
                self.error(where + ("name",), f"register name {name!r} may not start with or contain '__'")
            if reg["group"] not in groups:
                self.error(where + ("group",), f"unknown group {reg['group']!r} (define it under groups)")
            self.check_register_values(reg, where)
        self.check_overlaps()
        for i, reg in enumerate(regs):
            page = reg.get("page")
            if page:
                sel = page["selector"]
                if sel not in self.register_names:
                    self.error(("registers", i, "page", "selector"), f"page selector {sel!r} is not a register")
                elif sel == reg["name"]:
                    self.error(("registers", i, "page", "selector"), "a register cannot select its own page")

    def check_register_values(self, reg: dict[str, Any], where: PathT) -> None:
        rtype = reg.get("type", "u16")
        bits_total = 32 if rtype in ("u32", "s32") else 16
        lo_raw, hi_raw = TYPE_BOUNDS[rtype]
        scale = reg.get("scale", 1)
        offset = reg.get("offset", 0)
        if rtype in ("u32", "s32") and "word_order" not in reg:
            self.error(where + ("type",), f"{rtype} register needs word_order (high_first or low_first)")
        if rtype in ("u16", "s16") and "word_order" in reg:
            self.error(where + ("word_order",), "word_order only applies to 32-bit types")
        count = reg.get("count", 1)
        stride = reg.get("stride", 1)
        words = bits_total // 16
        if count > 1 and stride < words:
            self.error(where + ("stride",), f"stride {stride} is smaller than the register width ({words} words)")
        last = reg["address"] + (count - 1) * stride + words - 1
        if last > 0xFFFF:
            self.error(where + ("address",), f"register extends past address 0xFFFF (to {last:#x})")
        if "stride" in reg and count == 1:
            self.error(where + ("stride",), "stride without count")
        if "element_params" in reg and len(reg["element_params"]) != count:
            self.error(where + ("element_params",), f"element_params has {len(reg['element_params'])} entries, count is {count}")
        if reg.get("enum") and reg.get("bits"):
            self.error(where + ("enum",), "a register has either an enum or bits, not both")
        if reg.get("enum") and (scale != 1 or offset != 0):
            self.error(where + ("enum",), "an enum register cannot be scaled")
        if reg.get("command") and "w" not in reg["access"]:
            self.error(where + ("command",), "a command register must be writable")
        if reg.get("write_delay_ms") is not None and reg.get("storage") not in ("eeprom",):
            self.error(where + ("write_delay_ms",), "write_delay_ms is for storage: eeprom")

        def raw_of(value: float) -> float:
            return float((value - offset) / scale)

        def fits(value: float) -> bool:
            raw = raw_of(value)
            return lo_raw - 1e-9 <= raw <= hi_raw + 1e-9

        enum_values: list[int] | None = None
        if reg.get("enum"):
            enum_values = self._enum_values(reg["enum"])
            if enum_values is None:
                self.error(where + ("enum",), f"unknown enum {reg['enum']!r}")
            else:
                for v in enum_values:
                    if not lo_raw <= v <= hi_raw:
                        self.error(where + ("enum",), f"enum {reg['enum']} value {v} does not fit type {rtype}")
        lo, hi = reg.get("min"), reg.get("max")
        for key, value in (("min", lo), ("max", hi)):
            if value is not None and not fits(value):
                self.error(where + (key,), f"{key} {value} does not fit type {rtype} at scale {scale}")
        if lo is not None and hi is not None and lo > hi:
            self.error(where + ("min",), f"min {lo} is greater than max {hi}")
        default = reg.get("default")
        defaults = default if isinstance(default, list) else [default]
        if isinstance(default, list) and len(default) != count:
            self.error(where + ("default",), f"default lists {len(default)} values, count is {count}")
        for j, value in enumerate(defaults):
            if value is None:
                continue
            dwhere = where + (("default", j) if isinstance(default, list) else ("default",))
            if not fits(value):
                self.error(dwhere, f"default {value} does not fit type {rtype} at scale {scale}")
            elif (lo is not None and value < lo - 1e-9) or (hi is not None and value > hi + 1e-9):
                self.error(dwhere, f"default {value} is outside the range {lo}..{hi}")
            elif not math.isclose(raw_of(value), round(raw_of(value)), abs_tol=1e-6):
                self.error(dwhere, f"default {value} is not a multiple of the scale {scale}")
            elif enum_values is not None and round(raw_of(value)) not in enum_values:
                self.error(dwhere, f"default {value} is not a value of enum {reg['enum']}")
        self.check_bits(reg, where, bits_total)

    def check_bits(self, reg: dict[str, Any], where: PathT, bits_total: int) -> None:
        used: dict[int, int] = {}
        names: dict[str, int] = {}
        for j, bit in enumerate(reg.get("bits", [])):
            bwhere = where + ("bits", j)
            width = bit.get("width", 1)
            if bit["offset"] + width > bits_total:
                self.error(bwhere + ("offset",),
                           f"bit field {bit['name']} (bits {bit['offset']}..{bit['offset'] + width - 1}) is wider than the {bits_total}-bit register")
                continue
            if bit["name"] in names:
                self.error(bwhere + ("name",), f"duplicate bit name {bit['name']!r}", related=where + ("bits", names[bit["name"]]))
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

    def _cells(self) -> list[tuple[int, str, int, tuple[str, int] | None]]:
        """(address, name, register index, page) for every word of every register."""
        out = []
        for i, reg in enumerate(self.data["registers"]):
            words = 2 if reg.get("type") in ("u32", "s32") else 1
            page = (reg["page"]["selector"], reg["page"]["value"]) if reg.get("page") else None
            for k in range(reg.get("count", 1)):
                base = reg["address"] + k * reg.get("stride", 1)
                for w in range(words):
                    out.append((base + w, reg["name"], i, page))
        return out

    def check_overlaps(self) -> None:
        seen: dict[int, list[tuple[str, int, tuple[str, int] | None]]] = {}
        for address, name, index, page in self._cells():
            for other_name, other_index, other_page in seen.get(address, []):
                if other_index == index:
                    self.error(("registers", index, "stride"), f"elements of {name!r} overlap at {address:#06x}")
                    break
                if page and other_page and page[0] == other_page[0] and page[1] != other_page[1]:
                    continue
                self.error(("registers", index, "address"),
                           f"register {name!r} overlaps {other_name!r} at address {address:#06x}",
                           related=("registers", other_index, "address"), note=f"{other_name!r} is defined here")
                break
            seen.setdefault(address, []).append((name, index, page))

    # ---------------------------------------------------------------- protocol
    def check_protocol(self) -> None:
        p = self.data["protocol"]
        if p["unit_ids"]["min"] > p["unit_ids"]["max"]:
            self.error(("protocol", "unit_ids", "min"), "unit id min is greater than max")
        codes: dict[int, int] = {}
        for i, fc in enumerate(p["function_codes"]):
            if fc["code"] in codes:
                self.error(("protocol", "function_codes", i, "code"), f"function code {fc['code']:#04x} listed twice",
                           related=("protocol", "function_codes", codes[fc["code"]], "code"))
            codes.setdefault(fc["code"], i)
        excs: dict[int, int] = {}
        for i, ex in enumerate(p["exceptions"]):
            if ex["code"] in excs:
                self.error(("protocol", "exceptions", i, "code"), f"exception code {ex['code']:#04x} listed twice",
                           related=("protocol", "exceptions", excs[ex["code"]], "code"))
            excs.setdefault(ex["code"], i)
        comm = {c["code"] for c in p.get("comm_errors", [])}
        for i, ex in enumerate(p["exceptions"]):
            for c in ex.get("comm_errors", []):
                if c not in comm:
                    self.error(("protocol", "exceptions", i, "comm_errors"), f"communication error code {c:#04x} is not in protocol.comm_errors")
        for case, item in p.get("exception_policy", {}).items():
            if item.get("code") is not None and item["code"] not in excs:
                self.error(("protocol", "exception_policy", case, "code"), f"exception code {item['code']:#04x} is not in protocol.exceptions")
        for case, item in p.get("comm_error_policy", {}).items():
            if item.get("code") is not None and item["code"] not in comm:
                self.error(("protocol", "comm_error_policy", case, "code"), f"communication error code {item['code']:#04x} is not in protocol.comm_errors")
        hist = p.get("comm_error_history")
        if hist is not None and hist not in self.register_names:
            self.error(("protocol", "comm_error_history"), f"unknown register {hist!r}")
        cfg = p.get("configuration")
        if cfg:
            name = cfg["register"]
            if name not in self.register_names:
                self.error(("protocol", "configuration", "register"), f"unknown register {name!r}")
            elif "w" not in self.data["registers"][self.register_names[name]]["access"]:
                self.error(("protocol", "configuration", "register"), f"configuration register {name!r} is not writable")
        for i, port in enumerate(p["ports"]):
            for key, options in (("default_baudrate", "baudrates"), ("default_parity", "parity"), ("default_stop_bits", "stop_bits"), ("default_mode", "modes")):
                value = port.get(key)
                if value is not None and value not in port[options]:
                    self.error(("protocol", "ports", i, key), f"{key} {value!r} is not one of {options} {port[options]}")
            for mode in port["modes"]:
                if mode not in p["modes"]:
                    self.error(("protocol", "ports", i, "modes"), f"port mode {mode!r} is not in protocol.modes")
        timing = p["timing"]
        proc = timing.get("processing_ms")
        if proc and proc["min"] > proc["max"]:
            self.error(("protocol", "timing", "processing_ms", "min"), "processing_ms min is greater than max")

    def check_reserved(self) -> None:
        cells: dict[int, list[tuple[str, int, tuple[str, int] | None]]] = {}
        for address, name, index, page in self._cells():
            cells.setdefault(address, []).append((name, index, page))
        for i, item in enumerate(self.data.get("reserved", [])):
            if item["start"] > item["end"]:
                self.error(("reserved", i, "start"), "reserved range start is after its end")
                continue
            rpage = (item["page"]["selector"], item["page"]["value"]) if item.get("page") else None
            for address in range(item["start"], item["end"] + 1):
                hit = [c for c in cells.get(address, []) if not (rpage and c[2] and c[2][0] == rpage[0] and c[2][1] != rpage[1])]
                if hit:
                    name, index, _ = hit[0]
                    self.error(("reserved", i, "start"), f"reserved range overlaps register {name!r} at {address:#06x}",
                               related=("registers", index, "address"), note=f"{name!r} is defined here")
                    break

    def check_known_issues(self) -> None:
        names = set(self.register_names) | {e["name"] for e in self.data["examples"]}
        for i, issue in enumerate(self.data.get("known_issues", [])):
            for j, ref in enumerate(issue.get("affects", [])):
                base = ref.split("[")[0]
                if base not in names:
                    self.error(("known_issues", i, "affects", j), f"unknown register or example {ref!r}")

    # ---------------------------------------------------------------- examples
    def _value_ref(self, ref: str) -> bool:
        base, _, rest = ref.partition("[")
        if base not in self.register_names:
            return False
        reg = self.data["registers"][self.register_names[base]]
        count = reg.get("count", 1)
        if not rest:
            return bool(count == 1)
        try:
            index = int(rest.rstrip("]"))
        except ValueError:
            return False
        return bool(count > 1 and 0 <= index < count and rest.endswith("]"))

    def check_examples(self) -> None:
        p = self.data["protocol"]
        names: dict[str, int] = {}
        for i, ex in enumerate(self.data["examples"]):
            where: PathT = ("examples", i)
            if ex["name"] in names:
                self.error(where + ("name",), f"duplicate example name {ex['name']!r}", related=("examples", names[ex["name"]], "name"))
            names.setdefault(ex["name"], i)
            if ex["mode"] not in p["modes"]:
                self.error(where + ("mode",), f"mode {ex['mode']!r} is not in protocol.modes")
            meaning = ex["meaning"]
            for key in ("values",):
                for ref in meaning.get(key, {}):
                    if not self._value_ref(ref):
                        self.error(where + ("meaning", key, ref), f"unknown register {ref!r}", key=True)
            for ref in ex.get("preset") or {}:
                if not self._value_ref(ref):
                    self.error(where + ("preset", ref), f"unknown register {ref!r}", key=True)
            self.statuses[ex["name"]] = self.check_frames(ex, where)

    def check_frames(self, ex: dict[str, Any], where: PathT) -> str:
        mode = ex["mode"]
        erratum = ex.get("erratum") or {}
        illegible = False
        printed_wrong = False
        for part in ("request", "response"):
            text = ex.get(part)
            if text is None:
                if part == "request" and ex.get("response") is None:
                    self.error(where + (part,), "an example needs a request or a response frame")
                if part in erratum:
                    self.error(where + ("erratum", part), f"erratum corrects a {part} that is not printed")
                continue
            try:
                frame = frames.parse(text, mode)
            except frames.FrameSyntaxError as exc:
                self.error(where + (part,), f"{part}: {exc}")
                continue
            illegible = illegible or frame.illegible
            corrected = erratum.get(part)
            if frame.illegible:
                if not ex.get("illegible"):
                    self.error(where + (part,), f"{part} has illegible bytes ('?') but the example has no 'illegible' note")
            elif not frame.check_ok:
                if corrected is None:
                    want = frame.expected_check().hex(" ").upper()
                    self.error(where + (part,),
                               f"{part} checksum {frame.check.hex(' ').upper()} is wrong (computed {want}) and no erratum declares it")
                printed_wrong = True
            elif (problem := frames.structure_problem(frame, part)) is not None:
                if corrected is None:
                    self.error(where + (part,), f"{part} is not a well-formed Modbus frame: {problem}; declare an erratum")
                printed_wrong = True
            if corrected is not None:
                try:
                    fixed = frames.parse(corrected, mode)
                except frames.FrameSyntaxError as exc:
                    self.error(where + ("erratum", part), f"corrected {part}: {exc}")
                    continue
                if fixed.illegible:
                    self.error(where + ("erratum", part), f"corrected {part} may not contain '?'")
                elif not fixed.check_ok:
                    want = fixed.expected_check().hex(" ").upper()
                    self.error(where + ("erratum", part), f"corrected {part} checksum is wrong too (computed {want})")
                elif fixed.wire() == frame.wire() and not frame.illegible:
                    self.error(where + ("erratum", part), f"corrected {part} is the same as the printed one")
                elif (problem := frames.structure_problem(fixed, part)) is not None:
                    self.error(where + ("erratum", part), f"corrected {part} is not a well-formed Modbus frame: {problem}")
                else:
                    printed_wrong = True
                self.check_meaning(ex, where, fixed, part)
            elif not frame.illegible and frame.check_ok:
                self.check_meaning(ex, where, frame, part)
        if erratum and not printed_wrong and not illegible:
            self.error(where + ("erratum",), "declared erratum, but the printed frames are correct")
        if erratum and not (set(erratum) - {"reason"}):
            self.error(where + ("erratum",), "an erratum gives a corrected request or response")
        if illegible:
            return "illegible"
        return "erratum" if erratum else "verified"

    def check_meaning(self, ex: dict[str, Any], where: PathT, frame: frames.Frame, part: str) -> None:
        meaning = ex["meaning"]
        unit, fc = frame.body[0], frame.body[1] if len(frame.body) > 1 else -1
        if unit != meaning["unit"]:
            self.error(where + (part,), f"{part} is addressed to unit {unit} but meaning.unit is {meaning['unit']}")
        allowed = OPERATION_CODES[meaning["operation"]]
        base_fc = fc & 0x7F
        if base_fc not in allowed:
            self.error(where + (part,), f"{part} has function {fc:#04x}, not a {meaning['operation']} function")
        if part == "response" and fc & 0x80:
            code = frame.body[2] if len(frame.body) > 2 else None
            if meaning.get("exception") != code:
                self.error(where + ("meaning", "exception"), f"response carries exception code {code:#04x} but meaning.exception is {meaning.get('exception')}")
        elif part == "response" and meaning.get("exception") is not None:
            self.error(where + ("meaning", "exception"), "meaning.exception is set but the response is a normal reply")
        if part == "request" and meaning.get("address") is not None and base_fc in (3, 4, 6, 16) and len(frame.body) >= 4:
            address = int.from_bytes(frame.body[2:4], "big")
            if address != meaning["address"]:
                self.error(where + ("meaning", "address"), f"request addresses {address:#06x} but meaning.address is {meaning['address']:#06x}")
        if meaning.get("broadcast") and unit != self.data["protocol"].get("broadcast_address"):
            self.error(where + ("meaning", "broadcast"), "a broadcast example must address the broadcast unit")


def check(doc: Document) -> tuple[list[Diagnostic], dict[str, str]]:
    """Run every semantic check; returns diagnostics and each example's status."""
    checker = Checker(doc)
    return checker.run(), checker.statuses
