"""ESPHome's ``substitutions:``: ``${name}`` and ``$name`` in every string value replaced by the value given.

A value that is exactly one substitution takes the substituted value with its type (``address: ${reg}``
with ``reg: 40`` is the integer 40); inside longer text the value is written as text, and a text that
then reads as a number (``"0x${hi}00"``) is that number. A name no ``substitutions:`` (or include
``vars:``) gives is left as written and listed (ESPHome warns the same way).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from drivemap.onboard.importers.yamlsrc import Node, Tagged, here

__all__ = ["substitute"]

_VAR = re.compile(r"\$\{([A-Za-z0-9_]+)\}|\$([A-Za-z0-9_]+)")


def substitute(data: Any, variables: dict[str, Any], path: Path, unknown: list[str] | None = None) -> Any:
    """``data`` with the ``variables`` substituted (mappings keep their place in the file)."""
    return _walk(data, variables, path, unknown if unknown is not None else [], None)


def _walk(value: Any, variables: dict[str, Any], path: Path, unknown: list[str], where: Any) -> Any:
    if isinstance(value, Node):
        for key in list(value):
            value[key] = _walk(value[key], variables, path, unknown, value)
        return value
    if isinstance(value, list):
        return [_walk(v, variables, path, unknown, where) for v in value]
    if isinstance(value, dict):
        return {k: _walk(v, variables, path, unknown, where) for k, v in value.items()}
    if isinstance(value, str) and not isinstance(value, Tagged) and "$" in value:
        return _text(value, variables, path, unknown, where)
    return value


def _text(text: str, variables: dict[str, Any], path: Path, unknown: list[str], where: Any) -> Any:
    whole = _VAR.fullmatch(text)
    if whole:
        name = whole.group(1) or whole.group(2)
        if name in variables:
            value = variables[name]
            return _number(value) if isinstance(value, str) else value
    missing: list[str] = []

    def one(match: re.Match[str]) -> str:
        name = match.group(1) or match.group(2)
        if name not in variables:
            missing.append(name)
            return match.group(0)
        return str(variables[name])

    out = _VAR.sub(one, text)
    for name in missing:
        unknown.append(f"{here(where, path)}: ${{{name}}} is not given by substitutions: (left as written)")
    return _number(out) if out != text and not missing else out


def _number(text: str) -> Any:
    """``text`` as the number it reads as (YAML's reading of a plain scalar), else the text."""
    try:
        parsed = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return parsed if isinstance(parsed, int | float) and not isinstance(parsed, bool) else text
