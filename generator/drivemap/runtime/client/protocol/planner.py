"""The read planner: which registers go into which read request.

Each table (holding 03h, input 04h, coil 01h, discrete input 02h) is its own address space and is
planned on its own; a request reads one table.

A *unit* is an atomic readable block: one register element (all words of a multi-word type, which
are never split), one word of a reserved range the map marks ``readable: true``, or a ``min_read``
block (the register's block and every element inside it, which the device only reads whole). A
request covers a run of units with contiguous addresses, at most ``max_quantity`` words, and never
spans an address that is not a documented readable register or readable reserved word
(write-only registers, unknown addresses and ``readable: false|null`` reserved ranges are never
spanned) - except that with the map's ``max_gap`` it may read across up to that many
*undocumented* words (no register, no reserved range) between two units.

*Holes* are words a device refused (02h) when a request that spanned them was split by the client
(:meth:`drivemap.runtime.client.api.sync_client.Core.read_raw`). A unit on a hole is never a filler and is never
merged with another unit; a gap with a hole is never spanned.

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

Alignment rules (``protocol.alignment``, :mod:`drivemap.runtime.alignment`): units are whole
register elements, so a request never cuts a multi-word value; the read limit is rounded down to a
multiple of every rule's ``quantity_multiple``. The map's checks make every readable element of an
aligned block start and end on the rule's multiples, so the requests planned from them keep the rules;
the client checks each request again before it is sent.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass, field
from typing import Any

from drivemap.runtime.alignment import aligned_limit
from drivemap.runtime.spec import READ_CODES, DeviceSpec, PageSpec

#: Modbus limit for 03h/04h (125 registers) when the map gives no max_quantity (Modbus
#: Application Protocol v1.1b3, 6.3). Used only when the map says nothing.
MODBUS_MAX_READ = 125
#: Modbus limit for 01h/02h (2000 bits) when the map gives no max_quantity (ibid., 6.1, 6.2).
MODBUS_MAX_READ_BITS = 2000
#: Modbus limit for 10h (123 registers) when the map gives no max_quantity (ibid., 6.12).
MODBUS_MAX_WRITE = 123
#: Modbus limit for 0Fh (1968 coils) when the map gives no max_quantity (ibid., 6.11).
MODBUS_MAX_WRITE_BITS = 1968

Key = tuple[str, int]
"""A register element: (register name, index); index 0 for plain registers."""
Hole = tuple[str, int]
"""A word (bit) a device refused: (table, address)."""
TABLE_ORDER = {"holding": 0, "input": 1, "coil": 2, "discrete": 3}


@dataclass(frozen=True)
class Unit:
    address: int
    words: int
    page: PageSpec | None
    key: Key | None
    """The (first) element of the unit; None for a readable reserved word (filler only)."""
    table: str = "holding"
    members: tuple[tuple[Key, int], ...] = ()
    """Every element of the unit with its word offset (a ``min_read`` block holds several)."""

    @property
    def end(self) -> int:
        return self.address + self.words

    @property
    def keys(self) -> tuple[tuple[Key, int], ...]:
        if self.members:
            return self.members
        return ((self.key, 0),) if self.key is not None else ()


@dataclass(frozen=True)
class ReadRequest:
    """One read request: ``count`` words (bits) from ``address`` of ``table`` in page context ``page``."""

    address: int
    count: int
    page: PageSpec | None
    cells: tuple[tuple[Key, int], ...]  # (element, word offset in the reply)
    table: str = "holding"
    code: int = 0x03
    """The read function code (01h, 02h, 03h, 04h)."""
    units: tuple[Unit, ...] = field(default=(), compare=False, repr=False)
    """The units it covers (what the client splits when the device refuses the request)."""


def read_function(spec: DeviceSpec, table: str = "holding") -> int | None:
    """The read function code of ``table`` (01h, 02h, 03h, 04h) when the map lists it, else None."""
    code = READ_CODES[table]
    return code if spec.protocol.function(code) is not None else None


def max_read_words(spec: DeviceSpec, table: str = "holding") -> int:
    """Largest read of ``table`` the map allows: its max_quantity, the frame limit, else the Modbus limit."""
    code = read_function(spec, table)
    fc = spec.protocol.function(code) if code is not None else None
    bits = table in ("coil", "discrete")
    limit = fc.max_quantity if fc is not None and fc.max_quantity else (MODBUS_MAX_READ_BITS if bits else MODBUS_MAX_READ)
    if spec.protocol.max_frame_bytes:
        room = spec.protocol.max_frame_bytes - 5  # addr + fc + count + data + CRC
        limit = min(limit, room * 8 if bits else room // 2)
    return max(1, limit)


def max_write_words(spec: DeviceSpec, table: str = "holding") -> int:
    """Largest multiple write the map allows (10h; 0Fh for coils; 0 when the map has none)."""
    bits = table == "coil"
    fc = spec.protocol.function(0x0F if bits else 0x10)
    if fc is None:
        return 0
    limit = fc.max_quantity if fc.max_quantity else (MODBUS_MAX_WRITE_BITS if bits else MODBUS_MAX_WRITE)
    if spec.protocol.max_frame_bytes:
        room = spec.protocol.max_frame_bytes - 9  # addr + fc + start + qty + bytes + data + CRC
        limit = min(limit, room * 8 if bits else room // 2)
    return max(1, limit)


def _blocks(spec: DeviceSpec) -> dict[str, list[tuple[int, int]]]:
    """``min_read`` blocks per table, overlapping ones merged: (start, end)."""
    raw: dict[str, list[tuple[int, int]]] = {}
    for reg in spec.registers:
        if reg.min_read is not None and reg.readable:
            raw.setdefault(reg.table, []).append((reg.address, reg.address + reg.min_read))
    merged: dict[str, list[tuple[int, int]]] = {}
    for table, spans in raw.items():
        out: list[tuple[int, int]] = []
        for start, end in sorted(spans):
            if out and start < out[-1][1]:
                out[-1] = (out[-1][0], max(out[-1][1], end))
            else:
                out.append((start, end))
        merged[table] = out
    return merged


def units(spec: DeviceSpec) -> list[Unit]:
    """Every readable unit of the map, sorted by table and address."""
    out: list[Unit] = []
    for reg in spec.registers:
        if not reg.readable:
            continue
        for i in range(reg.count):
            out.append(Unit(reg.element_address(i), reg.words, reg.page, (reg.name, i), reg.table))
    for res in spec.reserved:
        if res.readable is True:
            out.extend(Unit(a, 1, res.page, None, res.table) for a in range(res.start, res.end + 1))
    blocks = _blocks(spec)
    if blocks:
        out = _merge_blocks(out, blocks)
    out.sort(key=lambda u: (TABLE_ORDER[u.table], u.address, u.page.value if u.page else -1))
    return out


def _merge_blocks(all_units: list[Unit], blocks: dict[str, list[tuple[int, int]]]) -> list[Unit]:
    """Every unit inside a ``min_read`` block becomes part of one unit covering the block."""
    out: list[Unit] = []
    inside: dict[tuple[str, int], list[Unit]] = {}
    for u in all_units:
        block = next(((s, e) for s, e in blocks.get(u.table, ()) if u.address < e and u.end > s), None)
        if block is None:
            out.append(u)
        else:
            inside.setdefault((u.table, block[0]), []).append(u)
    for (table, start), members in inside.items():
        end = max(max(e for s, e in blocks[table] if s == start), max(u.end for u in members))
        first = min(start, min(u.address for u in members))
        keys = tuple(sorted(((k, u.address - first + off) for u in members for k, off in u.keys),
                            key=lambda item: item[1]))
        out.append(Unit(first, end - first, None, keys[0][0] if keys else None, table, keys))
    return out


@dataclass
class _Layout:
    """Per table: what a gap between two units may contain (for ``max_gap``) and the refused words."""

    max_gap: int
    documented: frozenset[int]
    holes: frozenset[int]

    def spannable(self, start: int, end: int) -> bool:
        """Whether the undocumented words start..end-1 may be read across."""
        if end - start > self.max_gap:
            return False
        return not any(a in self.documented or a in self.holes for a in range(start, end))


def _documented(spec: DeviceSpec, table: str) -> frozenset[int]:
    words: set[int] = set()
    for reg in spec.registers:
        if reg.table == table:
            for i in range(reg.count):
                start = reg.element_address(i)
                words.update(range(start, start + reg.words))
    for res in spec.reserved:
        if res.table == table:
            words.update(range(res.start, res.end + 1))
    return frozenset(words)


def _components(all_units: list[Unit], layout: _Layout | None = None) -> list[list[Unit]]:
    """Groups of units whose address ranges touch, overlap or are joined by a spannable gap
    (requests never cross groups); a unit on a hole is a group of its own."""
    groups: list[list[Unit]] = []
    end = -1
    alone = False
    for u in all_units:
        hole = layout is not None and any(a in layout.holes for a in range(u.address, u.end))
        joins = groups and not hole and not alone and (
            u.address <= end or (layout is not None and layout.spannable(end, u.address)))
        if joins:
            groups[-1].append(u)
            end = max(end, u.end)
        else:
            groups.append([u])
            end = u.end
        alone = hole
    return groups


Request = tuple[PageSpec | None, tuple[Unit, ...]]


def _wanted(unit: Unit, targets: Collection[Key]) -> bool:
    key = unit.key
    if key is None:
        return False
    if not unit.members:
        return key in targets
    return any(k in targets for k, _ in unit.members)


def _greedy(line: list[Unit], targets: Collection[Key], limit: int, layout: _Layout | None = None) -> list[tuple[Unit, ...]]:
    out: list[tuple[Unit, ...]] = []
    i = 0
    while i < len(line):
        if not _wanted(line[i], targets):
            i += 1
            continue
        start = line[i].address
        taken = [line[i]]
        j = i + 1
        while j < len(line) and line[j].end - start <= limit and (
                line[j].address == taken[-1].end
                or (layout is not None and line[j].address > taken[-1].end
                    and layout.spannable(taken[-1].end, line[j].address))):
            taken.append(line[j])
            j += 1
        while not _wanted(taken[-1], targets):  # never end on a filler
            taken.pop()
        out.append(tuple(taken))
        i += len(taken)
    return out


def _layered(group: list[Unit], targets: Collection[Key], pages: list[PageSpec], limit: int) -> list[Request]:
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
                mandatory = _wanted(u, targets) and u.page is not None
                if not mandatory:
                    opts.append((None, 0, False, done))
                if cur is not None and cur[1] == a and u.end - cur[0] <= limit:
                    opts.append(((cur[0], u.end, cur[2] + (u,)), 0, _wanted(u, targets), ()))
                if _wanted(u, targets):
                    opts.append(((a, u.end, (u,)), 1, True, done))
                options.append(opts)
            common = next(
                (lines[p][a] for p in pages if a in lines[p] and lines[p][a].page is None and _wanted(lines[p][a], targets)),
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
    return _cheapest(states, pages, targets)


def _cheapest(states: dict[Any, tuple[int, tuple[Request, ...]]], pages: list[PageSpec],
              targets: Collection[Key]) -> list[Request]:
    """The requests of the cheapest final state, each trimmed of the units nobody asked for at its end."""
    best: tuple[int, tuple[Request, ...]] | None = None
    for state, (cost, closed) in states.items():
        final = closed + tuple((p, st[2]) for p, st in zip(pages, state, strict=True) if st is not None)
        if best is None or cost < best[0]:
            best = (cost, final)
    assert best is not None
    out: list[Request] = []
    for page, taken in best[1]:
        items = list(taken)
        while items and not _wanted(items[-1], targets):
            items.pop()
        if items:
            out.append((page, tuple(items)))
    return out

def plan_reads(spec: DeviceSpec, targets: Iterable[Key], holes: Collection[Hole] = ()) -> tuple[ReadRequest, ...]:
    """The fewest read requests that read every element in ``targets`` (see the module docstring),
    never spanning a word in ``holes``."""
    wanted = set(targets)
    all_units = units(spec)
    known = {k for u in all_units for k, _ in u.keys}
    missing = wanted - known
    if missing:
        raise KeyError(f"not readable: {sorted(missing)}")
    plans: list[tuple[str, PageSpec | None, tuple[Unit, ...]]] = []
    for table in sorted({u.table for u in all_units}, key=TABLE_ORDER.__getitem__):
        line = [u for u in all_units if u.table == table]
        if not any(_wanted(u, wanted) for u in line):
            continue
        layout = None
        table_holes = frozenset(a for t, a in holes if t == table)
        if spec.protocol.max_gap or table_holes:
            layout = _Layout(spec.protocol.max_gap, _documented(spec, table) if spec.protocol.max_gap else frozenset(), table_holes)
        limit = aligned_limit(spec, table, max_read_words(spec, table))
        plans.extend((table, page, taken) for page, taken in _plan_table(line, wanted, limit, layout))
    requests: list[ReadRequest] = []
    seen: set[Key] = set()
    for table, page, taken in plans:
        context = page if any(u.page is not None for u in taken) else None
        start = taken[0].address
        cells = tuple(
            (key, u.address - start + offset) for u in taken for key, offset in u.keys
            if key in wanted and key not in seen
        )
        seen.update(key for key, _ in cells)
        code = read_function(spec, table) or READ_CODES[table]
        requests.append(ReadRequest(start, taken[-1].end - start, context, cells, table, code, taken))
    requests.sort(key=lambda r: (TABLE_ORDER[r.table], (r.page.selector, r.page.value) if r.page else ("", -1),
                                 r.address))
    return tuple(requests)


def _plan_table(line: list[Unit], wanted: set[Key], limit: int, layout: _Layout | None) -> list[Request]:
    plans: list[Request] = []
    for group in _components(line, layout):
        if not any(_wanted(u, wanted) for u in group):
            continue
        pages = sorted({u.page for u in group if u.page is not None and _wanted(u, wanted)},
                       key=lambda p: (p.selector, p.value))
        if len(pages) <= 1:
            page = pages[0] if pages else None
            sub = [u for u in group if u.page is None or u.page == page]
            plans.extend((page, taken) for taken in _greedy(sub, wanted, limit, layout))
        else:
            plans.extend(_layered(group, wanted, pages, limit))
    return plans


def split_units(request: ReadRequest) -> tuple[tuple[Unit, ...], tuple[Unit, ...]]:
    """The units of a refused request in two halves (by count), for the client's adaptive split."""
    middle = len(request.units) // 2
    return request.units[:middle], request.units[middle:]


def request_for(request: ReadRequest, part: tuple[Unit, ...]) -> ReadRequest:
    """A request covering ``part`` (units of ``request``), with the cells of ``request`` that lie in it."""
    start, end = part[0].address, part[-1].end
    base = request.address
    cells = tuple((key, base + offset - start) for key, offset in request.cells if start <= base + offset < end)
    return ReadRequest(start, end - start, request.page, cells, request.table, request.code, part)


__all__ = [
    "MODBUS_MAX_READ",
    "MODBUS_MAX_READ_BITS",
    "MODBUS_MAX_WRITE",
    "MODBUS_MAX_WRITE_BITS",
    "Hole",
    "Key",
    "ReadRequest",
    "Unit",
    "max_read_words",
    "max_write_words",
    "plan_reads",
    "read_function",
    "request_for",
    "split_units",
    "units",
]
