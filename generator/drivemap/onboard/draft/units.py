"""Unit and resolution: ``0.01Hz``, ``×0.1 V``, ``1=0.1A``, ``(1=0.01 VDC)``, ``10/1A``, ``0.1 V/bit``.

:func:`parse_scale` returns the scale (engineering value per count) and the unit only when the
text states the resolution; a bare unit (``Hz``) gives the unit and no scale.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

_UNITS = (
    r"[Vv]olts?|[Aa]mps?|[Ww]atts?|[Hh]ertz|[Hh]ours?|[Ss]econds?|[Mm]inutes?|"
    r"kvarh|kVArh|kVarh|kvar|kVAr|kVar|kVAh|kVA|kWh|MWh|Wh|kW|MW|VArh|Varh|varh|VAr|Var|var|VA|W|"
    r"VDC|VAC|Vdc|Vac|mV|kV|V|mAh|kAh|Ah|mA|µA|μA|uA|kA|A|kHz|Hz|"
    r"r/min|rpm|RPM|min-1|°C|℃|°F|degC|deg|°|"
    r"µs|μs|ms|min|s|sec|h|hr|hours|"
    r"%RH|%|‰|MΩ|kΩ|mΩ|µΩ|μΩ|uΩ|Ω|ohms?|mH|Nm|N·m|N\.m|bar|mbar|kPa|Pa|MPa|psi|"
    r"m3/h|m³/h|l/min|L/min|l/h|m/s|mm|m|kg|g|pulses?|p/r|PPR|ppm"
)
UNIT = rf"(?:{_UNITS})"
_NUM = r"\d+(?:\.\d+)?"
_ONE_EQUALS = re.compile(rf"\b1\s*=\s*({_NUM})\s*({UNIT})(?![A-Za-z])")
_PER = re.compile(rf"(?<![\d.%])({_NUM})\s*/\s*({_NUM})\s*({UNIT})(?![A-Za-z/])")
_MEANS = re.compile(rf"\b({_NUM})\s*(?:means|corresponds\s+to|對應|对应|表示)\s*({_NUM})\s*({UNIT})(?![A-Za-z])", re.I)
_TIMES = re.compile(rf"(?:(?<![0-9A-Za-z])[xX]|[×*])\s*({_NUM})\s*({UNIT})(?![A-Za-z])")
_PER_BIT = re.compile(rf"({_NUM})\s*({UNIT})\s*/\s*(?:bit|lsb|count|digit|step)\b", re.I)
_LABELLED = re.compile(rf"(?:unit|resolution|单位|單位|分辨率|解析度)\s*[:：]?\s*({_NUM})\s*({UNIT})(?![A-Za-z])", re.I)
#: "Rated Current in A", "meter count in Wh": the value is given in that unit, one per count
_IN_UNIT = re.compile(rf"(?<![A-Za-z])in\s+({UNIT})(?![A-Za-z0-9²³/.])")
_WHOLE = re.compile(rf"^\s*[(\[]?\s*({_NUM})?\s*({UNIT})\s*[)\]]?\s*$")
_FOOTNOTE_AFTER = re.compile(r"^\s*\)?\s*\*(\d)")
_NORMAL = {"VDC": "V", "VAC": "V", "Vdc": "V", "Vac": "V", "℃": "°C", "degC": "°C", "rpm": "r/min",
           "RPM": "r/min", "min-1": "r/min", "uA": "µA", "μA": "µA", "uΩ": "µΩ", "μΩ": "µΩ", "μs": "µs", "sec": "s", "hr": "h", "hours": "h", "ohm": "Ω", "ohms": "Ω"}
_NORMAL.update({w: u for u, words in (("V", "volt volts"), ("A", "amp amps"), ("W", "watt watts"), ("Hz", "hertz"),
                                      ("h", "hour hours"), ("s", "second seconds"), ("min", "minute minutes"))
                for w in words.split() + [x.capitalize() for x in words.split()]})

#: spellings a unit cell prints that the unit words above do not take as written
_CAPITALISED = {"VAR": "var", "KWh": "kWh", "KVARh": "kvarh", "KVARH": "kvarh", "KW": "kW"}
#: a unit cell's spellings in the wrong case (``0.1kwh``, ``0.01v``) that name one unit only; ``S`` (siemens
#: or seconds?) and ``MWH`` (mega or milli?) are not among them
_FOLDED = {"kwh": "kWh", "kw": "kW", "v": "V", "kv": "kV", "mv": "mV", "hz": "Hz", "khz": "kHz", "kva": "kVA",
           "kvar": "kvar", "kvarh": "kvarh", "wh": "Wh", "va": "VA", "ah": "Ah", "mah": "mAh", "ma": "mA"}
_WHOLE_WORD = re.compile(rf"^\s*[(\[]?\s*({_NUM})?\s*([A-Za-z]+)\s*[)\]]?\s*$")
#: "Value weight: Volt*10" (Carlo Gavazzi and others): the register holds the quantity times the number
_WEIGHT = re.compile(r"\bweight\s*[:：]?\s*([A-Za-z°%][A-Za-z/°%]*)\s*[*×]\s*(\d+(?:\.\d+)?)(?![\d.])", re.I)
#: quantities without a unit a weight may name (power factor, cos phi)
_DIMENSIONLESS = re.compile(r"pf|cos(?:phi|φ)?|ratio|thd", re.I)
_QUANTITY = {"ampere": "A", "amperes": "A", "volt": "V", "volts": "V", "watt": "W", "watts": "W", "hertz": "Hz"}


@dataclass(frozen=True)
class Scale:
    scale: float | None
    unit: str | None
    printed: str
    note: str = ""
    """A doubt about the text (a footnote not printed, a zero resolution): no scale 1 is read from it."""
    reading: str = ""
    """How the unit was read, where it is not written as a unit is (``0.1kwh``: kWh), for the row's notes."""


def unit_name(text: str) -> str:
    return _NORMAL.get(text, text)


def _clean(value: float) -> float:
    clean = float(f"{value:.12g}")
    return int(clean) if clean.is_integer() else clean


def _found(scale: float, unit: str, m: re.Match[str], text: str,
           footnote: Callable[[str], bool] | None) -> Scale:
    after = _FOOTNOTE_AFTER.match(text[m.end():])
    if after and footnote is not None and not footnote(after.group(1)):
        return Scale(None, None, m.group(0), f"resolution '{m.group(0).strip()}' carries footnote *{after.group(1)}, "
                     "which the document does not print: scale left out")
    if scale <= 0:
        return Scale(None, unit_name(unit), m.group(0), "a zero resolution is not a scale")
    return Scale(_clean(scale), unit_name(unit), m.group(0))


def _weight(text: str) -> Scale | None:
    """``Value weight: Volt*10``: scale 0.1 V; ``PF*1000``: 0.001 without a unit; a quantity it does
    not know gives the scale and no unit."""
    m = _WEIGHT.search(text)
    if m is None or float(m.group(2)) <= 0:
        return None
    word = m.group(1)
    if _DIMENSIONLESS.fullmatch(word):
        unit = None
    elif re.fullmatch(UNIT, word) or word in _CAPITALISED:
        unit = _CAPITALISED.get(word) or unit_name(word)
    else:
        unit = _QUANTITY.get(word.lower())
    return Scale(_clean(1 / float(m.group(2))), unit, m.group(0),
                 f"scale {_clean(1 / float(m.group(2)))}: '{m.group(0)}' (the register holds the value times "
                 f"{m.group(2)})")


def unit_in_name(text: str) -> str | None:
    """The unit a cell that prints a quantity's unit beside its name gives (``V L1-N``, ``kWh(+) TOT``,
    ``DMD W max``): its one word that is a unit (a direction mark ``(+)`` aside); None when no word or
    two different ones are."""
    found = set()
    for word in text.split():
        word = re.sub(r"\([+-]\)$", "", word)
        if word in _CAPITALISED:
            found.add(_CAPITALISED[word])
        elif re.fullmatch(UNIT, word):
            found.add(unit_name(word))
    return found.pop() if len(found) == 1 else None


def parse_scale(text: str, *, unit_cell: bool = False, footnote: Callable[[str], bool] | None = None) -> Scale | None:
    """The resolution stated in ``text`` (a unit cell when ``unit_cell``, else free text)."""
    weight = _weight(text)
    if weight is not None:
        return weight
    for regex, kind in ((_ONE_EQUALS, "one"), (_MEANS, "per"), (_PER_BIT, "bit"), (_LABELLED, "bit"), (_TIMES, "bit"),
                        (_PER, "per")):
        m = regex.search(text)
        if not m:
            continue
        if kind == "per":
            counts, amount = float(m.group(1)), float(m.group(2))
            if counts == 0:
                continue
            return _found(amount / counts, m.group(3), m, text, footnote)
        return _found(float(m.group(1)), m.group(2), m, text, footnote)
    if not unit_cell:
        m = _IN_UNIT.search(text)
        if m:
            return Scale(1, unit_name(m.group(1)), m.group(0), f"scale 1: the text says the value is {m.group(0)!r}")
    if unit_cell:
        m = _WHOLE.match(text)
        if m:
            if m.group(1) is None:
                return Scale(None, unit_name(m.group(2)), text.strip())
            return _found(float(m.group(1)), m.group(2), m, text, footnote)
        m = _WHOLE_WORD.match(text)
        if m and m.group(2) == "us":  # µs in ASCII (``uS``, microsiemens, is not read as a time)
            return _read_as(m, "µs", "unit 'us' read as µs", text, footnote)
        if m and m.group(2).lower() in _FOLDED:
            unit = _FOLDED[m.group(2).lower()]
            return _read_as(m, unit, f"unit {m.group(2)!r} read as {unit}", text, footnote)
    return None


def _read_as(m: re.Match[str], unit: str, reading: str, text: str,
             footnote: Callable[[str], bool] | None) -> Scale:
    if m.group(1) is None:
        return Scale(None, unit, text.strip(), reading=reading)
    found = _found(float(m.group(1)), unit, m, text, footnote)
    return Scale(found.scale, found.unit, found.printed, found.note, reading)


#: a register's name that says it holds a time (``Communication timeout``, ``Ups_delay time``, ``自检时间``,
#: ``充电过流保护延迟TIMBatCOCPDly``)
_TIME_NAME = re.compile(r"(?i)time(?!s\b)|delay|(?-i:Dly)(?![a-z])|duration|interval|period|zeit|dauer|时间|時間|延时|延時|"
                        r"延迟|延遲")


def seconds_cell(text: str, name: str) -> Scale | None:
    """A unit cell ``S`` or ``1S``: siemens or seconds? Seconds where the register's name says it holds
    a time (a conductance is never a timeout); None otherwise."""
    m = _WHOLE_WORD.match(text)
    if m is None or m.group(2) != "S" or not _TIME_NAME.search(name):
        return None
    return _read_as(m, "s", f"unit 'S' read as seconds: the register's name ({name.strip()!r}) says it is a time",
                    text, None)


_TRAILING_UNIT = re.compile(rf"^\s*({UNIT})(?![A-Za-z])")


def unit_after_range(rest: str) -> str | None:
    """The unit printed right after a range (``0 ~ 65535  r/min``)."""
    m = _TRAILING_UNIT.match(rest)
    return unit_name(m.group(1)) if m else None
