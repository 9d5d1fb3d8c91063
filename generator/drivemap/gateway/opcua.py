"""The OPC UA side of the gateway (asyncua, the optional extra ``drivemap[opcua]``).

Address space, in the configured namespace: ``Objects/<gateway>/<device>`` (one object per device)
with an ``Online`` boolean and one variable per register, named as in the map. AccessLevel:
CurrentRead for published registers, CurrentWrite for those in the device's ``writable`` list
(arrays are read-only here); a write-only register's value reads ``BadNotReadable``.
UserAccessLevel (answered per session by a PostRead callback) drops CurrentWrite for sessions that
may not write. ``EngineeringUnits`` carry the UNECE unit id, data types follow the register type
(:mod:`drivemap.gateway.opcua_types`); ``EURange`` where the map gives min and max; for enumerated
registers ``EnumValues`` (value, name, label) plus ``EnumStrings`` when the values run 0..n-1. A
not-available value (the client reads None) is a null value with the status ``BadNoData``.
Connections are admitted by :mod:`drivemap.gateway.opcua_limits`.

Writes go through the same checks as MQTT commands (:meth:`drivemap.gateway.device.Device.command`)
before anything is queued, then wait for the device's reply; the status says what happened:
``BadUserAccessDenied`` (anonymous writes are off unless ``anonymous_writes: true``, or a user
without ``write``), ``BadNotWritable`` (a read-only register, an array, a register the device's
``writable`` list does not name, or one whose map leaves open a field that decides the written
words: the log names the fields), ``BadTypeMismatch`` (a variant of another type than the
variable's DataType: a UInt16 variable takes a UInt16, never an Int32 or a Double; or a value the
register's type does not take), ``BadOutOfRange``, ``BadTimeout`` /
``BadCommunicationError`` (no answer), ``BadDeviceFailure`` (exception reply).

Security: the policies listed in ``security`` (``none``, ``Basic256Sha256_Sign``,
``Basic256Sha256_SignAndEncrypt``; signing ones need ``certificate`` and ``private_key``), users
with passwords, client certificates mapped to users, anonymous sessions on or off.
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
from typing import Any

from asyncua import ua as _ua
from asyncua.common.callback import CallbackType
from asyncua.crypto.permission_rules import SimpleRoleRuleset, User, UserRole
from asyncua.server.address_space import AttributeService
from asyncua.server.internal_server import InternalServer

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.gateway.config import OpcuaConfig, OpcuaUser
from drivemap.gateway.device import Device, open_fields_reason
from drivemap.gateway.opcua_limits import LimitedServer, anonymous_sessions
from drivemap.gateway.opcua_types import CEFACT, unit_id, variant_name
from drivemap.model.nodes import Register
from drivemap.runtime.errors import (
    AccessError,
    DeviceException,
    DriveError,
    DriveTimeout,
    InvalidValue,
    TransportError,
    UnknownRegister,
    ValueOutOfRange,
)

log = logging.getLogger("drivemap.gateway.opcua")
#: asyncua's ``ua`` namespace, used untyped (its stubs do not export the generated names).
ua: Any = _ua

_POLICIES = {
    "none": ua.SecurityPolicyType.NoSecurity,
    "Basic256Sha256_Sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
    "Basic256Sha256_SignAndEncrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
}
#: Seconds a write waits for its bus (commands queue behind the poll in progress).
WRITE_TIMEOUT_S = 30.0


def _status(code: int) -> Any:
    return ua.StatusCode(code)


def status_for(error: BaseException) -> Any:
    """The OPC UA status code of a drivemap error."""
    if isinstance(error, AccessError):
        return ua.StatusCodes.BadNotWritable
    if isinstance(error, ValueOutOfRange):
        return ua.StatusCodes.BadOutOfRange
    if isinstance(error, (InvalidValue, UnknownRegister)):
        return ua.StatusCodes.BadTypeMismatch
    if isinstance(error, DriveTimeout):
        return ua.StatusCodes.BadTimeout
    if isinstance(error, TransportError):
        return ua.StatusCodes.BadCommunicationError
    if isinstance(error, DeviceException):
        return ua.StatusCodes.BadDeviceFailure
    return ua.StatusCodes.BadInternalError


class _IdentityCertificate(bytes):
    """A client certificate from an X509 identity token whose signature the server verified; asyncua
    passes the secure channel's certificate to the user manager the same way, as plain bytes."""


class _InternalServer(InternalServer):
    """asyncua's internal server, marking the certificates of X509 identity tokens (see :class:`_Users`)."""

    def verify_x509_token(self, isession: Any, token: Any, signature: Any) -> bytes:
        return _IdentityCertificate(super().verify_x509_token(isession, token, signature))


class _Users:
    """asyncua user manager: configured passwords, client certificates (X509 identity tokens) mapped to
    users, anonymous sessions when allowed.

    A user is who the identity token says: a password, or a certificate in ``trusted_certificates``
    (an X509 token signed with its private key). An identity certificate that is not trusted is
    refused, never taken for anonymous. The secure channel's own certificate authenticates the client
    application, not a user: a session over a signed channel with an anonymous token is anonymous.
    """

    def __init__(self, cfg: OpcuaConfig, certificates: dict[bytes, OpcuaUser], clients: Any = None) -> None:
        self.cfg = cfg
        self.certificates = certificates
        self.clients = clients
        """A callable returning the server's connections (to count anonymous sessions), once it runs."""

    def get_user(self, iserver: Any, username: str | None = None, password: str | None = None,
                 certificate: Any = None) -> User | None:
        if username is not None:
            for u in self.cfg.users:
                if u.password is not None and u.name == username and hmac.compare_digest(
                        u.password.encode(), (password or "").encode()):
                    return User(role=UserRole.User, name=u.name)
            return None
        if isinstance(certificate, _IdentityCertificate):
            found = self.certificates.get(bytes(certificate))
            return User(role=UserRole.User, name=found.name) if found is not None else None
        if not self.cfg.anonymous:
            return None
        if self.clients is not None and anonymous_sessions(self.clients()) >= self.cfg.limits.anonymous_sessions:
            log.warning("OPC UA: refusing an anonymous session (%d at once)", self.cfg.limits.anonymous_sessions)
            return None
        return User(role=UserRole.Anonymous)


class _Ruleset(SimpleRoleRuleset):
    """asyncua's roles, except that anonymous sessions may use the services users may (reading, browsing,
    subscribing); whether anyone may *write* a register is decided by :meth:`OpcuaBridge.write`."""

    def __init__(self) -> None:
        super().__init__()  # type: ignore[no-untyped-call]
        table: Any = self._permission_dict
        table[UserRole.Anonymous] = set(table[UserRole.User])


class _CheckedWrites(AttributeService):
    """Writes to register variables go to the device through the bridge; others as asyncua does them."""

    def __init__(self, aspace: Any, bridge: OpcuaBridge) -> None:
        super().__init__(aspace)
        self.bridge = bridge

    async def write(self, params: Any, user: User | None = None) -> list[Any]:
        user = user if user is not None else User(role=UserRole.Admin)
        results: list[ua.StatusCode] = []
        for item in params.NodesToWrite:
            target = self.bridge.targets.get(item.NodeId)
            if target is None or item.AttributeId != ua.AttributeIds.Value:
                results.extend(await super().write(ua.WriteParameters(NodesToWrite=[item]), user))
            else:
                results.append(await self.bridge.write(target[0], target[1], item.Value, user))
        return results


def _variant_type(reg: Register) -> ua.VariantType:
    """The variant type of a register's value (:func:`drivemap.gateway.opcua_types.variant_name`)."""
    return getattr(ua.VariantType, variant_name(reg))


_INITIAL: dict[ua.VariantType, Any] = {ua.VariantType.Boolean: False, ua.VariantType.String: "",
                                       ua.VariantType.Float: 0.0, ua.VariantType.Double: 0.0}


def data_value(reg: Register, raw: Any) -> ua.DataValue:
    """The DataValue of a published value; a not-available value (None) is a null value with the
    status BadNoData (a Variant of a type cannot hold None)."""
    if raw is None or (isinstance(raw, list) and any(v is None for v in raw)):
        return ua.DataValue(ua.Variant(), StatusCode=ua.StatusCode(ua.StatusCodes.BadNoData))
    return ua.DataValue(ua.Variant(raw, _variant_type(reg)))


def _raw_of(device: Device, reg: Register, value: Any) -> Any:
    """The OPC UA value of one published element (enum names and bit fields back to integers)."""
    if reg.enum is not None and isinstance(value, str):
        if value.startswith("UNKNOWN_"):
            return int(value[8:])
        return next(v.value for v in device.model.enum(reg.enum).members if v.name == value)
    if reg.bits and isinstance(value, dict):
        raw = 0
        for bit in reg.bits:
            v = value.get(bit.name, 0)
            if isinstance(v, str) and v.startswith("UNKNOWN_"):  # a value the map does not list: its bits
                v = int(v[8:])
            elif isinstance(v, str) and bit.enum is not None:
                v = next((e.value for e in device.model.enum(bit.enum).members if e.name == v), 0)
            raw |= (int(v) & ((1 << bit.width) - 1)) << bit.offset
        return raw
    return value


def _bits_json(device: Device, reg: Register, raw: int) -> dict[str, Any]:
    """The bit fields of a raw value written over OPC UA; a value that does not fit the register or
    sets a bit the map does not define is refused, never truncated."""
    width = 16 * {"u16": 1, "s16": 1, "u32": 2, "s32": 2}.get(reg.type, 4)
    if not 0 <= raw < 1 << width:
        raise ValueOutOfRange(f"{reg.name}: {raw} does not fit the register's {width} bits")
    defined = 0
    for bit in reg.bits:
        defined |= ((1 << bit.width) - 1) << bit.offset
    if raw & ~defined:
        raise ValueOutOfRange(f"{reg.name}: bit(s) {raw & ~defined:#x} are not defined by the map")
    out: dict[str, Any] = {}
    for bit in reg.bits:
        v = (raw >> bit.offset) & ((1 << bit.width) - 1)
        if bit.enum is not None:
            names = {e.value: e.name for e in device.model.enum(bit.enum).members}
            out[bit.name] = names.get(v, v)
        else:
            out[bit.name] = bool(v) if bit.width == 1 else v
    return out


class OpcuaBridge:
    """An asyncua server mirroring the devices; a :class:`~drivemap.gateway.lines.Sink`."""

    def __init__(self, cfg: OpcuaConfig, gateway: str, devices: dict[str, Device], submit: Any) -> None:
        self.cfg = cfg
        self.gateway = gateway
        self.devices = devices
        self.submit = submit
        self.server: LimitedServer | None = None
        self.nodes: dict[tuple[str, str], ua.NodeId] = {}
        self.online_nodes: dict[str, ua.NodeId] = {}
        self.targets: dict[ua.NodeId, tuple[Device, Register]] = {}
        self.idx = 0
        self._updates: asyncio.Queue[tuple[ua.NodeId, ua.DataValue]] = asyncio.Queue()
        self._task: asyncio.Task[None] | None = None
        self.writers = {u.name for u in cfg.users if u.write}
        self.levels: dict[Any, int] = {}
        """AccessLevel of every register node; a session's UserAccessLevel is this less what its user may not do."""

    def _clients(self) -> list[Any]:
        bserver = getattr(self.server, "bserver", None) if self.server is not None else None
        return list(bserver.clients) if bserver is not None else []

    def user_level(self, level: int, user: User | None) -> int:
        """The access a session has to a register of AccessLevel ``level``."""
        role = getattr(user, "role", UserRole.Anonymous)
        may_write = role == UserRole.Admin or (role == UserRole.Anonymous and self.cfg.anonymous_writes) or (
            role == UserRole.User and getattr(user, "name", None) in self.writers)
        return level if may_write else level & ~ua.AccessLevel.CurrentWrite.mask

    async def _after_read(self, event: Any, _dispatcher: Any) -> None:
        """Reads of UserAccessLevel answer what the session's user may do (PostRead callback)."""
        results = event.response_params
        if not isinstance(results, list):
            return
        for i, item in enumerate(event.request_params.NodesToRead):
            level = self.levels.get(item.NodeId)
            if level is not None and item.AttributeId == ua.AttributeIds.UserAccessLevel and i < len(results):
                results[i] = ua.DataValue(ua.Variant(self.user_level(level, event.user), ua.VariantType.Byte))

    # ------------------------------------------------------------------ server
    async def _certificates(self) -> dict[bytes, OpcuaUser]:
        from asyncua.crypto import uacrypto

        out: dict[bytes, OpcuaUser] = {}
        for u in self.cfg.users:
            if u.certificate is not None:
                cert = await uacrypto.load_certificate(u.certificate)
                out[uacrypto.der_from_x509(cert)] = u  # type: ignore[no-untyped-call]
        return out

    async def start(self) -> None:
        cfg = self.cfg
        users = _Users(cfg, await self._certificates(), self._clients)
        server = LimitedServer(iserver=_InternalServer(user_manager=users))  # type: ignore[arg-type]
        server.admission = cfg.limits
        await server.init()
        server.set_endpoint(cfg.endpoint)
        server.set_server_name(f"drivemap gateway {self.gateway}")
        await server.set_application_uri(f"urn:drivemap:gateway:{self.gateway}")
        server.set_security_policy([_POLICIES[p] for p in cfg.security], permission_ruleset=_Ruleset())
        tokens: list[type] = [ua.UserNameIdentityToken] if any(u.password for u in cfg.users) else []
        if cfg.anonymous:
            tokens.append(ua.AnonymousIdentityToken)
        if any(u.certificate for u in cfg.users):
            tokens.append(ua.X509IdentityToken)
        server.set_identity_tokens(tokens)
        if cfg.certificate is not None and cfg.private_key is not None:
            await server.load_certificate(str(cfg.certificate))
            await server.load_private_key(str(cfg.private_key))
        self.idx = await server.register_namespace(cfg.namespace)
        folder = await server.nodes.objects.add_folder(ua.NodeId(self.gateway, self.idx), f"{self.idx}:{self.gateway}")
        for device in self.devices.values():
            await self._add_device(folder, device)
        server.iserver.attribute_service = _CheckedWrites(server.iserver.aspace, self)
        server.subscribe_server_callback(CallbackType.PostRead, self._after_read)
        try:
            await server.start()
        except OSError as exc:  # the port is taken since --check, or the address is not this host's
            where = cfg.endpoint_at or Location("<config>", 1, 1)
            raise CompileError([Diagnostic(where, f"endpoint {cfg.endpoint!r}: cannot listen: "
                                                  f"{exc.strerror or exc}")]) from None
        self.server = server
        self._task = asyncio.create_task(self._apply_updates(), name="opcua updates")
        log.info("OPC UA server on %s (namespace %s)", cfg.endpoint, cfg.namespace)

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        if self.server is not None:
            await self.server.stop()
            self.server = None

    async def _add_device(self, folder: Any, device: Device) -> None:
        obj = await folder.add_object(ua.NodeId(f"{device.name}", self.idx), f"{self.idx}:{device.name}")
        online = await obj.add_variable(ua.NodeId(f"{device.name}.Online", self.idx), f"{self.idx}:Online", False,
                                        ua.VariantType.Boolean)
        self.online_nodes[device.name] = online.nodeid
        published = set(device.cfg.publish)
        for reg in device.model.registers:
            if reg.name in published or (device.may_write(reg.name) and not reg.is_array):
                await self._add_register(obj, device, reg, reg.name in published)

    async def _add_register(self, obj: Any, device: Device, reg: Register, readable: bool) -> None:
        vtype = _variant_type(reg)
        first = _INITIAL.get(vtype, 0)
        initial: Any = [first] * reg.count if reg.is_array else first
        node = await obj.add_variable(ua.NodeId(f"{device.name}.{reg.name}", self.idx), f"{self.idx}:{reg.name}", initial, vtype)
        writable = device.commandable(reg) and not reg.is_array
        level = (ua.AccessLevel.CurrentRead.mask if readable else 0) | (ua.AccessLevel.CurrentWrite.mask if writable else 0)
        for attr in (ua.AttributeIds.AccessLevel, ua.AttributeIds.UserAccessLevel):
            await node.write_attribute(attr, ua.DataValue(ua.Variant(level, ua.VariantType.Byte)))
        if not readable:  # a write-only register has no value to read: never a Good 0
            await node.write_attribute(ua.AttributeIds.Value, ua.DataValue(
                ua.Variant(), StatusCode=ua.StatusCode(ua.StatusCodes.BadNotReadable)))
        self.levels[node.nodeid] = level
        description = reg.description or reg.label or reg.name
        await node.write_attribute(ua.AttributeIds.Description,
                                   ua.DataValue(ua.Variant(ua.LocalizedText(description), ua.VariantType.LocalizedText)))
        await self._properties(node, device, reg)
        self.nodes[(device.name, reg.name)] = node.nodeid
        self.targets[node.nodeid] = (device, reg)

    async def _properties(self, node: Any, device: Device, reg: Register) -> None:
        name = device.name + "." + reg.name
        eu = ua.EUInformation(NamespaceUri=CEFACT, UnitId=unit_id(reg.unit),
                              DisplayName=ua.LocalizedText(reg.unit or ""), Description=ua.LocalizedText(reg.unit or ""))
        await node.add_property(ua.NodeId(f"{name}.EngineeringUnits", self.idx), "0:EngineeringUnits", eu,
                                datatype=ua.ObjectIds.EUInformation)
        if reg.min is not None and reg.max is not None:
            await node.add_property(ua.NodeId(f"{name}.EURange", self.idx), "0:EURange",
                                    ua.Range(Low=float(reg.min), High=float(reg.max)), datatype=ua.ObjectIds.Range)
        if reg.enum is None:
            return
        values = device.model.enum(reg.enum).members
        items = [ua.EnumValueType(Value=v.value, DisplayName=ua.LocalizedText(v.name),
                                  Description=ua.LocalizedText(v.label)) for v in values]
        await node.add_property(ua.NodeId(f"{name}.EnumValues", self.idx), "0:EnumValues", items,
                                datatype=ua.ObjectIds.EnumValueType)
        if [v.value for v in values] == list(range(len(values))):
            await node.add_property(ua.NodeId(f"{name}.EnumStrings", self.idx), "0:EnumStrings",
                                    [ua.LocalizedText(v.name) for v in values], ua.VariantType.LocalizedText)

    # ------------------------------------------------------------------ Sink
    def publish_values(self, device: Device, values: dict[str, Any], changed: dict[str, Any]) -> None:
        for name, value in changed.items():
            nodeid = self.nodes.get((device.name, name))
            if nodeid is None:
                continue
            reg = device.model.register(name)
            raw = [_raw_of(device, reg, v) for v in value] if isinstance(value, list) else _raw_of(device, reg, value)
            self._updates.put_nowait((nodeid, data_value(reg, raw)))

    def publish_availability(self, device: Device, online: bool) -> None:
        nodeid = self.online_nodes.get(device.name)
        if nodeid is not None:
            self._updates.put_nowait((nodeid, ua.DataValue(ua.Variant(online, ua.VariantType.Boolean))))

    def publish_outcome(self, device: Device, outcome: dict[str, Any]) -> None:
        return None

    async def _apply_updates(self) -> None:
        while True:
            nodeid, value = await self._updates.get()
            if self.server is not None:
                await self.server.write_attribute_value(nodeid, value)

    # ------------------------------------------------------------------ writes
    async def write(self, device: Device, reg: Register, value: ua.DataValue, user: User) -> Any:
        if user.role == UserRole.Anonymous and not self.cfg.anonymous_writes:
            return _status(ua.StatusCodes.BadUserAccessDenied)
        if user.role == UserRole.User and user.name not in self.writers:
            return _status(ua.StatusCodes.BadUserAccessDenied)
        if not reg.writable or reg.is_array or not device.may_write(reg.name) or reg.open_for_writes:
            if reg.open_for_writes:
                log.warning("OPC UA: refusing a write: %s", open_fields_reason(device.name, reg))
            return _status(ua.StatusCodes.BadNotWritable)
        expected = _variant_type(reg)
        if value.Value is None or value.Value.VariantType != expected or value.Value.is_array:
            got = value.Value.VariantType.name if value.Value is not None else "no value"
            log.warning("OPC UA: refusing a write of %s to %s.%s (a %s)", got, device.name, reg.name, expected.name)
            return _status(ua.StatusCodes.BadTypeMismatch)
        given = value.Value.Value
        try:
            if reg.bits and isinstance(given, int) and not isinstance(given, bool):
                given = _bits_json(device, reg, given)
            cmd = device.command(reg.name, json.dumps(given), "opcua")
        except DriveError as exc:
            return _status(status_for(exc))
        except (TypeError, ValueError, OverflowError):
            return _status(ua.StatusCodes.BadTypeMismatch)
        except Exception:  # noqa: BLE001 - no write may stop the server: logged, answered
            log.exception("OPC UA write of %s.%s failed", device.name, reg.name)
            return _status(ua.StatusCodes.BadInternalError)
        cmd.done = asyncio.get_running_loop().create_future()
        self.submit(cmd)
        try:
            await asyncio.wait_for(asyncio.shield(cmd.done), WRITE_TIMEOUT_S)
        except DriveError as exc:
            return _status(status_for(exc))
        except TimeoutError:
            return _status(ua.StatusCodes.BadTimeout)
        return _status(ua.StatusCodes.Good)
