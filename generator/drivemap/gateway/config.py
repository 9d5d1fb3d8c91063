"""The gateway's configuration file: YAML with positions -> its JSON Schema -> checks -> frozen config.

Every problem is a ``path:line:col: error: ...`` diagnostic (:class:`~drivemap.diagnostics.CompileError`),
found before anything connects: unknown models, registers and groups, unit ids the map does not
allow, duplicate names, a serial mode a model does not speak, missing passwords or certificates.
Maps are resolved like every other verb does (:func:`drivemap.compiler.resolve_map`): ``model:`` by
model id (the project's maps, then the seed maps), ``map:`` by path relative to the config file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivemap.compiler import compile_map, resolve_map
from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend import schema
from drivemap.frontend.load import Document, PathT, load_file
from drivemap.frontend.project import Project, display, load_project
from drivemap.gateway.access import group_writables
from drivemap.gateway.checks import (
    certificate_problem,
    endpoint_problem,
    key_pair_problem,
    map_file_problem,
    serial_port_problem,
)
from drivemap.model.nodes import Model

#: The configuration schema shipped with the package (a link to ``schemas/gateway.schema.json``).
SCHEMA_PATH = Path(__file__).resolve().parent.parent / "data" / "gateway.schema.json"

DEFAULT_INTERVAL_S = 5.0
RESERVED_NAMES = frozenset({"gateway"})


@dataclass(frozen=True)
class PollGroup:
    """Registers read together (one planned read) every ``interval`` seconds."""

    interval: float
    registers: tuple[str, ...]


@dataclass(frozen=True)
class DeviceConfig:
    name: str
    title: str
    model: Model
    unit: int
    page_policy: str
    publish: tuple[str, ...]
    polls: tuple[PollGroup, ...]
    writable: tuple[str, ...] = ()
    """The registers that take commands (published, or write-only, and listed in ``writable``)."""


@dataclass(frozen=True)
class BusConfig:
    name: str
    kind: str  # "tcp" | "rtu_over_tcp" | "serial"
    host: str | None
    port: int | None
    serial: dict[str, Any] | None
    timeout: float | None
    retries: int | None
    devices: tuple[DeviceConfig, ...]

    def describe(self) -> str:
        if self.kind == "serial":
            assert self.serial is not None
            return f"serial {self.serial['port']}"
        return f"{self.kind.replace('_', '-')} {self.host}:{self.port}"


@dataclass(frozen=True)
class MqttConfig:
    host: str
    port: int = 1883
    prefix: str = "drivemap"
    client_id: str = "drivemap"
    username: str | None = None
    password: str | None = None
    qos: int = 1
    keepalive: int = 30
    reconnect_min: float = 1.0
    reconnect_max: float = 30.0
    discovery: bool = True
    discovery_prefix: str = "homeassistant"
    #: the Home Assistant release discovery is for (YEAR, MONTH); None: the current one
    ha_version: tuple[int, int] | None = None


@dataclass(frozen=True)
class OpcuaUser:
    name: str
    password: str | None
    certificate: Path | None
    write: bool


@dataclass(frozen=True)
class OpcuaLimits:
    """How many connections the OPC UA server holds, and for how long before a session is activated."""

    max_connections: int = 100
    per_source: int = 10
    anonymous_sessions: int = 50
    reserve: int = 10
    handshake_timeout: float = 10.0


@dataclass(frozen=True)
class OpcuaConfig:
    endpoint: str
    namespace: str
    security: tuple[str, ...] = ("none",)
    certificate: Path | None = None
    private_key: Path | None = None
    users: tuple[OpcuaUser, ...] = ()
    anonymous: bool = True
    anonymous_writes: bool = False
    limits: OpcuaLimits = OpcuaLimits()
    endpoint_at: Location | None = None


@dataclass(frozen=True)
class GatewayConfig:
    path: str
    name: str
    buses: tuple[BusConfig, ...]
    mqtt: MqttConfig | None = None
    opcua: OpcuaConfig | None = None
    backoff_min: float = 1.0
    backoff_max: float = 30.0
    devices: dict[str, DeviceConfig] = field(default_factory=dict, compare=False)
    warnings: tuple[Diagnostic, ...] = field(default=(), compare=False)
    """Located warnings (``drivemap gateway --check`` prints them): a register listed as writable
    that takes no command while its map leaves a field open, a ``writable:`` group that opens none."""


class _Checker:
    """Collects located errors while the document is turned into a config."""

    def __init__(self, doc: Document, project: Project) -> None:
        self.doc = doc
        self.project = project
        self.errors: list[Diagnostic] = []
        self.warnings: list[Diagnostic] = []
        self.base = Path(doc.path).parent
        self.models: dict[Path, Model] = {}

    def compile(self, name: str) -> Model:
        """The model of a map (compiled once per file, however many devices use it)."""
        path = resolve_map(name, self.project).resolve()
        if path not in self.models:
            self.models[path] = compile_map(resolve_map(name, self.project))
        return self.models[path]

    def error(self, where: PathT, message: str, *, key: bool = False) -> None:
        self.errors.append(Diagnostic(self.doc.positions.at(where, key=key), message))

    def warning(self, where: PathT, message: str) -> None:
        self.warnings.append(Diagnostic(self.doc.positions.at(where), message, severity="warning"))

    def path(self, text: str) -> Path:
        p = Path(text)
        return p if p.is_absolute() else self.base / p

    def secret(self, item: dict[str, Any], where: PathT) -> str | None:
        if "password_env" in item:
            value = os.environ.get(item["password_env"])
            if value is None:
                self.error(where + ("password_env",), f"environment variable {item['password_env']} is not set")
            return value
        value = item.get("password")
        return value if isinstance(value, str) else None


def load_config(path: str | os.PathLike[str], project: Project | None = None, *,
                broker: tuple[str, int | None] | None = None) -> GatewayConfig:
    """Load, validate and check a gateway configuration; raise :class:`CompileError` with every error.

    ``broker`` (host, port or None) replaces the configuration's ``mqtt.host`` / ``mqtt.port``
    (``drivemap gateway --broker HOST[:PORT]``)."""
    doc = load_file(display(path))
    if not isinstance(doc.data, dict):
        raise CompileError([Diagnostic(doc.positions.at(()), "a gateway configuration is a YAML mapping")])
    errors = schema.validate(doc, SCHEMA_PATH)
    if errors:
        raise CompileError(errors)
    check = _Checker(doc, project or load_project())
    data = doc.data
    if broker is not None and "mqtt" in data:
        data["mqtt"] = {**data["mqtt"], "host": broker[0], **({"port": broker[1]} if broker[1] else {})}
    buses = tuple(_bus(check, b, ("buses", i)) for i, b in enumerate(data["buses"]))
    _unique_names(check, data)
    mqtt = _mqtt(check, data["name"], data["mqtt"]) if "mqtt" in data else None
    opcua = _opcua(check, data["name"], data["opcua"]) if "opcua" in data else None
    if mqtt is None and opcua is None:
        check.error((), "nothing to serve: give mqtt, opcua or both")
    if check.errors:
        raise CompileError(check.errors)
    backoff = data.get("offline_backoff", {})
    devices = {d.name: d for b in buses for d in b.devices}
    return GatewayConfig(doc.path, data["name"], buses, mqtt, opcua, backoff.get("min", 1.0),
                         backoff.get("max", max(30.0, backoff.get("min", 1.0))), devices, tuple(check.warnings))


def _unique_names(check: _Checker, data: dict[str, Any]) -> None:
    seen_bus: dict[str, PathT] = {}
    seen_dev: dict[str, PathT] = {}
    for i, bus in enumerate(data["buses"]):
        where: PathT = ("buses", i, "name")
        if bus["name"] in seen_bus:
            check.error(where, f"bus name {bus['name']!r} is used twice")
        seen_bus.setdefault(bus["name"], where)
        units: dict[int, str] = {}
        for j, dev in enumerate(bus["devices"]):
            dwhere: PathT = ("buses", i, "devices", j)
            if dev["name"] in seen_dev:
                check.error(dwhere + ("name",), f"device name {dev['name']!r} is used twice")
            if dev["name"] in RESERVED_NAMES or dev["name"] == data["name"]:
                check.error(dwhere + ("name",), f"device name {dev['name']!r} is reserved (gateway topics use it)")
            seen_dev.setdefault(dev["name"], dwhere)
            if dev["unit"] in units:
                check.error(dwhere + ("unit",), f"unit {dev['unit']} is already {units[dev['unit']]!r} on this bus")
            units.setdefault(dev["unit"], dev["name"])


def _bus(check: _Checker, bus: dict[str, Any], where: PathT) -> BusConfig:
    kinds = [k for k in ("tcp", "rtu_over_tcp", "serial") if k in bus]
    if len(kinds) != 1:
        check.error(where, f"bus {bus['name']!r}: give exactly one of serial, tcp and rtu_over_tcp"
                    + (f" (got {', '.join(kinds)})" if kinds else ""))
    kind = kinds[0] if kinds else "tcp"
    host = port = None
    if kind in ("tcp", "rtu_over_tcp") and kind in bus:
        text, _, number = bus[kind].rpartition(":")
        host, port = text.strip("[]"), int(number)
        if not 1 <= port <= 65535:
            check.error(where + (kind,), f"port {port} is outside 1..65535")
    devices = tuple(d for j, raw in enumerate(bus["devices"])
                    if (d := _device(check, raw, where + ("devices", j))) is not None)
    serial = dict(bus["serial"]) if kind == "serial" and "serial" in bus else None
    if serial is not None:
        problem = serial_port_problem(Path(serial["port"]))
        if problem is not None:
            check.error(where + ("serial", "port"), problem)
        for dev in devices:
            mode = serial.get("mode") or (dev.model.protocol.modes[0] if dev.model.protocol.modes else "rtu")
            if mode not in dev.model.protocol.modes:
                check.error(where + ("serial",), f"{dev.name} ({dev.model.name}) does not speak Modbus "
                            f"{mode.upper()} (modes: {', '.join(dev.model.protocol.modes)})")
    return BusConfig(bus["name"], kind, host, port, serial, bus.get("timeout"), bus.get("retries"), devices)


def _model(check: _Checker, dev: dict[str, Any], where: PathT) -> Model | None:
    given = [k for k in ("model", "map") if k in dev]
    if len(given) != 1:
        check.error(where, f"device {dev['name']!r}: give exactly one of model and map")
        return None
    key = given[0]
    name = dev[key] if key == "model" else str(check.path(dev[key]))
    if key == "map":
        problem = map_file_problem(Path(name))
        if problem is not None:
            check.error(where + (key,), problem)
            return None
    try:
        return check.compile(name)
    except CompileError as exc:
        if key == "model" and len(exc.diagnostics) == 1 and "no map for model" in exc.diagnostics[0].message:
            check.error(where + (key,), exc.diagnostics[0].message)
        else:
            check.errors.extend(exc.diagnostics)
        return None


def _device(check: _Checker, dev: dict[str, Any], where: PathT) -> DeviceConfig | None:
    model = _model(check, dev, where)
    if model is None:
        return None
    p = model.protocol
    unit = dev["unit"]
    fixed = {port.fixed_unit for port in p.ports if port.fixed_unit is not None}
    if not (p.unit_min <= unit <= p.unit_max or unit in fixed) or unit == p.broadcast_address:
        check.error(where + ("unit",), f"unit {unit} is not a unit id of {model.name} "
                    f"({p.unit_min}..{p.unit_max}" + (f", or {sorted(fixed)}" if fixed else "") + ")")
    policy = dev.get("page_policy", "raise")
    publish = _publish(check, model, dev, where, policy)
    polls = _polls(check, model, dev, where, publish, policy)
    published = tuple(dict.fromkeys([*publish, *(r for g in polls for r in g.registers)]))
    writable = _writable(check, model, dev, where, published)
    return DeviceConfig(dev["name"], dev.get("title", dev["name"]), model, unit, policy, published, polls, writable)


def _writable(check: _Checker, model: Model, dev: dict[str, Any], where: PathT,
              published: tuple[str, ...]) -> tuple[str, ...]:
    """The registers named (one by one, or by their map group) in the device's ``writable`` list."""
    entries = dev.get("writable", [])
    if entries is True:
        check.error(where + ("writable",), "writable: true is no longer accepted: list the registers (or map groups) "
                    "that take commands, e.g. writable: [run_command, frequency_command]")
        return ()
    out: list[str] = []
    groups = {g.name for g in model.groups}
    shown = set(published)
    for i, name in enumerate(entries or ()):
        here = where + ("writable", i)
        if name in groups and name not in {r.name for r in model.registers}:
            opened = [n for n in group_writables(model, name) if n in shown or not model.register(n).readable]
            if not opened:
                check.warning(here, f"group {name!r} of {model.name} opens no register to commands: "
                              + _why_none(model, name, shown))
            for n in opened:
                _warn_open(check, model, n, here)
            out.extend(opened)
            continue
        try:
            reg = model.register(name)
        except KeyError:
            check.error(here, f"{model.name} has no register or group {name!r}")
            continue
        if not reg.writable:
            check.error(here, f"{model.name}.{name} is read-only in the map")
        elif reg.readable and name not in shown:
            check.error(here, f"{model.name}.{name} is not published: a command reaches only a register the gateway "
                        "publishes (add it to publish)")
        else:
            _warn_open(check, model, name, here)
            out.append(name)
    return tuple(dict.fromkeys(out))


def _warn_open(check: _Checker, model: Model, name: str, here: PathT) -> None:
    """A register listed as writable whose map leaves open a field that decides the written words."""
    reg = model.register(name)
    if reg.open_for_writes:
        check.warning(here, f"{model.name}.{name} takes no command: the map leaves "
                      f"{', '.join(reg.open_for_writes)} open (review:), which decide the words a write sends; "
                      "its reads are published")


def _why_none(model: Model, group: str, shown: set[str]) -> str:
    """Why a group entry of ``writable`` opens no register (for the warning)."""
    regs = model.group_registers(group)
    writable = [r for r in regs if r.writable]
    if not writable:
        return "none of its registers is writable in the map"
    if not group_writables(model, group):
        return (f"its writable registers are link settings ({', '.join(r.name for r in writable[:5])}), "
                "which are opened one by one only")
    return "its writable registers are not published (add them to publish, or list them one by one)"


def _register_ok(check: _Checker, model: Model, name: str, where: PathT) -> bool:
    try:
        reg = model.register(name)
    except KeyError:
        check.error(where, f"{model.name} has no register {name!r}")
        return False
    if not reg.readable:
        check.error(where, f"{model.name}.{name} is write-only: it cannot be published (commands reach it anyway)")
        return False
    return True


def _default_publish(model: Model, policy: str) -> list[str]:
    return [r.name for r in model.registers if r.readable and (r.page is None or policy == "switch")]


def _publish(check: _Checker, model: Model, dev: dict[str, Any], where: PathT, policy: str) -> list[str]:
    if "publish" not in dev:
        return _default_publish(model, policy)
    return [n for i, n in enumerate(dev["publish"]) if _register_ok(check, model, n, where + ("publish", i))]


def _polls(check: _Checker, model: Model, dev: dict[str, Any], where: PathT, publish: list[str],
           policy: str) -> tuple[PollGroup, ...]:
    groups: list[PollGroup] = []
    covered: set[str] = set()
    for i, entry in enumerate(dev.get("poll", ())):
        here = where + ("poll", i)
        if ("group" in entry) == ("registers" in entry):
            check.error(here, "a poll entry gives exactly one of group and registers")
            continue
        if "group" in entry:
            if entry["group"] not in {g.name for g in model.groups}:
                check.error(here + ("group",), f"{model.name} has no group {entry['group']!r} "
                            f"(groups: {', '.join(g.name for g in model.groups)})")
                continue
            names = [r.name for r in model.group_registers(entry["group"])
                     if r.readable and (r.page is None or policy == "switch")]
        else:
            names = [n for j, n in enumerate(entry["registers"])
                     if _register_ok(check, model, n, here + ("registers", j))]
        names = [n for n in names if n not in covered]
        covered.update(names)
        if names:
            groups.append(PollGroup(float(entry["interval"]), tuple(names)))
    rest = tuple(n for n in publish if n not in covered)
    if rest:
        groups.append(PollGroup(float(dev.get("interval", DEFAULT_INTERVAL_S)), rest))
    return tuple(groups)


def _mqtt(check: _Checker, name: str, m: dict[str, Any]) -> MqttConfig:
    rec = m.get("reconnect", {})
    low = float(rec.get("min", 1.0))
    return MqttConfig(
        host=m["host"], port=m.get("port", 1883), prefix=m.get("prefix", "drivemap"),
        client_id=m.get("client_id", f"drivemap-{name}"), username=m.get("username"),
        password=check.secret(m, ("mqtt",)), qos=m.get("qos", 1), keepalive=m.get("keepalive", 30),
        reconnect_min=low, reconnect_max=max(low, float(rec.get("max", 30.0))),
        discovery=m.get("discovery", True), discovery_prefix=m.get("discovery_prefix", "homeassistant"),
        ha_version=_ha_version(m.get("ha_version")),
    )


def _ha_version(text: str | None) -> tuple[int, int] | None:
    """``mqtt.ha_version`` ("2024.3"; the schema checks its form) as (year, month)."""
    if text is None:
        return None
    year, month = str(text).split(".")[:2]
    return int(year), int(month)


def _opcua(check: _Checker, name: str, o: dict[str, Any]) -> OpcuaConfig:
    where: PathT = ("opcua",)
    security = tuple(o.get("security", ["none"]))
    cert = check.path(o["certificate"]) if "certificate" in o else None
    key = check.path(o["private_key"]) if "private_key" in o else None
    signing = [s for s in security if s != "none"]
    if (signing or o.get("trusted_certificates")) and (cert is None or key is None):
        check.error(where, "security policies that sign, and client certificates, need certificate and private_key")
    for label, p in (("certificate", cert), ("private_key", key)):
        if p is not None and not p.is_file():
            check.error(where + (label,), f"no such file: {display(p)}")
    if cert is not None and key is not None and cert.is_file() and key.is_file():
        problem = key_pair_problem(cert, key)
        if problem is not None:
            check.error(where + (problem[0],), problem[1])
    users = []
    _unique_users(check, o)
    for i, u in enumerate(o.get("users", ())):
        secret = check.secret(u, where + ("users", i))
        if secret is None and "password_env" not in u:
            check.error(where + ("users", i), f"user {u['name']!r}: give password or password_env")
        users.append(OpcuaUser(u["name"], secret, None, u.get("write", True)))
    for i, c in enumerate(o.get("trusted_certificates", ())):
        path = check.path(c["certificate"])
        unusable = f"no such file: {display(path)}" if not path.is_file() else certificate_problem(path)
        if unusable is not None:
            check.error(where + ("trusted_certificates", i, "certificate"), unusable)
        users.append(OpcuaUser(c["name"], None, path, c.get("write", True)))
    bad_endpoint = endpoint_problem(o["endpoint"])
    if bad_endpoint is not None:
        check.error(where + ("endpoint",), bad_endpoint)
    lim = o.get("limits", {})
    limits = OpcuaLimits(**{k: lim[k] for k in ("max_connections", "per_source", "anonymous_sessions", "reserve",
                                                 "handshake_timeout") if k in lim})
    if limits.reserve >= limits.max_connections:
        check.error(where + ("limits", "reserve"), f"reserve {limits.reserve} leaves no connection for anyone else "
                    f"(max_connections {limits.max_connections})")
    return OpcuaConfig(o["endpoint"], o.get("namespace", f"urn:drivemap:{name}"), security, cert, key, tuple(users),
                       o.get("anonymous", True), o.get("anonymous_writes", False), limits,
                       check.doc.positions.at(where + ("endpoint",)))


def _unique_users(check: _Checker, o: dict[str, Any]) -> None:
    """User names are unique across ``users`` and ``trusted_certificates`` (a name is one set of rights)."""
    seen: dict[str, Location] = {}
    for key in ("users", "trusted_certificates"):
        for i, u in enumerate(o.get(key, ())):
            here: PathT = ("opcua", key, i, "name")
            if u["name"] in seen:
                first = seen[u["name"]]
                check.error(here, f"user name {u['name']!r} is used twice (first at line {first.line}): "
                            "each user has one password or certificate and one write right")
            else:
                seen[u["name"]] = check.doc.positions.at(here)
