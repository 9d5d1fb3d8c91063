"""Two entities of a source that read the same register words as different registers: an error at the
second, naming the first, before any map is built (the compiler would point into the map instead)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.importers.yamlsrc import here, located

__all__ = ["check_overlaps"]


def _words(reg: dict[str, Any]) -> int:
    from drivemap.runtime.spec import TYPE_WORDS

    if reg.get("type") == "string":
        return int(reg.get("length", 1))
    per = TYPE_WORDS.get(str(reg.get("type", "u16")), 1)
    count = int(reg.get("count", 1))
    stride = int(reg.get("stride", per))
    return per + (count - 1) * stride


def _name(reg: dict[str, Any], node: Any) -> str:
    return str(node.get("name") if isinstance(node, dict) and node.get("name") else reg.get("name"))


def check_overlaps(path: Path, regs: list[tuple[dict[str, Any], Any]], option: str) -> None:
    """Raise at the later of two entities whose registers share a word (``option``: what to change)."""
    spans = sorted(((r["table"], int(r["address"]), int(r["address"]) + _words(r), r, node) for r, node in regs),
                   key=lambda s: (s[0], s[1]))
    for (table, _, end, reg, node), (table2, start2, _, reg2, node2) in zip(spans, spans[1:], strict=False):
        if table == table2 and start2 < end:
            first, second = _name(reg, node), _name(reg2, node2)
            raise located(path, node2 if node2 is not None else node,
                          f"{second!r} reads {table} address {start2}, which {first!r} ({here(node, path)}) reads "
                          f"too: {option}")
