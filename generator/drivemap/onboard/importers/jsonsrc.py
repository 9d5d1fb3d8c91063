"""Reading JSON sources (drivemap's JSON export, pymodbus simulator configurations) with every object's line.

Objects become :class:`~drivemap.onboard.importers.yamlsrc.Node` dicts that know where they start, so
an entry that cannot be imported is reported as ``file:line:col: error: ...`` like a YAML source's.
:func:`field` reads one value of an object and says where it is when it has the wrong shape.
"""

from __future__ import annotations

import bisect
import json
import json.decoder
import json.scanner
from pathlib import Path
from typing import Any

from drivemap.diagnostics import CompileError, Diagnostic, Location
from drivemap.frontend.project import display
from drivemap.onboard.importers.yamlsrc import Node, located, read_source

__all__ = ["MISSING", "field", "load_json", "objects", "plain"]

_MAX_BYTES = 32 * 1024 * 1024
#: :func:`field`'s marker for "the key may be absent": the default is returned then
MISSING: Any = object()
_KINDS = {"int": (int,), "number": (int, float), "str": (str,), "bool": (bool,), "list": (list,),
          "object": (dict,)}


class _Decoder(json.JSONDecoder):
    """The standard decoder whose objects are :class:`Node` (positions from the pure-Python scanner)."""

    def __init__(self, text: str) -> None:
        super().__init__()
        starts = [0] + [i + 1 for i, c in enumerate(text) if c == "\n"]
        plain = json.decoder.JSONObject  # type: ignore[attr-defined]

        def parse_object(s_and_end: tuple[str, int], *args: Any) -> tuple[Node, int]:
            value, end = plain(s_and_end, *args)
            pos = s_and_end[1] - 1
            node = Node(value)
            node.line = bisect.bisect_right(starts, pos)
            node.col = pos - starts[node.line - 1] + 1
            return node, end

        self.parse_object = parse_object
        self.scan_once = json.scanner.py_make_scanner(self)  # type: ignore[attr-defined]


def load_json(path: Path) -> Any:
    """The document of ``path``; a located error for an unreadable file or malformed JSON."""
    shown = display(path)
    text = read_source(path, _MAX_BYTES, "larger than 32 MiB: not an export", encoding="utf-8-sig")
    try:
        return _Decoder(text).decode(text)
    except json.JSONDecodeError as exc:
        raise CompileError([Diagnostic(Location(shown, exc.lineno, exc.colno), f"not JSON: {exc.msg}")]) from None
    except (ValueError, RecursionError) as exc:
        raise CompileError([Diagnostic(Location(shown, 1, 1), f"not JSON: {exc}")]) from None


def field(path: Path, node: Any, key: str, kind: str, where: str, default: Any = MISSING,
          nullable: bool = False) -> Any:
    """``node[key]`` if it is of ``kind`` (int, number, str, bool, list, object; null too if ``nullable``);
    ``default`` when the key is absent and a default is given; else a located error naming ``where``."""
    if not isinstance(node, dict):
        raise located(path, node, f"{where}: an object was expected")
    if key not in node:
        if default is not MISSING:
            return default
        raise located(path, node, f"{where}: '{key}' is missing")
    value = node[key]
    if value is None and nullable:
        return None
    types = _KINDS[kind]
    if not isinstance(value, types) or (kind in ("int", "number") and isinstance(value, bool)):
        shown = json.dumps(value, ensure_ascii=False)[:40]
        raise located(path, node, f"{where}: '{key}' must be {'an' if kind[0] in 'aio' else 'a'} {kind}"
                                  f"{' or null' if nullable else ''}, not {shown}")
    return value


def objects(path: Path, node: Any, key: str, where: str) -> list[Node]:
    """The list ``node[key]`` (absent: empty), each item an object; located errors otherwise."""
    items = field(path, node, key, "list", where, default=[])
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise located(path, node, f"{where}: {key}[{i}] must be an object")
    return list(items)


def plain(value: Any) -> Any:
    """``value`` with every :class:`Node` a plain dict (what the map writer represents)."""
    if isinstance(value, dict):
        return {key: plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [plain(item) for item in value]
    return value
