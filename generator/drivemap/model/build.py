"""Build the immutable :class:`~drivemap.model.nodes.Model` from a document that passed the schema and the checks.

The constructors trust their input (the checks ran first); every default the map may leave out is
filled in here, so the model never has a missing value.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from drivemap.diagnostics import Location
from drivemap.model import modicon
from drivemap.model.family import IDENTITY_KINDS, IdentityCheck
from drivemap.model.nodes import (
    Alignment,
    AllowedValue,
    Bit,
    Checksum,
    CommandSpec,
    CommError,
    Device,
    Enum,
    EnumValue,
    Example,
    ExceptionCode,
    FunctionCode,
    Group,
    KnownIssue,
    LengthRange,
    LrcExample,
    Manual,
    Meaning,
    Model,
    Page,
    PolicyCase,
    Port,
    PortSetting,
    Protocol,
    Register,
    RegType,
    ReplyQuirk,
    Reserved,
    RunningAdvice,
    RunningState,
    Status,
    Timing,
    Value,
    default_type,
    normalize_raw,
    type_words,
)
from drivemap.model.protocol import Origin
from drivemap.model.source import SourceRef, YamlPath
from drivemap.runtime.spec import SerialSpec

__all__ = ["build_model", "number", "whole"]


def build_model(path: str, data: dict[str, Any], statuses: dict[str, Status], lines: dict[str, int],
                at: Callable[[YamlPath], Location] | None = None) -> Model:
    """Turn a checked document into the model (``statuses``: example name -> status); with ``at`` (the
    loaded document's positions) every node carries where the map states it (``src``)."""
    p = data["protocol"]
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
    codes = {e.name: tuple(v.value for v in e.members) for e in enums}
    registers = [_register(p, r, lines, codes) for r in data["registers"]]
    reserved = tuple(
        Reserved(
            x["start"], x["end"], x.get("readable"),
            Page(x["page"]["selector"], x["page"]["value"]) if x.get("page") else None,
            writable=x.get("writable", False), source=x["source"], notes=x.get("notes"),
            kind=x.get("kind", "reserved"), table=x.get("table", "holding"),
        )
        for x in data.get("reserved", ())
    )
    issues = tuple(
        KnownIssue(k["title"], k["source"], k["printed"], k.get("corrected"), k["chosen"], k["reason"], tuple(k.get("affects", ())))
        for k in data.get("known_issues", ())
    )
    by_name = {r.name: r for r in registers}
    model = Model(
        path=path, device=_device(data["device"]), protocol=_protocol(p), enums=enums, groups=groups,
        registers=tuple(registers), reserved=reserved, known_issues=issues,
        identity=tuple(_identity(x, by_name[x["register"]]) for x in data.get("identity", ())),
        examples=tuple(_example(e, statuses[e["name"]]) for e in data["examples"]),
    )
    if at is not None:
        locate(model, at)
    return model


def locate(model: Model, at: Callable[[YamlPath], Location]) -> None:
    """Give every node of a model just built its :class:`SourceRef` (``at``: YAML path -> location).

    The nodes are frozen; this fills their one ``src`` field once, before anyone else holds them."""

    def put(node: object, where: YamlPath) -> None:
        loc = at(where)
        object.__setattr__(node, "src", SourceRef(loc.path, loc.line, loc.col, where))

    put(model, ())
    put(model.device, ("device",))
    p = model.protocol
    put(p, ("protocol",))
    put(p.timing, ("protocol", "timing"))
    for key, items in (("ports", p.ports), ("function_codes", p.function_codes), ("exceptions", p.exceptions),
                       ("comm_errors", p.comm_errors), ("alignment", p.alignment)):
        for i, item in enumerate(items):
            put(item, ("protocol", key, i))
    for enum in model.enums:
        put(enum, ("enums", enum.name))
        for j, member in enumerate(enum.members):
            put(member, ("enums", enum.name, "values", j))
    for key, nodes in (("groups", model.groups), ("reserved", model.reserved), ("known_issues", model.known_issues),
                       ("examples", model.examples), ("identity", model.identity)):
        for i, node in enumerate(nodes):
            put(node, (key, i))
    for i, reg in enumerate(model.registers):
        put(reg, ("registers", i))
        for j, bit in enumerate(reg.bits):
            put(bit, ("registers", i, "bits", j))
        for j, allowed in enumerate(reg.value_set):
            put(allowed, ("registers", i, "values", j))


def number(value: float | None) -> int | float | None:
    """A number as the map means it: an int when it is whole (so a printed spec reads ``10``, not ``10.0``)."""
    return None if value is None else whole(value)


def whole(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)


def _identity(x: dict[str, Any], reg: Register) -> IdentityCheck:
    kind = next(k for k in IDENTITY_KINDS if k in x)
    given = x[kind] if kind == "one_of" else [x[kind]]
    values = tuple(v if isinstance(v, str) else normalize_raw(reg.type, reg.table, reg.length, v) for v in given)
    return IdentityCheck(x["register"], kind, values, x["source"], x.get("notes"))  # type: ignore[arg-type]


def _device(dev: dict[str, Any]) -> Device:
    man = dev["manual"]
    return Device(
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
        evidence=dev.get("evidence"),
        origin=Origin(**dev["origin"]) if dev.get("origin") else None,
        kind=dev.get("kind"),
    )


def _timing(t: dict[str, Any]) -> Timing:
    proc = t.get("processing_ms")
    return Timing(
        silent_interval_chars=number(t.get("silent_interval_chars")),
        silent_interval_floor_ms=number(t.get("silent_interval_floor_ms")),
        silent_interval_floor_above_bps=t.get("silent_interval_floor_above_bps"),
        processing_ms=(whole(proc["min"]), whole(proc["max"])) if proc else None,
        inter_frame_gap_ms=number(t.get("inter_frame_gap_ms")),
        broadcast_gap_ms=number(t.get("broadcast_gap_ms")),
        response_timeout_ms=number(t.get("response_timeout_ms")),
        retries=t.get("retries"),
        source=t["source"],
        notes=t.get("notes"),
    )


def _checksum(ck: dict[str, Any] | None) -> Checksum | None:
    if not ck:
        return None
    lx = ck.get("lrc_example")
    return Checksum(
        ck["crc_first_byte_label"], ck.get("crc_second_byte_label"),
        LrcExample(bytes.fromhex(lx["data"]), lx["lrc"], lx.get("ascii"), lx["source"]) if lx else None,
        ck["source"], ck.get("notes"),
    )


def _port(x: dict[str, Any]) -> Port:
    return Port(
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


def _lengths(item: dict[str, int] | None) -> LengthRange | None:
    return LengthRange(item["min"], item["max"]) if item else None


def _serial(port: Port) -> SerialSpec:
    """The runtime's serial defaults: those of the first port."""
    return SerialSpec(
        mode=port.default_mode or port.modes[0], baudrate=port.default_baudrate, parity=port.default_parity,
        stop_bits=port.default_stop_bits,
        data_bits=8 if 8 in port.data_bits or not port.data_bits else port.data_bits[0],
    )


def _protocol(p: dict[str, Any]) -> Protocol:
    cfg = p.get("configuration")
    ports = tuple(_port(x) for x in p["ports"])
    lo, hi = p["unit_ids"]["min"], p["unit_ids"]["max"]
    return Protocol(
        modes=tuple(p["modes"]),
        unit_min=lo,
        unit_max=hi,
        unit_source=p["unit_ids"]["source"],
        broadcast_address=p.get("broadcast_address"),
        ports=ports,
        serial=_serial(ports[0]),
        fixed_units=tuple(sorted({x.fixed_unit for x in ports if x.fixed_unit is not None
                                  and not lo <= x.fixed_unit <= hi})),
        function_codes=tuple(
            FunctionCode(
                f["code"], f.get("max_quantity"), f.get("broadcast"), f.get("broadcast_reason"), name=f["name"],
                request_bytes=_lengths(f.get("request_bytes")), response_bytes=_lengths(f.get("response_bytes")),
                source=f["source"], notes=f.get("notes"),
            )
            for f in p["function_codes"]
        ),
        exceptions=tuple(
            ExceptionCode(e["code"], e["name"], e["meaning"], tuple(e.get("comm_errors", ())), e["source"], e.get("notes"),
                          documented=e.get("documented", e["source"] != "map choice"))
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
        timing=_timing(p["timing"]),
        max_frame_bytes=p.get("max_frame_bytes"),
        configuration=CommandSpec(cfg["register"], cfg["value"]) if cfg else None,
        checksum=_checksum(p.get("checksum")),
        source=p["source"],
        notes=p.get("notes"),
        max_gap=p.get("max_gap", 0),
        alignment=_alignment(p),
        running_state=_running_state(p.get("running_state")),
        reply_quirks=tuple(ReplyQuirk(q["quirk"], q["source"], q["reason"]) for q in p.get("reply_quirks", ())),
    )


def _example(e: dict[str, Any], status: Status) -> Example:
    m = e["meaning"]
    err = e.get("erratum") or {}
    return Example(
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
        status=status,
    )


def _register(p: dict[str, Any], r: dict[str, Any], lines: dict[str, int],
              enum_codes: dict[str, tuple[int, ...]]) -> Register:
    table, address = modicon.locate(r)
    rtype: RegType = r.get("type", default_type(table))
    length = r.get("length", 1)
    default = r.get("default")
    defaults = tuple(_default(d) for d in (default if isinstance(default, list) else (default,)))
    writable = "w" in r.get("access", "r")
    not_available = tuple(
        raw for raw in (normalize_raw(rtype, table, length, v) for v in r.get("not_available", ())) if raw is not None
    )
    given = r.get("register")
    return Register(
        name=r["name"], address=address, param=r.get("param"), param_rule=r.get("param_rule"),
        label=r.get("label"), description=r.get("description"), group=r["group"],
        type=rtype, word_order=r.get("word_order"), access=r.get("access", "r"),
        scale=whole(r.get("scale", 1)), offset=whole(r.get("offset", 0)), unit=r.get("unit"),
        min=number(r.get("min")), max=number(r.get("max")), defaults=defaults,
        reflect=r.get("reflect", "unknown"), storage=r.get("storage", "unknown"),
        write_delay_ms=number(r.get("write_delay_ms")), enum=r.get("enum"),
        enum_values=enum_codes[r["enum"]] if r.get("enum") else (),
        bits=tuple(
            Bit(b["name"], b["offset"], b.get("width", 1), b["label"], b.get("enum"), b.get("notes"))
            for b in r.get("bits", ())
        ),
        flags_name=r.get("flags_name"), count=r.get("count", 1), stride=r.get("stride", 1),
        element_params=tuple(r.get("element_params", ())),
        page=Page(r["page"]["selector"], r["page"]["value"]) if r.get("page") else None,
        command_value=r["command"]["value"] if r.get("command") else None,
        broadcast=r.get("broadcast", writable and not r.get("scale_register")
                        and _broadcast_writable(p, table, type_words(rtype, length))),
        refuse_while_running=r.get("refuse_while_running", False),
        source=r["source"], notes=r.get("notes"),
        table=table, byte_order=r.get("byte_order", "high_first"), length=length,
        encoding=r.get("encoding", "ascii") if rtype == "string" else "ascii", scale_register=r.get("scale_register"),
        not_available=not_available, min_read=r.get("min_read"),
        modicon_given=None if given is None else str(given),
        line=lines.get(r["name"], 0),
        advice=_running_advice(r.get("running_advice")),
        element_param_format=r.get("element_param_format"),
        value_set=tuple(AllowedValue(_value(rtype, v["value"]), v.get("label"), v.get("notes")) for v in r.get("values", ())),
        precision=r.get("precision"), first_index=r.get("first_index", 0),
        review=tuple(r.get("review", ())),
    )


def _default(value: Value) -> Value:
    """A default as the register's values are: text and true/false as given, numbers as ints when whole."""
    return value if isinstance(value, (str, bool)) else number(value)


def _value(rtype: str, value: float | str) -> float | str:
    """A value of a value set as the register's values are: float for floats, int for whole numbers."""
    if isinstance(value, str):
        return value
    if rtype in ("f32", "f64"):
        return float(value)
    return int(value) if float(value).is_integer() else float(value)


def _alignment(p: dict[str, Any]) -> tuple[Alignment, ...]:
    policy = p.get("exception_policy", {}).get("illegal_address", {})
    fallback = policy.get("code") if policy.get("code") is not None else 0x02
    return tuple(
        Alignment(
            table=a["table"], start=a.get("start", 0), end=a.get("end", 0xFFFF),
            start_multiple=a.get("start_multiple", 1), quantity_multiple=a.get("quantity_multiple", 1),
            min_quantity=a.get("min_quantity", 1), whole_values=a.get("whole_values", False),
            operations=tuple(a.get("operations", ("read", "write"))), exception=a.get("exception", fallback),
            source=a["source"], notes=a.get("notes"),
        )
        for a in p.get("alignment", ())
    )


def _broadcast_writable(protocol: dict[str, Any], table: str, words: int) -> bool:
    """A register may be broadcast when the function code used to write it allows broadcast."""
    if protocol.get("broadcast_address") is None:
        return False
    codes = {f["code"]: f.get("broadcast") for f in protocol["function_codes"]}
    single, multiple = (0x05, 0x0F) if table == "coil" else (0x06, 0x10)
    if words == 1 and codes.get(single) is True:
        return True
    return codes.get(multiple) is True


def _running_state(item: dict[str, Any] | None) -> RunningState | None:
    if not item:
        return None
    return RunningState(item["register"], tuple(item["values"]), item["source"], item.get("notes"))


def _running_advice(item: dict[str, Any] | None) -> RunningAdvice | None:
    if not item:
        return None
    return RunningAdvice(item["advice"], item.get("instead"), item["source"])
