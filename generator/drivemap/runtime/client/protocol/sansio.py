"""The protocol core of every client: operations written once as generators ("sans I/O").

An operation yields :class:`~drivemap.runtime.client.transport.bus.Exchange` requests and receives the replies;
:class:`~drivemap.runtime.client.api.sync_client.ClientBase` runs it on a :class:`Bus`,
:class:`~drivemap.runtime.client.api.async_client.AsyncClientBase` on an :class:`AsyncBus`. Every check on the
caller's input happens before the first request is yielded, so a bad value never sends a byte.

Tables: holding registers are read with 03h and written with 06h/10h, input registers read with
04h, coils read with 01h and written with 05h/0Fh, discrete inputs read with 02h.

Adaptive reads: when the device answers 02h (illegal data address) to a read that spans several
units, :meth:`Core.read_raw` splits it in halves until every unit the caller asked for is read;
a unit the device refuses on its own is a *hole* (:attr:`Core.holes`): later plans never span it,
and the words between two halves that both read fine on their own are holes too. The split's
requests are counted in ``Stats.split_reads`` and ``Stats.extra_requests``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from typing import Literal, TypeVar

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.bit_message import (
    WriteMultipleCoilsRequest,
    WriteSingleCoilRequest,
)
from pymodbus.pdu.diag_message import ReturnQueryDataRequest
from pymodbus.pdu.register_message import (
    WriteMultipleRegistersRequest,
    WriteSingleRegisterRequest,
)

from drivemap.runtime.alignment import refuse_misaligned
from drivemap.runtime.client.protocol.advice import warn_if_running
from drivemap.runtime.client.protocol.planner import (
    Hole,
    Key,
    ReadRequest,
    Unit,
    plan_reads,
    request_for,
    split_units,
)
from drivemap.runtime.client.protocol.review import warn_review
from drivemap.runtime.client.protocol.runner import Op, arun, arun_replay, run, run_replay
from drivemap.runtime.client.protocol.tables import SpecTables, spec_tables
from drivemap.runtime.client.protocol.wire import ILLEGAL_ADDRESS, READ_REQUESTS, Deferred, RawItem, reply_words
from drivemap.runtime.client.transport.exchange import Exchange, Stats
from drivemap.runtime.client.values.codec import raw_to_words, words_to_raw
from drivemap.runtime.errors import (
    BroadcastRead,
    DeviceException,
    DriveError,
    InvalidArgument,
    InvalidValue,
    NotBroadcastable,
    OpenForReview,
    PartialWrite,
    ReadOnlyRegister,
    TransportError,
    UnsupportedFunction,
    ValueOutOfRange,
    WriteOnlyRegister,
    WrongPage,
)
from drivemap.runtime.spec import READ_CODES, DeviceSpec, PageSpec, RegisterSpec

log = logging.getLogger("drivemap")

T = TypeVar("T")
PagePolicy = Literal["raise", "switch"]

# ----------------------------------------------------------------------------- core
class Core:
    """Per-client protocol state and the operations, as generators of exchanges."""

    def __init__(self, spec: DeviceSpec, unit: int, exceptions: Mapping[int, type[DeviceException]],
                 page_policy: PagePolicy, broadcast: bool, stats: Stats | None = None) -> None:
        if not isinstance(page_policy, str) or page_policy not in ("raise", "switch"):
            raise InvalidArgument(f"page_policy must be 'raise' or 'switch', not {page_policy!r}")
        self.spec = spec
        self.unit = unit
        self.exceptions = exceptions
        self.page_policy = page_policy
        self.broadcast = broadcast
        self.stats = stats if stats is not None else Stats()
        self.tables = spec_tables(spec)
        self.pages: dict[str, int] = {}  # selector -> value it is known to show
        #: while read_all visits pages under page_policy "raise": selector -> the value it showed before
        self._visiting: dict[str, int] | None = None
        self.pending_configuration: list[str] = []
        self.pending_power_cycle: list[str] = []
        #: words (bits) the device refused on their own: (table, address)
        self.holes: set[Hole] = set()
        self._hole_plans: dict[frozenset[Key], tuple[ReadRequest, ...]] = {}
        self.review_warned: set[str] = set()  # registers open for review whose read warned (.review)

    # -- checks and replies
    def raise_for(self, reply: ModbusPDU | None, function: int) -> ModbusPDU:
        if reply is None:
            raise TransportError(f"no reply to function 0x{function:02X}")
        if reply.isError():
            code = reply.exception_code
            cls = self.exceptions.get(code, DeviceException)
            known = self.spec.protocol.exception(code)
            raise cls(code, function, name=known.name if known else None, meaning=known.meaning if known else None)
        return reply

    def exchange(self, pdu: ModbusPDU, hold_ms: float = 0.0) -> Exchange:
        return Exchange(self.unit, pdu, self.spec.protocol.timing, not self.broadcast, hold_ms)

    def plan_with_holes(self, keys: Iterable[Key]) -> tuple[ReadRequest, ...]:
        """The plan for ``keys`` that avoids this client's holes (cached until a new hole is found)."""
        wanted = frozenset(keys)
        plan = self._hole_plans.get(wanted)
        if plan is None:
            plan = self._hole_plans[wanted] = plan_reads(self.spec, wanted, self.holes)
        return plan

    def _add_holes(self, table: str, start: int, end: int) -> None:
        new = {(table, a) for a in range(start, end)} - self.holes
        if new:
            self.holes.update(new)
            self._hole_plans.clear()
            log.info("unit %d: the device refuses %s address(es) %s; later reads do not span them", self.unit,
                     table, ", ".join(f"0x{a:04X}" for _, a in sorted(new)))

    # -- pages
    def _page_ops(self, page: PageSpec | None) -> Op[None]:
        if page is None:
            return
        current = self.pages.get(page.selector)
        if current == page.value:
            return
        sel = self.spec.register(page.selector)
        if self.page_policy == "switch":
            yield from self._write_words(sel, sel.address, raw_to_words(sel, page.value),
                                         hold_ms=sel.write_delay_ms or 0)
            self.pages[page.selector] = page.value
            return
        if current is None and not self.broadcast and sel.readable:
            words = yield from self._read_words(sel.table, sel.address, sel.words)
            current = self.pages[page.selector] = words_to_raw(sel, words)
            if current == page.value:
                return
        if self._visiting is not None and current is not None and sel.writable:  # read_all: visit, restore later
            self._visiting.setdefault(page.selector, current)
            yield from self._write_words(sel, sel.address, raw_to_words(sel, page.value),
                                         hold_ms=sel.write_delay_ms or 0)
            self.pages[page.selector] = page.value
            return
        raise WrongPage(f"{page.selector} shows page {current}, not {page.value} (use page_policy='switch', or "
                        "read_all(), which visits each page and puts the selector back)")

    def _read_words(self, table: str, address: int, count: int) -> Op[list[int]]:
        refuse_misaligned(self.spec, table, address, count, "read")
        code = READ_CODES[table]
        if code not in self.tables.read_codes:
            raise UnsupportedFunction(f"the map does not list {code:02X}h (read {table})")
        reply = yield Exchange(self.unit, READ_REQUESTS[code](address=address, count=count), self.spec.protocol.timing,
                               expect_reply=not self.broadcast)
        if reply is None or reply.isError():
            reply = self.raise_for(reply, code)
        return reply_words(reply, code, address, count)

    def _write_request(self, table: str, address: int, words: list[int]) -> tuple[ModbusPDU, int]:
        """The write request for ``words`` at ``address`` (the single-write function for one word or
        coil where possible, else the multiple write)."""
        refuse_misaligned(self.spec, table, address, len(words), "write")
        t = self.tables
        coil = table == "coil"
        single, multiple = (t.fc05, t.fc0f) if coil else (t.fc06, t.fc10)
        if len(words) == 1 and single is not None and (not self.broadcast or single.broadcast):
            if coil:
                return WriteSingleCoilRequest(address=address, bits=[bool(words[0])]), 0x05
            return WriteSingleRegisterRequest(address=address, registers=words), 0x06
        if multiple is not None and (not self.broadcast or multiple.broadcast):
            if coil:
                return WriteMultipleCoilsRequest(address=address, bits=[bool(w) for w in words]), 0x0F
            return WriteMultipleRegistersRequest(address=address, registers=words), 0x10
        what = "coil(s)" if coil else "word(s)"
        raise UnsupportedFunction(f"no function code of the map writes {len(words)} {what} here")

    def _write_words(self, reg: RegisterSpec, address: int, words: list[int], hold_ms: float = 0.0) -> Op[None]:
        """One write request to ``reg``'s table."""
        pdu, code = self._write_request(reg.table, address, words)
        reply = yield self.exchange(pdu, hold_ms)
        if not self.broadcast:
            self.raise_for(reply, code)

    # -- reads
    def check_readable(self, keys: Iterable[Key]) -> None:
        if self.broadcast:
            raise BroadcastRead("a broadcast client cannot read (nobody answers a broadcast)")
        readable = self.tables.readable
        for name, _ in keys:
            if name not in readable:
                self.spec.register(name)  # KeyError for a name the map does not have
                raise WriteOnlyRegister(f"{name} is write-only")
        if self.tables.read_review:
            warn_review(self, keys)

    def read_raw(self, keys: Sequence[Key], plan: tuple[ReadRequest, ...], *,
                 checked: bool = False) -> Op[dict[Key, int]]:
        """Read ``keys`` with ``plan``; ``checked``: the caller has already run :meth:`check_readable`."""
        if not checked:
            self.check_readable(keys)
        tables = self.tables
        read_codes = tables.read_codes
        unit, timing, expect_reply = self.unit, self.spec.protocol.timing, not self.broadcast
        out: dict[Key, int] = {}
        for req in plan:
            if req.page is not None:
                yield from self._page_ops(req.page)
            code = req.code
            if code not in read_codes:
                raise UnsupportedFunction(f"the map does not list {code:02X}h (read {req.table})")
            refuse_misaligned(self.spec, req.table, req.address, req.count, "read")
            reply = yield Exchange(unit, READ_REQUESTS[code](address=req.address, count=req.count), timing,
                                   expect_reply)
            if reply is None or reply.isError():
                if reply is not None and reply.exception_code == ILLEGAL_ADDRESS and len(req.units) > 1:
                    self.stats.split_reads += 1
                    yield from self._split(req, out)
                    continue
                reply = self.raise_for(reply, code)
            self._decode(req, reply.registers if code > 2 else reply_words(reply, code, req.address, req.count),
                         out)
        return out

    def read_visiting_pages(self, keys: Sequence[Key], plan: tuple[ReadRequest, ...]) -> Op[dict[Key, int]]:
        """:meth:`read_raw` for ``read_all``: under page_policy "raise", switch to each page the plan
        needs and afterwards (also after a failure) write every selector back to the page it showed."""
        if self.page_policy == "switch" or self.broadcast or all(req.page is None for req in plan):
            return (yield from self.read_raw(keys, plan, checked=True))
        original: dict[str, int] = {}
        self._visiting = original
        try:
            out = yield from self.read_raw(keys, plan, checked=True)
        except DriveError:
            self._visiting = None
            yield from self._restore_pages(original)  # its own failure is raised with this one as context
            raise
        finally:
            self._visiting = None
        yield from self._restore_pages(original)
        return out

    def _restore_pages(self, original: Mapping[str, int]) -> Op[None]:
        for selector, value in original.items():
            if self.pages.get(selector) == value:
                continue
            sel = self.spec.register(selector)
            self.pages.pop(selector, None)  # unknown until the write is confirmed
            yield from self._write_words(sel, sel.address, raw_to_words(sel, value), hold_ms=sel.write_delay_ms or 0)
            self.pages[selector] = value

    def _decode(self, req: ReadRequest, words: Sequence[int], out: dict[Key, int]) -> None:
        """The raw value of every cell of ``req`` from the reply's words (bits as 0/1)."""
        count = req.count
        if len(words) != count:
            raise TransportError(f"asked {count} registers at 0x{req.address:04X}, got {len(words)}")
        decode = self.tables.decode
        pages = self.pages
        for key, offset in req.cells:
            size, signed, low_first, selector, general = decode[key[0]]
            if general is not None:
                raw = words_to_raw(general, words[offset:offset + size])
            elif size == 1:
                raw = words[offset]
                if signed and raw & 0x8000:
                    raw -= 0x10000
            else:
                first, second = words[offset], words[offset + 1]
                raw = (second << 16) | first if low_first else (first << 16) | second
                if signed and raw & 0x80000000:
                    raw -= 0x100000000
            out[key] = raw
            if selector:
                pages[key[0]] = raw

    def _split(self, req: ReadRequest, out: dict[Key, int]) -> Op[bool]:
        """Read ``req``'s units in two halves after the device refused them together (02h).

        Returns whether a part was refused again; when neither half is, the words between them
        (a gap the request read across) are what the device refused.
        """
        left, right = split_units(req)
        refused = False
        for part in (left, right):
            refused = (yield from self._read_part(request_for(req, part), out)) or refused
        if not refused and right[0].address > left[-1].end:
            self._add_holes(req.table, left[-1].end, right[0].address)
        return True

    def _read_part(self, req: ReadRequest, out: dict[Key, int]) -> Op[bool]:
        """One part of a split read; returns whether the device refused it."""
        self.stats.extra_requests += 1
        reply = yield Exchange(self.unit, READ_REQUESTS[req.code](address=req.address, count=req.count),
                               self.spec.protocol.timing, not self.broadcast)
        if reply is not None and reply.isError() and reply.exception_code == ILLEGAL_ADDRESS:
            if len(req.units) > 1:
                yield from self._split(req, out)
                return True
            unit: Unit = req.units[0]
            self._add_holes(req.table, unit.address, unit.end)
            if req.cells:  # an element the caller asked for is unreadable on its own
                self.raise_for(reply, req.code)
            return True
        reply = self.raise_for(reply, req.code)
        self._decode(req, reply.registers if req.code > 2 else reply_words(reply, req.code, req.address, req.count),
                     out)
        return False

    # -- writes
    @staticmethod
    def not_the_command(reg: RegisterSpec, key: Key, raw: object) -> ValueOutOfRange:
        """A command register written with another value than the map's command value."""
        return ValueOutOfRange(f"{reg.element_name(key[1])} is a command: only {reg.command_value} may be written "
                               f"(use .execute()), not {raw!r}")

    def check_write(self, key: Key) -> RegisterSpec:
        reg = self.spec.register(key[0])
        if not reg.writable:
            raise ReadOnlyRegister(f"{reg.element_name(key[1])} is read-only")
        if reg.review and reg.open_for_writes:
            raise OpenForReview(reg.name, reg.open_for_writes)
        if self.broadcast and not reg.broadcast:
            raise NotBroadcastable(f"{reg.element_name(key[1])} may not be written by broadcast")
        refuse_misaligned(self.spec, reg.table, reg.element_address(key[1]), reg.words, "write")
        return reg

    def _resolve(self, items: Sequence[RawItem]) -> Op[list[tuple[Key, int]]]:
        """Raw values of deferred (scaled) items: their scale factors are read first, never remembered."""
        needed = sorted({item.codec.scale_key for _, item in items
                         if isinstance(item, Deferred) and item.codec.scale_key is not None})
        for key, _ in items:
            self.check_write(key)
        self.check_readable(needed)
        factors = yield from self.read_raw(needed, self.plan_with_holes(needed), checked=True)
        out: list[tuple[Key, int]] = []
        for key, item in items:
            if isinstance(item, Deferred):
                scale = item.codec.scale_key
                out.append((key, item.encode(None if scale is None else factors.get(scale))))
            else:
                out.append((key, item))
        return out

    def write_raw(self, items: Sequence[RawItem]) -> Op[None]:
        """Write raw values, contiguous runs in one multiple-write request where the map allows it.

        Requests go out in the order the items are given (a drive may need "set the frequency, then
        run"; an item joins the previous request only when it continues it) and stop at the first failure. When the write needed
        several requests, that failure is raised as :class:`PartialWrite` (written / unconfirmed /
        not written elements); a single request raises its own error (all or nothing).
        """
        if len(items) == 1:  # one element: one request, all or nothing (the common case, kept lean)
            key, item = items[0]
            if isinstance(item, Deferred):
                key, raw = (yield from self._resolve(items))[0]
            else:
                raw = item
            reg = self.check_write(key)
            if reg.command_value is not None and raw != reg.command_value:
                raise self.not_the_command(reg, key, raw)
            words = raw_to_words(reg, raw)
            if len(words) > 1 and self._limit(reg.table) == 0:
                raise UnsupportedFunction(f"{reg.name}: the map has no multiple write for a multi-word value")
            if reg.running_advice is not None:
                yield from self._advise_if_running([(reg, key)])
            if reg.page is not None:
                yield from self._page_ops(reg.page)
            pdu, code = self._write_request(reg.table, reg.element_address(key[1]), words)  # _write_words, inlined
            reply = yield Exchange(self.unit, pdu, self.spec.protocol.timing, not self.broadcast, reg.write_delay_ms or 0.0)
            if not self.broadcast:
                self.raise_for(reply, code)
            self._after_write(reg, key, int(raw))  # raw fits its type (raw_to_words checked): the words' value
            return
        if any(isinstance(item, Deferred) for _, item in items):
            resolved: Sequence[tuple[Key, int]] = yield from self._resolve(items)
        else:
            resolved = items  # type: ignore[assignment]
        groups = self._groups(resolved)
        advised = [(reg, key) for group in groups for reg, key, _ in group if reg.running_advice is not None]
        if advised:
            yield from self._advise_if_running(advised)
        yield from self._write_groups(groups)

    def _advise_if_running(self, items: Sequence[tuple[RegisterSpec, Key]]) -> Op[None]:
        """The map's running_advice: read its running_state register and warn if the drive runs
        (:mod:`drivemap.runtime.client.protocol.advice`); never refuses. A broadcast client cannot read: no check."""
        state = self.spec.protocol.running_state
        if state is None or self.broadcast:
            return
        sel = self.spec.register(state.register)
        yield from self._page_ops(sel.page)
        words = yield from self._read_words(sel.table, sel.address, sel.words)
        warn_if_running(self.spec, [(reg, reg.element_name(key[1])) for reg, key in items], words_to_raw(sel, words))

    def _limit(self, table: str) -> int:
        """Largest multiple write of ``table`` this client may send (0: none)."""
        t = self.tables
        multiple = t.fc0f if table == "coil" else t.fc10
        if self.broadcast and not (multiple and multiple.broadcast):
            return 0
        return t.write_limits.get(table, 0)

    def _groups(self, items: Sequence[tuple[Key, int]]) -> list[list[tuple[RegisterSpec, Key, list[int]]]]:
        """Items in the order given; an item that continues the previous one (same table and page, the
        next address, within the write limit) joins its request."""
        regs = [(reg, key, raw_to_words(reg, raw)) for key, raw in items for reg in (self.check_write(key),)]
        for (key, raw), (reg, _, _) in zip(items, regs, strict=True):
            if reg.command_value is not None and raw != reg.command_value:
                raise self.not_the_command(reg, key, raw)
        groups: list[list[tuple[RegisterSpec, Key, list[int]]]] = []
        for item in regs:
            reg, key, words = item
            if groups:
                last_reg, last_key, _ = groups[-1][-1]
                start = groups[-1][0][0].element_address(groups[-1][0][1][1])
                end = last_reg.element_address(last_key[1]) + last_reg.words
                if (reg.table == last_reg.table and reg.element_address(key[1]) == end and reg.page == last_reg.page
                        and end + reg.words - start <= self._limit(reg.table)):
                    groups[-1].append(item)
                    continue
            groups.append([item])
        for group in groups:
            for reg, _key, words in group:
                if len(words) > 1 and self._limit(reg.table) == 0:
                    raise UnsupportedFunction(f"{reg.name}: the map has no multiple write for a multi-word value")
        return groups

    def _write_groups(self, groups: list[list[tuple[RegisterSpec, Key, list[int]]]]) -> Op[None]:
        written: list[str] = []
        for number, group in enumerate(groups):
            reg0, key0, _ = group[0]
            sending = False
            try:
                yield from self._page_ops(reg0.page)
                words = [w for _, _, ws in group for w in ws]
                hold = max((r.write_delay_ms or 0.0) for r, _, _ in group)
                sending = True
                yield from self._write_words(reg0, reg0.element_address(key0[1]), words, hold)
            except DriveError as exc:
                if len(groups) == 1:
                    raise  # one request: all or nothing, the error says which
                names = [[r.element_name(k[1]) for r, k, _ in g] for g in groups]
                unsure = sending and isinstance(exc, TransportError)
                raise PartialWrite(
                    exc, written=tuple(written), maybe_written=tuple(names[number]) if unsure else (),
                    not_written=tuple(n for g in names[number + (1 if unsure else 0):] for n in g),
                ) from exc
            for reg, key, ws in group:
                self._after_write(reg, key, words_to_raw(reg, ws))
                written.append(reg.element_name(key[1]))

    def _after_write(self, reg: RegisterSpec, key: Key, raw: int) -> None:
        if reg.name in self.tables.selectors:
            self.pages[reg.name] = raw
        reflect = reg.reflect
        if reflect != "configuration" and reflect != "power_cycle":
            return
        name = reg.element_name(key[1])
        if reflect == "configuration" and name not in self.pending_configuration:
            self.pending_configuration.append(name)
        elif reflect == "power_cycle" and name not in self.pending_power_cycle:
            self.pending_power_cycle.append(name)
            log.warning("%s: written; takes effect after the drive is powered off and on again", name)

    def apply_configuration(self) -> Op[None]:
        if self.spec.protocol.configuration is None:
            raise UnsupportedFunction("the map defines no configuration command")
        name, value = self.spec.protocol.configuration.register, self.spec.protocol.configuration.value
        reg = self.spec.register(name)
        self.check_write((name, 0))
        yield from self._page_ops(reg.page)
        yield from self._write_words(reg, reg.address, raw_to_words(reg, value), reg.write_delay_ms or 0.0)
        self.pending_configuration.clear()

    def loopback(self, data: int) -> Op[int]:
        if self.spec.protocol.function(0x08) is None:
            raise UnsupportedFunction("the map does not list 08h (diagnostics / loopback)")
        if not isinstance(data, int) or isinstance(data, bool) or not 0 <= data <= 0xFFFF:
            raise InvalidValue("loopback data must be an int 0..0xFFFF")
        if self.broadcast:
            raise BroadcastRead("loopback needs a reply; a broadcast client cannot ask for one")
        reply = self.raise_for((yield self.exchange(ReturnQueryDataRequest(message=data))), 0x08)
        echoed = getattr(reply, "message", None)
        value = int.from_bytes(echoed, "big") if isinstance(echoed, bytes) else echoed
        if value != data:
            raise TransportError(f"loopback echoed {value!r}, sent {data:#06x}")
        return data


__all__ = ["Core", "Deferred", "Op", "PagePolicy", "READ_REQUESTS", "RawItem", "SpecTables", "arun", "arun_replay",
           "run", "run_replay", "spec_tables"]
