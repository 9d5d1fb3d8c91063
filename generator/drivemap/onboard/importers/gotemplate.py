"""The part of Go's text/template that evcc's render blocks use, evaluated per usage, line by line.

``{{ if }}`` / ``{{ else if }}`` / ``{{ else }}`` / ``{{ end }}`` whose condition depends only on
``.usage`` (``eq``, ``ne``, ``or``, ``and``, ``not``, string constants) are decided; a condition on
any other parameter (``.batterytype``, ``.firmware`` ...) is undecided: the lines of every branch are
kept and carry the condition's text, so a register they define is marked for review.
``{{ include "name" . }}`` lines are the template's shared blocks (connection settings: not registers)
and are dropped; any other action (``{{ .maxacpower }}``) is left as ``<param>``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

__all__ = ["Line", "expand"]

_ACTION = re.compile(r"\{\{-?\s*(.*?)\s*-?\}\}")
_INLINE = re.compile(r"\{\{-?\s*if\b.*\{\{-?\s*end\s*-?\}\}")
_TOKEN = re.compile(r'\(|\)|"[^"]*"|[^\s()]+')


@dataclass
class Line:
    """A line of the expanded block: its number in the block (0-based), text, undecided conditions."""

    index: int
    text: str
    conditions: tuple[str, ...] = ()
    includes: list[str] = field(default_factory=list)


@dataclass
class _Frame:
    branch: bool | None
    cond: str
    any_true: bool
    any_unknown: bool


def _tokens(text: str) -> list[str]:
    return _TOKEN.findall(text)


def _eval(tokens: list[str], usage: str) -> tuple[object, list[str]]:
    """Evaluate one expression (a call ``f a b`` or an atom) from ``tokens``; (value, rest).
    Values: a str/bool, or None when it depends on a parameter other than usage."""
    if not tokens:
        return None, []
    head, rest = tokens[0], tokens[1:]
    if head == "(":
        value, rest = _call(rest, usage)
        return value, rest[1:] if rest and rest[0] == ")" else rest
    if head.startswith('"'):
        return head[1:-1], rest
    if head == ".usage":
        return usage, rest
    if head in ("true", "false"):
        return head == "true", rest
    return None, rest


def _call(tokens: list[str], usage: str) -> tuple[object, list[str]]:
    if not tokens:
        return None, []
    head = tokens[0]
    if head not in ("eq", "ne", "or", "and", "not"):
        value, rest = _eval(tokens, usage)
        return value, rest
    rest = tokens[1:]
    args: list[object] = []
    while rest and rest[0] != ")":
        value, rest = _eval(rest, usage)
        args.append(value)
    return _apply(head, args), rest


def _apply(op: str, args: list[object]) -> object:
    if op == "not":
        return None if not args or args[0] is None else not bool(args[0])
    if op in ("eq", "ne"):
        if len(args) < 2 or any(a is None for a in args):
            return None
        equal = any(args[0] == other for other in args[1:])
        return equal if op == "eq" else not equal
    known = [a for a in args if a is not None]
    if op == "or":
        return True if any(bool(a) for a in known) else (None if len(known) < len(args) else False)
    return False if any(not bool(a) for a in known) else (None if len(known) < len(args) else True)


def condition(text: str, usage: str) -> bool | None:
    value, _ = _call(_tokens(text), usage)
    return None if value is None else bool(value)


def expand(block: str, usage: str) -> list[Line]:
    """The lines of ``block`` that are part of the rendering for ``usage``."""
    stack: list[_Frame] = []
    out: list[Line] = []
    for index, raw in enumerate(block.splitlines()):
        actions = list(_ACTION.finditer(raw))
        text = raw
        words = [m.group(1).split(" ", 1)[0] for m in actions]
        if "if" in words and "end" in words and _ACTION.sub("", raw).strip():
            # a condition inside the line (``address: {{ if .x }}1{{ else }}2{{ end }}``): its value is open
            out.append(Line(index, _INLINE.sub("<condition>", raw), tuple(f.cond for f in stack if f.branch is None)))
            continue
        includes: list[str] = []
        for match in actions:
            body = match.group(1)
            word = body.split(" ", 1)[0]
            if word in ("if", "range", "with", "define", "block"):
                cond = body[len(word):].strip()
                value = condition(cond, usage) if word == "if" else None
                stack.append(_Frame(value, cond, value is True, value is None))
            elif word == "else" and stack:
                _else(stack[-1], body[4:].strip(), usage)
            elif word == "end" and stack:
                stack.pop()
            elif word in ("include", "template"):
                name = re.findall(r'"([^"]*)"', body)
                includes.extend(name[:1])
            text = text.replace(match.group(0), "" if word in ("if", "else", "end", "range", "with", "define",
                                                               "block", "include", "template") else "<param>")
        if any(frame.branch is False for frame in stack):
            continue
        conds = tuple(f.cond for f in stack if f.branch is None)
        if text.strip() or includes:
            out.append(Line(index, text, conds, includes))
    return out


def _else(frame: _Frame, rest: str, usage: str) -> None:
    if frame.any_true:
        frame.branch = False
        return
    if rest.startswith("if "):
        value = condition(rest[3:], usage)
        frame.cond = rest[3:]
    else:
        value, frame.cond = True, f"not ({frame.cond})"
    if frame.any_unknown:
        frame.branch = None if value is not False else False
    else:
        frame.branch = value
    frame.any_true = frame.any_true or frame.branch is True
    frame.any_unknown = frame.any_unknown or frame.branch is None
