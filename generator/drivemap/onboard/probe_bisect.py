"""Probe by bisection with a budget: sweep in the largest blocks, split a refused block only where it pays.

:class:`Bisector` drives a :class:`~drivemap.onboard.probe.Prober` (reads only) in four steps, each
spending requests only while the budget (``--budget`` requests, ``--time`` seconds) lasts:

1. **sweep** each range in blocks of the table's largest read (125 words, 2000 bits). The first
   refused blocks of a table also test the device's rules: a block whose halves both answer means the
   device takes fewer words per request (the limit drops and the sweep goes on in the smaller size);
   a block that answers one word shorter at an even start, where a one-word read of a word just read is
   refused, means the device reads even quantities at even addresses only (``protocol.alignment``:
   from then on every read is aligned so, and a refused aligned pair is that pair proven unreadable);
   exception 01h refuses the whole table.
2. **hints**: the runs of readable words of known maps (the candidates' register blocks) that fall
   into refused blocks are read once each.
3. **edges**: each readable run is grown into the unknown words beside it by binary search, and the
   first word past it is read alone (its refusal proves it unreadable).
4. **bisection** of what is left, largest refused intervals first, halves read, down to single
   words (or aligned pairs): a refused single word is proven unreadable.

What no read answered and no single-word read proved is *unresolved* (never reported as empty).
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from drivemap.onboard.probe import Prober

__all__ = ["Bisector", "Outcome", "runs"]

UNKNOWN, READABLE, UNREADABLE = 0, 1, 2
#: refused sweep blocks per table on which the device's rules are tested
RULE_TRIES = 3


def runs(addresses: list[int]) -> list[tuple[int, int]]:
    """Sorted addresses -> inclusive (first, last) runs."""
    out: list[tuple[int, int]] = []
    for a in addresses:
        if out and a == out[-1][1] + 1:
            out[-1] = (out[-1][0], a)
        else:
            out.append((a, a))
    return out


@dataclass
class Outcome:
    """What the probe proved: values read, words proven unreadable, words left unresolved (per table)."""

    values: dict[str, dict[int, int]]
    unreadable: dict[str, list[tuple[int, int]]] = field(default_factory=dict)
    unresolved: dict[str, list[tuple[int, int]]] = field(default_factory=dict)
    rules: list[str] = field(default_factory=list)
    #: why the probe stopped before every word was resolved ("budget", "time"), or None
    stopped: str | None = None


@dataclass
class _Table:
    name: str
    state: bytearray
    swept: list[tuple[int, int]]
    #: reads must start at even addresses and hold even quantities (learned)
    pairs: bool = False
    pairs_tested: bool = False
    tries: int = 0
    form_tried: bool = False


class Bisector:
    """The four steps over ``ranges`` of ``tables`` (see the module doc)."""

    def __init__(self, prober: Prober, *, budget: int | None, seconds: float | None,
                 hints: dict[str, list[tuple[int, int]]] | None = None,
                 progress: Callable[[Bisector], None] | None = None) -> None:
        self.prober = prober
        self.budget = budget
        self.deadline = None if seconds is None else time.monotonic() + seconds
        self.hints = hints or {}
        self.progress = progress
        self.values: dict[str, dict[int, int]] = {}
        self.rules: list[str] = []
        self.stopped: str | None = None
        self.islands = 0

    # -- budget
    def spent(self) -> bool:
        if self.budget is not None and self.prober.requests >= self.budget:
            self.stopped = self.stopped or "budget"
            return True
        if self.deadline is not None and time.monotonic() >= self.deadline:
            self.stopped = self.stopped or "time"
            return True
        return False

    # -- reads
    def _read(self, t: _Table, address: int, count: int) -> list[int] | None:
        values = self.prober.read(t.name, address, count)
        if values is not None:
            into = self.values.setdefault(t.name, {})
            fresh = [a for a in range(address, address + count) if t.state[a] != READABLE]
            for a, v in zip(range(address, address + count), values, strict=False):
                into[a] = v
                t.state[a] = READABLE
            if fresh and (fresh[0] == 0 or t.state[fresh[0] - 1] != READABLE or fresh[0] > address):
                self.islands = len(runs(sorted(into)))
        if self.progress is not None:
            self.progress(self)
        return values

    def _unknown(self, t: _Table, a: int, b: int) -> bool:
        return any(t.state[x] == UNKNOWN for x in range(a, b + 1))

    # -- the steps
    def run(self, tables: list[str], ranges: list[tuple[int, int]], paired: set[str] | None = None) -> Outcome:
        """``paired``: the tables a map's alignment rules say to read in even pairs (``probe --map``)."""
        states = [_Table(name, bytearray(0x10000), ranges, pairs=name in (paired or set())) for name in tables]
        refused: dict[str, list[tuple[int, int]]] = {t.name: [] for t in states}
        for t in states:
            refused[t.name] = self._sweep(t)
        for t in states:
            self._hinted(t)
        for t in states:
            self._edges(t)
        self._bisect(states, refused)
        return self._outcome(states)

    def _sweep(self, t: _Table) -> list[tuple[int, int]]:
        refused: list[tuple[int, int]] = []
        for first, last in t.swept:
            address = first
            while address <= last:
                if t.name in self.prober.unsupported:
                    self._mark(t, address, last, UNREADABLE)
                    break
                if self.spent():
                    return refused
                count = self._aligned_count(t, address, min(self.prober.max_quantity[t.name], last - address + 1))
                if count <= 0:  # an odd word at the end of a range under the pairs rule
                    address += 1
                    continue
                if self._read(t, address, count) is None:
                    if t.name in self.prober.unsupported:
                        self.rules.append(f"{t.name}: the device refuses the function (exception 01h)")
                        continue
                    if self._form_refused(t, address, count):
                        continue  # read the block again in the aligned form just learned
                    if t.tries < RULE_TRIES and count > 2:
                        t.tries += 1
                        if self._rules(t, address, count):
                            continue  # read the block again under the rule just learned
                    refused.append((address, address + count - 1))
                address += count
        return refused

    def _form_refused(self, t: _Table, address: int, count: int) -> bool:
        """Exception 03h (illegal data value) names the request's form, not its addresses. Once per
        table, at an even address: the largest even quantity not refused with 03h (binary search) is
        the device's largest read; an odd quantity refused with 03h where the even ones around it are
        not means reads in even pairs only. True when a rule was learned (the block is read again)."""
        if t.form_tried or self.prober.last_refusal != 0x03 or count < 4 or address % 2:
            return False
        t.form_tried = True
        words = t.name in ("holding", "input")
        step = 2 if words else 1

        def accepted(quantity: int) -> bool:
            return self._read(t, address, quantity) is not None or self.prober.last_refusal not in (0x03, None)

        good, bad = 0, count - count % step + step if count % step else count
        while bad - good > step:
            mid = (good + bad) // 2
            mid -= mid % step
            if mid <= good:
                mid = good + step
            if self.spent():
                return False
            if accepted(mid):
                good = mid
            else:
                bad = mid
        if good == 0:
            return False
        learned = False
        if words and good >= 4 and not accepted(3):
            t.pairs = True
            learned = True
            self.rules.append(f"{t.name}: reads at even addresses in even quantities only (exception 03h to 3 words "
                              f"at {address}, not to {good}); protocol.alignment")
        elif words and good + 1 < count and accepted(good + 1):
            good += 1
        if good < self.prober.max_quantity[t.name]:
            self.prober.max_quantity[t.name] = good
            learned = True
            self.rules.append(f"{t.name}: at most {good} per read (exception 03h to {bad} at {address}); "
                              "protocol.function_codes max_quantity")
        return learned

    def _aligned_count(self, t: _Table, address: int, count: int) -> int:
        if t.pairs:
            return count - count % 2 if address % 2 == 0 else 0
        return count

    def _rules(self, t: _Table, address: int, count: int) -> bool:
        """Test the refused block at ``address`` for a rule; True when one was learned."""
        if not t.pairs and address % 2 == 0 and count % 2 and t.name in ("holding", "input"):
            if self._read(t, address, count - 1) is not None:
                return self._pairs_rule(t)
        half = count // 2 - (count // 2) % 2
        if half < 1:
            return False
        first = self._read(t, address, half)
        second = self._read(t, address + half, half) if first is not None else None
        if first is not None and second is not None:
            limit = self._largest(t, address, half, count)
            self.prober.max_quantity[t.name] = limit
            self.rules.append(f"{t.name}: at most {limit} per read (a read of {limit + 1} is refused where its "
                              "halves answer); protocol.function_codes max_quantity")
            return True
        return False

    def _largest(self, t: _Table, address: int, good: int, bad: int) -> int:
        """The largest quantity that answers at ``address`` (``good`` answers, ``bad`` is refused)."""
        step = 2 if t.pairs else 1
        while bad - good > step:
            mid = (good + bad) // 2
            mid -= mid % step
            if mid <= good:
                break
            if self._read(t, address, mid) is None:
                bad = mid
            else:
                good = mid
        return good

    def _hinted(self, t: _Table) -> None:
        for first, last in sorted(self.hints.get(t.name, [])):
            for a in range(first, last + 1, self.prober.max_quantity[t.name]):
                b = min(last, a + self.prober.max_quantity[t.name] - 1)
                if t.pairs:
                    a, b = a - a % 2, b + (1 - b % 2)
                    b = min(b, 0xFFFF)
                if not self._swept(t, a, b) or not self._unknown(t, a, b) or t.name in self.prober.unsupported:
                    continue
                if self.spent():
                    return
                self._read(t, a, b - a + 1)

    def _swept(self, t: _Table, a: int, b: int) -> bool:
        return any(lo <= a and b <= hi for lo, hi in t.swept)

    def _edges(self, t: _Table) -> None:
        for first, last in runs(sorted(self.values.get(t.name, {}))):
            self._grow(t, last + 1, 1)
            self._grow(t, first - 1, -1)

    def _grow(self, t: _Table, edge: int, direction: int) -> None:
        """From ``edge``, the unknown word beside a readable run, away from it: the readable words there
        (binary search of their number), and the first unreadable one (read alone)."""
        step = 2 if t.pairs else 1
        if not 0 <= edge <= 0xFFFF or t.state[edge] != UNKNOWN or not self._swept(t, edge, edge):
            return
        limit = self.prober.max_quantity[t.name]
        room = 0
        while room < limit and 0 <= edge + direction * room <= 0xFFFF and t.state[edge + direction * room] == UNKNOWN \
                and self._swept(t, edge + direction * room, edge + direction * room):
            room += 1
        room -= room % step
        good, bad = 0, room + step
        while bad - good > step:  # binary search of the readable length
            if self.spent():
                return
            mid = (good + bad) // 2
            mid -= mid % step
            if mid <= good:
                mid = good + step
            a = edge if direction > 0 else edge - mid + 1
            if self._read(t, a, mid) is None:
                bad = mid
            else:
                good = mid
        if bad <= room and not self.spent():  # the first word(s) past the readable ones, alone
            at = edge + direction * good
            self._single(t, at - at % step)

    def _single(self, t: _Table, address: int) -> None:
        """One word (an aligned pair under the pairs rule): read, or proven unreadable."""
        size = 2 if t.pairs else 1
        if address + size - 1 > 0xFFFF or not self._unknown(t, address, address + size - 1):
            return
        if self._read(t, address, size) is not None:
            return
        if size == 1 and self._pairs_rule(t):
            self._single(t, address - address % 2)
            return
        self._mark(t, address, address + size - 1, UNREADABLE)

    def _pairs_rule(self, t: _Table) -> bool:
        """Once per table, before a one-word refusal counts as proof: is a word known readable refused
        alone too? Then the device reads in even pairs only (``protocol.alignment``). True when learned."""
        if t.pairs or t.pairs_tested or t.name not in ("holding", "input"):
            return False
        known = self.values.get(t.name, {})
        pair = next((a for a in sorted(known) if a % 2 == 0 and a + 1 in known), None)
        if pair is None:
            return False
        t.pairs_tested = True
        if self.prober.read(t.name, pair, 1) is not None:
            return False
        t.pairs = True
        self.prober.max_quantity[t.name] -= self.prober.max_quantity[t.name] % 2
        self.rules.append(f"{t.name}: reads at even addresses in even quantities only (a one-word read of the "
                          f"readable word {pair} is refused); protocol.alignment")
        return True

    def _mark(self, t: _Table, a: int, b: int, what: int) -> None:
        for x in range(a, b + 1):
            if t.state[x] == UNKNOWN:
                t.state[x] = what

    def _bisect(self, states: list[_Table], refused: dict[str, list[tuple[int, int]]]) -> None:
        by_name = {t.name: t for t in states}
        heap: list[tuple[int, int, int, str, int]] = []
        for name, blocks in refused.items():
            for a, b in blocks:
                heapq.heappush(heap, self._key(by_name[name], a, b))
        while heap:
            _, _, a, name, b = heapq.heappop(heap)
            t = by_name[name]
            if name in self.prober.unsupported:
                self._mark(t, a, b, UNREADABLE)
                continue
            while a <= b and t.state[a] != UNKNOWN:
                a += 1
            while b >= a and t.state[b] != UNKNOWN:
                b -= 1
            size = 2 if t.pairs else 1
            if t.pairs:
                a, b = a - a % 2, min(0xFFFF, b + 1 - b % 2)
            if b < a or not self._unknown(t, a, b):
                continue
            if self.spent():
                return
            if b - a + 1 <= size:
                self._single(t, a)
                continue
            half = (b - a + 1) // 2
            half -= half % size
            for lo, hi in ((a, a + half - 1), (a + half, b)):
                if self.spent():
                    heapq.heappush(heap, self._key(t, lo, hi))
                    return
                if hi - lo + 1 <= size:
                    self._single(t, lo)
                elif self._read(t, lo, hi - lo + 1) is None:
                    heapq.heappush(heap, self._key(t, lo, hi))
                else:
                    self._grow(t, hi + 1, 1)
                    self._grow(t, lo - 1, -1)

    def _key(self, t: _Table, a: int, b: int) -> tuple[int, int, int, str, int]:
        """Bisection order: intervals near readable words first (islands cluster), then the largest."""
        window = t.state[max(0, a - 125):min(0x10000, b + 126)]
        return (0 if READABLE in window else 1, -(b - a + 1), a, t.name, b)

    def _outcome(self, states: list[_Table]) -> Outcome:
        out = Outcome({t.name: dict(self.values.get(t.name, {})) for t in states}, rules=list(self.rules),
                      stopped=self.stopped)
        for t in states:
            unreadable: list[int] = []
            unresolved: list[int] = []
            for first, last in t.swept:
                for a in range(first, last + 1):
                    if t.state[a] == UNREADABLE:
                        unreadable.append(a)
                    elif t.state[a] == UNKNOWN:
                        unresolved.append(a)
            out.unreadable[t.name] = runs(sorted(set(unreadable)))
            out.unresolved[t.name] = runs(sorted(set(unresolved)))
        if not any(out.unresolved.values()):
            out.stopped = None
        return out
