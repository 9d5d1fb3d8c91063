"""Draft recovery on public documents: `drivemap draft` on vendor register documents of devices not in
this repository (bench/public_docs.json), compared with the maps they were finished into.

The documents are not in the repository (most have no redistribution licence; the openly licensed
ones are not committed either, as material fetched in this workplace is not). The bench reads them from
$DRIVEMAP_PUBLIC_DOCS (default ~/.cache/drivemap/public-docs), checks each one's sha256, drafts it with
the verb's code and the manifest's arguments, and compares the draft with the shipped map
(bench/draftscore.py). A document that is absent or differs gives a "not measured" row.

* **exact**: finished registers drafted with the same table, address, type and scale (as compiled),
  at the printed address and table, and under the map's systematic choices (manifest `map_choices`);
* **map choices**: the edits those choices made (an address offset on every register, a table written
  on every register), counted apart;
* **hand edits**: finished registers the draft does not have (added) + drafted registers the map does
  not keep (dropped) + register fields written, changed or removed between draft and map (every field
  but address, table, label, source, notes and group);
* **map-level edits**: top-level keys of `device` and `protocol` that differ, and the enums, groups,
  reserved ranges, known issues and examples that differ.

    python bench/publicdocs.py [--docs DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section, print_section  # noqa: E402
from draftscore import Drafted, NoTable, Score, compare, entries, make_draft  # noqa: E402

TITLE = "Draft recovery, public documents"
MANIFEST = HERE / "public_docs.json"
NOT_COUNTED = frozenset({"address", "table", "label", "source", "notes", "group"})
LISTS = ("enums", "groups", "reserved", "known_issues", "examples")


def docs_folder() -> Path:
    """$DRIVEMAP_PUBLIC_DOCS, else the shared folder's public-docs ($DRIVEMAP_SHARED or ../shared) when
    present, else ~/.cache/drivemap/public-docs."""
    if os.environ.get("DRIVEMAP_PUBLIC_DOCS"):
        return Path(os.environ["DRIVEMAP_PUBLIC_DOCS"])
    shared = Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared") / "public-docs"
    return shared if shared.is_dir() else Path.home() / ".cache" / "drivemap" / "public-docs"


def load_manifest(path: Path = MANIFEST) -> list[dict[str, Any]]:
    documents: list[dict[str, Any]] = json.loads(path.read_text(encoding="utf-8"))["documents"]
    return documents


def locate(doc: dict[str, Any], folder: Path) -> tuple[Path | None, str]:
    """The document's path when it is there with the manifest's sha256, else (None, why not)."""
    path = folder / doc["file"]
    if not path.is_file():
        return None, f"not measured: {doc['file']} absent (looked in {folder})"
    if hashlib.sha256(path.read_bytes()).hexdigest() != doc["sha256"]:
        return None, f"not measured: {doc['file']} sha256 differs from the manifest's"
    return path, ""


@dataclass
class Edits:
    """What separates a draft from the map it was finished into."""

    added: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    fields: list[str] = field(default_factory=list)
    systematic: Counter[str] = field(default_factory=Counter)
    map_level: Counter[str] = field(default_factory=Counter)

    @property
    def hand(self) -> int:
        return len(self.added) + len(self.dropped) + len(self.fields)


def _differ(a: Any, b: Any) -> bool:
    return json.dumps(a, sort_keys=True, default=str) != json.dumps(b, sort_keys=True, default=str)


def _map_level(drafted: dict[str, Any], finished: dict[str, Any], out: Counter[str]) -> None:
    for part in ("device", "protocol"):
        mine, theirs = drafted.get(part) or {}, finished.get(part) or {}
        out[part] += sum(_differ(mine.get(k), theirs.get(k)) for k in set(mine) | set(theirs))
    for part in LISTS:
        mine_l, theirs_l = drafted.get(part) or [], finished.get(part) or []
        if isinstance(mine_l, dict) or isinstance(theirs_l, dict):  # enums: name -> values
            mine_l = [{k: v} for k, v in dict(mine_l).items()]
            theirs_l = [{k: v} for k, v in dict(theirs_l).items()]
        ours = Counter(json.dumps(x, sort_keys=True, default=str) for x in mine_l)
        ref = Counter(json.dumps(x, sort_keys=True, default=str) for x in theirs_l)
        out[part] += max(sum((ref - ours).values()), sum((ours - ref).values()))


def hand_edits(drafted: Drafted, finished_data: dict[str, Any], finished: Any, offset: int = 0,
               table: str | None = None) -> Edits:
    """The edits from ``drafted`` to the finished map, each drafted register read at its address +
    ``offset`` in ``table``; the map choices' own edits are counted in ``systematic``."""
    out = Edits()
    theirs = {(r.table, r.address): r for r in finished.registers}
    mine = {(table or r.table, r.address + offset): r for r in drafted.model.registers}
    d_entries, f_entries = entries(drafted.data, drafted.model), entries(finished_data, finished)
    out.added = [r.name for key, r in theirs.items() if key not in mine]
    out.dropped = [r.name for key, r in mine.items() if key not in theirs]
    for key, reg in mine.items():
        if key not in theirs:
            continue
        fin = theirs[key]
        a, b = d_entries[reg.name], f_entries[fin.name]
        if offset and fin.address == reg.address + offset:
            out.systematic["address"] += 1
        if table and fin.table == table and a.get("table") != b.get("table"):
            out.systematic["table"] += 1
        elif a.get("table") != b.get("table"):
            out.fields.append(f"{fin.name}.table")
        out.fields += [f"{fin.name}.{k}" for k in sorted((set(a) | set(b)) - NOT_COUNTED) if _differ(a.get(k), b.get(k))]
    _map_level(drafted.data, finished_data, out.map_level)
    return out


def as_printed(score: Score, drafted: Drafted, finished: Any, offset: int, table: str | None) -> int:
    """Of the registers exact under the map choices, those the draft has at the finished map's own table
    and address (the choices changed nothing for them)."""
    mine = {(table or r.table, r.address + offset): r for r in drafted.model.registers}
    by_name = {r.name: r for r in finished.registers}
    out = 0
    for name in score.exact_names:
        fin = by_name[name]
        reg = mine[(fin.table, fin.address)]
        out += (reg.table, reg.address) == (fin.table, fin.address)
    return out


@dataclass
class Measured:
    doc: dict[str, Any]
    drafted: Drafted
    chosen: Score | None = None
    printed: int = 0
    """Registers exact with the address and table as printed (no map choice needed)."""
    edits: Edits | None = None


def _pages(args: list[str]) -> tuple[tuple[int, int] | None, int]:
    from drivemap.onboard.draft.cli import _pages as pages_of

    ap = argparse.ArgumentParser(prog="drivemap draft", add_help=False)
    ap.add_argument("--pages", default=None)
    ap.add_argument("--max-pages", type=int, default=400)
    ns = ap.parse_args(args)
    return pages_of(ns.pages), ns.max_pages


def measure(doc: dict[str, Any], path: Path) -> Measured:
    """Draft ``path`` as the manifest says and compare it with its finished map (if any)."""
    from drivemap.compiler import compile_map
    from drivemap.frontend.load import load_text
    from drivemap.onboard.draft.cli import _time_limit

    pages, max_pages = _pages(list(doc.get("draft_args", [])))
    model_id = Path(doc["map"]).stem if doc.get("map") else Path(doc["file"]).stem.replace("-", "_").lower()
    with _time_limit(300.0):
        drafted = make_draft(path, model_id, pages, max_pages)
    result = Measured(doc, drafted)
    if not doc.get("map"):
        return result
    map_path = ROOT / doc["map"]
    finished = compile_map(map_path)
    finished_data = load_text(map_path.read_text(encoding="utf-8"), str(map_path)).data
    choices = doc.get("map_choices") or {}
    offset, table = int(choices.get("address_offset", 0)), choices.get("table")
    result.chosen = compare(model_id, finished, drafted, offset, table)
    result.printed = as_printed(result.chosen, drafted, finished, offset, table)
    result.edits = hand_edits(drafted, finished_data, finished, offset, table)
    return result


def _counts(items: Counter[str] | list[str], suffix: bool = False) -> str:
    c = Counter(x.rsplit(".", 1)[1] for x in items) if suffix and isinstance(items, list) else Counter(items)
    return ", ".join(f"{k} {v}" for k, v in c.most_common() if v) or "none"


def _row_line(m: Measured) -> str:
    d, s, p, e = m.doc, m.chosen, m.printed, m.edits
    assert s is not None and e is not None
    return (f"| {d['file']} ({d['format']}) | `{d['map']}` | {len(m.drafted.model.registers)} / "
            f"{m.drafted.seconds:.2f} s | {s.proven} | {p} ({p / s.proven:.2f}) | {s.exact} ({s.exact / s.proven:.2f}) | "
            f"{s.fields_right}/{7 * s.proven} ({s.fields_right / (7 * s.proven):.2f}) | {len(s.wrong_stated)} | "
            f"{sum(e.systematic.values())} ({_counts(e.systematic)}) | {e.hand} ({len(e.added)} added, "
            f"{len(e.dropped)} dropped, {len(e.fields)} fields) | {sum(e.map_level.values())} |")


def _detail_lines(m: Measured) -> list[str]:
    s, e = m.chosen, m.edits
    assert s is not None and e is not None
    pad = " | | | | | | | | | |"
    out = [f"|  | wrong: {w}{pad}" for w in s.wrong_stated + s.lists_wrong]
    if e.added:
        out.append(f"|  | added by hand: {', '.join(e.added)}{pad}")
    if e.dropped:
        out.append(f"|  | drafted, not kept: {', '.join(e.dropped)}{pad}")
    out.append(f"|  | fields edited: {_counts(e.fields, suffix=True)}{pad}")
    out.append(f"|  | map-level edits: {_counts(e.map_level)}{pad}")
    if s.not_exact:
        out.append(f"|  | type/scale not as finished: {', '.join(s.not_exact)}{pad}")
    return out


def _measure_row(section: Section, m: Measured) -> None:
    d = m.doc
    if m.chosen is None:
        section.rows.append(Row(TITLE, f"{d['file']}: registers drafted", None, "—", None,
                                f"{len(m.drafted.model.registers)}; no finished map; {m.drafted.seconds:.1f} s"))
        return
    s, e = m.chosen, m.edits
    assert e is not None
    section.rows.append(Row(TITLE, f"{d['file']}: registers exact", s.exact / s.proven, "—", None,
                            f"{s.exact}/{s.proven}; wrong fields written {len(s.wrong_stated)}; hand edits {e.hand} "
                            f"(+{sum(e.systematic.values())} map choices); {m.drafted.seconds:.2f} s"))


def run(quick: bool = False, folder: Path | None = None, manifest: Path = MANIFEST) -> Section:
    section = Section(TITLE)
    folder = folder or docs_folder()
    head = ["| document (format) | finished map | draft: registers / tool time | finished registers | exact at the "
            "printed address and table | exact under the map choices | fields right | wrong fields written | "
            "map choices (edits) | hand edits | map-level edits |", "|---|---|---:|---:|---:|---:|---:|---:|---|---|---:|"]
    detail, other = list(head), []
    scored: list[Measured] = []
    for doc in load_manifest(manifest):
        path, why = locate(doc, folder)
        if path is None:
            section.rows.append(Row(TITLE, doc["file"], None, "—", None, why))
            other.append(f"* {doc['title']} {doc['revision']} ({doc['format']}): {why}.")
            continue
        try:
            m = measure(doc, path)
        except NoTable as exc:
            section.rows.append(Row(TITLE, f"{doc['file']}: registers drafted", None, "—", None,
                                    f"0: {exc}; {exc.seconds:.1f} s"))
            read = " ".join(doc["draft_args"]) or "whole document"
            other.append(f"* {doc['title']} {doc['revision']} ({doc['format']}, {read}): `drivemap draft` drafts "
                         f"nothing in {exc.seconds:.1f} s: {exc}." + ("" if doc.get("map") else " No finished map."))
            continue
        except RuntimeError as exc:  # the draft does not validate: a defect of the tool, reported as such
            section.rows.append(Row(TITLE, f"{doc['file']}: draft", None, "validates", False, str(exc)))
            other.append(f"* {doc['title']} {doc['revision']}: {exc}.")
            continue
        _measure_row(section, m)
        if m.chosen is None:
            other.append(f"* {doc['title']} {doc['revision']} ({doc['format']}): {len(m.drafted.model.registers)} "
                         f"registers drafted in {m.drafted.seconds:.1f} s; no finished map to compare with.")
            continue
        scored.append(m)
        detail.append(_row_line(m))
        detail += _detail_lines(m)
    _totals(section, scored, sum(1 for d in load_manifest(manifest) if d.get("map")))
    section.detail = detail + ([""] + other if other else [])
    return section


def _totals(section: Section, scored: list[Measured], with_map: int) -> None:
    if not scored:
        section.rows.append(Row(TITLE, "documents with a finished map measured", None, "—", None, f"0 of {with_map}"))
        return
    exact = sum(m.chosen.exact for m in scored if m.chosen)
    proven = sum(m.chosen.proven for m in scored if m.chosen)
    wrong = [w for m in scored if m.chosen for w in m.chosen.wrong_stated]
    section.rows.append(Row(TITLE, "finished documents: registers exact", exact / proven, "—", None,
                            f"{exact}/{proven} over {len(scored)} of {with_map} documents with a finished map"))
    section.rows.append(Row(TITLE, "wrong fields written", None, "0", not wrong,
                            f"{len(wrong)}" + (f": {'; '.join(wrong)}" if wrong else "")))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--docs", default=None, help="the documents' folder (default: $DRIVEMAP_PUBLIC_DOCS, else ../shared/public-docs)")
    args = ap.parse_args(argv)
    return print_section(run(folder=Path(args.docs) if args.docs else None))


if __name__ == "__main__":
    sys.exit(main())
