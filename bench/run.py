"""Run every drivemap benchmark side by side and write bench/RESULTS.md.

    python bench/run.py            # full run (about 14 minutes on 2 cores), writes bench/RESULTS.md
    python bench/run.py --quick    # smoke mode (fewer, shorter rounds; writes nothing unless --out)

Sections: (1) read planning, (2) client overhead vs raw pymodbus, (3) wire efficiency on a paced
virtual serial line, (4) simulator throughput vs a plain pymodbus SimDevice server, (5) compiler
scaling, (6) exports: entities and reads per poll cycle of the Home Assistant and ESPHome exports, (7)
gateway scale (20 lines x 10 drives to MQTT), (8) import time of generated clients of 100 to 50k registers, (9) draft
recovery (`drivemap draft` on the seed manuals against the proven maps), (10) draft recovery on public documents
(bench/public_docs.json; the documents from $DRIVEMAP_PUBLIC_DOCS, else ../shared/public-docs), (11) the draft
corpus (shared/draft-corpus scored against its truth files), (12) the SunSpec probe of the Fronius simulator
against the proven map, probe by bisection, scan among many maps, the catalogue (every shared definition file
imported, the maps of one device compared), (13) against the baseline: (2) and (8) for the tree before the runtime's layer refactor and this tree, side by side in the same run (bench/baseline.py). Every figure is
the median of several bounded rounds; only 127.0.0.1 and ptys are used.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import baseline  # noqa: E402
import catalogue as catalogue_bench  # noqa: E402
import compiler_scaling  # noqa: E402
import draft as draft_bench  # noqa: E402
import draftcorpus  # noqa: E402
import exports  # noqa: E402
import gateway as gateway_bench  # noqa: E402
import imports  # noqa: E402
import overhead  # noqa: E402
import planning  # noqa: E402
import probe as probe_bench  # noqa: E402
import publicdocs  # noqa: E402
import scan as scan_bench  # noqa: E402
import simthroughput  # noqa: E402
import sunspecprobe  # noqa: E402
import wire  # noqa: E402
from common import Row, Section, machine  # noqa: E402

FULL_BUDGET_S = 290.0


def _fmt_ratio(row: Row) -> str:
    return "—" if row.ratio is None else f"{row.ratio:.3f}"


def _fmt_met(row: Row) -> str:
    return {True: "met", False: "MISSED", None: "info"}[row.met]


def table(sections: list[Section]) -> str:
    rows = [r for s in sections for r in s.rows]
    head = ("section", "measure", "ratio", "goal", "status", "absolute")
    cells = [(r.section, r.name, _fmt_ratio(r), r.goal, _fmt_met(r), r.absolute) for r in rows]
    widths = [max(len(str(c[i])) for c in [head, *cells]) for i in range(len(head))]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(cell, widths, strict=True)).rstrip() for cell in cells]
    for s in sections:
        if s.error:
            lines.append(f"{s.title}: ERROR {s.error.splitlines()[-1]}")
    return "\n".join(lines)


DEFINITIONS = {
    "Read planning": """\
Targets: every readable register element of the map (array elements one by one; a 32-bit value is
one 2-word element that is never split). Counts are read requests.

* **drivemap (sent)**: read requests `Client.read_all()` actually sent to the generated simulator over
  TCP (counted at the bus); `drivemap plan` is `len(Client.plan())`; page switches (writes to a page
  selector, `page_policy="switch"`) are counted apart and are not read requests.
* **lower bound**: computed in `bench/planning.py` from the generated `SPEC` only, without the
  runtime planner. A request may span only addresses that are a readable register element valid in
  its page context or a reserved word the map marks `readable: true`; it never splits a 32-bit
  element and carries at most the device's max quantity (the map's 03h/04h `max_quantity`, capped by
  `max_frame_bytes` as `(max_frame_bytes - 5) // 2`, else 125). Per connected run of readable
  addresses the bound is `max(A, B)`: A = the exact minimum (O(n²) dynamic programme) when pages are
  ignored (a relaxation), B = the sum over page contexts of the exact minimum for that page's paged
  elements alone (requests of different contexts are distinct). No valid plan can use fewer.
* **naive**: one request per readable element.
* **contiguous-only (ESPHome style)**: like ESPHome's `modbus_controller`, elements sorted by
  (page context, address); an element joins the current request only if its address equals the
  request's end address (strictly adjacent — no gap is ever read, not even a reserved word the map
  marks readable, since such a tool knows nothing of reserved-readable gaps) and the request stays
  within the device's max quantity; paged elements group only with the same page.""",
    "Client overhead (TCP loopback)": """\
Ratio = time per operation of the generated client / raw pymodbus for the same requests
(median of the per-round ratios; rounds interleave the two clients and alternate their order).
The model is vfd1000 (no EEPROM write delay, no broadcast gap). Inter-frame gaps and silent
intervals are serial-line rules: the bus does not keep them on Modbus TCP
(`generator/drivemap/runtime/client/transport/busbase.py`, `quiet_after`).""",
    "Simulator throughput (TCP loopback)": "",
    "Wire efficiency (paced virtual serial line, 115200 8N1)": """\
Efficiency = achieved requests/s ÷ physical limit. Goals apply to the generated client (`sync`,
`async`) on the generated simulator (`simulator`). References on the same line: raw pymodbus clients
(`raw-sync`, `raw-async`) keeping the same t3.5 of silence after each reply (`time.sleep` /
`asyncio.sleep` after the call returns), and the `lean` device of `bench/servers.py` (pymodbus's
`FramerRTU`, the simulator's own reply bytes, a precise delay from the request's last byte, no
server framework). The phase table splits each transaction by the line's timestamps, so the device,
the line relay and the client are measured apart.""",
    "Exports (entities and reads per poll cycle)": """\
Counted from the exported files (`bench/exports.py`), for every readable element the exports cover
(default page, all groups; commands are switches and are not read). **drivemap plan**: the reads of
`plan_reads` for those elements. **Home Assistant**: each modbus sensor entry polls on its own (an
array that fits one read is one entry with `virtual_count`); switches without `verify` and
template entities read nothing. **ESPHome**: the ranges ESPHome's own range builder (ported in
`tests/esphome_ranges.py`) makes from the file, every update, for the release the export is
written for (the newest: since 2026.9 one controller per update interval, ranges joined by
`reuse_previous_range`; before, one controller, `force_new_range`, skip_updates ignored).
Where ESPHome needs more reads than drivemap, the contiguous run is longer than the device's
maximum and the word where drivemap splits it holds an entity that cannot carry `register_count`
(a `number`, or several entities): only that word can start ESPHome's new range, which costs one
read per split (listed in the export's header).""",
    "Import time of a generated client": """\
A fresh interpreter per figure imports `<package>.client` of a synthetic map (`bench/synthetic.py`;
the runtime and pymodbus imported first and not counted): **cold** with `python -B` and no
`__pycache__`, **cached** with the bytecode a previous import wrote. Sizes interleave within each
round. What an import does is linear in the registers: compiling the source (cold only);
constructing the spec (`runtime/spec.py`: the register descriptions fill their `__dict__` at
once, about 2 µs each, where the frozen dataclass's own `__init__` took about 11 µs); one class
per bit-field record type (`@record`, `runtime/client/values/records.py`: methods shared by every record,
`__dataclass_fields__` made when first read; the synthetic maps have one per 5 registers); the
`Snapshot` (`@snapshot`, no `__init__` of one parameter per register).""",
    "Gateway scale (20 lines x 10 drives, MQTT)": """\
One `drivemap gateway` process (`bench/gateway.py`): 20 Modbus TCP lines, 10 ev drives on each (the
generated simulator with realistic timing), a real MQTT broker, an independent subscriber; then the
same over paced virtual serial lines at 19200 Bd (`bench/gateway_serial.py`: 1 to 20 lines of 10
drives on Modbus RTU, relays and simulators in their own processes, CPU of each part measured apart).
On TCP, polls/s per line are counted from the per-poll `state` snapshots that reach the subscriber, on
serial lines from the request frames on the wire; latency runs from the moment a simulator's value
changes to the moment its MQTT message arrives (one monotonic clock for all processes). The capacity
plan built on these figures is in `docs/gateway.md`.""",
    "Draft recovery (seed manuals vs proven maps)": """\
`bench/draft.py`: `drivemap draft` (in memory, the verb's code) on each seed manual of shared/manuals,
compared with the proven map. **Registers exact**: a proven register whose every element address is
drafted in the same table with the same type and scale as compiled (a field the draft leaves out takes
the schema default: u16, scale 1). **Fields right**: table+address, type, scale, unit, access, min, max
right as compiled, over 7 x proven registers. **Wrong stated**: fields the draft writes that differ from
the proven map (goal 0). **Defaulted, differs**: fields the draft leaves out and lists whose default
differs from the proven map (found in the review). **Hand edits**: registers to add + fields to change +
drafted registers the proven map does not have. Where pages share an address, the draft's one register
is compared with the page it matches best. Tool time is reading, drafting and the in-memory compile.""",
    "Draft recovery, public documents": """\
`bench/publicdocs.py`: the public register documents of devices not in this repository listed in
`bench/public_docs.json` (title, revision, format, where each is published, sha256, size, the draft's
arguments, the map it was finished into, the licence where one is granted). None is in the repository
(vendor files without a redistribution licence; the openly licensed ones are not committed either, as
material fetched in this workplace is not): the bench reads them from `$DRIVEMAP_PUBLIC_DOCS` (default
`~/.cache/drivemap/public-docs`) and measures only a file whose sha256 is the manifest's; any other
gives a "not measured" row. Each is drafted in memory with the verb's code and arguments and compared
with the shipped map as in section "Draft recovery" (`bench/draftscore.py`). **Map choices**: the
finished map's systematic choices (manifest `map_choices`: WattNode numbers registers from 1, address
= printed - 1, and is read as holding registers; the Delta pages name no table, read as holding
registers), applied to every drafted register before comparing; their edits are counted apart.
**Exact at the printed address and table**: exact registers for which the choices changed nothing.
**Hand edits**: finished registers the draft lacks (added) + drafted registers not kept (dropped) +
register fields written, changed or removed from draft to map (all but address, table, label, source,
notes, group). **Map-level edits**: top-level keys of `device` and `protocol` that differ, and the
enums, groups, reserved ranges, known issues and examples that differ. Tool time is reading, drafting
and the in-memory compile (the time from document to a validated map).""",
    draftcorpus.TITLE: """\
`bench/draftcorpus.py`: every document of `shared/draft-corpus/docs` ($DRIVEMAP_SHARED, else `../shared`) drafted
in a child process (the verb's code, nothing written) and scored on the map as written against its truth file
(`truth/<name>.json`, registers with 0-based addresses; see the corpus's SOURCES.md). **Exact**: a drafted
register at the truth's address with its table, type, scale and unit (a field left out reads as the schema
default; SI-prefix-equal (scale, unit) pairs are equal; any drafted unit is right where the truth has none).
**Wrong**: a field stated (or defaulted without a `review:` item) that differs. **Open**: a field the draft
lists in `review:`, or a unit it leaves out. **Dropped silently**: a truth register neither drafted nor in
a row the draft lists as skipped. Time and peak RSS are the child's.""",
    "SunSpec probe recovery": """\
`bench/sunspecprobe.py`: the generated Fronius Symo Hybrid simulator on 127.0.0.1, its SunSpec marker,
model IDs and lengths preset (the shipped map gives them no value), and `drivemap probe --sunspec`
against it in a subprocess; the map the probe writes is compared with `maps/fronius_symo_hybrid.yaml`
element address by element address. **Cells recovered**: same holding address, type, width and
scale-factor register. The other fields are compared on the cells both maps have and every difference
is listed with both values: the probe's map takes them from the SunSpec models (pysunspec2), the proven
map from Fronius' documents.""",
    probe_bench.TITLE: (probe_bench.__doc__ or "").split("\n\n    python")[0],
    scan_bench.TITLE: (scan_bench.__doc__ or "").split("\n\n    python")[0],
    baseline.TITLE: baseline.DEFINITION,
    "Compiler scaling": """\
µs/register = timed build (compile + render + write, after a warm-up build in the same process) ÷
registers. The goal compares the largest synthetic map with the smallest (≤ 1.3×). Peak RSS is the
worker process's VmHWM (its own peak; `ru_maxrss` would carry the parent's across exec); RSS growth is the increase caused by the timed build.""",
}


def markdown(sections: list[Section], info: dict[str, str], elapsed: float, quick: bool) -> str:
    out = ["# drivemap benchmarks", ""]
    out.append("Written by `python bench/run.py`" + (" --quick" if quick else "") + f" on {info['date']} "
               f"in {elapsed:.0f} s. Do not edit by hand; rerun the benchmarks.")
    out.append("")
    out.append(f"Machine: {info['cpu']}, {info['cores']} cores, {info['os']}; Python {info['python']}, "
               f"pymodbus {info['pymodbus']}. Load average (1/5/15 min) at the start: {info['load']}, "
               f"at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())} — other processes running on the "
               "machine at the same time show up as wide ranges between rounds.")
    out.append("")
    out.append("## Summary (ratios first)")
    out.append("")
    out.append("| section | measure | ratio | goal | status | absolute |")
    out.append("|---|---|---:|---|---|---|")
    for s in sections:
        for r in s.rows:
            out.append(f"| {r.section} | {r.name} | {_fmt_ratio(r)} | {r.goal} | {_fmt_met(r)} | {r.absolute} |")
        if s.error:
            out.append(f"| {s.title} | error | — | — | ERROR | {s.error.splitlines()[-1]} |")
    for n, s in enumerate(sections, 1):
        out += ["", f"## {n}. {s.title}", ""]
        if DEFINITIONS.get(s.title):
            out += [DEFINITIONS[s.title], ""]
        if s.error:
            out += ["```", s.error.strip(), "```", ""]
        out += s.detail
        missed = [r for r in s.rows if r.met is False]
        if missed:
            out += ["", "### Shortfall", ""]
            out += [f"* {r.name}: {_fmt_ratio(r)} (goal {r.goal}); {r.absolute}." for r in missed]
            expl = EXPLAIN.get(s.title)
            if expl:
                out += ["", expl(s)]
            for p in s.profiles:
                out += ["", p]
    return "\n".join(out).rstrip() + "\n"


def _explain_wire(s: Section) -> str:
    return """\
Where the time goes, from the phase table (this run's medians, ms above the ideal share):

""" + s.explanation + """

* **Line relay** (`generator/drivemap/testing/vserial.py`, its own process): request and reply on the wire
  are within about 0.05 ms of bytes × 86.8 µs each; the relay is not where the time goes.
* **Device**: the lean device turns around 0.15–0.35 ms late (two cross-process wake-ups through the
  relay on 2 shared cores: it waits exactly 4.00 ms from the moment it reads the request). The
  generated simulator on pymodbus's serial server turns around within about 0.02–0.07 ms of it
  (`generator/drivemap/runtime/sim/serve.py`; the device turnaround column above): its processing
  time counts from the read that brought the request's last bytes (`_stamp_reads`; pymodbus's receive
  path up to the framer is the simulator's own time, not the line's) and is waited
  precisely (`sleep_until`; a bare `asyncio.sleep(0.004)`, rounded up
  by the event loop, gave 5.2–5.3 ms); the reply goes to the port when pymodbus hands it over
  (`_write_at_once`, not one event-loop turn later through the transport's `add_writer` callback,
  which cost 0.1–0.2 ms); and the wait ends early by the measured way from `datastore_update` to the
  port (framing, CRC, the write; learnt per reply, at most 0.2 ms), so the reply reaches the port when
  the map's timing says. What is left is the two wake-ups through the relay the lean device has too.
* **Client, sync**: pymodbus's sync serial client notices the end of a reply only by polling
  `in_waiting` every `_recv_interval` = max(4 characters, 1 ms) and returns after a poll that sees no
  new byte (`pymodbus/client/serial.py`, `_wait_for_data`): the "reply end seen" column of the
  `raw-sync` rows, 1.4–2.1 ms at 115200 Bd. drivemap's sync serial bus no longer goes through that
  poll: `generator/drivemap/runtime/client/transport/serialrx.py` (`SerialReceiver`, installed as the pymodbus client's
  `recv`, pymodbus unpatched) reads the reply length the request implies as it arrives (inter-character
  timeout); with the stale-reply guard (the default, `generator/drivemap/runtime/client/transport/staleguard.py`) it
  hands every chunk before the reply to the guard with its arrival time and then listens for the
  guard's settle time, max(4 characters, 1 ms), after the last byte, so a frame that follows the
  reply is seen (the guard keeps the last of frames that come back to back). So the `sync` rows'
  "reply end seen" is that settle time plus the client's wake-up (≈ 1.2–1.4 ms at 115200 Bd); the
  bus counts the t3.5 from the reply's last byte as the receiver read it, so the settle time overlaps
  the silence the line keeps anyway and the client turnaround is the same as without the guard
  (measured side by side, interleaved: 2.35 vs 2.32 ms; pymodbus's own receive: 3.0–3.4 ms). An
  earlier version of this text said no change above pymodbus could remove the sync loss; that was wrong.
* **Client, async**: the reply is seen within ≈ 0.2 ms (event loop reader). The bus's quiet time
  used to be an `asyncio.sleep` that the loop rounds up to whole milliseconds (≈ +0.7 ms, still
  visible in the `raw-async` rows); `generator/drivemap/runtime/client/transport/bus.py` `sleep_until` now sleeps whole
  milliseconds and yields the rest, so "client work + quiet" is ≈ t3.5 + 0.05 ms. The request then
  takes 0.2–0.3 ms to reach the line: pymodbus builds the frame after the wait, and its serial
  transport writes through an `add_writer` callback (one more loop turn) before the relay reads it.
* What stays out of reach on this machine: the sync goal (0.95) allows 0.51 ms of overhead per
  transaction for `read 16` and 0.38 ms for `write one` (the async goal, 0.90: 1.07 and 0.79 ms).
  A transaction crosses processes four times (client → relay → device → relay → client), each a
  wake-up of about 0.1 ms on these 2 shared cores: the lean reference device with the same sync client
  lands at 0.94–0.95, and the generated simulator now within about 0.01–0.02 of it. The client's own part
  above t3.5 is the wake-up after the relay writes the last reply byte (the bus can count the t3.5
  only from the moment it read that byte) and its request's way to the relay; watching the line for
  the last byte instead of blocking was tried and changed nothing (client turnaround 1.94–1.95 ms
  either way). Closing the rest would mean sending before the t3.5 after the last byte the client
  saw, or a device replying before its processing time: neither is done. The efficiencies move by
  ±0.05 between runs with the machine's load (see the load average above), and both
  clients land at 0.75-0.88 in a loaded run."""


def _explain_sim(s: Section) -> str:
    return """\
The generated simulator runs each request through pymodbus's `custom_pdu` path
(`generator/drivemap/runtime/sim/serve.py`, `_SimRequest.datastore_update`: an async call per request, the
request kept as bytes, a new `_SimResponse`) and then `Simulator.handle`
(`generator/drivemap/runtime/sim/simulator.py`), which checks the dialect (function, quantity, pages, access)
and serves reads from a cached per-(address, quantity, page) plan, where the plain server copies a
slice of its register list. The profile below is of `Simulator.handle` alone."""


def _explain_compiler(s: Section) -> str:
    return """\
Cost per register grows with the map: rendering `client.py` is quadratic. In
`generator/drivemap/backends/templates/client.py.jinja` (lines 182 and 200) the `BroadcastClient` and
`AsyncBroadcastClient` bodies look up each broadcast-writable accessor with
`accessors | selectattr("name", "equalto", name) | first` — a linear scan per register, so
O(registers²) Jinja filter calls (`select_or_reject`, `_filter_test_common`, `getitem` at the top of
the profile below). Fix (in `generator/drivemap/backends/views/client.py`): give the template the accessor objects
directly (e.g. `broadcast_sync` as a list of (accessor, class) pairs) or a dict by name. Loading
(PyYAML's pure-Python scanner with a position table, `generator/drivemap/load.py`) and JSON-Schema validation
are the largest linear costs; a 10,000-register map (~1.9 MB) is close to the loader's 2 MiB cap
(`MAX_MAP_BYTES`, `generator/drivemap/load.py`). When the largest map times out, its µs/register is the
timeout divided by the registers: a lower bound."""


EXPLAIN: dict[str, Callable[[Section], str]] = {
    "Client overhead (TCP loopback)": overhead.explain,
    "Wire efficiency (paced virtual serial line, 115200 8N1)": _explain_wire,
    "Simulator throughput (TCP loopback)": _explain_sim,
    "Compiler scaling": _explain_compiler,
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smoke mode: fewer and shorter rounds")
    ap.add_argument("--out", default=None, help="Markdown report (default: bench/RESULTS.md; none with --quick)")
    ap.add_argument("--only", action="append",
                    choices=["planning", "overhead", "wire", "simulator", "compiler", "exports", "gateway", "imports",
                             "draft", "publicdocs", "corpus", "sunspec", "probe", "scan", "catalogue", "baseline"],
                    help="run only these sections (repeatable)")
    args = ap.parse_args(argv)
    out = Path(args.out) if args.out else (None if args.quick else HERE / "RESULTS.md")
    started = time.perf_counter()
    info = machine()
    plan: list[tuple[str, str, Callable[[], Section]]] = [
        ("planning", "Read planning", lambda: planning.run(args.quick)),
        ("overhead", "Client overhead (TCP loopback)", lambda: overhead.run(args.quick)),
        ("wire", "Wire efficiency (paced virtual serial line, 115200 8N1)", lambda: wire.run(args.quick)),
        ("simulator", "Simulator throughput (TCP loopback)", lambda: simthroughput.run(args.quick)),
        ("compiler", "Compiler scaling", lambda: compiler_scaling.run(
            args.quick, max(30.0, (45.0 if args.quick else FULL_BUDGET_S) - (time.perf_counter() - started)))),
        ("exports", "Exports (entities and reads per poll cycle)", lambda: exports.run(args.quick)),
        ("gateway", "Gateway scale (20 lines x 10 drives, MQTT)", lambda: gateway_bench.run(args.quick)),
        ("imports", "Import time of a generated client", lambda: imports.run(args.quick)),
        ("draft", "Draft recovery (seed manuals vs proven maps)", lambda: draft_bench.run(args.quick)),
        ("publicdocs", publicdocs.TITLE, lambda: publicdocs.run(args.quick)),
        ("corpus", draftcorpus.TITLE, lambda: draftcorpus.run(args.quick)),
        ("sunspec", sunspecprobe.TITLE, lambda: sunspecprobe.run(args.quick)),
        ("probe", probe_bench.TITLE, lambda: probe_bench.run(args.quick)),
        ("scan", scan_bench.TITLE, lambda: scan_bench.run(args.quick)),
        ("catalogue", catalogue_bench.TITLE, lambda: catalogue_bench.section(args.quick)),
        ("baseline", baseline.TITLE, lambda: baseline.run(args.quick)),
    ]
    sections: list[Section] = []
    for key, title, fn in plan:
        if args.only and key not in args.only:
            continue
        t0 = time.perf_counter()
        print(f"[{time.perf_counter() - started:5.0f} s] {title} ...", file=sys.stderr, flush=True)
        try:
            sec = fn()
        except Exception:  # noqa: BLE001 - a failing section is reported, the others still run
            sec = Section(title, error=traceback.format_exc())
        sec.detail.append("")
        sec.detail.append(f"Section time: {time.perf_counter() - t0:.0f} s.")
        sections.append(sec)
    elapsed = time.perf_counter() - started
    print(f"drivemap benchmarks — {info['cpu']}, {info['cores']} cores, Python {info['python']}, "
          f"pymodbus {info['pymodbus']}, {info['date']}, {elapsed:.0f} s")
    print(table(sections))
    if out is not None:
        out.write_text(markdown(sections, info, elapsed, args.quick), encoding="utf-8")
        print(f"wrote {out}")
    return 1 if any(s.error for s in sections) else 0


if __name__ == "__main__":
    sys.exit(main())
