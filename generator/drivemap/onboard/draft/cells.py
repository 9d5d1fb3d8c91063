"""Cell parsers: address, access, data type, range, default, enum and bit lists.

Each parser returns None when the text does not state the fact plainly; the caller then leaves the
field out and lists it. Nothing here guesses a radix, a sign or a word order.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

_HEX_MARKED = re.compile(r"^(?:0[xX]([0-9A-Fa-f]{1,5})|([0-9A-Fa-f]{1,5})\s?[hH])$")
_PLAIN = re.compile(r"^\d{1,6}$")
#: IEC 61131-3 hex literal, with the decimal a vendor prints beside it: ``16#2136``, ``16#2136 = 08502``
_IEC_HEX = re.compile(r"^16#([0-9A-Fa-f]{1,5})(?:\s*[=/(]\s*(\d{1,6})\)?)?$")
_BARE_HEX = re.compile(r"^[0-9A-Fa-f]{2,5}$")
_ADDR_RANGE = re.compile(r"^(?:0[xX])?[0-9A-Fa-f]{2,5}[hH]?\s*(?:~|～|-|–|to)\s*(?:0[xX])?[0-9A-Fa-f]{2,5}[hH]?$")


@dataclass(frozen=True)
class Address:
    """An address as printed: its value if the radix is plain, both readings if it is not."""

    text: str
    hex_value: int | None
    dec_value: int | None
    marked: bool
    """True when the text itself says hex (``0x``, ``h``) or holds a hex letter."""


def parse_address(text: str) -> Address | None:
    """``00E6H``, ``0x1A``, ``1A2Bh``, ``16#1A2B`` (IEC; ``16#2136 = 08502`` where both forms agree),
    ``40001``, ``0100`` (radix left to the column) -> Address."""
    t = text.strip().strip("()[]•").strip()  # a bullet glyph printed beside the number ("190 •")
    t = t[:-1] if re.fullmatch(r"\d{1,6}\.", t) else t  # "0." of a numbered list of registers
    t = t.replace("O", "0") if re.fullmatch(r"[0-9A-FO]{4}[hH]", t) else t
    m = _HEX_MARKED.match(t)
    if m:
        return Address(text, int(m.group(1) or m.group(2), 16), None, True)
    iec = _IEC_HEX.match(t)
    if iec:
        value = int(iec.group(1), 16)
        if iec.group(2) is not None and int(iec.group(2)) != value:
            return None  # the two forms of one cell disagree: no address is read from it
        return Address(text, value, None, True)
    if _PLAIN.match(t):
        return Address(text, int(t, 16) if len(t) <= 5 else None, int(t), False)
    if _BARE_HEX.match(t) and re.search(r"[A-Fa-f]", t):
        return Address(text, int(t, 16), None, True)
    return None


def address_conflict(text: str) -> str | None:
    """Why an address cell printed in two forms is not read: the forms disagree (``16#2138 = 08510``)."""
    iec = _IEC_HEX.match(text.strip())
    if iec and iec.group(2) is not None and int(iec.group(2)) != int(iec.group(1), 16):
        return (f"address {text.strip()!r}: 16#{iec.group(1)} is {int(iec.group(1), 16)}, the decimal beside it "
                f"says {int(iec.group(2))}: the two forms disagree")
    return None


def parse_address_pair(text: str) -> tuple[Address, Address] | None:
    """``1001, 1002`` (or ``1001+1002``): the two addresses of one two-register row (consecutive or not: the caller checks)."""
    m = re.fullmatch(r"\s*([^,;/&+\s]+)\s*[,;/&+]\s*([^,;/&+\s]+)\s*", text)
    if not m:
        return None
    first, second = parse_address(m.group(1)), parse_address(m.group(2))
    return (first, second) if first is not None and second is not None else None


def is_address_range(text: str) -> bool:
    return bool(_ADDR_RANGE.match(text.strip()))


_ACCESS = {
    "r": "r", "ro": "r", "read": "r", "read only": "r", "read-only": "r", "readonly": "r", "只读": "r",
    "唯讀": "r", "只讀": "r", "w": "w", "wo": "w", "write": "w", "write only": "w", "只写": "w",
    "r/w": "rw", "w/r": "rw", "rw": "rw", "wr": "rw", "read/write": "rw", "read-write": "rw", "read write": "rw",
    "read & write": "rw", "write-only": "w", "r/w/": "rw", "读写": "rw",
    "讀寫": "rw", "r&w": "rw", "r,w": "rw",
}
_ACCESS_TOKEN = re.compile(r"(?:^|\s)(R/W|W/R|RW|RO|WO|R|W)\s*$")


def parse_access(text: str) -> str | None:
    """R, W, R/W, W/R, RO, read-only ... -> r | w | rw."""
    key = re.sub(r"\s+", " ", text.strip().lower()).strip(" .*")
    return _ACCESS.get(key)


def trailing_access(text: str) -> tuple[str | None, str]:
    """An access token at the end of a free-text row (``3000H Operating frequency R``)."""
    m = _ACCESS_TOKEN.search(text)
    if not m:
        return None, text
    return _ACCESS[m.group(1).lower()], text[: m.start()].rstrip()


_TYPE_WORDS: tuple[tuple[str, str], ...] = (
    (r"\b(?:float64|double|lreal|f64|ieee\s*754\s*double)\b", "f64"),
    (r"\b(?:float32|float|real|f32|ieee\s*-?\s*754|ieee\s*floating)\b", "f32"),
    (r"\b(?:uint64|u64|unsigned\s*64|ulint)\b", "u64"),
    (r"\b(?:int64|s64|signed\s*64|lint|sint64)\b", "s64"),
    (r"\b(?:uint32|u32|unsigned\s*32|udint|dword|unsigned\s*long|ulong)\b", "u32"),
    (r"\b(?:int32|s32|signed\s*32|dint|sint32|long)\b", "s32"),
    (r"\b(?:uint16|u16|unsigned\s*16|uint|word|unsigned\s*short|ushort|unsigned)\b", "u16"),
    (r"\b(?:int16|s16|signed\s*16|sint16|sint|short|int|signed)\b", "s16"),
    (r"\b(?:string|ascii|char|text|str|utf-?8)\b", "string"),
    (r"\b(?:bool|boolean|bit)\b", "bool"),
)
_SIGNED_HINT = re.compile(r"(?<![A-Za-z])(?:sign attached|signed)(?![A-Za-z])|有符号|附符号|带符号|帶符號|有號|附符號|"
                          r"two'?s complement", re.I)
"""Whole words only: "Assigned", "Designed" say nothing about a sign."""
_UNSIGNED_HINT = re.compile(r"(?<![A-Za-z])unsigned(?![A-Za-z])|无符号|無符號", re.I)
#: registers (16-bit words) of each type
WIDTHS = {"u16": 1, "s16": 1, "u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4, "f64": 4, "bool": 1}


def parse_type(text: str, words: int | None = None) -> str | None:
    """A data-type cell (with the register count if a length column gives one) -> schema type."""
    low = re.sub(r"\s+", " ", text.strip().lower())
    if not low:
        return None
    # a type token broken over two lines or spaced: "UINT 16", "Int1 6", "U 32"
    low = re.sub(r"\b(u?int|float|real|[us])\s?(\d)\s?(\d)\b", r"\1\2\3", low)
    low = re.sub(r"\b(u?int(?:8|16|32|64))_t\b", r"\1", low)  # C's names: uint16_t, int32_t
    for pattern, rtype in _TYPE_WORDS:
        found = re.search(pattern, low)
        if found:
            if words is not None and rtype in WIDTHS and WIDTHS[rtype] != words and rtype != "bool":
                if not _SIZED.search(found.group(0)):
                    return _resize(rtype, words)
                # the token states its width: a length of twice its words counts bytes; any other, a contradiction
                return rtype if words == 2 * WIDTHS[rtype] else None
            return rtype
    return None


#: a type token that states its width itself (``UINT32``, ``float64``, ``DINT``, ``double``): a length
#: column cannot resize it
_SIZED = re.compile(r"\d|dword|udint|\bdint|ulint|\blint|lreal|double")


def _resize(rtype: str, words: int) -> str | None:
    """A signedness word with a length that says the width (``signed`` + 2 words -> s32)."""
    family = {"u": "u", "s": "s", "f": "f"}[rtype[0]]
    sized = {1: "16", 2: "32", 4: "64"}.get(words)
    if sized is None or (family == "f" and words == 1):
        return None
    return f"{family}{sized}"


_GLOSSARY = re.compile(
    r"^[ \t]*(?P<token>[A-Z][A-Z0-9_]{0,11})[ \t]*[:=：\-–]?[ \t]+(?P<said>(?i:"
    r"(?:an?\s+)?(?P<sign>un)?signed\s+(?:integer|int|short|long|number|value)?\s*[,(（]?\s*(?P<w1>16|32|64)\s*-?\s*bits?"
    r"|(?P<w2>16|32|64)\s*-?\s*bits?\s+(?P<sign2>un)?signed(?:\s+(?:integer|int|number|value))?"
    r"|(?:ieee[\s-]*754\s+)?(?:floating[\s-]*point|float)(?:\s+number)?\s*[,(（]?\s*(?P<w3>32|64)\s*-?\s*bits?"
    r"|(?P<w4>32|64)\s*-?\s*bits?\s+(?:ieee[\s-]*754\s+)?(?:floating[\s-]*point|float)"
    r")[ \t]*[)）]?)", re.M)
"""A line of a document's glossary of data types: ``I32  Signed integer (32 bits)``, ``U16: unsigned
16-bit integer``, ``INT16 16-bit signed integer``, ``F32 floating point (32 bits)``."""


def type_glossary(text: str) -> dict[str, tuple[str, str]]:
    """The data types a document defines in its own words: token (upper case) -> (schema type, the
    line that defines it). A token defined twice differently is left out (the document contradicts itself)."""
    found: dict[str, tuple[str, str]] = {}
    clashes: set[str] = set()
    for m in _GLOSSARY.finditer(text):
        token = m.group("token").upper()
        if not re.search(r"\d|^[A-Z]{2,}$", token):
            continue
        width = m.group("w1") or m.group("w2") or m.group("w3") or m.group("w4")
        if m.group("w3") or m.group("w4"):
            rtype = f"f{width}"
        else:
            rtype = f"{'u' if (m.group('sign') or m.group('sign2')) else 's'}{width}"
        line = m.group(0).strip()
        if token in found and found[token][0] != rtype:
            clashes.add(token)
        found.setdefault(token, (rtype, line))
    return {k: v for k, v in found.items() if k not in clashes}


def signed_hint(text: str) -> bool:
    return bool(_SIGNED_HINT.search(text)) and not _UNSIGNED_HINT.search(text)


def parse_length(text: str, header: str) -> int | None:
    """A length cell -> registers (words). Bytes are converted when the header or cell says bytes."""
    m = re.fullmatch(r"\s*(\d{1,3})\s*(bytes?|words?|regs?|registers?)?\s*", text.lower())
    if not m:
        return None
    n = int(m.group(1))
    unit = m.group(2) or ("byte" if "byte" in header.lower() else "word" if re.search(r"word|reg|quant|number|count|size|len", header.lower()) else None)
    if unit is None:
        return None
    if unit.startswith("byte"):
        return n // 2 if n % 2 == 0 and n > 0 else None
    return n if n > 0 else None


_NUMBER = r"[-−+]?\d+(?:\.\d+)?"
_RANGE = re.compile(rf"({_NUMBER})\s*(?:~|～|to|–|—|\.\.|-)\s*({_NUMBER})")


_REFERENCE = re.compile(r"(?:\btable|\btab\.|\bfig(?:ure|\.)?|\bchapter|\bsection|\bsec\.|\bappendix|表|图|圖)\s*$", re.I)
"""``Table 2-2``, ``Figure 3-1``: the numbers of a table or figure, not a range."""


_INTERVAL = re.compile(rf"[\[(]\s*({_NUMBER})\s*[,，;]\s*({_NUMBER})\s*[\])]|\[\s*({_NUMBER})\s+({_NUMBER})\s*\]")
"""``[0,1000]``, ``[-32768,32767]``, ``[0000 6300]``: an interval written with brackets and a comma (or, in
square brackets, a space)."""

#: a range that is exactly the span of a raw register type states that type (``[-32768,32767]``: s16)
FULL_SPANS: dict[tuple[float, float], str] = {(-32768, 32767): "s16", (0, 65535): "u16", (-2147483648, 2147483647): "s32", (0, 4294967295): "u32"}


def span_type(text: str) -> str | None:
    """The register type a range states by being its whole span (``[-32768,32767]`` -> s16), else None."""
    rng = parse_range(text) if text else None
    return FULL_SPANS.get((rng[0], rng[1])) if rng is not None else None


def parse_range(text: str) -> tuple[float, float, str] | None:
    """``0 ~ 1000``, ``-10000~10000``, ``0-65535 r/min``, ``[0,1000]`` -> (low, high, the text after it)."""
    text = text.replace("−", "-")
    interval = _INTERVAL.search(text)
    if interval and not _REFERENCE.search(text[:interval.start()]):
        low, high = _num(interval.group(1) or interval.group(3)), _num(interval.group(2) or interval.group(4))
        return (low, high, text[interval.end():].strip()) if low <= high else None
    m = next((m for m in _RANGE.finditer(text) if not _REFERENCE.search(text[:m.start()])), None)
    if not m:
        return None
    low, high = _num(m.group(1)), _num(m.group(2))
    if low > high:
        return None
    return low, high, text[m.end():].strip()


def _num(text: str) -> float:
    value = float(text.replace("−", "-"))
    return int(value) if value.is_integer() and "." not in text else value


def parse_number(text: str) -> float | None:
    t = text.strip().replace(",", "")
    if re.fullmatch(_NUMBER, t):
        return _num(t)
    return None


_ENUM_VALUE_FIRST = re.compile(
    r"(?:^|[\s,;(])(?P<v>-?\d{1,5}|[0-9A-Fa-f]{1,4}[hH])(?:\s*\((?:[0-9A-Fa-f]+h|\d+)\))?(?:\([01]+b\))?"
    r"\s*[:：=]\s*(?P<l>[^,;:\n=]+?)(?=\s*(?:[,;\n]|$|\s-?\d{1,5}\s*[:：=]|\s[0-9A-F]{1,4}H\s*:))")
_ENUM_LABEL_FIRST = re.compile(
    r"(?:^|[,;(\n])\s*(?P<l>[A-Za-z][A-Za-z /_-]{0,40}?)\s*=\s*(?P<v>-?\d{1,5})(?=\s*(?:[,;\n)]|$))")
_BIT_ITEM = re.compile(r"(?:^|[\s,;；])bit[ \t]*(?P<b>\d{1,2})(?![ \t]*[-~～][ \t]*\d)[ \t]*[:：=-][ \t]*"
                       r"(?P<l>[^,;；\n]+?)(?=[ \t]*(?:[,;；\n]|$|bits?[ \t]*\d))", re.I)
"""``bit3: label``; a label ends at the next ``bitN`` (a list run into one line); ``bit0~7:`` is a field."""


def _int_value(text: str) -> int | None:
    t = text.strip()
    if t[-1:] in "hH":
        try:
            return int(t[:-1], 16)
        except ValueError:
            return None
    try:
        return int(t)
    except ValueError:
        return None


@dataclass(frozen=True)
class ValueList:
    """A list of ``N = text`` items (``1 = 1200 baud, 2 = 2400 baud``): what the register's values mean."""

    items: list[tuple[int, str]]
    ambiguous: bool
    """Every item is an amount and every amount is the value times one step (``1 = 0.1 A, 10 = 1 A``):
    the list may be a set of values or a resolution restated; the document does not say which."""
    printed: str = ""


_AMOUNT = re.compile(rf"^\s*({_NUMBER})\s*([A-Za-z%°/]+)\s*$")
_BARE_NUMBER = re.compile(rf"^\s*{_NUMBER}\s*$")


def _one_step(items: list[tuple[int, str]]) -> bool:
    """True when every label is an amount in one unit and each amount is its value times one step."""
    amounts = [_AMOUNT.match(label) for _, label in items]
    if not all(amounts) or len({m.group(2) for m in amounts if m}) != 1:
        return False
    steps = set()
    for (value, _), m in zip(items, amounts, strict=True):
        amount = float(m.group(1)) if m else 0.0
        if value == 0:
            if amount != 0:
                return False
            continue
        steps.add(round(amount / value, 9))
    return len(steps) == 1


def value_list(text: str) -> ValueList | None:
    """``N = text`` (or ``N: text``) items, two or more with distinct values, amounts (``9600 baud``,
    ``60 Hz``) included; None when the text lists no values. A bare number (``12:00``) is no label,
    and an amount in parentheses (``(1 = 0.01 VDC)``) states a resolution, not a value."""
    items: list[tuple[int, str]] = []
    span: list[int] = []
    for m in _ENUM_VALUE_FIRST.finditer(text):
        value, label = _int_value(m.group("v")), m.group("l").strip()
        if value is None or not label or _BARE_NUMBER.match(label) or label.lower().startswith(("bit", "byte")):
            continue
        if _AMOUNT.match(label) and text[:m.start("v")].rstrip().endswith(("(", "（")):
            continue
        items.append((value, label))
        span += [m.start("v"), m.end("l")]
    values = [v for v, _ in items]
    if len(items) < 2 or len(set(values)) != len(values):
        return _line_list(text) if not items else None
    return ValueList(items, _one_step(items), re.sub(r"\s+", " ", text[span[0]:span[-1]]))


#: one line of a value list written one value a line, the label after spaces (``0x01 60hz``, ``1 智能负载输出``)
_LINE_ITEM = re.compile(r"^\s*(?P<v>0[xX][0-9A-Fa-f]{1,4}|\d{1,5})(?![\d.)\]:：=,，/~-])\s+(?P<l>\S.*?)\s*$")
_LETTER = re.compile(r"[^\W\d_]")
_SAYS_AMOUNT = re.compile(r"^(?:means|corresponds|对应|對應|表示)", re.I)


def _line_list(text: str) -> ValueList | None:
    """Values listed one a line, each line a value and its label, a label's further lines under it:
    ``0x00 50HZ`` / ``0x01 60hz``. None when a line before the first value says something else (the list's
    first values are not printed), when a label is no words, or when zero-padded numbers of two digits or
    more (``0010``) may be hex or decimal."""
    items: list[tuple[int, str]] = []
    padded = False
    for line in text.splitlines():
        m = _LINE_ITEM.match(line)
        if m is None or not _LETTER.search(m.group("l")) or _SAYS_AMOUNT.match(m.group("l")):
            if not line.strip():
                continue
            if not items:
                return None
            items[-1] = (items[-1][0], f"{items[-1][1]} {line.strip()}")
            continue
        v = m.group("v")
        padded = padded or (len(v) > 1 and v.startswith("0") and not v.lower().startswith("0x"))
        items.append((int(v, 16) if v.lower().startswith("0x") else int(v), m.group("l")))
    values = [v for v, _ in items]
    if len(items) < 2 or len(set(values)) != len(values) or (padded and max(values) > 9):
        return None
    return ValueList(items, _one_step(items), re.sub(r"\s+", " ", text.strip()))


def parse_enum(text: str) -> list[tuple[int, str]] | None:
    """``0: STOP 2: RUN``, ``0001H: Forward running``, ``Resistive=1, inductive=2`` -> [(value, label)].
    A list of amounts (``4 = 9600 baud, 5 = 19200 baud``) is a list of values too, unless every amount
    is its value times one step (:attr:`ValueList.ambiguous`): then None, and no resolution either."""
    listed = value_list(text)
    if listed is not None:
        return None if listed.ambiguous else listed.items
    items = []
    for m in _ENUM_LABEL_FIRST.finditer(text):
        label = m.group("l").strip()
        if label.lower() not in ("1", "bit") and not label.lower().startswith("bit"):
            items.append((int(m.group("v")), label))
    values = [v for v, _ in items]
    if len(items) < 2 or len(set(values)) != len(values):
        return None
    return items


def parse_bits(text: str) -> list[tuple[int, str]] | None:
    """``bit0: run, bit1: fault`` -> [(offset, label)]."""
    items = [(int(m.group("b")), m.group("l").strip()) for m in _BIT_ITEM.finditer(text)]
    offsets = [b for b, _ in items]
    if not items or len(set(offsets)) != len(offsets) or max(offsets) > 31:
        return None
    return items


def bit_index(text: str) -> int | None:
    """A bit column's cell: ``0`` .. ``15``, or one hex digit ``A``..``F`` (bit 10..15)."""
    t = text.strip()
    if re.fullmatch(r"\d{1,2}", t) and int(t) <= 31:
        return int(t)
    if re.fullmatch(r"[A-Fa-f]", t):
        return int(t, 16)
    m = re.fullmatch(r"(?:bit|b)\s*(\d{1,2})", t, re.I)
    return int(m.group(1)) if m and int(m.group(1)) <= 31 else None
