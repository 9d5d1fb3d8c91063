"""Draft recovery: `drivemap draft` on the seed manuals against the proven maps.

For every seed manual (shared/manuals, the files the proven maps cite) the draft is made in memory
(the same code as the verb, nothing written) and compared with the proven map:

* **registers exact**: a proven register whose every element address is drafted in the same table
  with the same type and scale (as compiled: a field the draft leaves out takes the schema default);
* **fields right**: over the proven registers, table+address, type, scale, unit, access, min, max
  right as compiled, divided by 7 x registers;
* **wrong stated**: fields the draft *writes* that differ from the proven map (goal 0; a type or scale
  written wrong is the defect the tool must never make);
* **defaulted, differs**: fields the draft leaves out (and lists) whose schema default differs from
  the proven map (the review finds them in the summary);
* **hand edits**: registers to add + fields to change on found registers + drafted registers the
  proven map does not have (to delete or keep as extra).

    python bench/draft.py [--manuals DIR]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section  # noqa: E402

SEEDS = {"edx": "004_698379178adcef99.txt", "v2": "003_81ad9a58587804cf.txt",
         "vfd1000": "002_65caa110b92ac236.txt", "ev": "001_47d2095fcebbe4cf.txt"}
FIELDS = ("type", "scale", "unit", "access", "min", "max")


def manuals_folder() -> Path | None:
    for candidate in (ROOT.parent / "shared" / "manuals", ROOT / "shared" / "manuals", Path("/work/shared/manuals")):
        if candidate.is_dir():
            return candidate
    return None


@dataclass
class Score:
    model: str
    proven: int
    exact: int
    fields_right: int
    wrong_stated: list[str]
    defaulted: int
    extra: int
    seconds: float
    drafted: int

    @property
    def edits(self) -> int:
        return (self.proven - self.found) + self.field_edits + self.extra

    found: int = 0
    field_edits: int = 0
    not_found: list[str] = field(default_factory=list)
    lists_right: int = 0
    lists_total: int = 0
    lists_wrong: list[str] = field(default_factory=list)
    not_exact: list[str] = field(default_factory=list)


def _cells(model: Any) -> dict[tuple[str, int], Any]:
    out = {}
    for r in model.registers:
        for i in range(r.count):
            out[(r.table, r.address + i * (r.stride or 1))] = r
    return out


def _value(reg: Any, key: str) -> Any:
    value = getattr(reg, key, None)
    return float(value) if key == "scale" and value is not None else value


def _comparable(registers: Any, cells: dict[tuple[str, int], Any]) -> list[Any]:
    """The proven registers to compare: where several pages share an address, the draft (which holds one
    register per address) is compared with the page whose register it matches best; the others count
    as not found."""
    by_key: dict[tuple[str, int], list[Any]] = {}
    for reg in registers:
        by_key.setdefault((reg.table, reg.address), []).append(reg)
    out = []
    for key, regs in by_key.items():
        mine = cells.get(key)
        if len(regs) == 1 or mine is None:
            out += regs
            continue
        out.append(max(regs, key=lambda r: sum(_value(mine, f) == _value(r, f) for f in FIELDS)))
    return out


def _values(model: Any, reg: Any) -> set[int] | None:
    if reg.enum is None:
        return None
    return {v.value for e in model.enums if e.name == reg.enum for v in e.members}


def _compare_lists(s: Score, reg: Any, mine: Any, proven: Any, drafted: Any) -> None:
    """Enum values and bit offsets of a proven register that has them: right when the draft has the same
    set, wrong when the draft writes a different one, missing when it writes none."""
    for kind, theirs, ours in (("enum", _values(proven, reg), _values(drafted, mine)),
                               ("bits", {b.offset for b in reg.bits} or None, {b.offset for b in mine.bits} or None)):
        if theirs is None:
            continue
        s.lists_total += 1
        if ours == theirs:
            s.lists_right += 1
        elif ours is not None:
            s.lists_wrong.append(f"{reg.name}.{kind}: drafted {sorted(ours)}, proven {sorted(theirs)}")


def score(model_id: str, document: Path) -> Score:
    from drivemap.compiler import compile_map
    from drivemap.frontend.load import load_text
    from drivemap.model.build import build_model
    from drivemap.onboard.draft.assemble import draft
    from drivemap.onboard.draft.read import read_document
    from drivemap.onboard.draft.writer import compile_text, settle

    started = time.perf_counter()
    source = read_document(document)
    result = draft(source, model_id)
    text, errors = settle(result, "", f"{model_id}.yaml")
    seconds = time.perf_counter() - started
    if errors:
        raise RuntimeError(f"{model_id}: the draft does not validate: {errors[0].format()}")
    assert not compile_text(text, f"{model_id}.yaml")
    doc = load_text(text, f"{model_id}.yaml")
    from drivemap.frontend import checks

    _, statuses = checks.check(doc)
    drafted = build_model(f"{model_id}.yaml", doc.data, statuses, {})  # type: ignore[arg-type]
    stated = {(str(e.get("table", "holding")), int(e["address"]) + i * int(e.get("stride", 1))): e
              for e in doc.data["registers"] for i in range(int(e.get("count", 1)))}
    proven = compile_map(ROOT / "maps" / f"{model_id}.yaml")
    cells = _cells(drafted)
    s = Score(model_id, len(proven.registers), 0, 0, [], 0, 0, seconds, len(drafted.registers))
    for reg in _comparable(proven.registers, cells):
        keys = [(reg.table, reg.address + i * (reg.stride or 1)) for i in range(reg.count)]
        if not all(k in cells for k in keys):
            s.not_found.append(reg.name)
            continue
        s.found += 1
        mine = cells[keys[0]]
        entry = stated[keys[0]]
        s.fields_right += 1
        exact = True
        for key in FIELDS:
            same = _value(mine, key) == _value(reg, key)
            s.fields_right += same
            if not same:
                s.field_edits += 1
                if key in entry:
                    s.wrong_stated.append(f"{reg.name}.{key}: drafted {_value(mine, key)!r}, proven {_value(reg, key)!r}")
                else:
                    s.defaulted += 1
                if key in ("type", "scale"):
                    exact = False
        _compare_lists(s, reg, mine, proven, drafted)
        if exact and all(cells[k].type == reg.type and float(cells[k].scale) == float(reg.scale) for k in keys):
            s.exact += 1
        else:
            s.not_exact.append(f"{reg.name} ({mine.type} x{mine.scale} vs {reg.type} x{reg.scale})")
    proven_cells = _cells(proven)
    s.extra = sum(1 for r in drafted.registers if (r.table, r.address) not in proven_cells)
    return s


def run(quick: bool = False) -> Section:
    section = Section("Draft recovery (seed manuals vs proven maps)")
    folder = manuals_folder()
    if folder is None:
        section.error = "shared/manuals not found beside the repository: nothing to measure"
        return section
    detail = ["| manual | map | proven registers | exact | fields right | wrong stated | defaulted, differs | "
              "drafted | extra | hand edits | tool time |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    total = Score("all", 0, 0, 0, [], 0, 0, 0.0, 0)
    for model_id, name in SEEDS.items():
        s = score(model_id, folder / name)
        ratio = s.exact / s.proven
        wrong_ts = [w for w in s.wrong_stated if w.split(".")[1].startswith(("type", "scale"))]
        section.rows.append(Row(section.title, f"{model_id}: registers exact", ratio, ">= 0.90", ratio >= 0.90,
                                f"{s.exact}/{s.proven}; wrong types/scales stated {len(wrong_ts)}; {s.seconds:.2f} s"))
        detail.append(f"| {name} | {model_id} | {s.proven} | {s.exact} ({ratio:.2f}) | "
                      f"{s.fields_right}/{7 * s.proven} ({s.fields_right / (7 * s.proven):.2f}) | {len(s.wrong_stated)} | "
                      f"{s.defaulted} | {s.drafted} | {s.extra} | {s.edits} | {s.seconds:.2f} s |")
        for w in s.wrong_stated + s.lists_wrong:
            detail.append(f"|  | wrong: {w} | | | | | | | | | |")
        detail.append(f"|  | enums and bit lists: {s.lists_right}/{s.lists_total} right, {len(s.lists_wrong)} "
                      "written differently | | | | | | | | | |")
        if s.not_found:
            detail.append(f"|  | not found: {', '.join(s.not_found)} | | | | | | | | | |")
        if s.not_exact:
            detail.append(f"|  | type/scale left at the default: {', '.join(s.not_exact)} | | | | | | | | | |")
        for attr in ("proven", "exact", "fields_right", "defaulted", "extra", "drafted", "found", "field_edits"):
            setattr(total, attr, getattr(total, attr) + getattr(s, attr))
        total.wrong_stated += s.wrong_stated
        total.seconds += s.seconds
    ratio = total.exact / total.proven
    wrong_ts = [w for w in total.wrong_stated if w.split(".")[1].startswith(("type", "scale"))]
    section.rows.append(Row(section.title, "all seed manuals: registers exact", ratio, ">= 0.90", ratio >= 0.90,
                            f"{total.exact}/{total.proven}"))
    section.rows.append(Row(section.title, "wrong types or scales written", None, "0", not wrong_ts,
                            f"{len(wrong_ts)} (all wrong fields written: {len(total.wrong_stated)})"))
    detail.append(f"| all | | {total.proven} | {total.exact} ({ratio:.2f}) | {total.fields_right}/{7 * total.proven} "
                  f"({total.fields_right / (7 * total.proven):.2f}) | {len(total.wrong_stated)} | {total.defaulted} | "
                  f"{total.drafted} | {total.extra} | {total.edits} | {total.seconds:.2f} s |")
    section.detail = detail
    return section


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.parse_args(argv)
    section = run()
    if section.error:
        print(section.error)
        return 1
    for row in section.rows:
        print(f"{row.name}: {row.ratio if row.ratio is None else round(row.ratio, 3)} (goal {row.goal}) {row.absolute}")
    print("\n".join(section.detail))
    return 0


if __name__ == "__main__":
    sys.exit(main())
