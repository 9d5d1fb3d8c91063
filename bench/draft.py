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
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section, print_section  # noqa: E402
from draftscore import Score, compare, make_draft  # noqa: E402

SEEDS = {"edx": "004_698379178adcef99.txt", "v2": "003_81ad9a58587804cf.txt",
         "vfd1000": "002_65caa110b92ac236.txt", "ev": "001_47d2095fcebbe4cf.txt"}


def manuals_folder() -> Path | None:
    for candidate in (ROOT.parent / "shared" / "manuals", ROOT / "shared" / "manuals", Path("/work/shared/manuals")):
        if candidate.is_dir():
            return candidate
    return None


def score(model_id: str, document: Path) -> Score:
    from drivemap.compiler import compile_map

    return compare(model_id, compile_map(ROOT / "maps" / f"{model_id}.yaml"), make_draft(document, model_id))


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
    return print_section(run())


if __name__ == "__main__":
    sys.exit(main())
