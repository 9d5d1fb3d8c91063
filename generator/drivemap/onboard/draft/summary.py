"""The review summary printed after a draft: tables, registers and what each misses, rows
skipped and why, limits hit, and the next commands."""

from __future__ import annotations

from collections import Counter

from rich.console import Console
from rich.table import Table as RichTable

from drivemap.onboard.draft.assemble import Draft
from drivemap.onboard.draft.tables import Skipped, Source

MAX_ROWS = 400


def _hex(value: object) -> str:
    return f"0x{int(str(value)):04X}"


def _runs(skipped: list[Skipped]) -> list[tuple[str, str, str]]:
    """Consecutive rows skipped for the same reason, one line each."""
    out: list[tuple[str, str, str]] = []
    i = 0
    while i < len(skipped):
        j = i
        while j + 1 < len(skipped) and skipped[j + 1].reason == skipped[i].reason:
            j += 1
        first, last = skipped[i], skipped[j]
        if j == i:
            out.append((first.where, first.reason, first.text[:70]))
        else:
            out.append((f"{first.where} .. {last.where}", f"{first.reason} ({j - i + 1} rows)",
                        f"{first.text[:30]} .. {last.text[:30]}"))
        i = j + 1
    return out


def print_summary(console: Console, source: Source, draft: Draft, target: str, model: str) -> None:
    console.print(f"[bold]drivemap draft[/bold] {source.name} (sha256 {source.sha256[:16]}…) -> {target}")
    tables = RichTable(title=f"Register tables found: {len(draft.tables)}", show_lines=False)
    tables.add_column("table")
    tables.add_column("registers", justify="right")
    for label, count in draft.tables:
        tables.add_row(label, str(count))
    console.print(tables)
    regs = RichTable(title=f"Registers drafted: {len(draft.registers)} (fields the document does not state)")
    for col in ("register", "table", "address", "source", "missing"):
        regs.add_column(col)
    for d in draft.registers[:MAX_ROWS]:
        e = d.entry
        size = f"[{e['count']}]" if "count" in e else ""
        regs.add_row(f"{e['name']}{size}", str(e.get("table", "-")), _hex(e["address"]), d.where,
                     ", ".join(dict.fromkeys(d.missing)) or "-")
    if len(draft.registers) > MAX_ROWS:
        regs.add_row(f"… {len(draft.registers) - MAX_ROWS} more (see the map)", "", "", "", "")
    console.print(regs)
    missing = Counter(m for d in draft.registers for m in dict.fromkeys(d.missing))
    if missing:
        console.print("Fields not stated (registers): " + ", ".join(f"{k} {v}" for k, v in missing.most_common())
                      + " — left out and to be filled from the manual; table, type, word order and scale are "
                      "written as each register's `review:` items.")
    if draft.skipped:
        skipped = RichTable(title=f"Rows skipped: {len(draft.skipped)}")
        for col in ("where", "reason", "row"):
            skipped.add_column(col)
        for where, reason, text in _runs(draft.skipped)[:MAX_ROWS]:
            skipped.add_row(where, reason, text)
        console.print(skipped)
    for note in source.notes:
        console.print(f"[yellow]note:[/yellow] {note}")
    console.print("To review (placeholders the register tables do not give):")
    for item in draft.review:
        console.print(f"  {item}", soft_wrap=True)
    console.print("Next:")
    console.print(f"  drivemap validate {target}")
    console.print(f"  drivemap verify {target} --tcp HOST:502 --unit 1     # the map against the device")
    console.print(f"  drivemap export {target} --format homeassistant")
