"""The read planner: which registers go into which read request.

A *unit* is an atomic readable block: one register element (two words for u32/s32, which are never
split) or one word of a reserved range the map marks ``readable: true``. A request covers a run of
units with contiguous addresses, at most ``max_quantity`` words, and never spans an address that is
not a documented readable register or readable reserved word (write-only registers, unknown
addresses and ``readable: false|null`` reserved ranges are never spanned).

Pages: a register with ``page: {selector, value}`` is only valid while its selector shows that
page. A request has a *context*: ``None`` (spans only unpaged units) or one page (spans unpaged
units and that page's units). A paged target must be read in its page's context; unpaged targets
may be read in any context.

Optimality
----------
*One context* (no paged target in a component): greedy from the left. Let t be the leftmost
target not yet covered. Some request of any solution covers t; the part of that request right of
t covers only targets reachable from t through contiguous spannable units within max_quantity words
of t, and nothing left of t is uncovered. The greedy request starts exactly at t and extends as far
as the same constraints allow, so it covers a superset of those targets; exchanging the solution's
request for the greedy one keeps the solution feasible and the same size. By induction greedy uses
the minimum number of requests.

*Several contexts* (paged targets): an exact dynamic programme over unit start addresses whose
state is, per context, the open request (start, end) or none; a new request starts only at a
target unit (starting earlier at a filler never covers more). Components are small (one
selector's window), so the state space stays tiny.

The tests check both against an independently computed lower bound for every map.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from .spec import DeviceSpec, PageSpec

#: Modbus limit for 03h/04h (125 registers) when the map gives no max_quantity (Modbus
#: Application Protocol v1.1b3, 6.3). Used only when the map says nothing.
MODBUS_MAX_READ = 125
#: Modbus limit for 10h (123 registers) when the map gives no max_quantity (ibid., 6.12).
MODBUS_MAX_WRITE = 123

Key = tuple[str, int]
"""A register element: (register name, index); index 0 for plain registers."""


@dataclass(frozen=True)
class Unit:
    address: int
    words: int
    page: PageSpec | None
    key: Key | None  # None for a readable reserved word (filler only)

    @property
    def end(self) -> int:
        return self.address + self.words


@dataclass(frozen=True)
class ReadRequest:
    """One read request: ``count`` words from ``address`` in page context ``page``."""

    address: int
    count: int
    page: PageSpec | None
    cells: tuple[tuple[Key, int], ...]  # (element, word offset in the reply)


def read_function(spec: DeviceSpec) -> int | None:
    """The read function code the map lists (03h preferred, else 04h)."""
    for code in (0x03, 0x04):
        if spec.function(code) is not None:
            return code
    return None


def max_read_words(spec: DeviceSpec) -> int:
    """Largest read the map allows: its max_quantity, the frame limit, else :data:`MODBUS_MAX_READ`."""
    code = read_function(spec)
    fc = spec.function(code) if code is not None else None
    limit = fc.max_quantity if fc is not None and fc.max_quantity else MODBUS_MAX_READ
    if spec.max_frame_bytes:
        limit = min(limit, (spec.max_frame_bytes - 5) // 2)  # addr + fc + count + 2N + CRC
    return max(1, limit)


def max_write_words(spec: DeviceSpec) -> int:
    """Largest 10h write the map allows (0 when the map has no 10h)."""
    fc = spec.function(0x10)
    if fc is None:
        return 0
    limit = fc.max_quantity if fc.max_quantity else MODBUS_MAX_WRITE
    if spec.max_frame_bytes:
        limit = min(limit, (spec.max_frame_bytes - 9) // 2)  # addr + fc + start + qty + bytes + 2N + CRC
    return max(1, limit)


def units(spec: DeviceSpec) -> list[Unit]:
    """Every readable unit of the map, sorted by address."""
    out: list[Unit] = []
    for reg in spec.registers:
        if not reg.readable:
            continue
        for i in range(reg.count):
            out.append(Unit(reg.element_address(i), reg.words, reg.page, (reg.name, i)))
    for res in spec.reserved:
        if res.readable is True:
            out.extend(Unit(a, 1, res.page, None) for a in range(res.start, res.end + 1))
    out.sort(key=lambda u: (u.address, u.page.value if u.page else -1))
    return out


def _components(all_units: list[Unit]) -> list[list[Unit]]:
    """Groups of units whose address ranges touch or overlap (requests never cross groups)."""
    groups: list[list[Unit]] = []
    end = -1
    for u in all_units:
        if groups and u.address <= end:
            groups[-1].append(u)
            end = max(end, u.end)
        else:
            groups.append([u])
            end = u.end
    return groups


Request = tuple[PageSpec | None, tuple[Unit, ...]]


def _greedy(line: list[Unit], targets: set[Key], limit: int) -> list[tuple[Unit, ...]]:
    out: list[tuple[Unit, ...]] = []
    i = 0
    while i < len(line):
        if line[i].key not in targets:
            i += 1
            continue
        start = line[i].address
        taken = [line[i]]
        j = i + 1
        while j < len(line) and line[j].address == taken[-1].end and line[j].end - start <= limit:
            taken.append(line[j])
            j += 1
        while taken[-1].key not in targets:  # never end on a filler
            taken.pop()
        out.append(tuple(taken))
        i += len(taken)
    return out


def _layered(group: list[Unit], targets: set[Key], pages: list[PageSpec], limit: int) -> list[Request]:
    lines = {p: {u.address: u for u in group if u.page is None or u.page == p} for p in pages}
    events = sorted({u.address for u in group})
    # state: per page, (start, end, units) of the open request or None; value: (cost, closed requests)
    Open = tuple[int, int, tuple[Unit, ...]] | None
    states: dict[tuple[Open, ...], tuple[int, tuple[Request, ...]]] = {tuple(None for _ in pages): (0, ())}
    for a in events:
        nxt: dict[tuple[Open, ...], tuple[int, tuple[Request, ...]]] = {}
        for state, (cost, closed) in states.items():
            options: list[list[tuple[Open, int, bool, tuple[Request, ...]]]] = []
            for k, p in enumerate(pages):
                cur = state[k]
                u = lines[p].get(a)
                if cur is not None and cur[1] < a:  # ended before this address: close it
                    closed = closed + ((p, cur[2]),)
                    cur = None
                if u is None:
                    if cur is not None and cur[1] == a:
                        closed = closed + ((p, cur[2]),)
                        cur = None
                    options.append([(cur, 0, False, ())])
                    continue
                opts: list[tuple[Open, int, bool, tuple[Request, ...]]] = []
                done = ((p, cur[2]),) if cur is not None else ()
                mandatory = u.key in targets and u.page is not None
                if not mandatory:
                    opts.append((None, 0, False, done))
                if cur is not None and cur[1] == a and u.end - cur[0] <= limit:
                    opts.append(((cur[0], u.end, cur[2] + (u,)), 0, u.key in targets, ()))
                if u.key in targets:
                    opts.append(((a, u.end, (u,)), 1, True, done))
                options.append(opts)
            common = next(
                (lines[p][a] for p in pages if a in lines[p] and lines[p][a].page is None and lines[p][a].key in targets),
                None,
            )
            combos: list[tuple[tuple[Open, ...], int, bool, tuple[Request, ...]]] = [((), 0, False, ())]
            for opts in options:
                combos = [
                    (s + (o[0],), c + o[1], cov or o[2], d + o[3]) for s, c, cov, d in combos for o in opts
                ]
            for s, c, cov, d in combos:
                if common is not None and not cov:
                    continue
                value = (cost + c, closed + d)
                if s not in nxt or value[0] < nxt[s][0]:
                    nxt[s] = value
        states = nxt
    best: tuple[int, tuple[Request, ...]] | None = None
    for state, (cost, closed) in states.items():
        final = closed + tuple((p, st[2]) for p, st in zip(pages, state, strict=True) if st is not None)
        if best is None or cost < best[0]:
            best = (cost, final)
    assert best is not None
    out: list[Request] = []
    for page, taken in best[1]:
        items = list(taken)
        while items and items[-1].key not in targets:
            items.pop()
        if items:
            out.append((page, tuple(items)))
    return out


def plan_reads(spec: DeviceSpec, targets: Iterable[Key]) -> tuple[ReadRequest, ...]:
    """The fewest read requests that read every element in ``targets`` (see the module docstring)."""
    wanted = set(targets)
    limit = max_read_words(spec)
    all_units = units(spec)
    known = {u.key for u in all_units}
    missing = wanted - known
    if missing:
        raise KeyError(f"not readable: {sorted(missing)}")
    plans: list[Request] = []
    for group in _components(all_units):
        if not any(u.key in wanted for u in group):
            continue
        pages = sorted({u.page for u in group if u.page is not None and u.key in wanted}, key=lambda p: (p.selector, p.value))
        if len(pages) <= 1:
            page = pages[0] if pages else None
            line = [u for u in group if u.page is None or u.page == page]
            plans.extend((page, taken) for taken in _greedy(line, wanted, limit))
        else:
            plans.extend(_layered(group, wanted, pages, limit))
    requests: list[ReadRequest] = []
    seen: set[Key] = set()
    for page, taken in plans:
        context = page if any(u.page is not None for u in taken) else None
        start = taken[0].address
        cells = tuple(
            (u.key, u.address - start) for u in taken if u.key is not None and u.key in wanted and u.key not in seen
        )
        seen.update(key for key, _ in cells)
        requests.append(ReadRequest(start, taken[-1].end - start, context, cells))
    requests.sort(key=lambda r: ((r.page.selector, r.page.value) if r.page else ("", -1), r.address))
    return tuple(requests)


__all__ = [
    "MODBUS_MAX_READ",
    "MODBUS_MAX_WRITE",
    "ReadRequest",
    "Unit",
    "max_read_words",
    "max_write_words",
    "plan_reads",
    "read_function",
    "units",
]
