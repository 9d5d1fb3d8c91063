"""Arrays of numbered series; the names themselves follow :mod:`drivemap.onboard.naming` (re-exported here)."""

from __future__ import annotations

import re

from drivemap.onboard.draft.tables import Drafted
from drivemap.onboard.naming import camel, snake, unique, upper

__all__ = ["arrays", "camel", "snake", "unique", "upper"]

_SERIES = re.compile(r"^(?P<base>.*?\D)\s*(?:no\.?\s*)?(?P<n>\d{1,3})\s*$", re.I)


def _series_key(d: Drafted) -> tuple[str, int] | None:
    """(base text, number) of a label or parameter that ends in a number (``Alarm 履歷 3``, ``P_12``)."""
    label = str(d.entry.get("label") or d.entry.get("param") or "")
    if re.fullmatch(r"[A-Za-z]{1,2}\d{2,}", label):  # parameter codes (F00, C12) are not a series
        return None
    m = _SERIES.match(label)
    return (m.group("base").strip(), int(m.group("n"))) if m else None


_SAME = ("table", "type", "scale", "unit", "access", "min", "max", "word_order", "length")


def _joins(prev: Drafted, cur: Drafted, stride: int | None) -> bool:
    a, b = _series_key(prev), _series_key(cur)
    if a is None or b is None or a[0] != b[0] or b[1] != a[1] + 1:
        return False
    if any(prev.entry.get(k) != cur.entry.get(k) for k in _SAME) or prev.entry.get("bits") or cur.entry.get("bits"):
        return False
    step = int(str(cur.entry["address"])) - int(str(prev.entry["address"]))
    return step > 0 and (stride is None or step == stride)


def arrays(drafts: list[Drafted]) -> list[Drafted]:
    """Runs of three or more rows numbered 1, 2, 3 ... at a constant address step become one array."""
    out: list[Drafted] = []
    i = 0
    while i < len(drafts):
        j, stride = i, None
        while j + 1 < len(drafts) and _joins(drafts[j], drafts[j + 1], stride):
            stride = int(str(drafts[j + 1].entry["address"])) - int(str(drafts[j].entry["address"]))
            j += 1
        run = drafts[i:j + 1]
        for k in range(0, len(run), 256):
            chunk = run[k:k + 256]
            if len(chunk) >= 3:
                out.append(_merge(chunk, stride or 1))
            else:
                out.extend(chunk)
        i = j + 1
    return out


def _merge(run: list[Drafted], stride: int) -> Drafted:
    first = run[0]
    entry = dict(first.entry)
    key = _series_key(first)
    assert key is not None
    entry["count"], entry["stride"] = len(run), stride
    entry["label"] = f"{key[0]} {key[1]}..{key[1] + len(run) - 1}".strip()
    entry["series_base"] = key[0]
    defaults = [d.entry.get("default") for d in run]
    entry.pop("default", None)
    if all(v is not None for v in defaults):
        entry["default"] = defaults
    params = [d.entry.get("param") for d in run]
    if all(isinstance(p, str) for p in params) and any(params):
        entry["element_params"] = params
    enum = first.entry.get("enum")
    if enum is not None and any(d.entry.get("enum") != enum for d in run):
        entry.pop("enum")
    where = f"{first.where} .. {run[-1].where}"
    missing = sorted({m for d in run for m in d.missing})
    notes = [f"array of the numbered rows {first.where} .. {run[-1].where}"] + first.notes
    return Drafted(entry, where, missing, notes, first.table_label)
