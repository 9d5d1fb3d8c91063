"""Versions of the map format, and how a map of an older one is read and rewritten.

A map says its format in ``drivemap: N``. A new key either comes with a default that keeps every
older map valid (then the format stays), or it cannot (then the format goes up by one and this
module says, per step, what an older map lacks):

==========  ====================================================================================
format      what changed
==========  ====================================================================================
1           the first format
2           ``protocol.function_codes[].broadcast_reason`` is required where ``broadcast`` is null
==========  ====================================================================================

A format-1 map is still read: :func:`upgrade` fills in, in memory, what format 2 requires, with
values that say so (never a guess). ``drivemap migrate`` (:func:`migrate_text`) writes the same into
the file by inserting lines (comments and layout stay as they are) and sets ``drivemap: 2``.
``protocol.exceptions[].documented`` needed no new format: it defaults to what the exception's
source already says (false for ``source: map choice``, else true).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic
from drivemap.frontend.load import Document, PathT

CURRENT = 2
FORMATS = (1, 2)

#: The reason a format-1 map's unclear broadcast gets: the map never said why (it predates the key).
UNSTATED_BROADCAST_REASON = (
    "not stated: this map was written in drivemap format 1, before a reason was asked for; "
    "review what the manual says about broadcast and replace this text"
)


@dataclass(frozen=True)
class Addition:
    """One key a newer format requires that an older map lacks: insert ``key: value`` into the
    mapping at ``parent`` (after its key ``after``)."""

    parent: PathT
    after: str
    key: str
    value: str
    why: str


def format_of(data: Any) -> int | None:
    """The map's ``drivemap:`` value when it is a known format (None otherwise: the schema reports it)."""
    version = data.get("drivemap") if isinstance(data, dict) else None
    return version if isinstance(version, int) and not isinstance(version, bool) and version in FORMATS else None


def additions(data: Any) -> Iterator[Addition]:
    """What a format-1 map lacks for format 2 (nothing for a map of another format)."""
    if format_of(data) != 1:
        return
    protocol = data.get("protocol")
    codes = protocol.get("function_codes") if isinstance(protocol, dict) else None
    if not isinstance(codes, list):
        return
    for i, fc in enumerate(codes):
        if isinstance(fc, dict) and "broadcast" in fc and fc["broadcast"] is None and "broadcast_reason" not in fc:
            yield Addition(("protocol", "function_codes", i), "broadcast", "broadcast_reason",
                           UNSTATED_BROADCAST_REASON, "format 2 asks why broadcast is null")


def upgrade(doc: Document) -> int | None:
    """Fill in, in memory, what a format-1 map lacks (:func:`additions`); the map's format (or None)."""
    version = format_of(doc.data)
    for item in list(additions(doc.data)):
        target: Any = doc.data
        for part in item.parent:
            target = target[part]
        target[item.key] = item.value
    return version


def _yaml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def migrate_text(text: str, doc: Document) -> str:
    """``text`` (the source of ``doc``) rewritten to the current format by editing lines in place:
    the ``drivemap:`` value is replaced and each missing key is inserted after its sibling, at the
    sibling's indentation. Comments, order, quoting and blank lines are kept. A map already in the
    current format comes back unchanged."""
    version = format_of(doc.data)
    if version is None or version == CURRENT:
        return text
    lines = text.splitlines(keepends=True)
    inserts: dict[int, list[str]] = {}
    for item in additions(doc.data):
        line, col = doc.positions.keys[item.parent + (item.after,)]
        row = lines[line - 1]
        if row[: col - 1].strip() not in ("", "-"):
            raise CompileError([Diagnostic(doc.positions.at(item.parent + (item.after,), key=True),
                                           f"cannot migrate a flow-style mapping: add {item.key}: by hand ({item.why})")])
        newline = "\r\n" if row.endswith("\r\n") else "\n"
        inserts.setdefault(line, []).append(" " * (col - 1) + f"{item.key}: {_yaml_string(item.value)}" + newline)
    line, col = doc.positions.values[("drivemap",)]
    row = lines[line - 1]
    token = str(version)
    if row[col - 1: col - 1 + len(token)] != token:
        raise CompileError([Diagnostic(doc.positions.at(("drivemap",)), "cannot migrate: write the format as a plain number")])
    lines[line - 1] = row[: col - 1] + str(CURRENT) + row[col - 1 + len(token):]
    out: list[str] = []
    for number, row in enumerate(lines, start=1):
        out.append(row)
        out.extend(inserts.get(number, ()))  # the sibling's value is one line (null)
    return "".join(out)


__all__ = ["CURRENT", "FORMATS", "UNSTATED_BROADCAST_REASON", "Addition", "additions", "format_of", "migrate_text",
           "upgrade"]
