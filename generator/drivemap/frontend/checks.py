"""Semantic checks on a document that passed the schema.

Each check reports a located :class:`Diagnostic`; all of a file's errors are collected in one run.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from drivemap.diagnostics import Diagnostic
from drivemap.frontend import checks_identity, examplevalues, frames
from drivemap.frontend.checks_registers import RegisterChecks, table_name
from drivemap.frontend.checks_rules import check_rules
from drivemap.frontend.load import Document, PathT
from drivemap.model.nodes import camel, is_keyword

OPERATION_CODES = {"read": (1, 2, 3, 4), "write": (5, 6), "write_multiple": (15, 16), "loopback": (8,)}
#: The table each function code addresses.
FUNCTION_TABLES = {0x01: "coil", 0x02: "discrete", 0x03: "holding", 0x04: "input", 0x05: "coil", 0x06: "holding",
                   0x0F: "coil", 0x10: "holding"}


class Checker(RegisterChecks):
    def __init__(self, doc: Document) -> None:
        super().__init__(doc)
        self.statuses: dict[str, str] = {}

    # --------------------------------------------------------------------- all
    def run(self) -> list[Diagnostic]:
        self.check_device()
        self.check_enums()
        self.check_registers()
        check_rules(self)
        self.check_protocol()
        self.check_reserved()
        self.check_known_issues()
        self.check_examples()
        self.check_running()
        self.check_reserved_pages()
        self.check_example_values()
        self.check_identity()
        return self.diagnostics

    def check_identity(self) -> None:
        """The map's identity checks (:mod:`.checks_identity`)."""
        tables = {r.get("name"): self.table_of(i) for i, r in enumerate(self.data.get("registers", ()))}
        for where, message in checks_identity.problems(self.data, tables):
            self.error(where, message)

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
            classes[name] = ("enums", name)
        for i, reg in enumerate(self.data["registers"]):
            if reg.get("bits"):
                cls = reg.get("flags_name") or camel(reg["name"])
                where: PathT = ("registers", i, "flags_name" if reg.get("flags_name") else "name")
                if cls in classes:
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
            elif name.startswith("_") or "__" in name:
                self.error(where + ("name",), f"register name {name!r} may not start with or contain '__'")
            if reg["group"] not in groups:
                self.error(where + ("group",), f"unknown group {reg['group']!r} (define it under groups)")
            self.locate(i, reg)
            self.check_register_values(i, reg)
        self.check_overlaps()
        for i, reg in enumerate(regs):
            page = reg.get("page")
            if page:
                sel = page["selector"]
                if sel not in self.register_names:
                    self.error(("registers", i, "page", "selector"), f"page selector {sel!r} is not a register")
                elif sel == reg["name"]:
                    self.error(("registers", i, "page", "selector"), "a register cannot select its own page")
                else:
                    self.check_page_value(regs[self.register_names[sel]], page["value"], ("registers", i, "page", "value"))
        self.check_scale_registers()
        self.check_read_blocks()
        self.check_table_functions()

    def check_page_value(self, selector: dict[str, Any], value: Any, where: PathT) -> None:
        """A page's value is one the selector can hold: a value of its enum, when it has one."""
        enum = (self.data.get("enums") or {}).get(selector.get("enum") or "")
        if enum and value not in {v.get("value") for v in enum.get("values", [])}:
            names = ", ".join(str(v.get("value")) for v in enum.get("values", []))
            self.error(where, f"page value {value!r} is not a value of the selector's enum {selector['enum']} ({names})")

    def check_running(self) -> None:
        """protocol.running_state names a readable register; running_advice.instead a writable one."""
        regs = self.data["registers"]
        state = self.data["protocol"].get("running_state")
        if state:
            name = state["register"]
            if name not in self.register_names:
                self.error(("protocol", "running_state", "register"), f"unknown register {name!r}")
            elif "r" not in regs[self.register_names[name]].get("access", "r"):
                self.error(("protocol", "running_state", "register"), f"running_state register {name!r} is not readable")
        for i, reg in enumerate(regs):
            instead = (reg.get("running_advice") or {}).get("instead")
            if instead is None:
                continue
            if instead not in self.register_names:
                self.error(("registers", i, "running_advice", "instead"), f"unknown register {instead!r}")
            elif "w" not in regs[self.register_names[instead]].get("access", "r"):
                self.error(("registers", i, "running_advice", "instead"), f"register {instead!r} is not writable")

    # ---------------------------------------------------------------- protocol
    def check_protocol(self) -> None:
        p = self.data["protocol"]
        if p["unit_ids"]["min"] > p["unit_ids"]["max"]:
            self.error(("protocol", "unit_ids", "min"), "unit id min is greater than max")
        self._unique_codes(p["function_codes"], "function_codes", "function code")
        excs = self._unique_codes(p["exceptions"], "exceptions", "exception code")
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
        self._protocol_registers(p)
        self._ports(p)
        proc = p["timing"].get("processing_ms")
        if proc and proc["min"] > proc["max"]:
            self.error(("protocol", "timing", "processing_ms", "min"), "processing_ms min is greater than max")

    def _unique_codes(self, items: list[dict[str, Any]], key: str, what: str) -> dict[int, int]:
        """Each item's ``code`` once in ``protocol.<key>``; the index of each code's first item."""
        first: dict[int, int] = {}
        for i, item in enumerate(items):
            if item["code"] in first:
                self.error(("protocol", key, i, "code"), f"{what} {item['code']:#04x} listed twice",
                           related=("protocol", key, first[item["code"]], "code"))
            first.setdefault(item["code"], i)
        return first

    def _protocol_registers(self, p: dict[str, Any]) -> None:
        """The registers the protocol names (communication error history, the configuration command)."""
        hist = p.get("comm_error_history")
        if hist is not None and hist not in self.register_names:
            self.error(("protocol", "comm_error_history"), f"unknown register {hist!r}")
        cfg = p.get("configuration")
        if cfg:
            name = cfg["register"]
            if name not in self.register_names:
                self.error(("protocol", "configuration", "register"), f"unknown register {name!r}")
            elif "w" not in self.data["registers"][self.register_names[name]].get("access", "r"):
                self.error(("protocol", "configuration", "register"), f"configuration register {name!r} is not writable")

    def _ports(self, p: dict[str, Any]) -> None:
        for i, port in enumerate(p["ports"]):
            for key, options in (("default_baudrate", "baudrates"), ("default_parity", "parity"), ("default_stop_bits", "stop_bits"), ("default_mode", "modes")):
                value = port.get(key)
                if value is not None and value not in port[options]:
                    self.error(("protocol", "ports", i, key), f"{key} {value!r} is not one of {options} {port[options]}")
            for mode in port["modes"]:
                if mode not in p["modes"]:
                    self.error(("protocol", "ports", i, "modes"), f"port mode {mode!r} is not in protocol.modes")

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
            for ref, value in meaning.get("values", {}).items():
                if not self._value_ref(ref):
                    self.error(where + ("meaning", "values", ref), f"unknown register {ref!r}", key=True)
                else:
                    self.check_value_type(where + ("meaning", "values", ref), ref, value)
            for ref, value in (ex.get("preset") or {}).items():
                if not self._value_ref(ref):
                    self.error(where + ("preset", ref), f"unknown register {ref!r}", key=True)
                else:
                    self.check_value_type(where + ("preset", ref), ref, value)
            self.statuses[ex["name"]] = self.check_frames(ex, where)

    def check_value_type(self, where: PathT, ref: str, value: Any) -> None:
        """An example's value fits its register: text for strings, true/false for bools, null only where
        the register lists not_available values, a number otherwise."""
        index = self.register_names[ref.partition("[")[0]]
        reg = self.data["registers"][index]
        rtype = self.type_of(index)
        if value is None:
            if not reg.get("not_available"):
                self.error(where, f"{ref} is null, but the register lists no not_available values")
        elif rtype == "string":
            if not isinstance(value, str):
                self.error(where, f"{ref} is a string register: its value is text")
        elif rtype == "bool":
            if isinstance(value, str) or value not in (0, 1):
                self.error(where, f"{ref} is a bool register: its value is true or false")
        elif isinstance(value, (bool, str)):
            self.error(where, f"{ref} is a {rtype} register: its value is a number")

    def check_frames(self, ex: dict[str, Any], where: PathT) -> str:
        erratum = ex.get("erratum") or {}
        illegible = False
        printed_wrong = False
        for part in ("request", "response"):
            unreadable, wrong = self._check_part(ex, where, part, erratum)
            illegible = illegible or unreadable
            printed_wrong = printed_wrong or wrong
        if erratum and not printed_wrong and not illegible:
            self.error(where + ("erratum",), "declared erratum, but the printed frames are correct")
        if erratum and not (set(erratum) - {"reason"}):
            self.error(where + ("erratum",), "an erratum gives a corrected request or response")
        if illegible:
            return "illegible"
        return "erratum" if erratum else "verified"

    def _check_part(self, ex: dict[str, Any], where: PathT, part: str, erratum: dict[str, Any]) -> tuple[bool, bool]:
        """One printed frame (request or response) and its correction: (illegible, printed wrong)."""
        text = ex.get(part)
        if text is None:
            if part == "request" and ex.get("response") is None:
                self.error(where + (part,), "an example needs a request or a response frame")
            if part in erratum:
                self.error(where + ("erratum", part), f"erratum corrects a {part} that is not printed")
            return False, False
        try:
            frame = frames.parse(text, ex["mode"])
        except frames.FrameSyntaxError as exc:
            self.error(where + (part,), f"{part}: {exc}")
            return False, False
        corrected = erratum.get(part)
        printed_wrong = False
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
            printed_wrong = self._check_correction(ex, where, part, frame, corrected) or printed_wrong
        elif not frame.illegible and frame.check_ok:
            self.check_meaning(ex, where, frame, part)
        return frame.illegible, printed_wrong

    def _check_correction(self, ex: dict[str, Any], where: PathT, part: str, frame: frames.Frame,
                          corrected: str) -> bool:
        """An erratum's corrected frame; True when it is a real correction of a printed frame."""
        try:
            fixed = frames.parse(corrected, ex["mode"])
        except frames.FrameSyntaxError as exc:
            self.error(where + ("erratum", part), f"corrected {part}: {exc}")
            return False
        real = False
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
            real = True
        self.check_meaning(ex, where, fixed, part)
        return real

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
        if part == "request" and meaning.get("address") is not None and base_fc in FUNCTION_TABLES and len(frame.body) >= 4:
            address = int.from_bytes(frame.body[2:4], "big")
            if address != meaning["address"]:
                self.error(where + ("meaning", "address"), f"request addresses {address:#06x} but meaning.address is {meaning['address']:#06x}")
        table = FUNCTION_TABLES.get(base_fc)
        for ref in meaning.get("values", {}) if table is not None and part == "request" else ():
            index = self.register_names.get(ref.partition("[")[0])
            if index is not None and index in self.locations and self.locations[index][0] != table:
                self.error(where + ("meaning", "values", ref), f"{ref} is {table_name(self.locations[index][0])} "
                           f"register, but function {base_fc:#04x} addresses the {table} table", key=True)
        if meaning.get("broadcast") and unit != self.data["protocol"].get("broadcast_address"):
            self.error(where + ("meaning", "broadcast"), "a broadcast example must address the broadcast unit")
        if part == "request" and unit == 0 and meaning["operation"] == "read":
            self.error(where + (part,), "a read addressed to the broadcast unit 0 gets no reply: an example of "
                                        "one cannot be verified (address the device's unit id)")


def check(doc: Document) -> tuple[list[Diagnostic], dict[str, str]]:
    """Run every semantic check; returns diagnostics and each example's status."""
    checker = Checker(doc)
    return checker.run(), checker.statuses


def located(doc: Document, problems: Iterable[tuple[PathT, str, dict[str, Any]]]) -> list[Diagnostic]:
    """Problems found at paths of ``doc`` (an exporter's ``validate`` hook gives them) as diagnostics.

    The options are those of :meth:`CheckerBase.error`: ``key``, ``related``, ``note``, ``related_key``.
    """
    checker = Checker(doc)
    for where, message, options in problems:
        checker.error(where, message, **options)
    return checker.diagnostics
