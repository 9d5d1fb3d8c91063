"""Raw words <-> engineering values, with every check a write needs before anything is sent.

engineering = raw * scale + offset (the map's rule). Encoding rounds to the nearest raw step
(half away from zero) and then requires the raw value to fit the register type: a value is
*representable* when its rounded raw value lies in the type's bounds (u16 0..65535, s16
-32768..32767, u32, s32). The map's ``min``/``max`` (engineering units) are checked first.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Sequence
from typing import Any, Generic, TypeVar

from .errors import InvalidValue, ValueOutOfRange
from .spec import BitSpec, RegisterSpec

T = TypeVar("T")
E = TypeVar("E", bound=enum.IntEnum)
F = TypeVar("F", bound=enum.IntFlag)
D = TypeVar("D")

TYPE_BOUNDS: dict[str, tuple[int, int]] = {
    "u16": (0, 0xFFFF),
    "s16": (-0x8000, 0x7FFF),
    "u32": (0, 0xFFFFFFFF),
    "s32": (-0x80000000, 0x7FFFFFFF),
}

#: Relative tolerance when comparing a float against min/max (binary floats such as 0.1).
_EPS = 1e-9


class DriveEnum(enum.IntEnum):
    """Base of generated enums: a raw value the map does not name reads as a pseudo-member.

    ``MotorState(99)`` gives ``<MotorState.UNKNOWN_99: 99>`` instead of raising, so a read never
    fails on an undocumented value; writes still accept only the map's values.
    """

    @classmethod
    def _missing_(cls, value: object) -> Any:
        if not isinstance(value, int) or isinstance(value, bool):
            return None
        member = int.__new__(cls, value)
        member._name_ = f"UNKNOWN_{value}"
        member._value_ = value
        return member


def words_to_raw(spec: RegisterSpec, words: Sequence[int]) -> int:
    """The register's raw value (signed for s16/s32) from its wire words."""
    if spec.words == 2:
        hi, lo = (words[1], words[0]) if spec.word_order == "low_first" else (words[0], words[1])
        raw = (hi << 16) | lo
        if spec.signed and raw & 0x80000000:
            raw -= 1 << 32
        return raw
    raw = words[0]
    if spec.signed and raw & 0x8000:
        raw -= 1 << 16
    return raw


def raw_to_words(spec: RegisterSpec, raw: int) -> list[int]:
    """Wire words of a raw value (checked against the type's bounds)."""
    check_raw(spec, raw)
    if spec.words == 2:
        unsigned = raw & 0xFFFFFFFF
        hi, lo = unsigned >> 16, unsigned & 0xFFFF
        return [lo, hi] if spec.word_order == "low_first" else [hi, lo]
    return [raw & 0xFFFF]


def check_raw(spec: RegisterSpec, raw: object) -> int:
    if not isinstance(raw, int) or isinstance(raw, bool):
        raise InvalidValue(f"{spec.name}: raw value must be int, not {type(raw).__name__}")
    lo, hi = TYPE_BOUNDS[spec.type]
    if not lo <= raw <= hi:
        raise ValueOutOfRange(f"{spec.name}: raw value {_short(raw)} does not fit {spec.type} ({lo}..{hi})")
    return raw


def _digits(scale: float) -> int:
    """Decimal places that show a scaled value exactly (0.01 -> 2, 0.009765625 -> 9)."""
    text = repr(float(scale))
    if "e" in text:
        return 12
    return min(12, len(text.split(".")[1].rstrip("0")))


def _round_half_away(x: float) -> int:
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


class Codec(Generic[T]):
    """Converts one register's raw value to its Python value ``T`` and back."""

    python_type: str = "object"

    def __init__(self, spec: RegisterSpec) -> None:
        self.spec = spec

    def decode(self, raw: int) -> T:
        raise NotImplementedError

    def encode(self, value: T) -> int:
        """The raw value for ``value``; raises :class:`InvalidValue` / :class:`ValueOutOfRange`."""
        raise NotImplementedError

    def _check_range(self, value: float) -> None:
        spec = self.spec
        try:
            tol = _EPS * max(1.0, abs(value))
        except OverflowError:  # an int too large for a float (10**400): outside every range
            raise ValueOutOfRange(f"{spec.name}: {_short(value)} is not representable") from None
        if spec.min is not None and value < spec.min - tol:
            raise ValueOutOfRange(f"{spec.name}: {value} is below the minimum {spec.min}{_unit(spec)}")
        if spec.max is not None and value > spec.max + tol:
            raise ValueOutOfRange(f"{spec.name}: {value} is above the maximum {spec.max}{_unit(spec)}")


def _short(value: object) -> str:
    """``value`` for a message: a huge int (``10**400``) is named by its size, never converted to text."""
    if isinstance(value, int) and value.bit_length() > 96:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)


def _unit(spec: RegisterSpec) -> str:
    return f" {spec.unit}" if spec.unit else ""


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
        if rest * 2 >= scale:  # round half away from zero (scale > 0)
            raw += 1
        return _fits(self.spec, raw, value)


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
            raise ValueOutOfRange(f"{self.spec.name}: {_short(value)} is not finite")
        self._check_range(float(value))
        raw = _round_half_away((value - self.spec.offset) / self.spec.scale)
        return _fits(self.spec, raw, value)


def _fits(spec: RegisterSpec, raw: int, value: float) -> int:
    lo, hi = TYPE_BOUNDS[spec.type]
    if not lo <= raw <= hi:
        raise ValueOutOfRange(f"{spec.name}: {_short(value)}{_unit(spec)} is not representable ({spec.type} raw {_short(raw)})")
    return raw


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
        return _fits(self.spec, raw, raw)


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
            raise ValueOutOfRange(f"{self.spec.name}: {_short(raw)} does not fit the register")
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
    "Codec",
    "DriveEnum",
    "EnumCodec",
    "Field",
    "FieldsCodec",
    "FlagCodec",
    "FloatCodec",
    "IntCodec",
    "RawCodec",
    "TYPE_BOUNDS",
    "check_raw",
    "raw_to_words",
    "words_to_raw",
]
