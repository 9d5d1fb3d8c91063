"""Plain, frozen descriptions of a device: what the client and simulator runtime read.

The compiler makes one :class:`DeviceSpec` from a map (``drivemap.model.spec.spec_from_model``);
generated ``generated/<model>/spec.py`` is that object printed. The runtime reads only these
classes (never YAML at run time). The tables of type sizes and read codes here are the only ones.
The compiler's model nodes extend these classes (a model ``Register`` is a :class:`RegisterSpec`
plus compile-time facts), so each fact the runtime reads is declared here once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import MISSING, dataclass, field, fields
from typing import TYPE_CHECKING, Any, TypeVar

from drivemap._compat import flat as _flat

#: Words (registers) of each fixed-size type; strings have ``length`` words; a coil or discrete input is one bit.
TYPE_WORDS: dict[str, int] = {"u16": 1, "s16": 1, "bool": 1, "u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4,
                              "f64": 4}
SIGNED_TYPES = frozenset({"s16", "s32", "s64"})
FLOAT_TYPES = frozenset({"f32", "f64"})
BIT_TABLES = frozenset({"coil", "discrete"})
#: The read function code of each table.
READ_CODES: dict[str, int] = {"holding": 0x03, "input": 0x04, "coil": 0x01, "discrete": 0x02}


def type_words(rtype: str, length: int = 1) -> int:
    """Words of a type (``length`` for strings)."""
    return length if rtype == "string" else TYPE_WORDS[rtype]


#: Fields that decide the raw words a write sends: a register with one of them open (``review:``) is not written.
WRITE_DECIDING_FIELDS = frozenset({
    "table", "address", "type", "word_order", "byte_order", "length", "encoding", "scale", "offset", "scale_register",
})


_C = TypeVar("_C", bound=type)


class _InitPlan:
    """What a frozen dataclass's ``__init__`` does, read once from its fields (see :func:`_fast_init`)."""

    def __init__(self, cls: type) -> None:
        params = [f for f in fields(cls) if f.init]
        self.qualname = cls.__qualname__
        self.names = tuple(f.name for f in params)
        self.known = frozenset(self.names)
        self.defaults = {f.name: f.default for f in params if f.default is not MISSING}
        self.factories = {f.name: f.default_factory for f in params if f.default_factory is not MISSING}
        #: init=False fields with a default factory
        self.later = {f.name: f.default_factory for f in fields(cls) if not f.init and f.default_factory is not MISSING}
        self.post_init: Callable[[Any], None] | None = getattr(cls, "__post_init__", None)

    def fill(self, obj: Any, args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        state = obj.__dict__
        if args:
            self._positional(state, args, kwargs)
        for name in kwargs:
            if name not in self.known:
                raise TypeError(f"{self.qualname}.__init__() got an unexpected keyword argument {name!r}")
        state.update(kwargs)
        for name, value in self.defaults.items():
            if name not in state:
                state[name] = value
        for name, factory in self.factories.items():
            if name not in state:
                state[name] = factory()
        if len(state) < len(self.names):
            missing = [n for n in self.names if n not in state]
            raise TypeError(f"{self.qualname}.__init__() missing {len(missing)} required argument(s): "
                            + ", ".join(repr(n) for n in missing))
        for name, factory in self.later.items():
            state[name] = factory()
        if self.post_init is not None:
            self.post_init(obj)

    def _positional(self, state: dict[str, Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        if len(args) > len(self.names):
            raise TypeError(f"{self.qualname}.__init__() takes {len(self.names) + 1} positional arguments "
                            f"but {len(args) + 1} were given")
        for name, value in zip(self.names, args, strict=False):
            if name in kwargs:
                raise TypeError(f"{self.qualname}.__init__() got multiple values for argument {name!r}")
            state[name] = value


def _fast_init(cls: _C) -> _C:
    """Give a frozen dataclass an ``__init__`` that fills the instance's ``__dict__`` at once.

    The dataclass's own ``__init__`` sets each field through ``object.__setattr__`` (frozen): about
    11 µs for a :class:`RegisterSpec`, which made constructing the spec half the import time of a
    client with thousands of registers (bench section 8). This one takes the same arguments (by
    position or keyword, the same required ones, the same defaults and default factories), refuses
    the same mistakes with a ``TypeError`` and calls ``__post_init__``; type checkers still see the
    dataclass's signature. Classes with ``__slots__`` keep their ``__init__``."""
    if "__slots__" in cls.__dict__:
        return cls
    fill = _InitPlan(cls).fill

    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        fill(self, args, kwargs)

    __init__.__qualname__ = f"{cls.__qualname__}.__init__"
    if not TYPE_CHECKING:
        cls.__init__ = __init__
    return cls


@_fast_init
@dataclass(frozen=True)
class BitSpec:
    name: str
    offset: int
    width: int
    label: str
    enum: str | None = None

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.offset


@dataclass(frozen=True)
class PageSpec:
    selector: str
    value: int


@_fast_init
@dataclass(frozen=True)
class RegisterSpec:
    """One register or array; engineering value = raw * scale (* 10**scale factor) + offset.

    ``table`` is its address space (holding, input, coil, discrete). The raw value is an int for
    every type: the integer (signed for s16/s32/s64), the IEEE-754 bit pattern of a float, the text
    bytes of a string as one unsigned big-endian number, 0/1 for a coil. ``words`` is the number of
    16-bit words (bits for coils and discrete inputs) on the wire.
    """

    name: str
    address: int
    type: str = "u16"
    table: str = "holding"
    access: str = "rw"
    count: int = 1
    stride: int = 1
    word_order: str | None = None
    scale: float = 1
    offset: float = 0
    unit: str | None = None
    min: float | None = None
    max: float | None = None
    defaults: tuple[float | str | None, ...] = (None,)
    """Factory default per element (engineering units; text for strings, True/False for bools)."""
    reflect: str = "unknown"
    storage: str = "unknown"
    write_delay_ms: float | None = None
    enum: str | None = None
    enum_values: tuple[int, ...] = ()
    bits: tuple[BitSpec, ...] = ()
    page: PageSpec | None = None
    command_value: int | None = None
    broadcast: bool = False
    refuse_while_running: bool = False
    param: str | None = None
    source: str = ""
    #: the manual's advice for writes while the drive runs (the client warns; nothing is refused)
    running_advice: str | None = None
    byte_order: str = "high_first"
    length: int = 1
    """Words of a string (1 for other types)."""
    encoding: str = "ascii"
    scale_register: str | None = None
    not_available: tuple[int, ...] = ()
    """Raw values that read as None."""
    min_read: int | None = None
    #: the value set: (engineering value, label or None) of every value a write may send (empty: any)
    values: tuple[tuple[float | str, str | None], ...] = ()
    #: decimals shown to people (None: the shortest text that reads back the same value)
    precision: int | None = None
    #: the manual's number of element 0 of an array (names shown to people; Python indexes from 0)
    first_index: int = 0
    bits_class: str | None = None
    """The Python class of a bit-field value (an IntFlag or a record), when the register has bits."""
    review: tuple[str, ...] = ()
    """The fields the map's source leaves open (``review:``), still to be stated by a person."""
    words: int = field(init=False, compare=False, repr=False)
    signed: bool = field(init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "words", type_words(self.type, self.length))
        object.__setattr__(self, "signed", self.type in SIGNED_TYPES)

    @property
    def bit_table(self) -> bool:
        return self.table in BIT_TABLES

    @property
    def open_for_writes(self) -> tuple[str, ...]:
        """The open fields (``review:``) that decide what a write sends: while any is open, no write."""
        return tuple(f for f in self.review if f in WRITE_DECIDING_FIELDS)

    def sign_ambiguous(self, raw: int) -> bool:
        """Whether ``raw`` means another value signed than unsigned while the map leaves the register's
        signedness open (``review: [signedness]``): such a value is neither written nor trusted."""
        return "signedness" in self.review and not 0 <= raw < (1 << (16 * self.words - 1))

    @property
    def readable(self) -> bool:
        return "r" in self.access

    @property
    def writable(self) -> bool:
        return "w" in self.access

    @property
    def is_array(self) -> bool:
        return self.count > 1

    def element_address(self, index: int) -> int:
        return self.address + index * self.stride

    def element_name(self, index: int) -> str:
        return f"{self.name}[{index}]" if self.count > 1 else self.name

    def display_name(self, index: int, base: str | None = None) -> str:
        """The name people see for element ``index`` (0-based, as in Python): ``base`` (default the
        register's name) followed by the manual's number of the element (``pv_voltage 1`` for index 0
        when ``first_index`` is 1); a register that is not an array is ``base`` alone."""
        text = self.name if base is None else base
        return f"{text} {index + self.first_index}" if self.count > 1 else text

    def default_at(self, index: int) -> float | str | None:
        return self.defaults[0] if len(self.defaults) == 1 else self.defaults[index]

    def value_label(self, value: object) -> str | None:
        """The label the map gives ``value`` in the register's value set (None: none or not in it)."""
        for allowed, label in self.values:
            if allowed == value:
                return label
        return None


@dataclass(frozen=True)
class AlignmentSpec:
    """A rule on the requests to ``table`` words ``start``..``end`` (``protocol.alignment``).

    A request that overlaps the block must start at a multiple of ``start_multiple``, carry a multiple
    of ``quantity_multiple`` and at least ``min_quantity`` words and, with ``whole_values``, cover
    every multi-word register element it touches whole. ``operations``: "read", "write" or both. The
    device answers ``exception`` to a request that breaks it.
    """

    table: str
    start: int = 0
    end: int = 0xFFFF
    start_multiple: int = 1
    quantity_multiple: int = 1
    min_quantity: int = 1
    whole_values: bool = False
    operations: tuple[str, ...] = ("read", "write")
    exception: int = 0x02
    source: str = ""


@dataclass(frozen=True)
class ReservedSpec:
    start: int
    end: int
    readable: bool | None
    page: PageSpec | None = None
    table: str = "holding"


@dataclass(frozen=True)
class FunctionSpec:
    code: int
    max_quantity: int | None
    broadcast: bool | None
    #: why broadcast is null (unclear in the manual) or false by the map's choice
    broadcast_reason: str | None = None


@dataclass(frozen=True)
class ExceptionSpec:
    code: int
    name: str
    meaning: str


@dataclass(frozen=True)
class CommErrorSpec:
    code: int
    name: str
    meaning: str


@dataclass(frozen=True)
class PolicySpec:
    """Which code the device answers (or records) for one error case; None = no answer."""

    case: str
    code: int | None


@dataclass(frozen=True)
class TimingSpec:
    silent_interval_chars: float | None = None
    silent_interval_floor_ms: float | None = None
    silent_interval_floor_above_bps: int | None = None
    processing_ms: tuple[float, float] | None = None
    inter_frame_gap_ms: float | None = None
    broadcast_gap_ms: float | None = None
    response_timeout_ms: float | None = None
    retries: int | None = None


@dataclass(frozen=True)
class SerialSpec:
    """Defaults of the device's first serial port."""

    mode: str = "rtu"
    baudrate: int | None = None
    parity: str | None = None
    stop_bits: int | None = None
    data_bits: int = 8


@dataclass(frozen=True)
class IdentitySpec:
    """One identity check of a map: the register and the values that identify the device or family.

    ``kind``: ``equals`` / ``one_of`` (``values``: integers compared with the raw register value, or
    texts compared with a string register's text), ``prefix`` (the text starts with ``values[0]``),
    ``pattern`` (the text matches the regular expression ``values[0]`` as a whole)."""

    register: str
    kind: str
    values: tuple[int | str, ...]
    source: str = ""


@dataclass(frozen=True)
class EnumMemberSpec:
    value: int
    name: str
    label: str


@dataclass(frozen=True)
class EnumSpec:
    """A named set of values of the map (the client's ``DriveEnum`` of the same name)."""

    name: str
    members: tuple[EnumMemberSpec, ...]
    source: str = ""
    notes: str | None = None


@dataclass(frozen=True)
class ProductSpec:
    """What the device is: the map's model name and the manual's title for it."""

    model: str
    title: str


@dataclass(frozen=True)
class CommandSpec:
    """A command: writing ``value`` to ``register`` (e.g. the write that applies the configuration)."""

    register: str
    value: int


@dataclass(frozen=True)
class RunningStateSpec:
    """How the drive reports that it runs: ``register`` reads one of ``values`` (raw)."""

    register: str
    values: tuple[int, ...]


@dataclass(frozen=True)
class ReplyQuirkSpec:
    """A non-standard reply form the device may send, which the client accepts (runtime.quirks)."""

    quirk: str


@dataclass(frozen=True)
class ProtocolSpec:
    """How the device speaks Modbus: modes, unit ids, function codes, exceptions, timing and its dialect."""

    modes: tuple[str, ...]
    unit_min: int
    unit_max: int
    broadcast_address: int | None
    serial: SerialSpec
    function_codes: tuple[FunctionSpec, ...]
    exceptions: tuple[ExceptionSpec, ...]
    timing: TimingSpec
    comm_errors: tuple[CommErrorSpec, ...] = ()
    exception_policy: tuple[PolicySpec, ...] = ()
    comm_error_policy: tuple[PolicySpec, ...] = ()
    comm_error_history: str | None = None
    #: the write that applies registers which take effect at configuration, or None
    configuration: CommandSpec | None = None
    max_frame_bytes: int | None = None
    #: unit ids a port fixes outside the settable range (e.g. EV's RS-232 port answers as 17)
    fixed_units: tuple[int, ...] = ()
    #: how the drive reports that it is running, or None
    running_state: RunningStateSpec | None = None
    #: non-standard reply forms the client accepts besides the standard ones (runtime.quirks)
    reply_quirks: tuple[ReplyQuirkSpec, ...] = ()
    #: undocumented words the read planner may read across (0: none)
    max_gap: int = 0
    #: rules on request start addresses and quantities (runtime.alignment)
    alignment: tuple[AlignmentSpec, ...] = ()

    @property
    def quirks(self) -> tuple[str, ...]:
        """The names of the reply quirks."""
        return tuple(q.quirk for q in self.reply_quirks)

    def valid_unit(self, unit: int) -> bool:
        """Whether a device of this model can have unit id ``unit`` (broadcast excluded)."""
        return (self.unit_min <= unit <= self.unit_max or unit in self.fixed_units) and unit != self.broadcast_address

    def function(self, code: int) -> FunctionSpec | None:
        for fc in self.function_codes:
            if fc.code == code:
                return fc
        return None

    def policy(self, case: str) -> int | None:
        """Exception code for an error case (None when the map gives none)."""
        for item in self.exception_policy:
            if item.case == case:
                return item.code
        return None

    def comm_policy(self, case: str) -> int | None:
        for item in self.comm_error_policy:
            if item.case == case:
                return item.code
        return None

    def exception(self, code: int) -> ExceptionSpec | None:
        for item in self.exceptions:
            if item.code == code:
                return item
        return None


#: The attributes a DeviceSpec had before it was split into ``device`` and ``protocol``: the part that holds each.
_MOVED = _flat.moved_attributes(ProtocolSpec.__dataclass_fields__)


@dataclass(frozen=True)
class DeviceSpec:
    """One device: what it is (``device``), how it speaks (``protocol``), its registers, enums and identity."""

    device: ProductSpec
    protocol: ProtocolSpec
    registers: tuple[RegisterSpec, ...]
    reserved: tuple[ReservedSpec, ...] = ()
    #: registers and values that identify the device (runtime.client.identity); () when the map names none
    identity: tuple[IdentitySpec, ...] = ()
    enums: tuple[EnumSpec, ...] = ()
    _index: dict[str, RegisterSpec] = field(init=False, default_factory=dict, compare=False, repr=False)

    @property
    def name(self) -> str:
        """The model name (``device.model``)."""
        return self.device.model

    def register(self, name: str) -> RegisterSpec:
        if not self._index:
            self._index.update({r.name: r for r in self.registers})
        return self._index[name]

    if not TYPE_CHECKING:  # type checkers see only the current names and the generated __init__

        def __init__(self, device: ProductSpec | None = None, protocol: ProtocolSpec | None = None,
                     registers: tuple[RegisterSpec, ...] = (), reserved: tuple[ReservedSpec, ...] = (),
                     identity: tuple[IdentitySpec, ...] = (), enums: tuple[EnumSpec, ...] = (),
                     **flat_form: object) -> None:
            """The dataclass's fields, or the flat form a ``spec.py`` of an earlier release prints
            (``DeviceSpec(model=..., title=..., modes=..., ...)``), with a DeprecationWarning."""
            if flat_form:
                _flat.warn_flat_form()
                device, protocol = _flat.split_flat(flat_form, ProductSpec, ProtocolSpec, CommandSpec,
                                                    RunningStateSpec, ReplyQuirkSpec)
            if device is None or protocol is None:
                raise TypeError("DeviceSpec needs device and protocol")
            for name, value in (("device", device), ("protocol", protocol), ("registers", registers),
                                ("reserved", reserved), ("identity", identity), ("enums", enums), ("_index", {})):
                object.__setattr__(self, name, value)

        def __getattr__(self, name: str) -> object:
            """The flat attributes of earlier releases (``SPEC.timing``, ``SPEC.model``), with a DeprecationWarning."""
            part = _MOVED.get(name)
            if part is None:
                raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
            _flat.warn_flat_attribute(name, part)
            return getattr(object.__getattribute__(self, part), name)
