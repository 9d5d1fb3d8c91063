"""Plain, frozen descriptions of a device that generated modules embed as literals.

Generated ``generated/<model>/spec.py`` builds one :class:`DeviceSpec`; the client and the
simulator runtime read only these classes (never YAML at run time).
"""

from __future__ import annotations

from dataclasses import dataclass, field


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


@dataclass(frozen=True)
class RegisterSpec:
    """One register or array; engineering value = raw * scale + offset."""

    name: str
    address: int
    type: str = "u16"
    access: str = "rw"
    count: int = 1
    stride: int = 1
    word_order: str | None = None
    scale: float = 1
    offset: float = 0
    unit: str | None = None
    min: float | None = None
    max: float | None = None
    defaults: tuple[float | None, ...] = (None,)
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

    @property
    def words(self) -> int:
        return 2 if self.type in ("u32", "s32") else 1

    @property
    def signed(self) -> bool:
        return self.type in ("s16", "s32")

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

    def default_at(self, index: int) -> float | None:
        return self.defaults[0] if len(self.defaults) == 1 else self.defaults[index]


@dataclass(frozen=True)
class ReservedSpec:
    start: int
    end: int
    readable: bool | None
    page: PageSpec | None = None


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
class DeviceSpec:
    model: str
    title: str
    modes: tuple[str, ...]
    unit_min: int
    unit_max: int
    broadcast_address: int | None
    serial: SerialSpec
    function_codes: tuple[FunctionSpec, ...]
    exceptions: tuple[ExceptionSpec, ...]
    timing: TimingSpec
    registers: tuple[RegisterSpec, ...]
    reserved: tuple[ReservedSpec, ...] = ()
    comm_errors: tuple[CommErrorSpec, ...] = ()
    exception_policy: tuple[PolicySpec, ...] = ()
    comm_error_policy: tuple[PolicySpec, ...] = ()
    comm_error_history: str | None = None
    configuration: tuple[str, int] | None = None
    max_frame_bytes: int | None = None
    #: unit ids a port fixes outside the settable range (e.g. EV's RS-232 port answers as 17)
    fixed_units: tuple[int, ...] = ()
    #: (register, raw values) by which the drive reports that it is running, or None
    running_state: tuple[str, tuple[int, ...]] | None = None
    #: non-standard reply forms the client accepts besides the standard ones (runtime.quirks)
    reply_quirks: tuple[str, ...] = ()
    _index: dict[str, RegisterSpec] = field(init=False, default_factory=dict, compare=False, repr=False)

    def valid_unit(self, unit: int) -> bool:
        """Whether a device of this model can have unit id ``unit`` (broadcast excluded)."""
        return (self.unit_min <= unit <= self.unit_max or unit in self.fixed_units) and unit != self.broadcast_address

    def register(self, name: str) -> RegisterSpec:
        if not self._index:
            self._index.update({r.name: r for r in self.registers})
        return self._index[name]

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
