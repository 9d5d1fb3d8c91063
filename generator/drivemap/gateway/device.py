"""One drive behind the gateway: its generated async client, what it publishes and the commands it takes.

Values leave in engineering units as JSON values: numbers whole, as the codec decodes them (a value
scaled by a scale register with the factor read with it; an unscaled f32 as the shortest decimal of
the same f32), strings as text, coils and bools as true/false, a not-available value as null, enum
registers as the member's name (``FORWARD_RUNNING``; an undocumented raw value as ``UNKNOWN_<n>``),
bit-field registers as an object of their fields (single bits true/false, enumerated fields by name,
wider fields as integers), arrays as lists of those. A value topic shows a number as the runtime
shows it (:func:`drivemap.runtime.client.values.display.register_text`: ``4.00`` at the map's precision 2);
precision is for people, JSON and OPC UA carry the value whole.

Commands are parsed and checked here, before they are queued: the register must exist, be
writable in the map and be listed in the device's ``writable`` list; the payload is parsed strictly
and bounded (:mod:`drivemap.gateway.payload`), must have the register's type, and must pass the
codec's checks (range, enum membership, representability, exactness: a value the register cannot
hold exactly is refused, never rounded). A register whose map leaves open a field that decides the
words a write sends (``review:`` naming its type, scale, word order, table, address ...:
:attr:`~drivemap.runtime.spec.RegisterSpec.open_for_writes`) takes no command
(:class:`UnreviewedRegister`, naming the open fields); its reads are published as usual. A register with a value set takes
a value of the set by option text, label or value (:mod:`drivemap.gateway.valuesets`). Everything that fails raises a
typed :class:`~drivemap.runtime.errors.DriveError`; only checked raw values reach the bus.
"""

from __future__ import annotations

import asyncio
import dataclasses
import enum
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from drivemap.gateway.config import DeviceConfig, PollGroup
from drivemap.gateway.payload import (
    bool_word,
    index_word,
    integer_word,
    number,
    parse_json,
    payload_text,
    show,
)
from drivemap.gateway.valuesets import set_value
from drivemap.model.nodes import Model, Register
from drivemap.runtime.client.protocol.review import sign_checked
from drivemap.runtime.client.values.codec import (
    BoolCodec,
    EnumCodec,
    FieldsCodec,
    FlagCodec,
    StringCodec,
    check_raw,
    unwrap,
)
from drivemap.runtime.client.values.display import display_text, register_text
from drivemap.runtime.errors import AccessError, InvalidValue, ReadOnlyRegister, UnknownRegister, ValueOutOfRange

#: Payload that presses a command register (a Home Assistant button sends it).
PRESS = "PRESS"


class UnreviewedRegister(AccessError):
    """A command for a register whose map still leaves open (``review:``) a field that decides the
    words a write sends: nothing is written until a person states it."""


def open_fields_reason(device: str, reg: Register) -> str:
    """Why ``reg`` takes no command: the open fields that decide what a write sends."""
    fields = ", ".join(reg.open_for_writes)
    return (f"{device}.{reg.name}: the map leaves {fields} open (review: {list(reg.open_for_writes)}), "
            "which decide the words a write sends: state them in the map before writing")


@dataclass
class Command:
    """A checked write waiting for its bus: ``raw`` is what goes on the wire."""

    device: Device
    target: str
    """``register`` or ``register[i]``."""
    accessor: Any
    raw: int | None
    """None for a register with a scale register: ``value`` is written through the accessor, which
    reads the factor just before the write (never a stale one)."""
    given: Any
    """The value as the sender gave it (echoed in the outcome)."""
    source: str = "mqtt"
    value: Any = None
    done: asyncio.Future[None] | None = None


@dataclass
class PollState:
    group: PollGroup
    accessors: tuple[Any, ...]
    due: float = 0.0


def _enum_name(value: Any) -> Any:
    return value.name if isinstance(value, enum.Enum) else value


class Device:
    """A configured device: its client on a bus, its poll schedule, its last values and availability."""

    def __init__(self, cfg: DeviceConfig, package: Any, bus: Any, prefix: str = "drivemap") -> None:
        self.cfg = cfg
        self.name = cfg.name
        self.model: Model = cfg.model
        self.package = package
        self.client = package.AsyncClient(bus, cfg.unit, page_policy=cfg.page_policy)
        self.topic = f"{prefix}/{cfg.name}"
        self.polls = [PollState(g, tuple(self.client.accessor(n) for n in g.registers)) for g in cfg.polls]
        self.values: dict[str, Any] = {}
        self.online: bool | None = None
        self.failures = 0
        self.retry_at = 0.0
        self.last_error: str | None = None
        self.polls_done = 0

    # ------------------------------------------------------------------ values
    def register(self, name: str) -> Register:
        return self.model.register(name)

    def to_json(self, name: str, value: Any) -> Any:
        """The published (JSON) form of a decoded value of register ``name``."""
        reg = self.register(name)
        if isinstance(value, tuple):
            return [self._element_json(reg, v) for v in value]
        return self._element_json(reg, value)

    def _element_json(self, reg: Register, value: Any) -> Any:
        if reg.bits:
            return self.bits_json(reg, value)
        if isinstance(value, enum.Enum):
            return value.name
        if isinstance(value, float) and math.isfinite(value):
            spec = self.package.SPEC.register(reg.name)  # the value whole: precision is for the text only
            return float(display_text(value, single=spec.type == "f32" and spec.scale == 1 and spec.offset == 0))
        return value

    def value_text(self, name: str, value: Any) -> str | None:
        """The text of a value topic for a published number of register ``name`` (``4.00`` at
        precision 2); None for what is not a single number (the caller writes JSON)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return None
        return register_text(self.package.SPEC.register(name), value)

    def bits_json(self, reg: Register, value: Any) -> dict[str, Any]:
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            codec = self.client.CODECS[reg.name]
            assert isinstance(codec, FieldsCodec)
            return {bit.name: (bool(v) if bit.width == 1 and not isinstance(v, enum.Enum) else _enum_name(v))
                    for f, bit in codec.fields for v in (getattr(value, f.attribute),)}
        raw = int(value)
        return {b.name: bool((raw >> b.offset) & 1) for b in reg.bits}

    def snapshot_json(self, snap: Any, accessors: tuple[Any, ...]) -> dict[str, Any]:
        return {acc.name: self.to_json(acc.name, snap[acc]) for acc in accessors}

    # ------------------------------------------------------------------ commands
    def element(self, target: str) -> tuple[Register, Any]:
        """The register and accessor of ``register`` or ``register[i]`` / ``register/i``."""
        base, _, index = target.replace("/", "[", 1).partition("[")
        try:
            reg = self.register(base)
        except KeyError:
            raise UnknownRegister(f"{self.model.name} has no register {show(base)}") from None
        if index:
            acc = self.client.accessor(f"{base}[{index_word(base, index.rstrip(']'))}]")
        else:
            acc = self.client.accessor(base)
        if reg.is_array and not index:
            raise InvalidValue(f"{base} is an array: address one element, {base}/INDEX/set")
        return reg, acc

    def may_write(self, name: str) -> bool:
        """Whether the gateway's configuration lets commands reach register ``name``."""
        return name in self.cfg.writable

    def commandable(self, reg: Register) -> bool:
        """Whether commands for ``reg`` are offered (discovery's controls, OPC UA's CurrentWrite):
        writable in the map, listed in ``writable``, and no field that decides its words open."""
        return reg.writable and self.may_write(reg.name) and not reg.open_for_writes

    def command(self, target: str, payload: bytes | str, source: str = "mqtt") -> Command:
        """Parse and check a command; raise a typed DriveError before anything is queued."""
        text = payload_text(payload)
        reg, acc = self.element(target)
        if not reg.writable:
            raise ReadOnlyRegister(f"{reg.name} is read-only")
        if not self.may_write(reg.name):
            raise ReadOnlyRegister(f"{self.name}.{reg.name}: the gateway configuration does not accept commands for "
                                   "it (list it in the device's writable)")
        if reg.open_for_writes:
            raise UnreviewedRegister(open_fields_reason(self.name, reg))
        if reg.command_value is not None:  # a command register takes PRESS (or its command value) only
            if text.strip().upper() != PRESS and integer_word(text.strip()) != reg.command_value:
                raise InvalidValue(f"{reg.name} is a command: send {PRESS} (it writes {reg.command_value}), "
                                   f"got {show(text)}")
            raw = check_raw(acc.spec, reg.command_value)
            return Command(self, acc.name, acc, raw, text, source)
        value = self.parse_value(reg, acc, text)
        if acc.codec.scale_key is not None:
            acc.codec.check(value)
            return Command(self, acc.name, acc, None, text, source, value=value)
        raw = sign_checked(acc.codec.spec, acc.codec.encode(value))  # exact or refused (InexactValue): the codec's one rule
        return Command(self, acc.name, acc, raw, text, source)

    def parse_value(self, reg: Register, acc: Any, text: str) -> Any:
        """The Python value for ``acc`` from a payload text (JSON or plain)."""
        codec = unwrap(acc.codec)
        if reg.optional and text.strip() in ("null", "None", ""):
            return None  # writes the map's first not-available value
        if reg.values and not isinstance(codec, (BoolCodec, EnumCodec, FlagCodec, FieldsCodec)):
            value = set_value(reg, acc.spec, text)
            return value if isinstance(value, str) else number(reg.name, value, integer=_integer(reg))
        if isinstance(codec, StringCodec):
            return _text_value(text)
        if isinstance(codec, BoolCodec):
            return _bool_value(reg, text)
        if isinstance(codec, EnumCodec):
            return _parse_enum(reg, codec, self.model, text)
        if isinstance(codec, (FlagCodec, FieldsCodec)):
            return _parse_bits(reg, codec, self.model, parse_json(reg.name, text))
        value = parse_json(reg.name, text)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidValue(f"{reg.name}: expected a number, got {show(text)}")
        return number(reg.name, value, integer=_integer(reg))

    def command_value(self, reg: Register, value: Any) -> Any:
        """The Python value for a typed OPC UA write (numbers; enum registers take the raw value)."""
        acc = self.client.accessor(reg.name)
        return self.parse_value(reg, acc, json.dumps(value))


def _integer(reg: Register) -> bool:
    return reg.is_integer and reg.type not in ("f32", "f64")


def _text_value(text: str) -> str:
    """A string payload: a JSON string, or the text as sent."""
    if text.startswith('"'):
        try:
            value = json.loads(text)
        except ValueError:
            return text
        if isinstance(value, str):
            return value
    return text


def _bool_value(reg: Register, text: str) -> bool:
    return bool_word(reg.name, text)


def _parse_enum(reg: Register, codec: EnumCodec[Any], model: Model, text: str) -> Any:
    """A member by name (any case) or label, or by its value written as a bare ASCII integer (a
    quoted ``"12"`` is a name, and no member is called that)."""
    quoted = text.strip().startswith('"')
    word = _text_value(text.strip()) if quoted else text.strip()
    assert reg.enum is not None
    values = model.enum(reg.enum).members
    for v in values:
        if word.upper() == v.name.upper():
            return codec.enum_type(v.value)
    labels = [v for v in values if v.label == word]
    if len(labels) == 1:
        return codec.enum_type(labels[0].value)
    given = None if quoted else integer_word(word)
    if given is None:
        names = ", ".join(v.name for v in values)
        raise InvalidValue(f"{reg.name}: {show(word)} is not a value of {reg.enum} ({names})")
    if given not in {v.value for v in values}:
        raise ValueOutOfRange(f"{reg.name}: {given} is not a value of {reg.enum}")
    return codec.enum_type(given)


def _field_value(reg: Register, bit: Any, enum_type: Any, model: Model, value: Any) -> Any:
    if enum_type is not None:
        if isinstance(value, str):
            for v in model.enum(bit.enum).members:
                if v.name.upper() == value.upper():
                    return enum_type(v.value)
            raise InvalidValue(f"{reg.name}.{bit.name}: {value!r} is not a value of {bit.enum}")
        if isinstance(value, int) and not isinstance(value, bool):
            return enum_type(value)
        raise InvalidValue(f"{reg.name}.{bit.name}: expected a name of {bit.enum}")
    if bit.width == 1:
        if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
            return bool(value)
        raise InvalidValue(f"{reg.name}.{bit.name}: a single bit is true/false or 1/0, got {repr(value)[:40]}")
    if isinstance(value, int) and not isinstance(value, bool):
        if not 0 <= value < 1 << bit.width:
            raise ValueOutOfRange(f"{reg.name}.{bit.name}: {repr(value)[:40]} does not fit {bit.width} bits")
        return value
    raise InvalidValue(f"{reg.name}.{bit.name}: expected an integer")


def _parse_bits(reg: Register, codec: Any, model: Model, value: Any) -> Any:
    """Bit fields from a JSON object ``{field: value}`` (fields left out are 0/false) or a raw integer."""
    if isinstance(value, int) and not isinstance(value, bool) and isinstance(codec, FlagCodec):
        if not 0 <= value < 1 << (16 * codec.spec.words):
            raise ValueOutOfRange(f"{reg.name}: {repr(value)[:40]} does not fit the register")
        return codec.flag_type(value)
    if not isinstance(value, Mapping):
        raise InvalidValue(f"{reg.name}: expected an object of bit fields ({', '.join(b.name for b in reg.bits)})")
    bits = {b.name: b for b in reg.bits}
    unknown = [k for k in value if k not in bits]
    if unknown:
        raise InvalidValue(f"{reg.name}: no bit field {unknown[0]!r} (fields: {', '.join(bits)})")
    if isinstance(codec, FlagCodec):
        raw = 0
        for name, v in value.items():
            if _field_value(reg, bits[name], None, model, v):  # a flag: true/false/1/0 only
                raw |= 1 << bits[name].offset
        return codec.flag_type(raw)
    kwargs: dict[str, Any] = {}
    for f, bit in codec.fields:
        given = value.get(bit.name, False if bit.width == 1 and f.enum_type is None else 0)
        kwargs[f.attribute] = _field_value(reg, bit, f.enum_type, model, given)
    return codec.data_type(**kwargs)
