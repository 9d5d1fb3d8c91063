"""(1) Read planning: requests needed to read every readable register of each model.

Four counts per model, all for the same target set (every readable register element):

* **drivemap** — the number of read requests ``Client.read_all()`` actually sends to the
  generated simulator over TCP (``client.stats``), page-switch writes counted apart; it is
  checked against ``len(Client.plan())``.
* **lower bound** — computed here, independently of ``generator/drivemap/runtime/client/protocol/planner.py``, from the
  ``SPEC`` alone (see :func:`lower_bound`): an exact dynamic programme over the targets of each
  page context, combined as ``max(relaxed single line, sum over page contexts)`` per connected
  address run, which no valid plan can beat.
* **naive** — one request per register element (a 32-bit value is one 2-word request).
* **contiguous-only (ESPHome style)** — see :func:`contiguous_only`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from common import MODELS, Row, Section

Ctx = tuple[str, int] | None  # page context: (selector, value) or None


@dataclass(frozen=True)
class Target:
    start: int
    end: int
    ctx: Ctx  # the page the element needs (None: unpaged, readable in any context)


def _page(obj: Any) -> Ctx:
    return (obj.page.selector, obj.page.value) if obj.page is not None else None


def max_quantity(spec: Any) -> int:
    """Registers one read may carry: the map's 03h (else 04h) limit, the frame-size limit, else 125."""
    fc = next((f for code in (0x03, 0x04) for f in spec.protocol.function_codes if f.code == code), None)
    limit = fc.max_quantity if fc is not None and fc.max_quantity else 125
    if spec.protocol.max_frame_bytes:
        limit = min(limit, (spec.protocol.max_frame_bytes - 5) // 2)  # unit + fc + byte count + 2N + CRC(2)
    return max(1, limit)


def targets(spec: Any) -> list[Target]:
    out = []
    for reg in spec.registers:
        if "r" not in reg.access:
            continue
        words = 2 if reg.type in ("u32", "s32") else 1
        for i in range(reg.count):
            a = reg.address + i * reg.stride
            out.append(Target(a, a + words, _page(reg)))
    return sorted(out, key=lambda t: (t.start, str(t.ctx)))


def _line(spec: Any, ctx: Ctx | str) -> dict[int, tuple[int, int]]:
    """address -> (start, end) of the atomic block holding it, for one context.

    ``ctx == "any"`` relaxes pages (every paged block is valid): used only for a lower bound.
    """
    blocks: dict[int, tuple[int, int]] = {}
    for reg in spec.registers:
        page = _page(reg)
        if "r" not in reg.access or not (page is None or ctx == "any" or page == ctx):
            continue
        words = 2 if reg.type in ("u32", "s32") else 1
        for i in range(reg.count):
            a = reg.address + i * reg.stride
            for w in range(words):
                blocks[a + w] = (a, a + words)
    for res in spec.reserved:
        page = _page(res)
        if res.readable is True and (page is None or ctx == "any" or page == ctx):
            for a in range(res.start, res.end + 1):
                blocks.setdefault(a, (a, a + 1))
    return blocks


def _min_cover(points: list[Target], blocks: dict[int, tuple[int, int]], limit: int) -> int:
    """Fewest requests covering ``points`` on one line (exact DP, O(n^2)); requests start at a
    point's start and end at a point's end (any optimal plan can be shrunk to that)."""
    pts = sorted({(p.start, p.end) for p in points})
    n = len(pts)
    best = [0] + [n + 1] * n
    for i in range(n):
        start = pts[i][0]
        ok_to = start  # every address in [start, ok_to) is spannable
        for j in range(i, n):
            end = pts[j][1]
            if end - start > limit:
                break
            while ok_to < end and ok_to in blocks:
                ok_to += 1
            if ok_to < end:
                break
            if blocks.get(end - 1, (0, end))[1] != end:  # would split a 2-word block
                continue
            best[j + 1] = min(best[j + 1], best[i] + 1)
        # best[] over prefixes: a later prefix is never cheaper to reach than an earlier one needs
    return best[n]


def lower_bound(spec: Any) -> int:
    limit = max_quantity(spec)
    all_targets = targets(spec)
    relaxed = _line(spec, "any")
    # connected runs of readable addresses (any context): requests never cross them
    groups: list[list[Target]] = []
    end = -1
    for t in all_targets:
        if groups and all(a in relaxed for a in range(end, t.start)):
            groups[-1].append(t)
            end = max(end, t.end)
        else:
            groups.append([t])
            end = t.end
    total = 0
    for group in groups:
        single = _min_cover(group, relaxed, limit)
        per_page = 0
        for ctx in sorted({t.ctx for t in group if t.ctx is not None}):
            per_page += _min_cover([t for t in group if t.ctx == ctx], _line(spec, ctx), limit)
        total += max(single, per_page)
    return total


def contiguous_only(spec: Any) -> int:
    """ESPHome-style grouping (modbus_controller): targets sorted by (page context, address);
    a target joins the current request only when its address equals the request's end
    (strictly adjacent: no gap is ever read, not even a reserved address the map marks
    readable) and the request stays within the device's max quantity; a paged target joins
    only targets of its own page (ESPHome has no notion of pages), unpaged ones only unpaged."""
    limit = max_quantity(spec)
    requests = 0
    cur: tuple[Ctx, int, int] | None = None  # ctx, start, end
    for t in sorted(targets(spec), key=lambda t: (str(t.ctx), t.start)):
        if cur is not None and cur[0] == t.ctx and t.start == cur[2] and t.end - cur[1] <= limit:
            cur = (cur[0], cur[1], t.end)
            continue
        requests += 1
        cur = (t.ctx, t.start, t.end)
    return requests


def measured_read_all(model: str) -> tuple[int, int, int]:
    """(read requests, other requests, len(plan)) of ``Client.read_all()`` against the simulator,
    counted where the requests arrive (the simulator's ``handle``), whatever path the client takes."""
    from drivemap.runtime.sim.serve import ThreadedSimServer

    client_mod = importlib.import_module(f"drivemap_models.{model}.client")
    sim_mod = importlib.import_module(f"drivemap_models.{model}.simulator")
    sim = sim_mod.Simulator([1])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        pages = any(r.page is not None for r in client_mod.SPEC.registers)
        client = client_mod.Client.tcp(host, port, 1, timeout=2.0, page_policy="switch" if pages else "raise")
        reads = others = 0
        real_handle = sim.handle

        def counting(unit_id: int, pdu: bytes, **kwargs: Any) -> Any:  # what reached the device
            nonlocal reads, others
            if pdu[:1] in (b"\x03", b"\x04"):
                reads += 1
            else:
                others += 1
            return real_handle(unit_id, pdu, **kwargs)

        sim.handle = counting  # type: ignore[method-assign]
        with client:
            before = client.stats.transactions
            client.read_all()
            sent = client.stats.transactions - before
        assert sent == reads + others, (sent, reads, others)
        return reads, others, len(client_mod.Client.plan())


def run(quick: bool) -> Section:
    sec = Section("Read planning")
    sec.detail.append("| model | readable elements | max quantity | drivemap (sent) | drivemap plan | page switches "
                      "| lower bound | naive | contiguous-only | naive / drivemap | contiguous / drivemap |")
    sec.detail.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for model in MODELS:
        spec = importlib.import_module(f"drivemap_models.{model}.spec").SPEC
        lb = lower_bound(spec)
        naive = len(targets(spec))
        contiguous = contiguous_only(spec)
        try:
            reads, others, planned = measured_read_all(model)
        except Exception as exc:  # noqa: BLE001 - reported in the table
            sec.detail.append(f"| {model} | {naive} | {max_quantity(spec)} | error: {type(exc).__name__}: {exc} "
                              f"| | | {lb} | {naive} | {contiguous} | | |")
            sec.rows.append(Row("1 planning", model, None, "= lower bound", False, f"error {exc}"))
            continue
        sec.detail.append(
            f"| {model} | {naive} | {max_quantity(spec)} | {reads} | {planned} | {others} | {lb} | {naive} "
            f"| {contiguous} | {naive / reads:.1f}× | {contiguous / reads:.2f}× |")
        sec.rows.append(Row("1 planning", f"{model}: drivemap / lower bound", reads / lb, "= 1.00", reads == lb,
                            f"{reads} vs {lb} requests (naive {naive}, contiguous-only {contiguous})"))
    return sec


if __name__ == "__main__":
    s = run(False)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
