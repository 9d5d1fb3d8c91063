"""The name policy of everything that writes maps from other sources (``draft``, ``import``, ``probe``).

Text becomes a snake_case register name, UPPER_CASE members and flags, CamelCase enums. A name the
compiler refuses is renamed the one way: a Python keyword gets ``_value`` (``class`` ->
``class_value``); a name the generated client could not have (a client attribute such as ``self`` or
``read``, a builtin the generated classes name) gets ``_reg``. :func:`refused` says why the compiler
refuses a name, from the same sets the python exporter's check reads.
"""

from __future__ import annotations

import keyword
import re
import unicodedata

__all__ = ["camel", "refused", "register_name", "snake", "unique", "upper"]

_WORD = re.compile(r"[A-Za-z][A-Za-z0-9]*|[0-9]+")
_CAMEL = re.compile(r"(?<=[a-z]{2})(?=[A-Z])|(?<=[A-Za-z][0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z]{2})")
"""Word starts inside a run of letters: ``InverterStatus``, ``PV1Curr``, ``PpvH``, ``DCBus`` (not ``kWh``)."""


def snake(text: str, fallback: str) -> str:
    """``Phase 1 line to neutral volts`` -> ``phase_1_line_to_neutral_volts``; ``fallback`` if no ASCII word."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    ascii_text = ascii_text.replace("%", " percent ").replace("&", " and ")
    ascii_text = _CAMEL.sub(" ", ascii_text)
    words = [w.lower() for w in _WORD.findall(ascii_text)]
    name = "_".join(words)[:56].strip("_")
    if not name or not name[0].isalpha():
        name = f"{fallback}_{name}" if name else fallback
    name = name[:48].rstrip("_")  # room for a suffix: names are at most 64 characters
    if keyword.iskeyword(name) or keyword.issoftkeyword(name):
        name += "_value"  # `class` -> `class_value`; other refused names: register_name
    return name


def upper(text: str, fallback: str) -> str:
    return snake(text, fallback.lower()).upper()


def camel(name: str) -> str:
    return "".join(p[:1].upper() + p[1:] for p in name.split("_") if p) or "Values"


def unique(name: str, taken: set[str]) -> str:
    candidate, n = name, 2
    while candidate in taken:
        candidate = f"{name}_{n}"
        n += 1
    taken.add(candidate)
    return candidate


def refused(name: str) -> str | None:
    """Why the compiler refuses ``name`` as a register name (None: it does not)."""
    from drivemap.vocab.namecheck import CLIENT_ATTRIBUTES
    from drivemap.vocab.reserved import reserved

    if keyword.iskeyword(name) or keyword.issoftkeyword(name):
        return "a Python keyword"
    if name in CLIENT_ATTRIBUTES or name in reserved().client:
        return "a client attribute"
    if name in reserved().annotation:
        return "a builtin the generated classes name"
    return None


def register_name(name: str) -> str:
    """``name`` as the compiler accepts it: a keyword + ``_value``, another refused name + ``_reg``."""
    why = refused(name)
    if why is None:
        return name
    if why == "a Python keyword":
        return f"{name[:58]}_value"
    return f"{name[:52].rstrip('_')}_reg"
