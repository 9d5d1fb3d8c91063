"""The immutable, typed model every template and the runtime read.

Built from a document that passed the schema and the semantic checks (:mod:`checks`), so
constructors here trust their input. Everything is frozen; collections are tuples.
"""

from __future__ import annotations

import keyword
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

Access = Literal["r", "w", "rw"]
RegType = Literal["u16", "s16", "u32", "s32"]
Mode = Literal["rtu", "ascii", "tcp"]
Status = Literal["verified", "erratum", "illegible"]

TYPE_BOUNDS: dict[str, tuple[int, int]] = {
    "u16": (0, 0xFFFF),
    "s16": (-0x8000, 0x7FFF),
    "u32": (0, 0xFFFFFFFF),
    "s32": (-0x80000000, 0x7FFFFFFF),
}


def camel(name: str) -> str:
    """``digital_speed_ram`` -> ``DigitalSpeedRam``."""
    return "".join(part[:1].upper() + part[1:] for part in name.split("_") if part)


def is_keyword(name: str) -> bool:
    return keyword.iskeyword(name) or keyword.issoftkeyword(name)


@dataclass(frozen=True)
class Manual:
    file: str
    document: str | None
    revision: str | None
    date: str | None
    language: str
    cross_check: tuple[str, ...] = ()


@dataclass(frozen=True)
class Device:
    model: str
    title: str
    vendor: str | None
    manual: Manual
    coverage: str | None
    source: str
    notes: str | None


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


@dataclass(frozen=True)
class LengthRange:
    min: int
    max: int


@dataclass(frozen=True)
class FunctionCode:
    code: int
    name: str
    max_quantity: int | None
    broadcast: bool | None
    request_bytes: LengthRange | None
    response_bytes: LengthRange | None
    source: str
    notes: str | None
    broadcast_reason: str | None = None


@dataclass(frozen=True)
class ExceptionCode:
    code: int
    name: str
    meaning: str
    comm_errors: tuple[int, ...]
    source: str
    notes: str | None
    #: False: assumed by the map (source "map choice"), not printed in the manual
    documented: bool = True


@dataclass(frozen=True)
class CommError:
    code: int
    name: str
    meaning: str
    source: str
    notes: str | None


@dataclass(frozen=True)
class PolicyCase:
    case: str
    code: int | None
    source: str
    reason: str | None


@dataclass(frozen=True)
class Timing:
    silent_interval_chars: float | None
    silent_interval_floor_ms: float | None
    silent_interval_floor_above_bps: int | None
    processing_ms: tuple[float, float] | None
    inter_frame_gap_ms: float | None
    broadcast_gap_ms: float | None
    response_timeout_ms: float | None
    retries: int | None
    source: str
    notes: str | None


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
class CommandRef:
    register: str
    value: int


@dataclass(frozen=True)
class RunningState:
    """How the drive reports that it runs: ``register`` shows one of ``values`` (raw)."""

    register: str
    values: tuple[int, ...]
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
class ReplyQuirk:
    """A non-standard reply form the device may send (``protocol.reply_quirks``)."""

    quirk: str
    source: str
    reason: str


@dataclass(frozen=True)
class Protocol:
    modes: tuple[str, ...]
    unit_min: int
    unit_max: int
    unit_source: str
    broadcast_address: int | None
    ports: tuple[Port, ...]
    function_codes: tuple[FunctionCode, ...]
    exceptions: tuple[ExceptionCode, ...]
    comm_errors: tuple[CommError, ...]
    exception_policy: tuple[PolicyCase, ...]
    comm_error_policy: tuple[PolicyCase, ...]
    comm_error_history: str | None
    timing: Timing
    max_frame_bytes: int | None
    configuration: CommandRef | None
    checksum: Checksum | None
    source: str
    notes: str | None
    running_state: RunningState | None = None
    reply_quirks: tuple[ReplyQuirk, ...] = ()

    def function(self, code: int) -> FunctionCode | None:
        for fc in self.function_codes:
            if fc.code == code:
                return fc
        return None

    def policy(self, case: str) -> PolicyCase | None:
        for item in self.exception_policy:
            if item.case == case:
                return item
        return None

    def comm_policy(self, case: str) -> PolicyCase | None:
        for item in self.comm_error_policy:
            if item.case == case:
                return item
        return None


@dataclass(frozen=True)
class EnumValue:
    value: int
    name: str
    label: str
    notes: str | None


@dataclass(frozen=True)
class Enum:
    name: str
    values: tuple[EnumValue, ...]
    source: str
    notes: str | None


@dataclass(frozen=True)
class Bit:
    name: str
    offset: int
    width: int
    label: str
    enum: str | None
    notes: str | None

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.offset


@dataclass(frozen=True)
class Page:
    selector: str
    value: int


@dataclass(frozen=True)
class Group:
    name: str
    title: str
    source: str
    notes: str | None


@dataclass(frozen=True)
class Register:
    """One register, or one array of registers (``count`` > 1)."""

    name: str
    address: int
    param: str | None
    param_rule: str | None
    label: str | None
    description: str | None
    group: str
    type: RegType
    word_order: str | None
    access: Access
    scale: float
    offset: float
    unit: str | None
    min: float | None
    max: float | None
    defaults: tuple[float | None, ...]
    reflect: str
    storage: str
    write_delay_ms: float | None
    enum: str | None
    bits: tuple[Bit, ...]
    flags_name: str | None
    count: int
    stride: int
    element_params: tuple[str, ...]
    page: Page | None
    command_value: int | None
    broadcast: bool
    refuse_while_running: bool
    source: str
    notes: str | None
    line: int = 0
    running_advice: RunningAdvice | None = None
    #: each element's parameter id by rule: {index} / {address} (decimal), e.g. "P_{address}"
    element_param_format: str | None = None

    @property
    def words(self) -> int:
        return 2 if self.type in ("u32", "s32") else 1

    @property
    def signed(self) -> bool:
        return self.type in ("s16", "s32")

    @property
    def is_array(self) -> bool:
        return self.count > 1

    @property
    def readable(self) -> bool:
        return "r" in self.access

    @property
    def writable(self) -> bool:
        return "w" in self.access

    @property
    def bits_class(self) -> str | None:
        if not self.bits:
            return None
        return self.flags_name or camel(self.name)

    @property
    def multibit(self) -> bool:
        return any(b.width > 1 for b in self.bits)

    @property
    def is_integer(self) -> bool:
        """Engineering values are ints when scale and offset are whole numbers."""
        return float(self.scale).is_integer() and float(self.offset).is_integer()

    def element_address(self, index: int) -> int:
        return self.address + index * self.stride

    def element_name(self, index: int) -> str:
        return f"{self.name}[{index}]" if self.is_array else self.name

    def element_param(self, index: int) -> str | None:
        if self.element_params:
            return self.element_params[index]
        if self.element_param_format is not None:
            return self.element_param_format.format(index=index, address=self.element_address(index))
        return self.param if index == 0 else None

    def default_at(self, index: int) -> float | None:
        if len(self.defaults) == 1:
            return self.defaults[0]
        return self.defaults[index]

    def raw_bounds(self) -> tuple[int, int]:
        return TYPE_BOUNDS[self.type]

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


@dataclass(frozen=True)
class Reserved:
    start: int
    end: int
    readable: bool | None
    writable: bool
    page: Page | None
    source: str
    notes: str | None
    #: reserved (marked by the manual) / unlabeled (listed without a name) / not_listed
    kind: str = "reserved"


@dataclass(frozen=True)
class KnownIssue:
    title: str
    source: str
    printed: str
    corrected: str | None
    chosen: str
    reason: str
    affects: tuple[str, ...]


@dataclass(frozen=True)
class Meaning:
    unit: int
    operation: str
    address: int | None
    quantity: int | None
    values: tuple[tuple[str, float], ...]
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
    preset: tuple[tuple[str, float], ...]
    inject_exception: int | None
    corrected_request: str | None
    corrected_response: str | None
    erratum: str | None
    illegible: str | None
    notes: str | None
    status: Status

    @property
    def wire_request(self) -> str | None:
        """The frame as it really is on the line: corrected where an erratum says so."""
        return self.corrected_request if self.corrected_request is not None else self.request

    @property
    def wire_response(self) -> str | None:
        return self.corrected_response if self.corrected_response is not None else self.response


@dataclass(frozen=True)
class Model:
    path: str
    device: Device
    protocol: Protocol
    enums: tuple[Enum, ...]
    groups: tuple[Group, ...]
    registers: tuple[Register, ...]
    reserved: tuple[Reserved, ...]
    known_issues: tuple[KnownIssue, ...]
    examples: tuple[Example, ...]
    _by_name: dict[str, Register] = field(default_factory=dict, compare=False, repr=False)

    @property
    def name(self) -> str:
        return self.device.model

    def register(self, name: str) -> Register:
        return self._by_name[name]

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
        reg = self._by_name[base]
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


def build_model(path: str, data: dict[str, Any], statuses: dict[str, Status], lines: dict[str, int]) -> Model:
    """Turn a checked document into the model (``statuses``: example name -> status)."""
    dev = data["device"]
    man = dev["manual"]
    device = Device(
        model=dev["model"],
        title=dev["title"],
        vendor=dev.get("vendor"),
        manual=Manual(
            man["file"], man.get("document"), man.get("revision"), man.get("date"), man["language"],
            tuple(man.get("cross_check", ())),
        ),
        coverage=dev.get("coverage"),
        source=dev["source"],
        notes=dev.get("notes"),
    )
    p = data["protocol"]
    t = p["timing"]
    proc = t.get("processing_ms")
    timing = Timing(
        silent_interval_chars=t.get("silent_interval_chars"),
        silent_interval_floor_ms=t.get("silent_interval_floor_ms"),
        silent_interval_floor_above_bps=t.get("silent_interval_floor_above_bps"),
        processing_ms=(proc["min"], proc["max"]) if proc else None,
        inter_frame_gap_ms=t.get("inter_frame_gap_ms"),
        broadcast_gap_ms=t.get("broadcast_gap_ms"),
        response_timeout_ms=t.get("response_timeout_ms"),
        retries=t.get("retries"),
        source=t["source"],
        notes=t.get("notes"),
    )

    def lr(item: dict[str, int] | None) -> LengthRange | None:
        return LengthRange(item["min"], item["max"]) if item else None

    ck = p.get("checksum")
    checksum = None
    if ck:
        lx = ck.get("lrc_example")
        checksum = Checksum(
            ck["crc_first_byte_label"], ck.get("crc_second_byte_label"),
            LrcExample(bytes.fromhex(lx["data"]), lx["lrc"], lx.get("ascii"), lx["source"]) if lx else None,
            ck["source"], ck.get("notes"),
        )
    cfg = p.get("configuration")
    protocol = Protocol(
        modes=tuple(p["modes"]),
        unit_min=p["unit_ids"]["min"],
        unit_max=p["unit_ids"]["max"],
        unit_source=p["unit_ids"]["source"],
        broadcast_address=p.get("broadcast_address"),
        ports=tuple(
            Port(
                name=x["name"], modes=tuple(x["modes"]), default_mode=x.get("default_mode"),
                baudrates=tuple(x["baudrates"]), default_baudrate=x.get("default_baudrate"),
                parity=tuple(x["parity"]), default_parity=x.get("default_parity"),
                data_bits=tuple(x["data_bits"]), stop_bits=tuple(x["stop_bits"]),
                default_stop_bits=x.get("default_stop_bits"), fixed_unit=x.get("fixed_unit"),
                set_by=x["set_by"],
                settings=tuple(
                    PortSetting(s["what"], s["how"], s.get("when"), s["source"], s.get("notes"))
                    for s in x.get("settings", ())
                ),
                source=x["source"], notes=x.get("notes"),
            )
            for x in p["ports"]
        ),
        function_codes=tuple(
            FunctionCode(
                f["code"], f["name"], f.get("max_quantity"), f.get("broadcast"),
                lr(f.get("request_bytes")), lr(f.get("response_bytes")), f["source"], f.get("notes"),
                broadcast_reason=f.get("broadcast_reason"),
            )
            for f in p["function_codes"]
        ),
        exceptions=tuple(
            ExceptionCode(e["code"], e["name"], e["meaning"], tuple(e.get("comm_errors", ())), e["source"], e.get("notes"),
                          documented=e.get("documented", True))
            for e in p["exceptions"]
        ),
        comm_errors=tuple(
            CommError(e["code"], e["name"], e["meaning"], e["source"], e.get("notes")) for e in p.get("comm_errors", ())
        ),
        exception_policy=tuple(
            PolicyCase(k, v.get("code"), v["source"], v.get("reason")) for k, v in p.get("exception_policy", {}).items()
        ),
        comm_error_policy=tuple(
            PolicyCase(k, v.get("code"), v["source"], v.get("reason")) for k, v in p.get("comm_error_policy", {}).items()
        ),
        comm_error_history=p.get("comm_error_history"),
        timing=timing,
        max_frame_bytes=p.get("max_frame_bytes"),
        configuration=CommandRef(cfg["register"], cfg["value"]) if cfg else None,
        checksum=checksum,
        source=p["source"],
        notes=p.get("notes"),
        running_state=_running_state(p.get("running_state")),
        reply_quirks=tuple(ReplyQuirk(q["quirk"], q["source"], q["reason"]) for q in p.get("reply_quirks", ())),
    )
    enums = tuple(
        Enum(
            name,
            tuple(EnumValue(v["value"], v["name"], v["label"], v.get("notes")) for v in e["values"]),
            e["source"],
            e.get("notes"),
        )
        for name, e in data.get("enums", {}).items()
    )
    groups = tuple(Group(g["name"], g["title"], g["source"], g.get("notes")) for g in data.get("groups", ()))
    registers = []
    for r in data["registers"]:
        default = r.get("default")
        defaults: tuple[float | None, ...] = tuple(default) if isinstance(default, list) else (default,)
        writable = "w" in r["access"]
        registers.append(
            Register(
                name=r["name"], address=r["address"], param=r.get("param"), param_rule=r.get("param_rule"),
                label=r.get("label"), description=r.get("description"), group=r["group"],
                type=r.get("type", "u16"), word_order=r.get("word_order"), access=r["access"],
                scale=r.get("scale", 1), offset=r.get("offset", 0), unit=r.get("unit"),
                min=r.get("min"), max=r.get("max"), defaults=defaults,
                reflect=r.get("reflect", "unknown"), storage=r.get("storage", "unknown"),
                write_delay_ms=r.get("write_delay_ms"), enum=r.get("enum"),
                bits=tuple(
                    Bit(b["name"], b["offset"], b.get("width", 1), b["label"], b.get("enum"), b.get("notes"))
                    for b in r.get("bits", ())
                ),
                flags_name=r.get("flags_name"), count=r.get("count", 1), stride=r.get("stride", 1),
                element_params=tuple(r.get("element_params", ())),
                page=Page(r["page"]["selector"], r["page"]["value"]) if r.get("page") else None,
                command_value=r["command"]["value"] if r.get("command") else None,
                broadcast=r.get("broadcast", writable and _broadcast_writable(p, r)),
                refuse_while_running=r.get("refuse_while_running", False),
                source=r["source"], notes=r.get("notes"), line=lines.get(r["name"], 0),
                running_advice=_running_advice(r.get("running_advice")),
                element_param_format=r.get("element_param_format"),
            )
        )
    reserved = tuple(
        Reserved(
            x["start"], x["end"], x.get("readable"), x.get("writable", False),
            Page(x["page"]["selector"], x["page"]["value"]) if x.get("page") else None,
            x["source"], x.get("notes"), kind=x.get("kind", "reserved"),
        )
        for x in data.get("reserved", ())
    )
    issues = tuple(
        KnownIssue(k["title"], k["source"], k["printed"], k.get("corrected"), k["chosen"], k["reason"], tuple(k.get("affects", ())))
        for k in data.get("known_issues", ())
    )
    examples = []
    for e in data["examples"]:
        m = e["meaning"]
        err = e.get("erratum") or {}
        examples.append(
            Example(
                name=e["name"], title=e.get("title"), source=e["source"], mode=e["mode"],
                request=e.get("request"), response=e.get("response"),
                meaning=Meaning(
                    unit=m["unit"], operation=m["operation"], address=m.get("address"), quantity=m.get("quantity"),
                    values=tuple(m.get("values", {}).items()), raw=tuple(m.get("raw", ())),
                    loopback=tuple(m.get("loopback", ())), exception=m.get("exception"),
                    broadcast=m.get("broadcast", False),
                ),
                preset=tuple((e.get("preset") or {}).items()),
                inject_exception=e.get("inject_exception"),
                corrected_request=err.get("request"), corrected_response=err.get("response"),
                erratum=err.get("reason"), illegible=e.get("illegible"), notes=e.get("notes"),
                status=statuses[e["name"]],
            )
        )
    model = Model(
        path=path, device=device, protocol=protocol, enums=enums, groups=groups, registers=tuple(registers),
        reserved=reserved, known_issues=issues, examples=tuple(examples),
    )
    model._by_name.update({r.name: r for r in registers})
    return model


def _broadcast_writable(protocol: dict[str, Any], reg: dict[str, Any]) -> bool:
    """A register may be broadcast when the function code used to write it allows broadcast."""
    if protocol.get("broadcast_address") is None:
        return False
    words = 2 if reg.get("type") in ("u32", "s32") else 1
    codes = {f["code"]: f.get("broadcast") for f in protocol["function_codes"]}
    if words == 1 and codes.get(6) is True:
        return True
    return codes.get(16) is True


def _running_state(item: dict[str, Any] | None) -> RunningState | None:
    if not item:
        return None
    return RunningState(item["register"], tuple(item["values"]), item["source"], item.get("notes"))


def _running_advice(item: dict[str, Any] | None) -> RunningAdvice | None:
    if not item:
        return None
    return RunningAdvice(item["advice"], item.get("instead"), item["source"])
