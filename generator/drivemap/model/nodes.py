"""The immutable, typed model every template and the runtime read.

Built from a document that passed the schema and the semantic checks (:mod:`checks`), so
constructors here trust their input. Everything is frozen; collections are tuples. A node that
describes what the runtime describes extends the runtime's class (:mod:`drivemap.runtime.spec`)
with compile-time facts only; :func:`drivemap.model.spec.project` gives its runtime part.
"""

from __future__ import annotations

import keyword
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal, cast

from drivemap.model import modicon
from drivemap.model.family import IdentityCheck, Variant
from drivemap.model.modicon import Table
from drivemap.model.protocol import (
    Checksum,
    CommandSpec,
    CommError,
    Device,
    ExceptionCode,
    FunctionCode,
    LengthRange,
    LrcExample,
    Manual,
    PolicyCase,
    Port,
    PortSetting,
    Protocol,
    ReplyQuirk,
    RunningAdvice,
    RunningState,
    Timing,
)
from drivemap.model.rules import Alignment, AllowedValue
from drivemap.model.source import SourceRef
from drivemap.runtime.names import camel
from drivemap.runtime.spec import (
    BIT_TABLES,
    FLOAT_TYPES,
    READ_CODES,
    SIGNED_TYPES,
    TYPE_WORDS,
    BitSpec,
    DeviceSpec,
    EnumMemberSpec,
    EnumSpec,
    PageSpec,
    RegisterSpec,
    ReservedSpec,
    type_words,
)
from drivemap.runtime.types import TYPE_BOUNDS as _INTEGER_BOUNDS

Access = Literal["r", "w", "rw"]
RegType = Literal["u16", "s16", "u32", "s32", "u64", "s64", "f32", "f64", "string", "bool"]
Mode = Literal["rtu", "ascii", "tcp"]
Status = Literal["verified", "erratum", "illegible"]
#: An example's or a default's value: a number, true/false (bool registers), text (strings) or None.
Value = float | str | None

#: Raw bounds of the integer types (the runtime's table) and of a bool in a bit table.
TYPE_BOUNDS: dict[str, tuple[int, int]] = {**_INTEGER_BOUNDS, "bool": (0, 1)}
#: TYPE_WORDS, SIGNED_TYPES, FLOAT_TYPES, BIT_TABLES, READ_CODES and type_words are the runtime's tables
#: (:mod:`drivemap.runtime.spec`), re-exported here.
INTEGER_TYPES = frozenset({"u16", "s16", "u32", "s32", "u64", "s64"})
#: Largest finite magnitude of each float type.
FLOAT_MAX: dict[str, float] = {"f32": 3.4028234663852886e38, "f64": 1.7976931348623157e308}


def default_type(table: str) -> RegType:
    """The type a register has when the map gives none: bool in bit tables, else u16."""
    return "bool" if table in BIT_TABLES else "u16"


def raw_bounds(rtype: str, table: str, length: int = 1) -> tuple[int, int]:
    """Bounds of a register's raw value: integers signed for s16/s32/s64; floats and strings as their
    unsigned bit patterns; a bool is one bit in a bit table, a whole word in a register."""
    if rtype in TYPE_BOUNDS and not (rtype == "bool" and table not in BIT_TABLES):
        return TYPE_BOUNDS[rtype]
    return 0, (1 << (16 * type_words(rtype, length))) - 1


def normalize_raw(rtype: str, table: str, length: int, value: int) -> int | None:
    """A raw value given as printed (``0x8000`` or ``-32768`` for an s16) as the register's raw value;
    None when it fits neither form."""
    lo, hi = raw_bounds(rtype, table, length)
    if lo <= value <= hi:
        return value
    bits = 16 * type_words(rtype, length)
    if rtype in SIGNED_TYPES and (1 << (bits - 1)) <= value < (1 << bits):
        return value - (1 << bits)
    return None


def is_keyword(name: str) -> bool:
    return keyword.iskeyword(name) or keyword.issoftkeyword(name)


@dataclass(frozen=True)
class EnumValue(EnumMemberSpec):
    """A member of an enum: the runtime's :class:`EnumMemberSpec` and the map's notes."""

    notes: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Enum(EnumSpec):
    """A named set of values: the runtime's :class:`EnumSpec` whose members keep their notes."""

    members: tuple[EnumValue, ...]
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Bit(BitSpec):
    """A bit field of a register: the runtime's :class:`BitSpec` and the map's notes."""

    notes: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


#: A register's page (selector register and value): the runtime's class as it is.
Page = PageSpec


@dataclass(frozen=True)
class Group:
    name: str
    title: str
    source: str
    notes: str | None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True, kw_only=True)
class Register(RegisterSpec):
    """One register, or one array of registers (``count`` > 1): the runtime's :class:`RegisterSpec`
    (numbers as ints when whole) and what the map says for people and for the compiler.

    ``value_set``, ``advice`` and ``flags_name`` are the map's richer forms of the runtime's
    ``values``, ``running_advice`` and ``bits_class``, which are derived from them."""

    type: RegType = "u16"
    access: Access = "rw"
    table: Table = "holding"
    bits: tuple[Bit, ...] = ()
    param_rule: str | None = None
    label: str | None = None
    description: str | None = None
    group: str
    flags_name: str | None = None
    element_params: tuple[str, ...] = ()
    notes: str | None = None
    modicon_given: str | None = None
    """The Modicon number as the map gives it (``register:``), else None."""
    line: int = 0
    advice: RunningAdvice | None = None
    """The manual's advice for writes while the drive runs (``running_advice:``)."""
    #: each element's parameter id by rule: {index} / {address} (decimal), e.g. "P_{address}"
    element_param_format: str | None = None
    #: the value set (``values:``): the only values a write may send, with their notes
    value_set: tuple[AllowedValue, ...] = ()
    values: tuple[tuple[float | str, str | None], ...] = field(init=False, default=())
    running_advice: str | None = field(init=False, default=None)
    bits_class: str | None = field(init=False, default=None)
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "values", tuple((v.value, v.label) for v in self.value_set))
        object.__setattr__(self, "running_advice", self.advice.text() if self.advice else None)
        object.__setattr__(self, "bits_class", (self.flags_name or camel(self.name)) if self.bits else None)

    @property
    def is_float(self) -> bool:
        return self.type in FLOAT_TYPES

    @property
    def optional(self) -> bool:
        """Whether the client may read None (the map lists not_available values)."""
        return bool(self.not_available)

    @property
    def modicon(self) -> str:
        """The Modicon number of the register (of element 0 for arrays)."""
        return modicon.number(self.table, self.address)

    @property
    def multibit(self) -> bool:
        return any(b.width > 1 for b in self.bits)

    @property
    def is_integer(self) -> bool:
        """Engineering values are ints: an integer type whose scale and offset are whole numbers and
        that has no scale register."""
        return (self.type in INTEGER_TYPES and self.scale_register is None and float(self.scale).is_integer()
                and float(self.offset).is_integer())

    def element_param(self, index: int) -> str | None:
        if self.element_params:
            return self.element_params[index]
        if self.element_param_format is not None:
            return self.element_param_format.format(index=index, address=self.element_address(index))
        return self.param if index == 0 else None

    def raw_bounds(self) -> tuple[int, int]:
        return raw_bounds(self.type, self.table, self.length)

    def cells(self) -> Iterator[Cell]:
        for i in range(self.count):
            yield Cell(self, i)


@dataclass(frozen=True)
class Cell:
    """One element of a register (the register itself when it is not an array)."""

    register: Register
    index: int

    @property
    def name(self) -> str:
        return self.register.element_name(self.index)

    @property
    def address(self) -> int:
        return self.register.element_address(self.index)

    @property
    def addresses(self) -> range:
        return range(self.address, self.address + self.register.words)


@dataclass(frozen=True, kw_only=True)
class Reserved(ReservedSpec):
    """A reserved block: the runtime's :class:`ReservedSpec` and what the map says of it."""

    writable: bool
    source: str
    notes: str | None
    #: reserved (marked by the manual) / unlabeled (listed without a name) / not_listed
    kind: str = "reserved"
    table: Table = "holding"
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class KnownIssue:
    title: str
    source: str
    printed: str
    corrected: str | None
    chosen: str
    reason: str
    affects: tuple[str, ...]
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Meaning:
    unit: int
    operation: str
    address: int | None
    quantity: int | None
    values: tuple[tuple[str, Value], ...]
    raw: tuple[int, ...]
    loopback: tuple[int, ...]
    exception: int | None
    broadcast: bool


@dataclass(frozen=True)
class Example:
    name: str
    title: str | None
    source: str
    mode: Literal["rtu", "ascii"]
    request: str | None
    response: str | None
    meaning: Meaning
    preset: tuple[tuple[str, Value], ...]
    inject_exception: int | None
    corrected_request: str | None
    corrected_response: str | None
    erratum: str | None
    illegible: str | None
    notes: str | None
    status: Status
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    @property
    def wire_request(self) -> str | None:
        """The frame as it really is on the line: corrected where an erratum says so."""
        return self.corrected_request if self.corrected_request is not None else self.request

    @property
    def wire_response(self) -> str | None:
        return self.corrected_response if self.corrected_response is not None else self.response


@dataclass(frozen=True, kw_only=True)
class Model(DeviceSpec):
    """A compiled map: the runtime's :class:`DeviceSpec` (device, protocol, registers, reserved, identity,
    enums, each node extending its runtime class) with the map's groups, known issues and examples."""

    path: str
    device: Device
    protocol: Protocol
    enums: tuple[Enum, ...]
    groups: tuple[Group, ...]
    registers: tuple[Register, ...]
    reserved: tuple[Reserved, ...]
    known_issues: tuple[KnownIssue, ...]
    examples: tuple[Example, ...]
    #: the map's format (``drivemap:``); a format-1 map is read with frontend.formats' defaults
    format_version: int = 2
    identity: tuple[IdentityCheck, ...] = ()
    #: set when the map extends another (model.family)
    variant: Variant | None = None
    #: the compile cache's key of everything this model was compiled from (None: not from compile_cached)
    cache_key: str | None = field(default=None, compare=False, repr=False)
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def register(self, name: str) -> Register:
        """The register ``name`` (the runtime's index, built on first use, so a replaced model indexes its own)."""
        return cast(Register, super().register(name))

    def enum(self, name: str) -> Enum:
        for item in self.enums:
            if item.name == name:
                return item
        raise KeyError(name)

    def cells(self) -> Iterator[Cell]:
        for reg in self.registers:
            yield from reg.cells()

    def cell(self, name: str) -> Cell:
        """``digital_speed[3]`` or ``motor_state``."""
        base, _, rest = name.partition("[")
        reg = self.register(base)
        index = int(rest.rstrip("]")) if rest else 0
        if not 0 <= index < reg.count or (rest == "") == reg.is_array:
            raise KeyError(name)
        return Cell(reg, index)

    def group_registers(self, group: str) -> tuple[Register, ...]:
        return tuple(r for r in self.registers if r.group == group)

    def status_counts(self) -> dict[str, int]:
        counts = {"verified": 0, "erratum": 0, "illegible": 0}
        for ex in self.examples:
            counts[ex.status] += 1
        return counts


__all__ = [
    "Access",
    "Alignment",
    "AllowedValue",
    "BIT_TABLES",
    "Bit",
    "Cell",
    "Checksum",
    "CommError",
    "CommandSpec",
    "Device",
    "Enum",
    "EnumValue",
    "Example",
    "ExceptionCode",
    "FLOAT_MAX",
    "FLOAT_TYPES",
    "FunctionCode",
    "Group",
    "INTEGER_TYPES",
    "KnownIssue",
    "LengthRange",
    "LrcExample",
    "Manual",
    "Meaning",
    "Mode",
    "Model",
    "Page",
    "PolicyCase",
    "Port",
    "PortSetting",
    "Protocol",
    "READ_CODES",
    "RegType",
    "Register",
    "ReplyQuirk",
    "Reserved",
    "RunningAdvice",
    "RunningState",
    "SIGNED_TYPES",
    "Status",
    "TYPE_BOUNDS",
    "TYPE_WORDS",
    "Timing",
    "Value",
    "camel",
    "default_type",
    "is_keyword",
    "normalize_raw",
    "raw_bounds",
    "type_words",
]
