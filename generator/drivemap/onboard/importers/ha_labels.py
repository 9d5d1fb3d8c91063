"""Home Assistant template sensors that are label maps: a register's value -> text, nothing else.

A template is a label map when it reads exactly one entity's state and only looks its value up:

* a mapping literal ``{0: 'Standby', 1: 'Normal'}`` (keys integers or integer text) indexed by or
  ``.get``-ing the value, or tested with ``in``;
* an ``if`` / ``elif`` chain of ``value == N`` (or ``is_state('sensor.x', 'N')``) giving fixed text.

Anything else in it (arithmetic, other entities, filters other than ``int``/``string``/``default``,
bit tests) makes it the user's own logic: :func:`label_map` says None and :func:`open_fields` names
the register fields it seems to compute (listed for review, never imported).
"""

from __future__ import annotations

import ast
import re

__all__ = ["entities_of", "label_map", "open_fields"]

_STATES = re.compile(r"""states\(\s*['"](sensor\.[a-z0-9_]+)['"]\s*\)|states\.(sensor\.[a-z0-9_]+)\.state"""
                     r"""|is_state\(\s*['"](sensor\.[a-z0-9_]+)['"]""")
_INT = r"-?(?:0[xX][0-9a-fA-F]+|\d+)"
_BRANCH = re.compile(r"\{%-?\s*(?:if|elif)\s+(?:[a-z_][a-z0-9_]*|\(?states\([^)]*\)[^=]*?)\s*==\s*['\"]?(" + _INT +
                     r")['\"]?\s*-?%\}([^{]*)")
_IS_STATE = re.compile(r"\{%-?\s*(?:if|elif)\s+is_state\(\s*['\"]sensor\.[a-z0-9_]+['\"]\s*,\s*['\"](" + _INT +
                       r")['\"]\s*\)\s*-?%\}([^{]*)")
_MAX_LITERALS = 20
_FILTERS = {"int", "string", "default", "trim", "lower", "upper", "title"}
_ARITHMETIC = re.compile(r"(?<![{%])[*/+](?![}%])|//|\s-\s|\bfloat\b|\bround\b|bitwise|>>|<<|\|\s*abs|\bmax\b|\bmin\b")


def entities_of(template: str) -> list[str]:
    """The entity ids whose state the template reads, in order, each once."""
    return list(dict.fromkeys(next(g for g in m.groups() if g) for m in _STATES.finditer(template)))


def _number(text: str) -> int:
    return int(text, 0) if not re.fullmatch(r"-?0\d+", text) else int(text)


def _literal(template: str) -> tuple[dict[int, str], str] | None:
    """The one mapping literal of integer keys and text values in the template, and the template
    without it."""
    found = None
    ends: dict[int, int] = {}
    stack: list[int] = []
    for i, char in enumerate(template):  # every brace's partner in one pass
        if char == "{":
            stack.append(i)
        elif char == "}" and stack:
            ends[stack.pop()] = i + 1
    starts = [m.start() for m in re.finditer(r"\{(?![{%#])", template) if m.start() in ends]
    for start in starts[:_MAX_LITERALS]:
        end = ends[start]
        try:
            value = ast.literal_eval(template[start:end])
        except (ValueError, SyntaxError, MemoryError, RecursionError):
            continue
        if not isinstance(value, dict) or not value:
            continue
        try:
            pairs = {(_number(k) if isinstance(k, str) else k): v for k, v in value.items()}
        except ValueError:
            return None
        if not all(isinstance(k, int) and not isinstance(k, bool) and isinstance(v, str) for k, v in pairs.items()):
            return None
        if found is not None:
            return None  # two mappings: not a plain lookup
        found = (pairs, template[:start] + " LABELS " + template[end:])
    return found


def _plain(rest: str) -> bool:
    """Whether what is left of a template besides its lookup does nothing but read one value."""
    rest = re.sub(r"'[^']*'|\"[^\"]*\"", "''", rest)  # text constants (labels, 'unknown') say nothing
    if _ARITHMETIC.search(rest.replace("{{", "").replace("}}", "").replace("{%", "").replace("%}", "")):
        return False
    return all(f in _FILTERS for f in re.findall(r"\|\s*([a-z_]+)", rest))


#: a label map is short; a longer template is the user's own logic (and no scan of it grows with its square)
MAX_TEMPLATE = 20_000


def label_map(template: str) -> tuple[str, dict[int, str]] | None:
    """(entity id, {value: label}) of a template that is a plain label map, else None."""
    if len(template) > MAX_TEMPLATE:
        return None
    entities = entities_of(template)
    if len(entities) != 1:
        return None
    literal = _literal(template)
    if literal is not None:
        pairs, rest = literal
        return (entities[0], pairs) if _plain(rest) else None
    branches = _BRANCH.findall(template) or _IS_STATE.findall(template)
    if len(branches) < 2:
        return None
    pairs = {}
    for value, text in branches:
        label = text.strip()
        if not label or "{{" in label or _number(value) in pairs:
            return None
        pairs[_number(value)] = label
    rest = _IS_STATE.sub("", _BRANCH.sub("", template))
    return (entities[0], pairs) if _plain(rest) else None


def open_fields(template: str) -> list[str]:
    """The register fields a template that is not a label map decodes itself, so the register's source
    leaves them open: ``bits`` (bit tests on the value), ``enum`` (value comparisons giving text). A
    template that only computes with the value (a sum, a unit conversion) opens no field."""
    if len(template) > MAX_TEMPLATE:
        return []
    bare = re.sub(r"'[^']*'|\"[^\"]*\"", "''", template)
    if re.search(r"bitwise_and|//\s*\d+\s*\)\s*%\s*2|>>", bare):
        return ["bits"]
    if re.search(r"==\s*\d", bare) and re.search(r"%\}\s*[A-Za-z]", template):
        return ["enum"]
    return []
