"""The catalogue section of the bench: every file of ``../shared/catalogue-sources`` imported (a map that
validates, or one located error naming what the importer does not read), counted per source, and the
maps that define one device (drivemap.onboard.importers.pairs) compared, with their disagreements.

    python bench/catalogue.py            # import into a temporary folder, print the counts
    python bench/catalogue.py --write    # (re)write maps/catalogue/ from the sources

The shared folder is ``$DRIVEMAP_SHARED`` or ``<repo>/../shared``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from collections import Counter
from pathlib import Path

from common import (  # noqa: E402
    ROOT,  # noqa: F401 - puts the repository on sys.path
    Row,
    Section,
)

from drivemap.onboard.importers.catalogue import SOURCES, Outcome, Pair, build

TITLE = "Catalogue (import, compare)"


def shared_dir() -> Path:
    return Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared")


def project_ids() -> set[str]:
    return {p.stem for p in (ROOT / "maps").glob("*.yaml")}


def run(out: Path, found: list[Pair]) -> list[Outcome]:
    shared = shared_dir()
    if not (shared / "catalogue-sources").is_dir():
        raise SystemExit(f"{shared}/catalogue-sources: not found (set DRIVEMAP_SHARED)")
    return build(shared, out, project_ids(), ROOT, found)


def report(outcomes: list[Outcome], found: list[Pair]) -> str:
    lines = ["| source | files | maps | located errors |", "|---|---|---|---|"]
    for source in SOURCES:
        mine = [o for o in outcomes if o.source == source]
        lines.append(f"| {source} | {len(mine)} | {sum(1 for o in mine if o.written)} | "
                     f"{sum(1 for o in mine if o.error)} |")
    total = len(outcomes)
    lines.append(f"| all | {total} | {sum(1 for o in outcomes if o.written)} | {sum(1 for o in outcomes if o.error)} |")
    reasons = Counter(o.error.split(": error: ", 1)[-1].split(" (", 1)[0][:90] for o in outcomes if o.error)
    lines += ["", "located errors by message:"] + [f"  {n:3d}  {text}" for text, n in reasons.most_common()]
    lines += ["", f"maps of one device compared ({len(found)} pairs; the disagreements are known issues of the "
                  "imported map(s)):"]
    lines += [f"  {p.a:34s} {p.b:34s} {p.disagreements:4d}  ({p.rule})" for p in found]
    return "\n".join(lines)


def section(quick: bool = False) -> Section:
    """The bench section: per source, files imported to a map that validates and files that end in one
    located error (no traceback either way), and the pairs compared (``quick`` changes nothing: one pass)."""
    sec = Section(TITLE)
    found: list[Pair] = []
    with tempfile.TemporaryDirectory() as tmp:
        outcomes = run(Path(tmp), found)
    for source in SOURCES:
        mine = [o for o in outcomes if o.source == source]
        maps, errors = sum(1 for o in mine if o.written), sum(1 for o in mine if o.error)
        sec.rows.append(Row(TITLE, f"{source}: files that import or end in one located error",
                            (maps + errors) / len(mine) if mine else None, "= 1.00 (no traceback)",
                            maps + errors == len(mine), f"{len(mine)} files: {maps} maps, {errors} located errors"))
    maps = sum(1 for o in outcomes if o.written)
    sec.rows.append(Row(TITLE, "catalogue maps imported", None, ">= 100", maps >= 100, f"{maps} maps"))
    sec.rows.append(Row(TITLE, "maps of one device compared", None, "each pair", None,
                        ", ".join(f"{p.a} / {p.b}: {p.disagreements}" for p in found)))
    sec.detail += ["```", report(outcomes, found), "```"]
    return sec


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", action="store_true", help="rewrite maps/catalogue/ from the sources")
    args = parser.parse_args()
    found: list[Pair] = []
    if args.write:
        target = ROOT / "maps" / "catalogue"
        shutil.rmtree(target, ignore_errors=True)
        outcomes = run(target, found)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            outcomes = run(Path(tmp), found)
    print(report(outcomes, found))
    return 0


if __name__ == "__main__":
    sys.exit(main())
