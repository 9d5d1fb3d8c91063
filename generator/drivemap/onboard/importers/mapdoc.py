"""A map document built from facts another source states, rendered as YAML that validates as written.

Shared by ``drivemap import`` and ``drivemap probe``. The header carries only what the source says:
every protocol fact it does not give is ``null`` (or an empty list) and listed for review, never a
guessed default. :func:`write_map` validates the text under the name it will have, then writes it
atomically; an existing file is replaced only with ``force``.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.formats import CURRENT
from drivemap.frontend.project import display

__all__ = ["MapDoc", "Review", "safe", "snake", "unique_name", "upper", "write_map"]

CODE_NAMES = {1: "Read Coils", 2: "Read Discrete Inputs", 3: "Read Holding Registers", 4: "Read Input Registers",
              5: "Write Single Coil", 6: "Write Single Register", 15: "Write Multiple Coils",
              16: "Write Multiple Registers"}
TABLE_CODES = {"coil": 1, "discrete": 2, "holding": 3, "input": 4}
#: Write function codes per table; a writable register without a stated one gets the last (multiple).
WRITE_CODES = {"coil": (5, 15), "holding": (6, 16), "discrete": (), "input": ()}


def snake(text: str, fallback: str = "register") -> str:
    """A lower-case identifier from free text ("Phase 1 volts" -> ``phase_1_volts``)."""
    out = re.sub(r"[^a-z0-9]+", "_", re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", text).lower()).strip("_")
    if not out:
        out = fallback
    if not out[0].isalpha():
        out = f"{fallback}_{out}"
    return out[:56].rstrip("_")  # room for a _N suffix under the schema's 64


def safe(text: str) -> str:
    """A register name from ``text`` that the compiler accepts, renamed as ``draft`` renames
    (:func:`drivemap.onboard.naming.register_name`: a keyword + ``_value``, a client attribute such
    as ``self`` or a builtin the generated classes use + ``_reg``)."""
    from drivemap.onboard.naming import register_name

    return register_name(snake(text))


def upper(text: str, fallback: str = "VALUE") -> str:
    return snake(text, fallback.lower()).upper()


def camel(text: str) -> str:
    return "".join(part.capitalize() for part in snake(text, "enum").split("_"))


def unique_name(name: str, taken: set[str]) -> str:
    candidate, n = name, 2
    while candidate in taken:
        candidate, n = f"{name}_{n}", n + 1
    taken.add(candidate)
    return candidate


@dataclass
class Review:
    """What the source did not state (per register) and what was left out (and why)."""

    missing: dict[str, list[str]] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def miss(self, name: str, *facts: str) -> None:
        if facts:
            self.missing.setdefault(name, []).extend(facts)

    def lines(self) -> list[str]:
        out = [f"  {name}: {', '.join(facts)}" for name, facts in self.missing.items()]
        out += [f"  skipped: {why}" for why in self.skipped]
        out += [f"  note: {text}" for text in self.notes]
        return out


@dataclass
class MapDoc:
    """A map under construction: header facts, groups, enums and registers in schema form."""

    model: str
    title: str
    source: str
    manual_file: str
    modes: list[str] = field(default_factory=lambda: ["tcp"])
    vendor: str | None = None
    unit_min: int = 1
    unit_max: int = 247
    unit_source: str | None = None
    groups: dict[str, str] = field(default_factory=dict)
    enums: dict[str, dict[str, Any]] = field(default_factory=dict)
    registers: list[dict[str, Any]] = field(default_factory=list)
    max_quantity: dict[int, int | None] = field(default_factory=dict)
    review: Review = field(default_factory=Review)
    notes: str = ""
    #: a serial port the source states (replaces the placeholder port), timing facts it states
    port: dict[str, Any] | None = None
    timing: dict[str, Any] = field(default_factory=dict)
    #: address ranges the source says read (as 0) but names nothing at
    reserved: list[dict[str, Any]] = field(default_factory=list)
    #: the broadcast unit id the source states (pymodbus-sim's broadcast_enable: 0)
    broadcast_address: int | None = None
    #: a whole protocol section the source states (drivemap's JSON export), used as it is
    protocol: dict[str, Any] | None = None
    known_issues: list[dict[str, Any]] = field(default_factory=list)
    identity: list[dict[str, Any]] = field(default_factory=list)
    examples: list[dict[str, Any]] = field(default_factory=list)
    #: device.evidence / device.origin / device.kind (an import from another project's definitions)
    evidence: str | None = None
    origin: dict[str, str] | None = None
    kind: str | None = None
    _names: set[str] = field(default_factory=set)
    _next: dict[str, int] = field(default_factory=dict)

    def name(self, wanted: str) -> str:
        """A unique register name (see :func:`safe`): the name, else ``name_2``, ``name_3`` ... (counted
        per name, so a name repeated n times costs n steps, not n squared)."""
        name = safe(wanted)
        candidate, n = name, self._next.get(name, 2)
        while candidate in self._names:
            candidate, n = f"{name}_{n}", n + 1
        self._next[name] = n
        self._names.add(candidate)
        return candidate

    def claim(self, name: str) -> None:
        """Mark ``name`` as taken (a register named by the source itself), so :meth:`name` never repeats it."""
        self._names.add(name)

    def taken(self, name: str) -> bool:
        return name in self._names

    def group(self, name: str, title: str | None = None) -> str:
        """A group; its title gets " (group)" where the docs page has a fixed heading of that anchor."""
        from drivemap.vocab.escape import slug
        from drivemap.vocab.reserved import reserved

        key = snake(name, "group")
        if key not in self.groups:
            text = title or name
            taken = reserved().headings | {slug(t) for t in self.groups.values()}
            self.groups[key] = f"{text} (group {key})" if slug(text) in taken else text
        return key

    def enum(self, wanted: str, values: list[tuple[int, str]]) -> str:
        """An enum of (value, label) pairs; its value names come from the labels."""
        names: set[str] = set()
        rows = [{"value": v, "name": unique_name(upper(label, f"value_{v}"), names), "label": label}
                for v, label in values]
        return self.enum_rows(wanted, rows)

    def enum_rows(self, wanted: str, rows: list[dict[str, Any]]) -> str:
        """An enum of schema rows (value, name, label); the same rows under the same name are one enum."""
        key = camel(wanted)
        existing = self.enums.get(key)
        if existing is not None and existing["values"] == rows:
            return key
        n = 2
        base = key
        while key in self.enums:
            key, n = f"{base}{n}", n + 1
        self.enums[key] = {"values": rows, "source": self.source}
        return key

    def enum_named(self, name: str, values: list[tuple[int, str]]) -> str:
        """An enum the source names (its value names from the labels); the same name twice must agree."""
        names: set[str] = set()
        rows = [{"value": v, "name": unique_name(upper(label, f"value_{v}"), names), "label": label}
                for v, label in values]
        existing = self.enums.get(name)
        if existing is not None and existing["values"] != rows:
            raise ValueError(f"enum {name} is given twice with different values")
        self.enums[name] = {"values": rows, "source": self.source}
        return name

    def add(self, register: dict[str, Any]) -> None:
        table = register.get("table", "holding")
        self.max_quantity.setdefault(TABLE_CODES[table], None)
        if "w" in register.get("access", "") and not any(c in self.max_quantity for c in WRITE_CODES[table]):
            self.max_quantity[WRITE_CODES[table][-1]] = None
        self.registers.append(register)

    # -- rendering
    def data(self) -> dict[str, Any]:
        codes = sorted(self.max_quantity) or [3]
        doc: dict[str, Any] = {
            "drivemap": CURRENT,
            "device": {
                "model": self.model, "title": self.title, "vendor": self.vendor,
                "manual": {"file": self.manual_file, "document": None, "revision": None, "date": None,
                           "language": "und"},
                "coverage": f"What {self.source} states; every other fact is null and listed for review.",
                "source": self.source,
            },
            "protocol": self.protocol or self._protocol(codes),
        }
        if self.notes:
            doc["device"]["notes"] = self.notes
        for key in ("evidence", "origin", "kind"):
            if getattr(self, key) is not None:
                doc["device"][key] = getattr(self, key)
        if self.enums:
            doc["enums"] = self.enums
        doc["groups"] = [{"name": k, "title": v, "source": self.source} for k, v in self.groups.items()]
        doc["registers"] = self.registers
        if self.reserved:
            doc["reserved"] = self.reserved
        for key in ("known_issues", "identity"):
            if getattr(self, key):
                doc[key] = getattr(self, key)
        doc["examples"] = self.examples
        return doc

    def _protocol(self, codes: list[int]) -> dict[str, Any]:
        return {
            "modes": list(dict.fromkeys([*self.modes, *(self.port["modes"] if self.port else ["rtu"])])),
            "unit_ids": {"min": self.unit_min, "max": self.unit_max, "source": self.unit_source or self.source,
                         "notes": "" if self.unit_source else "Not stated by the source: the Modbus range 1-247."},
            "broadcast_address": self.broadcast_address,
            "ports": [self.port or self._placeholder_port()],
            "function_codes": [{"code": c, "name": CODE_NAMES[c], "max_quantity": self.max_quantity.get(c),
                                "broadcast": None, "broadcast_reason": "not stated by the source",
                                "source": self.source} for c in codes],
            "exceptions": [],
            "timing": {"silent_interval_chars": None, "response_timeout_ms": None, "retries": None,
                       **self.timing, "source": self.source},
            "source": self.source,
        }

    def _placeholder_port(self) -> dict[str, Any]:
        return {"name": "serial", "modes": ["rtu"], "default_mode": None, "baudrates": [], "default_baudrate": None,
                "parity": [], "default_parity": None, "data_bits": [], "stop_bits": [], "default_stop_bits": None,
                "set_by": "unknown", "source": self.source,
                "notes": "Serial settings are not stated by the source. The map schema needs one serial port, so "
                         "this entry (and 'rtu' in modes) is a placeholder until the manual says more."}

    def text(self) -> str:
        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
        body = yaml.dump(self.data(), Dumper=dumper, sort_keys=False, allow_unicode=True, width=110,
                         default_flow_style=False)
        return f"# drivemap map written from {self.source}; review every null before use.\n{body}"


def validate_text(text: str, shown: str) -> None:
    """Compile ``text`` as the map ``shown`` (load, schema, checks); raise CompileError."""
    from drivemap.frontend import checks, schema
    from drivemap.frontend.load import load_text

    doc = load_text(text, shown)
    errors = schema.validate(doc)
    if errors:
        raise CompileError(errors)
    problems, _ = checks.check(doc)
    if problems:
        raise CompileError(problems)


def model_id(given: str | None, output: str | None, default: str) -> str:
    """The map's model id: ``--model``, else the ``-o`` file's name, else ``default`` (a located error if
    it is not a lower-case identifier or does not match the file name)."""
    from drivemap.device.target import locate_error

    model = given or (Path(output).stem if output else default)
    if snake(model) != model:
        token = given or output or model
        raise locate_error(token, f"model id {model!r} must be a lower-case identifier, e.g. {snake(model)}")
    if output and Path(output).stem != model:
        raise locate_error(given or model, f"--model {model} differs from the file name {Path(output).name}: "
                                           f"a map's file is named after its model id")
    return model


def target_path(output: str | None, model: str, maps_folder: Path) -> Path:
    return Path(output) if output else maps_folder / f"{model}.yaml"


def write_map(doc: MapDoc, target: Path, *, force: bool) -> None:
    """Validate the map as ``target``, then write it atomically (an existing file only with ``force``)."""
    shown = display(target)
    if target.is_dir():
        raise CompileError([Diagnostic(Location(shown, 1, 1), "is a folder; give a file name (-o maps/ID.yaml)")])
    if os.path.lexists(target) and not force:
        raise CompileError([Diagnostic(Location(shown, 1, 1), "file exists; not overwritten (pass --force)")])
    if target.suffix not in (".yaml", ".yml"):
        raise CompileError([Diagnostic(Location(shown, 1, 1), "a map file name ends in .yaml")])
    if target.stem != doc.model:
        raise CompileError([Diagnostic(Location(shown, 1, 1),
                                       f"the file name must be the model id: {doc.model}.yaml (or pass --model "
                                       f"{snake(target.stem)})")])
    text = doc.text()
    try:
        validate_text(text, shown)
    except CompileError as exc:
        raise CompileError([*exc.diagnostics, Diagnostic(Location(shown, 1, 1), (
            "not written: the map built from the source does not validate (the errors above point into it); "
            "fix the source or report it"))]) from None
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=".drivemap-tmp-")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
