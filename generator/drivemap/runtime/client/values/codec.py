"""Raw words <-> engineering values, with every check a write needs before anything is sent.

Words -> raw: :func:`words_to_raw` undoes the register's byte order (bytes inside each word) and
word order and joins the words, most significant first, into one int: the integer value (signed
for s16/s32/s64), the IEEE-754 bit pattern of f32/f64, the bytes of a string as one unsigned
number, 0/1 for a coil. :func:`raw_to_words` is its inverse.

Raw -> value: engineering = raw * scale + offset (the map's rule; times 10**factor for a
register with a scale-factor register). Encoding rounds to the nearest raw step (half away from
zero) and then requires the raw value to fit the register type: a value is *representable* when
its raw value lies in the type's bounds (u16 0..65535, s16 -32768..32767, u32, s32, u64,
s64) and it is a whole number of steps of the register's resolution: (value - offset) / scale
(times 10**-factor) must be an integer. Binary floats cannot hold most decimals (12.3 / 0.1 is
122.99999999999999), so a value within :data:`STEP_TOLERANCE` of a step (one millionth of a
step) of an integer raw value is that raw value; any other value is refused with
:class:`~drivemap.runtime.errors.InexactValue`, which names the nearest representable values
(never rounded silently). The map's ``min``/``max`` (engineering units) are checked first. Floats and strings are
converted with pymodbus's own ``convert_to_registers`` / ``convert_from_registers``.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import struct
from collections.abc import Sequence
from typing import Any, Generic, TypeVar

from pymodbus.client.mixin import ModbusClientMixin

from drivemap.runtime.client.values.display import allowed_text, check_values, display_text, register_text
from drivemap.runtime.client.values.enums import DriveEnum
from drivemap.runtime.client.values.steps import (
    STEP_TOLERANCE,
    exact_f32,
    exact_raw,
    fits_raw,
    number_text,
    offset_text,
    short_value,
    shortest_f32_text,
    unit_suffix,
)
from drivemap.runtime.client.values.words import (
    TYPE_BOUNDS,
    check_raw,
    join_words,
    raw_bounds,
    raw_to_words,
    split_words,
    words_to_raw,
)
from drivemap.runtime.errors import InvalidValue, ScaleUnavailable, ValueOutOfRange
from drivemap.runtime.spec import BitSpec, RegisterSpec

T = TypeVar("T")
E = TypeVar("E", bound=enum.IntEnum)
F = TypeVar("F", bound=enum.IntFlag)
D = TypeVar("D")

DATATYPE = ModbusClientMixin.DATATYPE
#: A scale factor outside this range is not a plausible power of ten (SunSpec uses -10..10).
SCALE_FACTOR_LIMIT = 20

#: Relative tolerance when comparing a float against min/max (binary floats such as 0.1).
_EPS = 1e-9


def _digits(scale: float) -> int:
    """Decimal places that show a scaled value exactly (0.01 -> 2, 0.009765625 -> 9)."""
    text = repr(float(scale))
    if "e" in text:
        return 12
    return min(12, len(text.split(".")[1].rstrip("0")))


class Codec(Generic[T]):
    """Converts one register's raw value to its Python value ``T`` and back.

    A codec whose value depends on another register (a scale-factor register) names that
    register's element in ``scale_key``; the client reads it with the value and calls
    :meth:`decode_scaled` / :meth:`encode_scaled`. Every other codec has ``scale_key`` None.
    """

    scale_key: tuple[str, int] | None = None

    def __init__(self, spec: RegisterSpec) -> None:
        self.spec = spec

    def decode(self, raw: int) -> T:
        raise NotImplementedError

    def encode(self, value: T) -> int:
        """The raw value for ``value``; raises :class:`InvalidValue` / :class:`ValueOutOfRange`."""
        raise NotImplementedError

    def check(self, value: T) -> None:
        """Every check :meth:`encode` makes that does not need the scale factor (the base: encode)."""
        self.encode(value)

    def decode_scaled(self, raw: int, factor: int | None) -> T:
        """The value of ``raw`` given the raw value of the scale-factor register (ignored here)."""
        return self.decode(raw)

    def encode_scaled(self, value: T, factor: int | None) -> int:
        return self.encode(value)

    def _check_range(self, value: float) -> None:
        spec = self.spec
        try:
            tol = _EPS * max(1.0, abs(value)) if math.isfinite(value) else 0.0
        except OverflowError:  # an int too large for a float (10**400): outside every range
            raise ValueOutOfRange(f"{spec.name}: {short_value(value)} is not representable") from None
        if spec.min is not None and value < spec.min - tol:
            raise ValueOutOfRange(f"{spec.name}: {value} is below the minimum {spec.min}{unit_suffix(spec)}")
        if spec.max is not None and value > spec.max + tol:
            raise ValueOutOfRange(f"{spec.name}: {value} is above the maximum {spec.max}{unit_suffix(spec)}")
        check_values(spec, value)


class RawCodec(Codec[int]):
    """The raw value itself (``read_raw`` / ``write_raw``): only the type's bounds apply."""

    def decode(self, raw: int) -> int:
        return raw

    def encode(self, value: int) -> int:
        return check_raw(self.spec, value)


class IntCodec(Codec[int]):
    """Whole-number scale and offset: engineering values are ``int``."""

    def __init__(self, spec: RegisterSpec) -> None:
        super().__init__(spec)
        self._scale = int(spec.scale)
        self._offset = int(spec.offset)

    def decode(self, raw: int) -> int:
        return raw * self._scale + self._offset

    def encode(self, value: int) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidValue(f"{self.spec.name}: expected int, got {type(value).__name__}")
        if isinstance(value, float) and not float(value).is_integer():
            raise InvalidValue(f"{self.spec.name}: expected a whole number, got {value!r}")
        value = int(value)
        self._check_range(value)
        scale, offset = int(self.spec.scale), int(self.spec.offset)
        raw, rest = divmod(value - offset, scale)
        if rest:  # between two steps: refused with the nearest values (exact integer arithmetic)
            exact_raw(self.spec, value, scale, offset, 0, offset_text(offset))
        return fits_raw(self.spec, raw, value)


class FloatCodec(Codec[float]):
    """Fractional scale or offset: engineering values are ``float`` rounded to the scale's decimals."""

    def __init__(self, spec: RegisterSpec) -> None:
        super().__init__(spec)
        self._scale = spec.scale
        self._offset = spec.offset
        self._digits = _digits(spec.scale) + _digits(spec.offset)

    def decode(self, raw: int) -> float:
        return round(raw * self._scale + self._offset, self._digits)

    def encode(self, value: float) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidValue(f"{self.spec.name}: expected a number, got {type(value).__name__}")
        try:
            finite = math.isfinite(value)
        except OverflowError:  # an int too large for a float
            finite = False
        if not finite:
            raise ValueOutOfRange(f"{self.spec.name}: {short_value(value)} is not finite")
        self._check_range(float(value))
        raw = exact_raw(self.spec, float(value), self.spec.scale, self.spec.offset, self._digits,
                        offset_text(self.spec.offset))
        return fits_raw(self.spec, raw, value)


def _number(spec: RegisterSpec, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidValue(f"{spec.name}: expected a number, got {type(value).__name__}")
    return float(value)


class IeeeCodec(Codec[float]):
    """f32 / f64: IEEE-754 floats (NaN and infinities read as such), converted by pymodbus."""

    def __init__(self, spec: RegisterSpec) -> None:
        super().__init__(spec)
        self._datatype = DATATYPE.FLOAT32 if spec.type == "f32" else DATATYPE.FLOAT64
        self._count = spec.words
        self._scale = spec.scale
        self._offset = spec.offset
        self._plain = spec.scale == 1 and spec.offset == 0

    def decode(self, raw: int) -> float:
        value = float(ModbusClientMixin.convert_from_registers(split_words(raw, self._count), self._datatype))  # type: ignore[arg-type]
        return value if self._plain else value * self._scale + self._offset

    def check(self, value: float) -> None:
        number = _number(self.spec, value)
        if math.isnan(number):
            if self.spec.min is not None or self.spec.max is not None:
                raise ValueOutOfRange(f"{self.spec.name}: nan is outside the range {self.spec.min}..{self.spec.max}")
            check_values(self.spec, number)
            return
        self._check_range(number)

    def encode(self, value: float) -> int:
        """The raw words of ``value``; one an f32 cannot show is refused (:func:`.steps.exact_f32`), not rounded."""
        self.check(value)
        number = float(value)
        if not self._plain:
            number = (number - self._offset) / self._scale
        try:
            words = ModbusClientMixin.convert_to_registers(number, self._datatype)
        except (OverflowError, struct.error) as exc:
            raise ValueOutOfRange(f"{self.spec.name}: {value}{unit_suffix(self.spec)} is not representable as "
                                  f"{self.spec.type}") from exc
        raw = join_words(words)
        if self.spec.type == "f32":
            exact_f32(self.spec, float(value), number, raw, self.decode(raw))
        return raw


class StringCodec(Codec[str]):
    """Text in ``length`` registers: trailing NUL and space stripped on read, NUL-padded on write."""

    def __init__(self, spec: RegisterSpec) -> None:
        super().__init__(spec)
        self._size = 2 * spec.words
        self._encoding = spec.encoding

    def decode(self, raw: int) -> str:
        return raw.to_bytes(self._size, "big").rstrip(b"\x00 ").decode(self._encoding, errors="replace")

    def encode(self, value: str) -> int:
        if not isinstance(value, str):
            raise InvalidValue(f"{self.spec.name}: expected str, got {type(value).__name__}")
        try:
            data = value.encode(self._encoding)
        except UnicodeEncodeError as exc:
            raise InvalidValue(f"{self.spec.name}: {value!r} is not {self._encoding} text") from exc
        if len(data) > self._size:
            raise ValueOutOfRange(f"{self.spec.name}: {value!r} is {len(data)} bytes; the field holds {self._size} "
                                  f"({self.spec.words} registers)")
        check_values(self.spec, value)
        words = ModbusClientMixin.convert_to_registers(value, DATATYPE.STRING, string_encoding=self._encoding)
        return join_words(words + [0] * (self.spec.words - len(words)))


class BoolCodec(Codec[bool]):
    """A coil, a discrete input, or a register read as a flag (0 false, anything else true)."""

    def decode(self, raw: int) -> bool:
        return raw != 0

    def encode(self, value: bool) -> int:
        if not isinstance(value, bool):
            raise InvalidValue(f"{self.spec.name}: expected bool, got {type(value).__name__}")
        return 1 if value else 0


class ScaledCodec(Codec[float]):
    """A register scaled by a scale-factor register (SunSpec): raw * scale * 10**factor + offset.

    The factor is the raw value of ``factor_spec``, read together with the value every time; a
    factor that reads as not available, is implausible or was not read raises
    :class:`ScaleUnavailable` (a value is never scaled by a stale or missing factor).
    """

    def __init__(self, spec: RegisterSpec, factor_spec: RegisterSpec) -> None:
        super().__init__(spec)
        self.factor_spec = factor_spec
        self.scale_key = (factor_spec.name, 0)
        self._unavailable = frozenset(factor_spec.not_available)
        self._digits = _digits(spec.scale) + _digits(spec.offset)

    def factor(self, raw: int | None) -> int:
        name, factor = self.spec.name, self.factor_spec.name
        if raw is None:
            raise ScaleUnavailable(f"{name}: its scale factor {factor} was not read")
        if raw in self._unavailable:
            raise ScaleUnavailable(f"{name}: the scale factor {factor} reads 'not available' ({raw})")
        if not -SCALE_FACTOR_LIMIT <= raw <= SCALE_FACTOR_LIMIT:
            raise ScaleUnavailable(f"{name}: the scale factor {factor} reads {raw}, not a plausible power of ten")
        return raw

    def decode(self, raw: int) -> float:
        raise ScaleUnavailable(f"{self.spec.name}: its value needs the scale factor {self.factor_spec.name}")

    def decode_scaled(self, raw: int, factor: int | None) -> float:
        exponent = self.factor(factor)
        value = raw * self.spec.scale * 10.0 ** exponent + self.spec.offset
        return round(value, max(0, -exponent) + self._digits)

    def check(self, value: float) -> None:
        number = _number(self.spec, value)
        if not math.isfinite(number):
            raise ValueOutOfRange(f"{self.spec.name}: {value} is not finite")
        self._check_range(number)

    def encode(self, value: float) -> int:
        raise ScaleUnavailable(f"{self.spec.name}: writing needs the scale factor {self.factor_spec.name}")

    def encode_scaled(self, value: float, factor: int | None) -> int:
        self.check(value)
        exponent = self.factor(factor)
        digits = max(0, -exponent) + self._digits
        why = f" (scale {number_text(self.spec.scale)} x 10^{exponent}: {self.factor_spec.name} reads {exponent})"
        raw = exact_raw(self.spec, float(value), self.spec.scale * 10.0 ** exponent, self.spec.offset, digits, why)
        return fits_raw(self.spec, raw, value)


class OptionalCodec(Codec[T | None], Generic[T]):
    """A register with not-available values: those raw values read as None; writing None writes the
    first of them, and a value that would encode to one of them is refused."""

    def __init__(self, inner: Codec[T]) -> None:
        super().__init__(inner.spec)
        self.inner = inner
        self.scale_key = inner.scale_key
        self._unavailable = frozenset(inner.spec.not_available)
        self._marker = inner.spec.not_available[0]

    def decode(self, raw: int) -> T | None:
        return None if raw in self._unavailable else self.inner.decode(raw)

    def decode_scaled(self, raw: int, factor: int | None) -> T | None:
        return None if raw in self._unavailable else self.inner.decode_scaled(raw, factor)

    def _refuse_marker(self, value: T, raw: int) -> int:
        if raw in self._unavailable:
            raise ValueOutOfRange(f"{self.spec.name}: {value!r} encodes to raw {raw}, which the map says means "
                                  "'not available'")
        return raw

    def check(self, value: T | None) -> None:
        if value is not None:
            self.inner.check(value)

    def encode(self, value: T | None) -> int:
        if value is None:
            return self._marker
        return self._refuse_marker(value, self.inner.encode(value))

    def encode_scaled(self, value: T | None, factor: int | None) -> int:
        if value is None:
            return self._marker
        return self._refuse_marker(value, self.inner.encode_scaled(value, factor))


def unwrap(codec: Codec[Any]) -> Codec[Any]:
    """The codec inside an :class:`OptionalCodec` (the codec itself otherwise)."""
    return codec.inner if isinstance(codec, OptionalCodec) else codec


class EnumCodec(Codec[E]):
    """Registers holding one of the map's enumerated values."""

    def __init__(self, spec: RegisterSpec, enum_type: type[E]) -> None:
        super().__init__(spec)
        self.enum_type = enum_type
        self._members: dict[Any, Any] = enum_type._value2member_map_

    def decode(self, raw: int) -> E:
        member = self._members.get(raw)  # the member enum_type(raw) returns, without the call
        return member if member is not None else self.enum_type(raw)

    def encode(self, value: E) -> int:
        if not isinstance(value, self.enum_type):
            raise InvalidValue(f"{self.spec.name}: expected {self.enum_type.__name__}, got {type(value).__name__}")
        if int(value) not in self.spec.enum_values:
            raise ValueOutOfRange(f"{self.spec.name}: {value!r} is not a value of {self.enum_type.__name__}")
        raw = int(value)
        self._check_range(raw)
        return fits_raw(self.spec, raw, raw)


class FlagCodec(Codec[F]):
    """Bit-field registers whose bits are all single flags: an ``IntFlag``."""

    def __init__(self, spec: RegisterSpec, flag_type: type[F]) -> None:
        super().__init__(spec)
        self.flag_type = flag_type
        self._members: dict[Any, Any] = flag_type._value2member_map_
        self._mask = (1 << (16 * spec.words)) - 1
        defined = 0
        for member in flag_type.__members__.values():
            defined |= int(member)
        #: The bits the map defines; a write with any other bit set is refused.
        self.defined = defined

    def decode(self, raw: int) -> F:
        value = raw & self._mask
        member = self._members.get(value)  # what flag_type(value) returns (it caches combinations there)
        return member if member is not None else self.flag_type(value)

    def encode(self, value: F) -> int:
        if not isinstance(value, self.flag_type):
            raise InvalidValue(f"{self.spec.name}: expected {self.flag_type.__name__}, got {type(value).__name__}")
        raw = int(value)
        if not 0 <= raw < 1 << (16 * self.spec.words):
            raise ValueOutOfRange(f"{self.spec.name}: {short_value(raw)} does not fit the register")
        if raw & ~self.defined:
            raise ValueOutOfRange(f"{self.spec.name}: bit(s) {raw & ~self.defined:#x} are not defined by the map "
                                  f"({self.flag_type.__name__} defines {self.defined:#x})")
        if self.spec.signed and raw >= 1 << (16 * self.spec.words - 1):
            raw -= 1 << (16 * self.spec.words)
        return raw


@dataclasses.dataclass(frozen=True)
class Field:
    """One dataclass field of a multi-bit register: its attribute, bit field and value type."""

    attribute: str
    bit: str
    enum_type: type[enum.IntEnum] | None = None


class FieldsCodec(Codec[D]):
    """Bit-field registers with multi-bit or enumerated fields: a frozen dataclass ``D``."""

    def __init__(self, spec: RegisterSpec, data_type: type[D], fields: Sequence[Field]) -> None:
        super().__init__(spec)
        self.data_type = data_type
        bits = {b.name: b for b in spec.bits}
        self.fields: tuple[tuple[Field, BitSpec], ...] = tuple((f, bits[f.bit]) for f in fields)

    def decode(self, raw: int) -> D:
        values: dict[str, object] = {}
        for field, bit in self.fields:
            v = (raw >> bit.offset) & ((1 << bit.width) - 1)
            if field.enum_type is not None:
                values[field.attribute] = field.enum_type(v)
            elif bit.width == 1:
                values[field.attribute] = bool(v)
            else:
                values[field.attribute] = v
        return self.data_type(**values)

    def encode(self, value: D) -> int:
        if not isinstance(value, self.data_type):
            raise InvalidValue(f"{self.spec.name}: expected {self.data_type.__name__}, got {type(value).__name__}")
        raw = 0
        for field, bit in self.fields:
            v = getattr(value, field.attribute)
            if field.enum_type is not None and not isinstance(v, field.enum_type):
                raise InvalidValue(f"{self.spec.name}.{field.attribute}: expected {field.enum_type.__name__}")
            if isinstance(v, enum.Enum) and field.enum_type is not None and v.name.startswith("UNKNOWN_"):
                raise ValueOutOfRange(f"{self.spec.name}.{field.attribute}: {v!r} is not a value of the map")
            if not isinstance(v, int):
                raise InvalidValue(f"{self.spec.name}.{field.attribute}: expected int, got {type(v).__name__}")
            iv = int(v)
            if not 0 <= iv < 1 << bit.width:
                raise ValueOutOfRange(f"{self.spec.name}.{field.attribute}: {iv} does not fit {bit.width} bit(s)")
            raw |= iv << bit.offset
        if self.spec.signed and raw >= 1 << (16 * self.spec.words - 1):
            raw -= 1 << (16 * self.spec.words)
        return raw


__all__ = [
    "BoolCodec",
    "Codec",
    "STEP_TOLERANCE",
    "DriveEnum",
    "EnumCodec",
    "Field",
    "FieldsCodec",
    "FlagCodec",
    "FloatCodec",
    "IeeeCodec",
    "IntCodec",
    "OptionalCodec",
    "RawCodec",
    "ScaledCodec",
    "StringCodec",
    "TYPE_BOUNDS",
    "allowed_text",
    "check_raw",
    "check_values",
    "display_text",
    "exact_raw",
    "join_words",
    "number_text",
    "raw_bounds",
    "raw_to_words",
    "register_text",
    "shortest_f32_text",
    "split_words",
    "unwrap",
    "words_to_raw",
]
