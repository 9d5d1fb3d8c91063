"""The "map vs device" report of ``drivemap verify``: Markdown for people, JSON for programs.

Both files carry a marker; an existing file without it is never overwritten. Writes are atomic
(a temporary file in the same folder, then a rename).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivemap.device.errors import EXIT_INPUT, LiveError
from drivemap.live.verify_checks import Finding, Results

MARKER_MD = "<!-- written by drivemap verify -->"
MARKER_JSON = "drivemap verify"


@dataclass(frozen=True)
class Header:
    model: str
    map_path: str
    link: str
    started: str
    checks: str


def as_json(header: Header, results: Results) -> str:
    doc: dict[str, Any] = {
        "generator": MARKER_JSON, "model": header.model, "map": header.map_path, "link": header.link,
        "started": header.started, "checks": header.checks, "agree": not results.disagreements,
        "counts": results.counts, "not_checked": results.skipped,
        "findings": [f.json() | {"where": f"{header.map_path}:{f.line}"} for f in results.findings],
    }
    return json.dumps(doc, ensure_ascii=False, indent=2) + "\n"


def as_markdown(header: Header, results: Results) -> str:
    bad = results.disagreements
    notes = [f for f in results.findings if f.severity == "note"]
    verdict = "the map and the device agree" if not bad else f"{len(bad)} disagreement{'s' if len(bad) != 1 else ''}"
    lines = [
        MARKER_MD,
        f"# Map vs device: {header.model}",
        "",
        f"- map: `{header.map_path}`",
        f"- device: {header.link}",
        f"- run: {header.started}; checks: {header.checks}",
        "- covered: " + ", ".join(f"{name} {count}" for name, count in results.counts.items()),
        f"- result: **{verdict}**, {len(notes)} note{'s' if len(notes) != 1 else ''}",
        "",
    ]
    for title, items in (("Disagreements", bad), ("Notes", notes)):
        if items:
            lines += [f"## {title}", "", *_table(header, items), ""]
    if results.skipped:
        lines += ["## Not checked", "", *(f"- {text}" for text in results.skipped), ""]
    return "\n".join(lines)


def _table(header: Header, findings: list[Finding]) -> list[str]:
    rows = ["| map line | check | what | address | the map says | the device says | hint |",
            "|---|---|---|---|---|---|---|"]
    for f in findings:
        address = f"0x{f.address:04X}" if f.address is not None else ""
        cells = [f"`{header.map_path}:{f.line}`", f.check, f"`{f.subject}`", address, f.map_says, f.device_says, f.hint]
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return rows


def report_paths(stem: str, force: bool) -> tuple[Path, Path]:
    """STEM.md and STEM.json, refused when either exists and drivemap verify did not write it."""
    base = Path(stem[:-3] if stem.endswith(".md") else stem[:-5] if stem.endswith(".json") else stem)
    md, js = base.with_name(base.name + ".md"), base.with_name(base.name + ".json")
    for path, marker in ((md, MARKER_MD), (js, MARKER_JSON)):
        if path.exists() and not force and marker not in path.read_text(encoding="utf-8", errors="replace")[:400]:
            raise LiveError(EXIT_INPUT, f"--report: {path} exists and was not written by drivemap verify; "
                                        "not overwritten (choose another --report, or --force)")
    return md, js


def write_report(stem: str, header: Header, results: Results, force: bool) -> tuple[Path, Path]:
    md, js = report_paths(stem, force)
    _atomic(md, as_markdown(header, results))
    _atomic(js, as_json(header, results))
    return md, js


def _atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
