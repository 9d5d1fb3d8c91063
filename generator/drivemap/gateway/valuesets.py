"""Registers with a value set (``values:`` in the map) at the gateway: the options a Home Assistant
select shows, and the value a command names.

A command names a value of the set by its option text (what the select sends), its label or the
value itself (``5``, ``5.0``); anything else is refused with
:class:`~drivemap.runtime.errors.NotAllowedValue`, which lists the allowed values, before anything
is queued. A number is matched with the runtime's tolerance
(:func:`drivemap.runtime.client.values.display.is_allowed`) and replaced by the map's value, so the
gateway's exactness check and the codec's value-set check agree on what is in the set.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from drivemap.gateway.payload import parse_json, show
from drivemap.model.nodes import Register
from drivemap.runtime.client.values.display import allowed_text, is_allowed
from drivemap.runtime.errors import InvalidValue, NotAllowedValue
from drivemap.runtime.spec import RegisterSpec


def _plain(value: float | str) -> str:
    return str(int(value)) if isinstance(value, float) and value.is_integer() else str(value)


def value_options(reg: Register) -> list[tuple[float | str, str]]:
    """(value, option text) of each value of ``reg``'s value set: the label, else the value as the
    map writes it (``5``); the value and label (``5 (5 min)``) where two texts would be the same."""
    texts = [item.label or _plain(item.value) for item in reg.value_set]
    if len(set(texts)) != len(texts):
        texts = [item.text() for item in reg.value_set]
    return [(item.value, text) for item, text in zip(reg.value_set, texts, strict=True)]


def _word(text: str) -> str:
    """A payload as a word: a JSON string's text, else the text as sent (stripped)."""
    word = text.strip()
    if word.startswith('"'):
        try:
            value = json.loads(word)
        except ValueError:
            return word
        if isinstance(value, str):
            return value
    return word


def set_value(reg: Register, spec: RegisterSpec, text: str) -> Any:
    """The map's value a command names (option text, label or value); NotAllowedValue otherwise."""
    word = _word(text)
    for item, (value, option) in zip(reg.value_set, value_options(reg), strict=True):
        if word in (option, item.label):
            return value
    given: Any = word
    if not text.strip().startswith('"'):
        try:
            given = parse_json(reg.name, text)
        except InvalidValue:
            given = word
    if isinstance(given, (int, float)) and not isinstance(given, bool):
        for value, _ in spec.values:
            if is_allowed(dataclasses.replace(spec, values=((value, None),)), given):
                return value
    raise NotAllowedValue(f"{reg.name}: {show(word)} is not one of the allowed values {allowed_text(spec)}",
                          tuple(v for v, _ in spec.values))
