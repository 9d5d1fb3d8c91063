"""Draft on the public corpus: `drivemap draft` on every document of ``shared/draft-corpus/docs`` scored
against its truth file (``shared/draft-corpus/truth/<name>.json``, see that folder's SOURCES.md).

Each document is drafted in a child process (the verb's code, nothing written; the child reports its
tool time and peak resident memory) and every truth register is scored on the map **as written**:

* **found**: a drafted register (or array element) at the truth's exact 0-based address (in another table
  only where the truth has no register of its own at that address in that table);
* **exact**: found, and table, type, scale and unit as the truth says: a field the draft leaves out
  reads as the schema's default (holding, u16, 1); (scale, unit) pairs that differ by an SI prefix
  only are equal (0.001 kWh = 1 Wh); a drafted unit is not wrong where the truth unit is null;
* **wrong**: fields of found registers the draft states (writes, or lets a schema default stand for
  without a ``review:`` item) that differ from the truth;
* **open**: fields of found registers the draft lists in the register's ``review:`` (or leaves a unit
  out where the truth has one); a register whose address is in its ``review:`` is never exact;
* **silently dropped**: truth registers not found whose address appears in no skipped row the draft
  lists, in the row's text or in the reason it gives (read as decimal, hex, 1-based or Modicon
  3xxxx/4xxxx numbers: a row of offsets listed with the addresses its block's start gives is listed).

Where a truth file disagrees with what the document itself prints for a register's field
(``bench/corpus_errata.json``: the document's words, where they are, and why), that field is scored
against the document, and the section lists each such truth erratum.

    python bench/draftcorpus.py [--docs DIR] [--json]

The documents' folder defaults to $DRIVEMAP_SHARED/draft-corpus, else ../shared/draft-corpus beside the
repository.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section, print_section  # noqa: E402

TITLE = "Draft on the public corpus"
FIELDS = ("table", "type", "scale", "unit")
DEFAULTS: dict[str, Any] = {"table": "holding", "type": "u16", "scale": 1.0, "unit": None}
PREFIX = {"k": 1e3, "M": 1e6, "G": 1e9, "m": 1e-3, "µ": 1e-6, "u": 1e-6}
BASES = {"w", "wh", "v", "a", "va", "var", "varh", "vah", "vas", "ah", "hz", "ω", "ohm", "s", "g"}


def shared_folder() -> Path:
    return Path(os.environ.get("DRIVEMAP_SHARED") or ROOT.parent / "shared")


def corpus_folder() -> Path:
    return shared_folder() / "draft-corpus"


#: spellings of one unit (the truths write some units out): the same unit, not a wrong one
SPELLINGS = {"hours": "h", "hour": "h", "hrs": "h", "ohm": "Ω", "ohms": "Ω", "k-ohm": "kΩ", "kohm": "kΩ",
             "seconds": "s", "sec": "s", "minutes": "min", "volts": "V",
             "amps": "A", "watts": "W", "degc": "°C", "℃": "°C"}


def _si(scale: float, unit: str | None) -> tuple[float, str | None]:
    """(scale, unit) with an SI prefix folded into the scale: (1, 'kWh') -> (1000, 'wh'); a unit's
    spelled-out forms first read as its symbol (Hours = h, k-ohm = kΩ)."""
    if unit is None:
        return scale, None
    u = unit.strip()
    u = SPELLINGS.get(u.lower(), u)
    if len(u) > 1 and u[0] in PREFIX and u[1:].lower() in BASES:
        return scale * PREFIX[u[0]], u[1:].lower()
    return scale, u.lower()


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


@dataclass
class DocScore:
    document: str
    truth: int
    found: int = 0
    exact: int = 0
    wrong: list[str] = field(default_factory=list)
    open: int = 0
    dropped: list[str] = field(default_factory=list)
    listed: int = 0
    drafted: int = 0
    skipped: int = 0
    error: str = ""
    seconds: float = 0.0
    peak_mb: float = 0.0
    not_exact: list[str] = field(default_factory=list)
    errata: list[str] = field(default_factory=list)
    """Truth fields scored against the document instead (``corpus_errata.json``)."""

    @property
    def ratio(self) -> float:
        return self.exact / self.truth if self.truth else 0.0


def _elements(entry: dict[str, Any]) -> list[int]:
    address = int(entry["address"])
    count, stride = int(entry.get("count", 1)), int(entry.get("stride") or 1)
    return [address + i * stride for i in range(count)]


def _numbers(text: str) -> set[int]:
    """Every address a skipped row's text may print, read as the truth's 0-based address."""
    out: set[int] = set()
    for m in re.finditer(r"(?:0x|16#)([0-9A-Fa-f]+)|\b([0-9A-Fa-f]+)[hH]\b|%?M?W?(\d+)", text):
        if m.group(1) or m.group(2):
            values = [int(m.group(1) or m.group(2), 16)]
            if m.group(2) and m.group(2).isdigit():
                values.append(int(m.group(2)))
        else:
            values = [int(m.group(3))]
        for v in values:
            out |= {v, v - 1, v - 30001, v - 40001, v - 300001, v - 400001}
    return out


def _stated(entry: dict[str, Any], key: str) -> Any:
    value = entry.get(key, DEFAULTS[key])
    return float(value) if key == "scale" else value


ERRATA = HERE / "corpus_errata.json"


def errata_of(document: str) -> list[dict[str, Any]]:
    """The truth errata of one corpus document (fields the document prints otherwise than its truth)."""
    return [e for e in json.loads(ERRATA.read_text(encoding="utf-8"))["errata"] if e["document"] == document]


def _as_printed(truth: dict[str, Any], errata: list[dict[str, Any]], score: DocScore) -> dict[str, Any]:
    """The truth register with each field the document prints otherwise set to the document's value."""
    fixed = dict(truth)
    for e in errata:
        if e["table"] == truth["table"] and int(e["address"]) == int(truth["address"]):
            fixed[e["field"]] = e["document_says"]
            if "document_unit" in e:
                fixed["unit"] = e["document_unit"]
            score.errata.append(f"{truth['name']}@{truth['address']}.{e['field']}: truth {e['truth']!r}, the document "
                                f"prints {e['printed']!r} ({e['where']})")
    return fixed


def _compare(truth: dict[str, Any], entry: dict[str, Any], score: DocScore,
             errata: list[dict[str, Any]] | None = None) -> None:
    truth = _as_printed(truth, errata or [], score)
    review = set(entry.get("review") or ())
    exact = True
    if "address" in review:  # found at the address the document's own sum gives, which it leaves open
        score.open += 1
        exact = False
    for key in FIELDS:
        want = truth[key]
        if key == "unit":
            continue
        if key == "scale":
            continue
        if key in review:
            score.open += 1
            exact = False
        elif _stated(entry, key) != want:
            score.wrong.append(f"{truth['name']}@{truth['address']}.{key}: drafted {_stated(entry, key)!r}, "
                               f"truth {want!r}")
            exact = False
    # scale and unit together, SI prefixes folded
    t_scale, t_unit = float(truth["scale"]), truth["unit"]
    d_unit = entry.get("unit")
    if "scale" in review:
        score.open += 1
        exact = False
    else:
        d_scale = _stated(entry, "scale")
        if t_unit is None or d_unit is None:
            same = _close(d_scale, t_scale)
        else:
            (a, ua), (b, ub) = _si(d_scale, d_unit), _si(t_scale, t_unit)
            same = _close(a, b) and ua == ub
            if not same and _close(d_scale, t_scale):
                score.wrong.append(f"{truth['name']}@{truth['address']}.unit: drafted {d_unit!r}, truth {t_unit!r}")
                exact = False
                same = True
        if not same:
            score.wrong.append(f"{truth['name']}@{truth['address']}.scale: drafted {d_scale!r} {d_unit or ''}, "
                               f"truth {t_scale!r} {t_unit or ''}")
            exact = False
    if t_unit is not None and d_unit is None:
        score.open += 1
        exact = False
    if exact:
        score.exact += 1
    else:
        score.not_exact.append(f"{truth['name']}@{truth['address']}")


def score_draft(document: str, truth: list[dict[str, Any]], registers: list[dict[str, Any]],
                skipped_texts: list[str], errata: list[dict[str, Any]] | None = None) -> DocScore:
    """Score the written register entries of a draft against the truth registers (as the document prints
    them, where ``errata`` says the truth disagrees with it)."""
    score = DocScore(document, len(truth), drafted=len(registers), skipped=len(skipped_texts))
    at: dict[int, list[dict[str, Any]]] = {}
    for entry in registers:
        for address in _elements(entry):
            at.setdefault(address, []).append(entry)
    listed: set[int] = set()
    for text in skipped_texts:
        listed |= _numbers(text)
    places = {(t["table"], int(t["address"])) for t in truth}
    for t in truth:
        # a drafted register at this address in another table belongs to the truth register of that table,
        # where the truth has one (Sungrow: holding 4999 "year" beside input 4999 "device type code")
        candidates = [e for e in at.get(int(t["address"]), [])
                      if e.get("table", "holding") == t["table"]
                      or (e.get("table", "holding"), int(t["address"])) not in places]
        if not candidates:
            if int(t["address"]) in listed:
                score.listed += 1
            else:
                score.dropped.append(f"{t['name']}@{t['address']}")
            continue
        score.found += 1
        entry = next((e for e in candidates if e.get("table", "holding") == t["table"]), candidates[0])
        _compare(t, entry, score, errata)
    return score


def draft_document(path: Path) -> tuple[list[dict[str, Any]], list[str]]:
    """The register entries as written (validated and compiled) and the skipped rows' texts."""
    from drivemap.frontend.load import load_text
    from drivemap.onboard.draft.assemble import draft
    from drivemap.onboard.draft.read import read_document
    from drivemap.onboard.draft.writer import compile_text, settle

    source = read_document(path, None, 400, 300.0)
    result = draft(source, "corpus_doc")
    skipped = [f"{s.where} {s.text} {s.reason}" for s in result.skipped]
    if not result.registers:
        return [], skipped
    text, errors = settle(result, "", "corpus_doc.yaml")
    if errors:
        raise RuntimeError(f"the draft does not validate: {errors[0].format()}")
    problems = compile_text(text, "corpus_doc.yaml")
    if problems:
        raise RuntimeError(f"the draft does not compile: {problems[0].format()}")
    data = load_text(text, "corpus_doc.yaml").data
    skipped = [f"{s.where} {s.text} {s.reason}" for s in result.skipped]
    return list(data["registers"]), skipped


def documents(folder: Path) -> list[tuple[Path, Path]]:
    """(document, truth file) of every corpus document, by name."""
    truths = {p.stem: p for p in (folder / "truth").glob("*.json")}
    return [(d, truths[d.stem]) for d in sorted((folder / "docs").iterdir()) if d.stem in truths]


def score_document(path: Path, truth_path: Path) -> DocScore:
    truth = json.loads(truth_path.read_text(encoding="utf-8"))["registers"]
    try:
        registers, skipped = draft_document(path)
    except Exception as exc:  # noqa: BLE001 - a failing draft is a row of the section, not a crash of it
        s = DocScore(path.name, len(truth), dropped=[f"{t['name']}@{t['address']}" for t in truth])
        s.error = f"{type(exc).__name__}: {exc}"
        return s
    return score_draft(path.name, truth, registers, skipped, errata_of(path.name))


def _child(path: Path, truth_path: Path) -> dict[str, Any]:
    import time

    from common import peak_rss_mb

    started = time.perf_counter()
    s = score_document(path, truth_path)
    s.seconds = time.perf_counter() - started
    s.peak_mb = peak_rss_mb()
    return asdict(s)


def measure(path: Path, truth_path: Path) -> DocScore:
    """Score one document in a child process (its own time and peak memory)."""
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--one", str(path), str(truth_path)],
                         capture_output=True, text=True, timeout=600, check=False)
    if out.returncode != 0:
        truth = json.loads(truth_path.read_text(encoding="utf-8"))["registers"]
        s = DocScore(path.name, len(truth), error=f"child failed: {out.stderr.strip()[-300:]}")
        return s
    return DocScore(**json.loads(out.stdout.splitlines()[-1]))


def run(quick: bool = False, folder: Path | None = None) -> Section:
    section = Section(TITLE)
    folder = folder or corpus_folder()
    if not (folder / "docs").is_dir():
        section.error = f"{folder}/docs not found (set DRIVEMAP_SHARED): nothing to measure"
        return section
    detail = ["| document | truth | found | exact | wrong | open | dropped silently | listed skipped | drafted | "
              "time | peak |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    scores = [measure(d, t) for d, t in documents(folder)]
    for s in scores:
        met = s.ratio >= 0.75 and not s.wrong and not s.dropped and s.seconds < 60 and s.peak_mb < 1024
        section.rows.append(Row(TITLE, f"{s.document}: truth registers exact", s.ratio, ">= 0.75, 0 wrong, 0 dropped",
                                met, f"{s.exact}/{s.truth}; wrong {len(s.wrong)}; open {s.open}; dropped "
                                f"{len(s.dropped)}; {s.seconds:.1f} s; {s.peak_mb:.0f} MB"
                                + (f"; {s.error}" if s.error else "")))
        detail.append(f"| {s.document} | {s.truth} | {s.found} | {s.exact} ({s.ratio:.2f}) | {len(s.wrong)} | {s.open} "
                      f"| {len(s.dropped)} | {s.listed} | {s.drafted} | {s.seconds:.1f} s | {s.peak_mb:.0f} MB |")
        for w in s.wrong:
            detail.append(f"|  | wrong: {w} | | | | | | | | | |")
        for e in s.errata:
            shown = e.replace("|", "\\|")
            detail.append(f"|  | truth erratum (scored as the document prints it): {shown} | | | | | | | | | |")
        if s.dropped:
            detail.append(f"|  | dropped silently: {', '.join(s.dropped[:40])} | | | | | | | | | |")
        if s.error:
            detail.append(f"|  | error: {s.error} | | | | | | | | | |")
    truth = sum(s.truth for s in scores)
    exact = sum(s.exact for s in scores)
    wrong = sum(len(s.wrong) for s in scores)
    dropped = sum(len(s.dropped) for s in scores)
    ratio = exact / truth if truth else 0.0
    section.rows.append(Row(TITLE, "all corpus documents: truth registers exact", ratio, ">= 0.90", ratio >= 0.90,
                            f"{exact}/{truth} over {len(scores)} documents"))
    section.rows.append(Row(TITLE, "wrong fields written", None, "0", wrong == 0, str(wrong)))
    section.rows.append(Row(TITLE, "rows dropped silently", None, "0", dropped == 0, str(dropped)))
    slow = max((s.seconds for s in scores), default=0.0)
    peak = max((s.peak_mb for s in scores), default=0.0)
    section.rows.append(Row(TITLE, "slowest draft / largest peak", None, "< 60 s, < 1024 MB",
                            slow < 60 and peak < 1024, f"{slow:.1f} s / {peak:.0f} MB"))
    detail.append(f"| all | {truth} | {sum(s.found for s in scores)} | {exact} ({ratio:.2f}) | {wrong} | "
                  f"{sum(s.open for s in scores)} | {dropped} | {sum(s.listed for s in scores)} | "
                  f"{sum(s.drafted for s in scores)} | {sum(s.seconds for s in scores):.1f} s | {peak:.0f} MB |")
    section.detail = detail
    return section


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--docs", default=None, help="the corpus folder (default: $DRIVEMAP_SHARED/draft-corpus)")
    ap.add_argument("--one", nargs=2, default=None, metavar=("DOCUMENT", "TRUTH"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(_child(Path(args.one[0]), Path(args.one[1]))))
        return 0
    return print_section(run(folder=Path(args.docs) if args.docs else None))


if __name__ == "__main__":
    sys.exit(main())
