"""Command payloads, parsed strictly: bounded in size and depth before any parser runs, nothing coerced.

A payload (MQTT ``/set``, an OPC UA write turned into JSON) is at most :data:`MAX_PAYLOAD_BYTES`
bytes of UTF-8 and nests at most :data:`MAX_DEPTH` levels of JSON arrays/objects; both are checked
on the raw text before ``json.loads`` (which recurses) sees it. NaN and Infinity are refused. Bools
are ``true``/``false``/``on``/``off``/``1``/``0`` (any case; JSON ``true``/``false``); a single bit
is 0, 1, true or false; integers are integers (a float only when it is a whole number); indexes
and numbers in names are ASCII digits. What is accepted is written exactly: the register's codec
refuses a value the register cannot hold exactly (``12.345`` at a resolution of 0.01, ``30.123456789``
in an f32) with :class:`~drivemap.runtime.errors.InexactValue` naming the nearest values it can hold;
the gateway never rounds. Exactness starts at the text as sent: a JSON number whose decimal value
(``Decimal`` of the text) a binary float does not hold (``1e-400`` would be 0, ``99.999999999999999999``
100.0) is refused before any codec sees it. An object that names a key twice
(``{"X0": true, "X0": false}``) is refused, never "last one wins".
"""

from __future__ import annotations

import json
import math
import re
from decimal import Decimal
from typing import Any

from drivemap.runtime.errors import InexactValue, InvalidValue, ValueOutOfRange

#: The longest command payload (bytes); a bit-field object of every field of a 64-bit register fits.
MAX_PAYLOAD_BYTES = 4096
#: The deepest nesting of JSON arrays and objects in a payload (a bit-field object is 1).
MAX_DEPTH = 2

_BOOL_WORDS = {"true": True, "on": True, "1": True, "false": False, "off": False, "0": False}
_INTEGER = re.compile(r"[+-]?(?:[0-9]+|0[xX][0-9a-fA-F]+)\Z", re.ASCII)
_INDEX = re.compile(r"[0-9]{1,6}\Z", re.ASCII)


def show(text: str, limit: int = 40) -> str:
    """A payload for a message: at most ``limit`` characters, repr-quoted."""
    return repr(text[:limit] + ("..." if len(text) > limit else ""))


def payload_text(payload: bytes | str) -> str:
    """The text of a payload: bounded in size, strict UTF-8 without NUL."""
    size = len(payload.encode("utf-8", "surrogatepass")) if isinstance(payload, str) else len(payload)
    if size > MAX_PAYLOAD_BYTES:
        raise InvalidValue(f"a payload of {size} bytes is longer than the {MAX_PAYLOAD_BYTES} a command may have")
    if isinstance(payload, bytes):
        try:
            payload = payload.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InvalidValue(f"the payload is not UTF-8 text (byte {exc.start})") from None
    if "\x00" in payload or any(0xD800 <= ord(c) <= 0xDFFF for c in payload):
        raise InvalidValue("the payload holds a NUL or a lone surrogate")
    return payload


def nesting(text: str) -> int:
    """How deep JSON arrays/objects nest in ``text`` (brackets inside strings do not count)."""
    depth = deepest = 0
    in_string = escaped = False
    for c in text:
        if in_string:
            if escaped:
                escaped = False
            elif c == "\\":
                escaped = True
            elif c == '"':
                in_string = False
        elif c == '"':
            in_string = True
        elif c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth -= 1
    return deepest


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a value")


class _Refused(Exception):
    """A payload refused while JSON parses it (carries the typed error past ``json.loads``)."""

    def __init__(self, error: Exception) -> None:
        super().__init__(str(error))
        self.error = error


def exact_float(register: str, text: str) -> float:
    """The float of a JSON number's text, only when it holds the text's decimal value exactly (a
    number too large for a float is infinite, which :func:`number` refuses as not finite)."""
    value = float(text)
    if math.isfinite(value) and Decimal(text) != Decimal(repr(value)):
        raise InexactValue(f"{register}: {show(text)} is not a number the gateway can pass on exactly "
                           f"(as a binary float it is {value!r}); send the value the register holds",
                           (value,))
    return value


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _Refused(InvalidValue(f"the payload names {show(key)} twice"))
        seen[key] = value
    return seen


def parse_json(register: str, text: str) -> Any:
    """A JSON value, after the depth check; NaN/Infinity, malformed text and an object naming a key
    twice are InvalidValue, a number the text states more exactly than a float holds InexactValue."""
    if nesting(text) > MAX_DEPTH:
        raise InvalidValue(f"{register}: the payload nests deeper than {MAX_DEPTH} levels")

    def parse_float(word: str) -> float:
        try:
            return exact_float(register, word)
        except InexactValue as exc:
            raise _Refused(exc) from None

    try:
        return json.loads(text, parse_constant=_no_constant, parse_float=parse_float,
                          object_pairs_hook=_unique_keys)
    except _Refused as refused:
        if isinstance(refused.error, InvalidValue):
            raise InvalidValue(f"{register}: {refused.error}") from None
        raise refused.error from None
    except (ValueError, RecursionError):
        raise InvalidValue(f"{register}: payload {show(text)} is not a value (JSON number, name or object)") from None


def bool_word(register: str, value: Any) -> bool:
    """A bool from ``true/false/on/off/1/0`` (text, JSON bool or the integers 0 and 1)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    if isinstance(value, str):
        word = value.strip().strip('"').lower()
        if word in _BOOL_WORDS:
            return _BOOL_WORDS[word]
    shown = show(value) if isinstance(value, str) else repr(value)[:40]
    raise InvalidValue(f"{register}: expected true/false (ON/OFF, 1/0), got {shown}")


def integer_word(word: str) -> int | None:
    """An integer written in ASCII (decimal or 0x hex), else None."""
    if not _INTEGER.match(word):
        return None
    sign = -1 if word.startswith("-") else 1
    body = word.lstrip("+-")
    return sign * (int(body[2:], 16) if body[:2].lower() == "0x" else int(body, 10))


def index_word(register: str, text: str) -> int:
    """An array index: ASCII digits only."""
    if not _INDEX.match(text):
        raise InvalidValue(f"{register}: index {show(text, 12)} is not a number (ASCII digits)")
    return int(text)


def number(register: str, value: Any, *, integer: bool) -> int | float:
    """A finite number; for an integer register an int (or a float that is a whole number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidValue(f"{register}: expected a number, got {type(value).__name__}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueOutOfRange(f"{register}: {value} is not finite")
    if integer and isinstance(value, float):
        if not value.is_integer():
            raise ValueOutOfRange(f"{register}: {value} is not a whole number (the register holds integers)")
        return int(value)
    return value
