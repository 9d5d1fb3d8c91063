"""Engineering values on the command line: ``NAME=VALUE`` parsed, encoded and checked before sending.

* numbers: ``digital_speed[0]=1500``, ``bus_voltage=48.5`` (the map's scale, min and max apply);
* enums: a member name, any case (``operation_mode=REMOTE``), or its number;
* bit flags: names joined by ``|`` (``net_in=X0|X2``), ``0`` for none, or a number;
* bit fields with multi-bit parts: ``field:value`` pairs joined by ``,``
  (``rs485_comm_settings=parity:EVEN,stop_bits:0,data_bits:0``);
* a whole array: values joined by ``,`` (``digital_speed=1500,1500,0,0,0,0,0,0``);
* coils and flags: ``true``/``false``, ``on``/``off``, ``1``/``0`` (any case).

Numbers are ASCII (``int(text, 0)`` and ``float`` would take other scripts' digits). A value
between two steps of the register's resolution is refused with the nearest representable values;
``round_values`` (``drivemap write --round``) sends the nearer one instead and says so.

Every value is encoded with the register's codec (the generated client's), so range, type and
enum checks are exactly the client's; any failure is a located error and nothing is sent.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from drivemap.device.target import Target, locate_error
from drivemap.diagnostics import CompileError
from drivemap.model.nodes import Register
from drivemap.runtime.client.protocol.review import sign_checked
from drivemap.runtime.client.protocol.sansio import Deferred
from drivemap.runtime.client.values.codec import (
    BoolCodec,
    EnumCodec,
    FieldsCodec,
    FlagCodec,
    IntCodec,
    RawCodec,
    StringCodec,
    number_text,
    unwrap,
)
from drivemap.runtime.errors import DriveError, InexactValue

_NAME = re.compile(r"^([a-z_][a-z0-9_]*)(?:\[([0-9]+)\])?$")
_BOOLS = {"true": True, "on": True, "1": True, "false": False, "off": False, "0": False}


@dataclass(frozen=True)
class Assignment:
    """One checked ``NAME=VALUE``: the element names, their raw values and engineering values."""

    text: str
    register: Register
    #: (element name, index, raw, engineering value); the raw value of a register with a scale
    #: register is a :class:`Deferred`: the client reads the factor just before the write
    items: tuple[tuple[str, int, int | Deferred, Any], ...]
    #: what ``--round`` changed: "NAME: asked X, sending Y"
    rounded: tuple[str, ...] = ()


def parse_assignments(target: Target, texts: Sequence[str], round_values: bool = False) -> list[Assignment]:
    """Every ``NAME=VALUE`` checked and encoded, in the order given; all errors reported together,
    nothing sent."""
    out: list[Assignment] = []
    errors: list[Any] = []
    for text in texts:
        try:
            out.append(parse_assignment(target, text, round_values))
        except CompileError as exc:
            errors.extend(exc.diagnostics)
    if errors:
        raise CompileError(errors)
    return out


def parse_assignment(target: Target, text: str, round_values: bool = False) -> Assignment:
    name, sep, value = text.partition("=")
    if not sep:
        raise locate_error(text, f"{text!r}: write NAME=VALUE (e.g. digital_speed[0]=1500)")
    reg, index = lookup(target, name.strip(), text)
    if not reg.writable:
        raise locate_error(text, f"{reg.name} is read-only", target, reg)
    if reg.command_value is not None and value.strip() == "":
        value = str(reg.command_value)
    codec = target.codecs[reg.name]
    indexes = [index] if index is not None else list(range(reg.count))
    parts = [value] if len(indexes) == 1 else value.split(",")
    if len(parts) != len(indexes):
        raise locate_error(text, f"{reg.name} has {reg.count} elements: give {reg.count} values joined by ',' "
                                 f"or one element as {reg.name}[i]=VALUE", target, reg)
    items = []
    rounded: list[str] = []
    for i, part in zip(indexes, parts, strict=True):
        try:
            engineering = from_text(codec, part.strip())
            raw: int | Deferred
            if codec.scale_key is not None:  # checked now, scaled by the factor read at the write
                codec.check(engineering)
                raw = Deferred(engineering, codec, round_values)
            else:
                raw, sent = _encode(codec, engineering, round_values)
                if sent != engineering:
                    rounded.append(f"{reg.element_name(i)}: asked {number_text(engineering)}, sending "
                                   f"{number_text(sent)} (--round)")
                    engineering = sent
        except (DriveError, ValueError) as exc:
            raise locate_error(text, f"{text}: {exc}", target, reg) from None
        items.append((reg.element_name(i), i, raw, engineering))
    return Assignment(text, reg, tuple(items), tuple(rounded))


def _encode(codec: Any, value: Any, round_values: bool) -> tuple[int, Any]:
    """(raw, value sent): a value between two steps is refused, or with ``round_values`` the nearer step."""
    try:
        return sign_checked(codec.spec, codec.encode(value)), value
    except InexactValue as exc:
        if not round_values or exc.rounded_raw is None:
            raise
        return sign_checked(codec.spec, codec.encode(exc.rounded)), exc.rounded


def lookup(target: Target, name: str, token: str) -> tuple[Register, int | None]:
    """The register and element index of ``name`` / ``name[i]``."""
    match = _NAME.match(name)
    reg = None
    if match is not None:
        with contextlib.suppress(KeyError):
            reg = target.model.register(match.group(1))
    if match is None or reg is None:
        hint = _similar(target, name)
        raise locate_error(token, f"{target.model.name} has no register {name!r}{hint}")
    if match.group(2) is None:
        return reg, None
    index = int(match.group(2))
    if not reg.is_array:
        raise locate_error(token, f"{reg.name} is not an array", target, reg)
    if not 0 <= index < reg.count:
        raise locate_error(token, f"{name}: index out of range 0..{reg.count - 1}", target, reg)
    return reg, index


def _similar(target: Target, name: str) -> str:
    import difflib

    close = difflib.get_close_matches(name.split("[")[0], [r.name for r in target.model.registers], n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


def from_text(codec: Any, text: str) -> Any:
    """The engineering value of ``text`` for ``codec`` (ValueError with a message when it is not one)."""
    codec = unwrap(codec)
    if isinstance(codec, BoolCodec):
        return parse_bool(text)
    if isinstance(codec, EnumCodec):
        return _member(codec.enum_type, text)
    if isinstance(codec, FlagCodec):
        return _flags(codec.flag_type, text)
    if isinstance(codec, FieldsCodec):
        return _fields(codec, text)
    labelled = _labelled(codec, text)
    if labelled is not None:
        return labelled
    if isinstance(codec, StringCodec):
        return text
    if isinstance(codec, IntCodec):
        number = _number(text)
        if not float(number).is_integer():
            raise ValueError(f"{text!r} is not a whole number")
        return int(number)
    if isinstance(codec, RawCodec):
        number = _number(text)
        if not float(number).is_integer():
            raise ValueError(f"{text!r} is not a whole number")
        return int(number)
    return float(_number(text))  # fractional scale, scale factor, f32/f64: never truncated to an int


def parse_bool(text: str) -> bool:
    """true/false, on/off, 1/0 in any case; anything else is a ValueError."""
    value = _BOOLS.get(text.strip().lower())
    if value is None:
        raise ValueError(f"{text!r} is not a bool (write true/false, on/off or 1/0)")
    return value


def _labelled(codec: Any, text: str) -> float | str | None:
    """The value of the register's value set whose label is ``text`` (any case), else None."""
    values = getattr(getattr(codec, "spec", None), "values", ())
    wanted = text.strip().casefold()
    return next((value for value, label in values if label is not None and label.casefold() == wanted), None)


def _number(text: str) -> float:
    if not text.isascii():
        raise ValueError(f"{text!r} is not a number (write ASCII digits)")
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a number") from None


def _int(text: str) -> int:
    """An ASCII integer (decimal, 0x.., 0b.., 0o..)."""
    if not text.isascii():
        raise ValueError(f"{text!r} is not a number (write ASCII digits)")
    return int(text, 0)


def _member(enum_type: type[enum.IntEnum], text: str) -> enum.IntEnum:
    by_name = {m.name.upper(): m for m in enum_type}
    if text.upper() in by_name:
        return by_name[text.upper()]
    try:
        number = _int(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a value of {enum_type.__name__} "
                         f"({', '.join(m.name for m in enum_type)})") from None
    member = enum_type(number)
    if member.name.startswith("UNKNOWN_"):
        raise ValueError(f"{number} is not a value of {enum_type.__name__} "
                         f"({', '.join(f'{m.name}={m.value}' for m in enum_type)})")
    return member


def _flags(flag_type: type[enum.IntFlag], text: str) -> enum.IntFlag:
    names = {m.name.upper(): m for m in flag_type if m.name}
    value = flag_type(0)
    for part in filter(None, (p.strip() for p in re.split(r"[|+]", text))):
        if part.upper() in names:
            value |= names[part.upper()]
            continue
        try:
            value |= flag_type(_int(part))
        except ValueError:
            raise ValueError(f"{part!r} is not a bit of {flag_type.__name__} ({'|'.join(names)})") from None
    known = 0
    for member in names.values():
        known |= int(member)
    if int(value) & ~known:
        raise ValueError(f"{int(value):#x} sets bits the map does not define ({flag_type.__name__}: {'|'.join(names)})")
    return value


def _fields(codec: FieldsCodec[Any], text: str) -> Any:
    fields = {f.attribute: f for f, _ in codec.fields}
    given: dict[str, Any] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        key, sep, raw = part.partition(":")
        field = fields.get(key.strip().lower())
        if not sep or field is None:
            raise ValueError(f"{part!r}: write FIELD:VALUE with FIELD one of {', '.join(fields)}")
        if field.enum_type is not None:
            given[field.attribute] = _member(field.enum_type, raw.strip())
        else:
            if _width(codec, field.bit) == 1:
                given[field.attribute] = parse_bool(raw)
                continue
            number = _number(raw.strip())
            if not float(number).is_integer():
                raise ValueError(f"{part!r}: {raw.strip()!r} is not a whole number")
            given[field.attribute] = int(number)
    missing = [name for name in fields if name not in given]
    if missing:
        raise ValueError(f"give every field ({', '.join(f'{n}:VALUE' for n in fields)}); missing {', '.join(missing)}")
    return codec.data_type(**given)


def _width(codec: FieldsCodec[Any], bit: str) -> int:
    return next(b.width for f, b in codec.fields if f.bit == bit)


def to_text(value: Any) -> str:
    """How an engineering value is written back on the command line."""
    if isinstance(value, enum.IntFlag):
        names = [m.name for m in type(value) if m.name and m in value]
        return "|".join(names) if names else "0"
    if isinstance(value, enum.Enum):
        return value.name
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return ",".join(f"{f.name}:{to_text(getattr(value, f.name))}" for f in dataclasses.fields(value))
    if isinstance(value, bool):
        return str(int(value))
    return str(value)
