"""The device and protocol part of the model: the manual, ports, function codes, exceptions, timing,
checksums, running state and reply quirks (what :class:`~drivemap.model.nodes.Model` holds as
``device`` and ``protocol``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

from drivemap.model.rules import Alignment
from drivemap.model.source import SourceRef
from drivemap.runtime.spec import (
    CommandSpec,
    CommErrorSpec,
    ExceptionSpec,
    FunctionSpec,
    PolicySpec,
    ProductSpec,
    ProtocolSpec,
    ReplyQuirkSpec,
    RunningStateSpec,
    TimingSpec,
)

__all__ = [
    "Checksum",
    "CommError",
    "CommandSpec",
    "Device",
    "ExceptionCode",
    "FunctionCode",
    "LengthRange",
    "LrcExample",
    "Manual",
    "PolicyCase",
    "Port",
    "PortSetting",
    "Protocol",
    "ReplyQuirk",
    "RunningAdvice",
    "RunningState",
    "Timing",
]


@dataclass(frozen=True)
class Manual:
    file: str
    document: str | None
    revision: str | None
    date: str | None
    language: str
    cross_check: tuple[str, ...] = ()


@dataclass(frozen=True)
class Origin:
    """Where an imported map's definitions come from (``device.origin``)."""

    project: str
    path: str
    commit: str
    licence: str
    format: str | None = None


@dataclass(frozen=True)
class Device(ProductSpec):
    """The device: the runtime's :class:`ProductSpec` (model, title) and what the map says of its manual."""

    vendor: str | None
    manual: Manual
    coverage: str | None
    source: str
    notes: str | None
    #: manual / imported / probed / verified (``device.evidence``); None where the map does not say
    evidence: str | None = None
    origin: Origin | None = None
    #: drive, inverter, meter, charger, ... (``device.kind``); None where the map does not say
    kind: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class PortSetting:
    what: str
    how: str
    when: str | None
    source: str
    notes: str | None


@dataclass(frozen=True)
class Port:
    name: str
    modes: tuple[str, ...]
    default_mode: str | None
    baudrates: tuple[int, ...]
    default_baudrate: int | None
    parity: tuple[str, ...]
    default_parity: str | None
    data_bits: tuple[int, ...]
    stop_bits: tuple[int, ...]
    default_stop_bits: int | None
    fixed_unit: int | None
    set_by: str
    settings: tuple[PortSetting, ...]
    source: str
    notes: str | None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class LengthRange:
    min: int
    max: int


@dataclass(frozen=True, kw_only=True)
class FunctionCode(FunctionSpec):
    """A function code: the runtime's :class:`FunctionSpec` and what the map says of it."""

    name: str
    request_bytes: LengthRange | None
    response_bytes: LengthRange | None
    source: str
    notes: str | None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class ExceptionCode(ExceptionSpec):
    """An exception code: the runtime's :class:`ExceptionSpec` and what the map says of it."""

    comm_errors: tuple[int, ...]
    source: str
    notes: str | None
    #: False: assumed by the map (source "map choice"), not printed in the manual
    documented: bool = True
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class CommError(CommErrorSpec):
    """A communication error code: the runtime's :class:`CommErrorSpec`, its source and notes."""

    source: str
    notes: str | None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class PolicyCase(PolicySpec):
    """An error case's code: the runtime's :class:`PolicySpec`, its source and the map's reason."""

    source: str
    reason: str | None


@dataclass(frozen=True, kw_only=True)
class Timing(TimingSpec):
    """The timing: the runtime's :class:`TimingSpec` (numbers as ints when whole), source and notes."""

    source: str
    notes: str | None = None
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class LrcExample:
    data: bytes
    lrc: int
    ascii: str | None
    source: str


@dataclass(frozen=True)
class Checksum:
    crc_first_byte_label: str
    crc_second_byte_label: str | None
    lrc_example: LrcExample | None
    source: str
    notes: str | None


@dataclass(frozen=True)
class RunningState(RunningStateSpec):
    """How the drive reports that it runs: the runtime's :class:`RunningStateSpec`, its source and notes."""

    source: str
    notes: str | None


@dataclass(frozen=True)
class RunningAdvice:
    """Advice (not a refusal) the manual gives for writes while the drive runs."""

    advice: str
    instead: str | None
    source: str

    def text(self) -> str:
        return self.advice + (f" (write {self.instead} instead)" if self.instead else "") + f" [{self.source}]"


@dataclass(frozen=True)
class ReplyQuirk(ReplyQuirkSpec):
    """A non-standard reply form the device may send: the runtime's :class:`ReplyQuirkSpec`, source and reason."""

    source: str
    reason: str


@dataclass(frozen=True, kw_only=True)
class Protocol(ProtocolSpec):
    """How the device speaks: the runtime's :class:`ProtocolSpec` (its ``serial`` and ``fixed_units`` taken
    from the ports) with the map's sources, ports and checksum notes."""

    unit_source: str
    ports: tuple[Port, ...]
    function_codes: tuple[FunctionCode, ...]
    exceptions: tuple[ExceptionCode, ...]
    comm_errors: tuple[CommError, ...] = ()
    exception_policy: tuple[PolicyCase, ...] = ()
    comm_error_policy: tuple[PolicyCase, ...] = ()
    timing: Timing
    checksum: Checksum | None
    source: str
    notes: str | None
    running_state: RunningState | None = None
    reply_quirks: tuple[ReplyQuirk, ...] = ()
    alignment: tuple[Alignment, ...] = ()
    """Rules on request start addresses and quantities (``protocol.alignment``)."""
    #: where the map states it (file, line, column, YAML path)
    src: SourceRef | None = field(default=None, compare=False, repr=False)

    def function(self, code: int) -> FunctionCode | None:
        """The runtime's lookup, typed with the map's function codes (name, lengths, source)."""
        return cast("FunctionCode | None", super().function(code))
