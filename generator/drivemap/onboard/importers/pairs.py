"""Which maps define the same device: the pairing rule of the catalogue's comparison.

Two maps from different sources (catalogue sources, or a catalogue map and a map of the project's own
``maps/``) are paired when their vendors agree and either

- their **designations** are equal: the words of the title that hold both letters and digits, each
  lower-cased with every non-alphanumeric character removed ("SDM-630" and "SDM630-Modbus" are both
  ``sdm630``), compared as whole sets (Growatt "MIN 3000TL-XE" and "MIN 6000TL-XH" differ; "X1/X3 G3/G4"
  and "X1/X3 G4" differ), or
- their **source ids** are equal: the name each source gives the definition (its file name, lower-cased,
  alphanumerics only: evcc ``deye-string`` and ha-solarman ``deye_string``).

Vendors agree when both, normalised the same way (first word, :data:`VENDOR_ALIASES`), are equal; a map
that names no vendor takes the first word of its source id. A map without vendor or designation is never
paired, nor are two maps of one source, nor SunSpec model maps (a model is not a device: its address
depends on its place in a device's chain). Missing a pair is preferred to a wrong pair. A pair the
rule cannot see is listed in :data:`REVIEWED` with the reason a person checked it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from itertools import combinations

__all__ = ["REVIEWED", "Entry", "VENDOR_ALIASES", "designations", "pairs"]

#: vendor spellings of one maker
VENDOR_ALIASES = {"ginlong": "solis", "sofarsolar": "sofar"}

#: (source id, source id): pairs checked by a person, with the reason
REVIEWED: dict[tuple[str, str], str] = {
    ("deye-hybrid-3p", "deye_p3"): "evcc's 3p hybrid template covers deye-hybrid-hp3; the ha-solarman profile "
                                   "names SUN-*K-SG04LP3 and SG01HP3: one three-phase hybrid family",
}


@dataclass(frozen=True)
class Entry:
    """One map: its model id, source ('project' for the project's own maps), vendor, title, source id."""

    model: str
    source: str
    vendor: str | None
    title: str
    source_id: str


def _alnum(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "", text.lower())


def designations(title: str) -> frozenset[str]:
    """The model designations of a title: its words with letters and digits ('modbus' dropped)."""
    words = re.sub(r"modbus", " ", title.lower()).split()
    out = {_alnum(w) for w in words}
    return frozenset(w for w in out if re.search(r"[a-z]", w) and re.search(r"[0-9]", w))


def _vendor(entry: Entry) -> str:
    words = (entry.vendor or "").split() or re.split(r"[^A-Za-z0-9]+", entry.source_id)[:1]
    word = _alnum(words[0]) if words else ""
    return VENDOR_ALIASES.get(word, word)


def pairs(entries: list[Entry]) -> list[tuple[Entry, Entry, str]]:
    """Every pair of maps of one device (different sources), with the rule that matched."""
    out: list[tuple[Entry, Entry, str]] = []
    for a, b in combinations(entries, 2):
        if a.source == b.source or "sunspec" in (a.source, b.source):
            continue
        reviewed = REVIEWED.get((a.source_id, b.source_id)) or REVIEWED.get((b.source_id, a.source_id))
        if reviewed:
            out.append((a, b, "reviewed"))
            continue
        vendor = _vendor(a)
        if not vendor or vendor != _vendor(b):
            continue
        da, db = designations(a.title), designations(b.title)
        if da and da == db:
            out.append((a, b, f"designation {'/'.join(sorted(da))}"))
        elif _alnum(a.source_id) and _alnum(a.source_id) == _alnum(b.source_id):
            out.append((a, b, f"source id {_alnum(a.source_id)}"))
    return out
