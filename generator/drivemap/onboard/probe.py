"""Discover what a live device answers: bounded reads that split on refusal, never a write.

:class:`Prober` sends only the four read function codes (01h-04h; :data:`READ_ONLY_CODES` is
checked before every request), at most ``max_quantity`` words (bits) each and at most ``rate``
requests per second. A read that is refused (any exception reply, or silence) is split in halves
down to 8 words (at even addresses), then tried word by word (a register refused on its own once
more in its even-aligned pair), so every readable word in the swept ranges is found and
no unreadable one is reported. A refused read whose halves both answer in full means the device
takes fewer words per request: later reads use the smaller size.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from drivemap.runtime.client.protocol.sansio import READ_REQUESTS
from drivemap.runtime.client.transport.bus import Bus
from drivemap.runtime.client.transport.exchange import Exchange
from drivemap.runtime.errors import DriveTimeout
from drivemap.runtime.spec import READ_CODES, TimingSpec

__all__ = ["READ_ONLY_CODES", "Block", "ProbeGarbled", "ProbeSilence", "Prober", "blocks_of", "line_seconds"]

READ_ONLY_CODES = frozenset(READ_CODES.values())
#: Largest request the Modbus standard allows per table (words; bits for coils and discrete inputs).
STANDARD_MAX = {"holding": 125, "input": 125, "coil": 2000, "discrete": 2000}
_SINGLES_BELOW = 8
#: reads without any answer at the start, and in a row from a unit that answers bad addresses with
#: exceptions, after which the probe stops (a unit that answers them with silence is read on: slowly)
SILENT_START = 3
SILENT_RUN = 20
#: reads in a row answered with bytes that form no valid reply (or a reply to another request), after
#: which the probe stops as ``read`` does at the first
GARBLED_RUN = 3
#: RTU characters around every frame: the 3.5-character silence before and after
_GAP_CHARS = 7


class ProbeSilence(Exception):
    """The unit does not answer: the probe stops (message: what was seen)."""


class ProbeGarbled(Exception):
    """Replies come, but garbled or not answering the request: the probe stops."""

    def __init__(self, timeout: DriveTimeout, rejected: str | None) -> None:
        super().__init__(str(timeout))
        self.timeout = timeout
        self.rejected = rejected


def line_seconds(chars: int, requests: int, silent: int, baudrate: int, timeout: float) -> float:
    """The time the frames of ``requests`` reads (``chars`` RTU characters, requests and replies) take
    on a serial line at ``baudrate`` (11 bits a character, the 3.5-character gaps), plus ``timeout``
    for each of the ``silent`` reads that got no answer."""
    return (chars + _GAP_CHARS * requests) * 11 / baudrate + silent * timeout


def frame_chars(code: int, count: int, reply: str) -> int:
    """RTU characters of one read and its reply (``reply``: "data", "exception" or "none")."""
    if reply == "none":
        return 8
    if reply == "exception":
        return 8 + 5
    body = (count + 7) // 8 if code <= 0x02 else 2 * count
    return 8 + 5 + body


@dataclass(frozen=True)
class Block:
    """Consecutive readable addresses of one table and the values read there."""

    table: str
    start: int
    values: tuple[int, ...]

    @property
    def end(self) -> int:
        """Last address (inclusive)."""
        return self.start + len(self.values) - 1


def blocks_of(values: dict[str, dict[int, int]]) -> list[Block]:
    """Runs of consecutive addresses per table, in table then address order."""
    out: list[Block] = []
    for table in ("coil", "discrete", "input", "holding"):
        cells = values.get(table, {})
        run: list[int] = []
        for address in sorted(cells):
            if run and address != run[-1] + 1:
                out.append(Block(table, run[0], tuple(cells[a] for a in run)))
                run = []
            run.append(address)
        if run:
            out.append(Block(table, run[0], tuple(cells[a] for a in run)))
    return out


@dataclass
class Prober:
    """Reads of one unit on a connected bus (read function codes only)."""

    bus: Bus
    unit: int
    max_quantity: dict[str, int]
    rate: float
    requests: int = 0
    answered: int = 0
    refusals: dict[int, int] = field(default_factory=dict)
    unsupported: set[str] = field(default_factory=set)
    silent_run: int = 0
    garbled_run: int = 0
    #: reads that got no answer at all; RTU characters of every request and reply (see line_seconds)
    silent: int = 0
    chars: int = 0
    #: the exception code of the last refused read (None: silence)
    last_refusal: int | None = None
    #: tables whose single-word reads are refused where even-aligned pairs answer -> words read in pairs
    pairs_first: dict[str, int] = field(default_factory=dict)
    #: tables the map's alignment rules say to read in pairs only (``probe --map``): no one-word reads
    pairs_only: set[str] = field(default_factory=set)
    _next_at: float = 0.0

    def read(self, table: str, address: int, count: int) -> list[int] | None:
        """The values of one read, or None when refused (exception or silence)."""
        code = READ_CODES[table]
        if code not in READ_ONLY_CODES or count > self.max_quantity[table]:
            raise AssertionError("the probe sends bounded reads only")
        self._pace()
        self.requests += 1
        pdu = READ_REQUESTS[code](address=address, count=count)
        stats = self.bus.stats
        before = (stats.bytes_garbled, stats.rejected)
        self.last_refusal = None
        try:
            reply = self.bus.exchange(Exchange(self.unit, pdu, TimingSpec()))
        except DriveTimeout as exc:
            self.chars += frame_chars(code, count, "none")
            self.silent += 1
            self._garbled(exc, stats.bytes_garbled > before[0], stats.rejected > before[1])
            self._silence()
            return None
        if reply is None:
            self.chars += frame_chars(code, count, "none")
            return None
        self.answered += 1
        self.silent_run = 0
        self.garbled_run = 0
        self.chars += frame_chars(code, count, "exception" if reply.isError() else "data")
        if reply.isError():
            self.last_refusal = reply.exception_code
            self.refusals[reply.exception_code] = self.refusals.get(reply.exception_code, 0) + 1
            if reply.exception_code == 0x01:
                self.unsupported.add(table)
            return None
        if code <= 0x02:
            return [1 if b else 0 for b in reply.bits[:count]]
        return list(reply.registers)

    def _garbled(self, exc: DriveTimeout, garbled: bool, rejected: bool) -> None:
        """Stop when replies keep coming that are garbage or answer another request (as ``read`` does)."""
        self.garbled_run = self.garbled_run + 1 if garbled or rejected else 0
        if self.garbled_run >= GARBLED_RUN:
            raise ProbeGarbled(exc, getattr(self.bus, "last_rejected", None) if rejected else None)

    def _silence(self) -> None:
        """Stop rather than wait out every address: a unit that never answered after a few reads, or one
        that answered bad addresses with exceptions and then fell silent, is not there (any more)."""
        self.silent_run += 1
        if self.answered == 0 and self.requests >= SILENT_START:
            raise ProbeSilence(f"no answer to the first {self.requests} reads")
        if self.refusals and self.silent_run >= SILENT_RUN:
            raise ProbeSilence(f"{self.silent_run} reads in a row went unanswered after {self.answered} answers "
                               "(did the device go away?)")

    def _pace(self) -> None:
        if self.rate <= 0:
            return
        now = time.monotonic()
        if now < self._next_at:
            time.sleep(self._next_at - now)
        self._next_at = max(now, self._next_at) + 1.0 / self.rate

    def sweep(self, table: str, first: int, last: int, into: dict[int, int]) -> None:
        """Every readable address of ``table`` in ``first..last`` with its value, into ``into``."""
        address = first
        while address <= last and table not in self.unsupported:
            count = min(self.max_quantity[table], last - address + 1)
            self._split(table, address, count, into)
            address += count

    def _split(self, table: str, address: int, count: int, into: dict[int, int]) -> bool:
        """Read ``count`` at ``address``, splitting on refusal; True when all of it was readable."""
        limit = self.max_quantity[table]
        if count > limit:  # the limit was lowered while this part waited
            return all([self._split(table, a, min(limit, address + count - a), into)
                        for a in range(address, address + count, limit)])
        values = self.read(table, address, count)
        if values is not None:
            into.update(zip(range(address, address + count), values, strict=False))
            return True
        if count == 1 or table in self.unsupported:
            return False
        if count <= _SINGLES_BELOW:
            self._pairs_then_singles(table, address, count, into)
            return False
        half = count // 2
        if count > 2 and (address + half) % 2:  # split at an even address: devices that need even starts
            half += 1
        whole = self._split(table, address, half, into) & self._split(table, address + half, count - half, into)
        if whole:  # both halves answered: the device takes fewer words per request than asked
            self.max_quantity[table] = min(self.max_quantity[table], count - half)
        return False


    def _pairs_then_singles(self, table: str, address: int, count: int, into: dict[int, int]) -> None:
        """Word by word; a register refused on its own is tried again in the pair at an even address
        that holds it. A device with alignment rules (even starts and quantities, whole 32-bit values)
        refuses every single-word read: once such a pair answered where its word alone was refused,
        the table is read in pairs first. A word is unreadable only when both reads were refused."""
        end = address + count
        pending = set(range(address, end))
        if table in self.pairs_first:
            pending -= self._pairs(table, address, end, pending, into)
        if table in self.pairs_only:
            return  # the map's alignment rules: a one-word read is refused, so none is sent
        refused: set[int] = set()
        for a in sorted(pending):
            if table in self.unsupported:
                return
            values = self.read(table, a, 1)
            if values is None:
                refused.add(a)
            else:
                into[a] = values[0]
        if refused and table in ("holding", "input") and table not in self.pairs_first:
            recovered = self._pairs(table, address, end, refused, into) & refused
            if recovered:
                self.pairs_first[table] = self.pairs_first.get(table, 0)
                self.pairs_first[table] += len(recovered)

    def _pairs(self, table: str, address: int, end: int, wanted: set[int], into: dict[int, int]) -> set[int]:
        """Read the even-aligned pairs that hold a ``wanted`` word; the addresses in ``address..end-1`` read."""
        got: set[int] = set()
        for pair in range(address - address % 2, end, 2):
            if pair + 1 > 0xFFFF or not ({pair, pair + 1} & wanted):
                continue
            values = self.read(table, pair, 2)
            if values is not None:
                cells = {a: v for a, v in zip((pair, pair + 1), values, strict=False) if address <= a < end}
                into.update(cells)
                got |= set(cells)
        if table in self.pairs_first:
            self.pairs_first[table] += len(got)
        return got
