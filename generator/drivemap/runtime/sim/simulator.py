"""The simulator core: a register store per unit id and the device's Modbus dialect.

Everything here is read from a :class:`~drivemap.runtime.spec.DeviceSpec` (the generated
``SPEC``), never from a map: the exception code of each error case (``exception_policy``), the
communication error codes a device records (``comm_error_policy``, ``comm_error_history``), which
function codes exist and which may be broadcast, register access, ranges, pages and storage.

Tables: holding registers answer 03h/06h/10h, input registers 04h, coils 01h/05h/0Fh, discrete
inputs 02h, each its own address space. Reserved ranges the map marks readable read as 0, and so do
undocumented words in a gap of at most the map's ``max_gap`` words between documented ones (the map
says the device reads across them); a read that covers part of a ``min_read`` block is refused like
an unknown address.

The core works on PDUs (function code + data) and knows nothing about transports;
:mod:`drivemap.runtime.sim.serve` puts it behind a pymodbus server (TCP, RTU, ASCII).
Behaviour (what a drive does when it is told to run) lives in :mod:`drivemap.runtime.sim.behaviours`.

Error cases and what the simulator answers (the code comes from the map's exception_policy):

``illegal_function``  function code not listed in the map (or an 08h sub-function other than 0000h)
``illegal_address``   an address that is neither a register nor a readable reserved address;
                      a write to a reserved address; a write that covers only part of a multi-word
                      register; a read that covers only part of a ``min_read`` block
``illegal_quantity``  quantity 0 or above the function code's ``max_quantity``
``bad_length``        a PDU whose length does not fit its function (10h byte count != 2 x quantity)
``out_of_range``      a written value outside the register's type, min/max or enum values
``read_only``         a write to a register without ``w`` access
``write_only``        a read of a register without ``r`` access
``busy``              a write to a ``refuse_while_running`` register while the behaviour says running;
                      with ``refuse_advised_while_running=True`` (opt-in, off by default) also a write
                      to a register that only carries the manual's ``running_advice``

A case the map leaves out falls back to a related case (write_only/read_only -> illegal_address,
bad_length -> illegal_quantity, busy -> out_of_range) and then to the standard Modbus code
(01h, 02h, 03h, 03h, 02h, 02h, 06h, 03h). A case whose code is ``null`` gets no reply.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from drivemap.runtime.alignment import violation
from drivemap.runtime.client.transport.quirks import encode_read_reply
from drivemap.runtime.sim import state as simstate
from drivemap.runtime.sim.cells import ReadPlan, Refused, Slot, cell_names, gap_words, packer, swapped, word_shift
from drivemap.runtime.sim.dialect import CASES, FALLBACK, READ_TABLES, STANDARD_CODES, STANDARD_MAX_QUANTITY
from drivemap.runtime.sim.persist import Persistence, StateFileError
from drivemap.runtime.sim.unit import SimulatorError, SimValue, Unit
from drivemap.runtime.sim.writes import WriteRequests
from drivemap.runtime.spec import BitSpec, DeviceSpec, PageSpec, RegisterSpec

if TYPE_CHECKING:
    from drivemap.runtime.sim.behaviours import Behaviour

__all__ = [
    "CASES",
    "STANDARD_CODES",
    "SimValue",
    "Simulator",
    "SimulatorError",
    "StateFileError",
    "Unit",
]

#: Standard Modbus exception code of every error case (used when the map names no code).
#: Read plans kept per simulator (table, address, quantity, page state); the cache starts over when full.
_MAX_READ_PLANS = 4096
class Simulator(WriteRequests, Persistence):
    """A simulated device: one register store per unit id, answering in the device's dialect.

    ``handle(unit_id, pdu)`` takes a request PDU (function code + data) and returns the response
    PDU, or ``None`` when the device stays silent (another unit's request, a broadcast, an error
    case the device does not answer). All methods are thread-safe.
    """

    def __init__(
        self,
        spec: DeviceSpec,
        units: Sequence[int] = (1,),
        *,
        behaviour: Behaviour | None = None,
        state_file: str | os.PathLike[str] | None = None,
        realistic_timing: bool = False,
        refuse_advised_while_running: bool = False,
        reply_quirks: Sequence[str] = (),
        presets: Sequence[tuple[str, SimValue]] = (),
    ) -> None:
        """``presets``: (cell name, engineering value) the memory holds at power-up, on every unit
        (after the state file, before the behaviour's start-up). ``refuse_advised_while_running``: also answer ``busy`` to writes the manual only advises
        against while running (``running_advice``); off by default, since the manual does not say
        the device refuses them (the client warns instead). ``reply_quirks``: answer in these
        non-standard forms of the map's ``reply_quirks`` (e.g. ``two_byte_byte_count``, as a
        manual prints a reply) instead of the standard one; none by default."""
        if behaviour is None:
            from drivemap.runtime.sim.behaviours import Behaviour

            behaviour = Behaviour()
        self.spec = spec
        self.behaviour = behaviour
        self.realistic_timing = realistic_timing
        self.refuse_advised_while_running = refuse_advised_while_running
        self.reply_quirks = tuple(dict.fromkeys(reply_quirks))
        for quirk in self.reply_quirks:
            if quirk not in spec.protocol.quirks:
                raise SimulatorError(f"{spec.name}: the map lists no reply quirk {quirk!r} "
                                     f"(it lists: {', '.join(spec.protocol.quirks) or 'none'})")
        self.state_file = Path(state_file) if state_file is not None else None
        self._lock = threading.RLock()
        self._dirty = False
        self._build_index(spec)
        unit_ids = list(dict.fromkeys(int(u) for u in units))
        if not unit_ids:
            raise SimulatorError("a simulator needs at least one unit id")
        for uid in unit_ids:
            if not spec.protocol.valid_unit(uid):
                raise SimulatorError(f"unit id {uid} is outside {spec.protocol.unit_min}..{spec.protocol.unit_max} of {spec.name}")
        self.units: dict[int, Unit] = {uid: Unit(self, uid) for uid in unit_ids}
        self._state: simstate.StateFile | None = None
        if self.state_file is not None:
            self._load_state(self.state_file)
        self._apply_presets(presets)
        for unit in self.units.values():
            self.behaviour.on_start(unit)
        self._dirty = False

    def _build_index(self, spec: DeviceSpec) -> None:
        """Which cell each word of each table belongs to, the pages, blocks and gaps (see :mod:`.cells`)."""
        self._regs: dict[str, RegisterSpec] = {}
        self._cells: dict[str, tuple[RegisterSpec, int]] = {}
        self._by_address: dict[tuple[str, int], list[Slot]] = {}
        for reg in spec.registers:
            self._regs[reg.name] = reg
            for name, index in cell_names(reg):
                self._cells[name] = (reg, index)
                start = reg.element_address(index)
                for word in range(reg.words):
                    self._by_address.setdefault((reg.table, start + word), []).append(Slot(name, reg, index, word))
        # (table, address) -> its slot when the first register there has no page (it always wins _resolve)
        self._static: dict[tuple[str, int], Slot] = {a: slots[0] for a, slots in self._by_address.items()
                                                      if slots[0].reg.page is None}
        # min_read blocks: (table, start, end); words inside that no register covers read as 0
        self._blocks = tuple((r.table, r.address, r.address + r.min_read) for r in spec.registers
                             if r.min_read is not None)
        self._gap_words = gap_words(spec, frozenset(self._by_address) | frozenset(
            (r.table, a) for r in spec.reserved for a in range(r.start, r.end + 1)))
        # every selector a page depends on: the page state of a unit is their values
        self._selectors: tuple[str, ...] = tuple(sorted(
            {r.page.selector for r in spec.registers if r.page is not None}
            | {r.page.selector for r in spec.reserved if r.page is not None}))
        # (table, address, quantity, page state) -> read plan (see _read_plan)
        self._read_plans: dict[tuple[str, int, int, tuple[int, ...]], ReadPlan | str] = {}

    def _apply_presets(self, presets: Sequence[tuple[str, SimValue]]) -> None:
        """The power-up values asked for, on every unit (checked against the map like a write)."""
        for name, value in presets:
            self.check_cell(name)
            for unit in self.units.values():
                unit.set(name, value)
                unit.unset.discard(name)
                if name in unit.applied:
                    unit.applied[name] = unit.values[name]

    # ==== public API ========================================================================
    @property
    def unit_ids(self) -> list[int]:
        return list(self.units)

    def unit(self, unit_id: int | None = None) -> Unit:
        """One unit (the first when ``unit_id`` is None)."""
        if unit_id is None:
            return next(iter(self.units.values()))
        try:
            return self.units[unit_id]
        except KeyError:
            raise SimulatorError(f"unit {unit_id} is not simulated (units: {self.unit_ids})") from None

    def _targets(self, unit: int | None) -> list[Unit]:
        return list(self.units.values()) if unit is None else [self.unit(unit)]

    def set(self, name: str, value: SimValue, unit: int | None = None) -> None:
        """Preset a register (engineering value: a number, text, true/false, None for the first
        not-available value) on one unit or, by default, on every unit.

        A preset is the device's state, not a Modbus write: no dialect checks, no behaviour hook;
        configuration-class registers are set as already applied.
        """
        with self._lock:
            for target in self._targets(unit):
                target.set(name, value)
                if name in target.applied:
                    target.applied[name] = target.values[name]
            self._save_if_dirty()

    def set_raw(self, name: str, raw: int, unit: int | None = None) -> None:
        """Preset a register's raw value (see :meth:`set`)."""
        with self._lock:
            for target in self._targets(unit):
                target.set_raw(name, raw)
                if name in target.applied:
                    target.applied[name] = target.values[name]
            self._save_if_dirty()

    def get(self, name: str, unit: int | None = None) -> SimValue:
        """Engineering value of a register on one unit (the first by default); None for a not-available value."""
        with self._lock:
            return self.unit(unit).get(name)

    def get_raw(self, name: str, unit: int | None = None) -> int:
        with self._lock:
            return self.unit(unit).raw(name)

    def inject_exception(self, code: int, unit: int | None = None) -> None:
        """Answer the next request (to ``unit``, or to any simulated unit) with exception ``code``.

        One-shot: the request is not executed; later requests are served normally.
        """
        if not 0 <= code <= 0xFF:
            raise SimulatorError(f"exception code {code} is not a byte")
        with self._lock:
            for target in self._targets(unit):
                target.injected = code

    def tick(self, dt: float) -> None:
        """Let ``dt`` seconds of device time pass (behaviour ``on_tick`` on every unit)."""
        with self._lock:
            for unit in self.units.values():
                self.behaviour.on_tick(unit, dt)
            self._save_if_dirty()

    def advance(self, seconds: float, step: float = 0.01) -> None:
        """Run :meth:`tick` in steps of ``step`` for ``seconds`` (deterministic tests)."""
        steps = max(1, math.ceil(seconds / step - 1e-9))
        for _ in range(steps):
            self.tick(seconds / steps)

    def reply_delay(self) -> float:
        """Seconds the real device needs before it answers (0 unless realistic timing is on).

        The map's processing time (midpoint of min..max); without one, its inter-frame gap
        (v2/edx: a reply comes no sooner than 10 ms after the request).
        """
        if not self.realistic_timing:
            return 0.0
        t = self.spec.protocol.timing
        if t.processing_ms is not None:
            return (t.processing_ms[0] + t.processing_ms[1]) / 2000.0
        if t.inter_frame_gap_ms is not None:
            return t.inter_frame_gap_ms / 1000.0
        return 0.0

    def frame_error(self, unit_id: int | None) -> None:
        """A frame with a bad CRC/LRC or a broken format arrived: no reply; record it if the map says so."""
        with self._lock:
            unit = self.units.get(unit_id) if unit_id is not None else None
            if unit is not None:
                self._record(unit, "bad_frame")

    def save_state(self) -> None:
        """Write EEPROM-class registers to the state file now (atomically)."""
        with self._lock:
            if self.state_file is not None:
                self._write_state(self.state_file)
                self._dirty = False

    def exception_code(self, case: str) -> int | None:
        """The code this device answers for an error case (None: no reply)."""
        seen: set[str] = set()
        current: str | None = case
        while current is not None and current not in seen:
            seen.add(current)
            for item in self.spec.protocol.exception_policy:
                if item.case == current:
                    return item.code
            current = FALLBACK.get(current)
        return STANDARD_CODES[case]

    # ==== request handling ====================================================================
    def handle(self, unit_id: int, pdu: bytes, *, always_answer: bool = False) -> bytes | None:
        """Serve one request PDU addressed to ``unit_id``; the response PDU or None (no reply).

        ``always_answer`` (Modbus TCP): an error case the map leaves unanswered (code null: right on
        a serial line) gets the Modbus standard code instead of silence. Other units and broadcasts
        still get no reply.
        """
        if not pdu:
            return None
        with self._lock:
            try:
                if self.spec.protocol.broadcast_address is not None and unit_id == self.spec.protocol.broadcast_address:
                    for each in self.units.values():
                        self.behaviour.on_request(each)
                    self._broadcast(pdu)
                    return None
                unit = self.units.get(unit_id)
                if unit is None:
                    return None
                self.behaviour.on_request(unit)
                injected = unit.injected
                if injected is not None:
                    for other in self.units.values():
                        if other.injected == injected:
                            other.injected = None
                    return bytes([pdu[0] | 0x80, injected])
                try:
                    return self._serve(unit, pdu[0], pdu[1:], broadcast=False)
                except Refused as refused:
                    self._record(unit, refused.case)
                    answer = refused.code if refused.code is not None else self.exception_code(refused.case)
                    if answer is None and always_answer:
                        answer = STANDARD_CODES[refused.case]
                    return None if answer is None else bytes([pdu[0] | 0x80, answer])
            finally:
                self._save_if_dirty()

    def _broadcast(self, pdu: bytes) -> None:
        fc = self.spec.protocol.function(pdu[0])
        if fc is None or fc.broadcast is not True or pdu[0] not in (0x05, 0x06, 0x0F, 0x10):
            return  # the device ignores broadcast requests it cannot execute
        for unit in self.units.values():
            try:
                self._serve(unit, pdu[0], pdu[1:], broadcast=True)
            except Refused as refused:
                self._record(unit, refused.case)

    def _record(self, unit: Unit, case: str) -> None:
        for item in self.spec.protocol.comm_error_policy:
            if item.case == case:
                if item.code is not None:
                    unit.record_comm_error(item.code)
                return

    def _serve(self, unit: Unit, code: int, data: bytes, *, broadcast: bool) -> bytes:
        fc = self.spec.protocol.function(code)
        if fc is None:
            raise Refused("illegal_function")
        if code in (0x03, 0x04):
            return self._read(unit, fc.code, fc.max_quantity, data)
        if code in (0x01, 0x02):
            return self._read_bits(unit, fc.code, fc.max_quantity, data)
        if code == 0x06:
            return self._write_single(unit, data, broadcast)
        if code == 0x10:
            return self._write_multiple(unit, fc.max_quantity, data, broadcast)
        if code == 0x05:
            return self._write_coil(unit, data, broadcast)
        if code == 0x0F:
            return self._write_coils(unit, fc.max_quantity, data, broadcast)
        if code == 0x08:
            return self._loopback(data)
        raise Refused("illegal_function")

    def _max_quantity(self, code: int, limit: int | None) -> int:
        return limit if limit is not None else STANDARD_MAX_QUANTITY.get(code, 125)

    def _read_request(self, code: int, limit: int | None, data: bytes) -> tuple[int, int]:
        """(address, quantity) of a read request, checked."""
        if len(data) != 4:
            raise Refused("bad_length")
        address = int.from_bytes(data[0:2], "big")
        quantity = int.from_bytes(data[2:4], "big")
        if not 1 <= quantity <= self._max_quantity(code, limit):
            raise Refused("illegal_quantity")
        if address + quantity > 0x10000:
            raise Refused("illegal_address")
        return address, quantity

    def _plan(self, unit: Unit, table: str, address: int, quantity: int) -> ReadPlan:
        selectors = self._selectors
        state = tuple(unit.values.get(sel, 0) for sel in selectors) if selectors else ()
        plan = self._read_plans.get((table, address, quantity, state))
        if plan is None:
            plan = self._read_plan(unit, table, address, quantity)
            if len(self._read_plans) >= _MAX_READ_PLANS:
                self._read_plans.clear()
            self._read_plans[(table, address, quantity, state)] = plan
        if isinstance(plan, str):
            raise Refused(plan)
        return plan

    def _aligned(self, table: str, address: int, quantity: int, operation: str) -> None:
        """Refuse a request that breaks an alignment rule of the map with the rule's exception code."""
        broken = violation(self.spec, table, address, quantity, operation) if self.spec.protocol.alignment else None
        if broken is not None:
            raise Refused("illegal_address", broken[0].exception)

    def _read(self, unit: Unit, code: int, limit: int | None, data: bytes) -> bytes:
        address, quantity = self._read_request(code, limit, data)
        self._aligned(READ_TABLES[code], address, quantity, "read")
        cells, words, swapping = self._plan(unit, READ_TABLES[code], address, quantity)
        self.behaviour.on_read(unit, list(cells))
        values = unit.values
        if swapping:
            body = packer(quantity)(*[0 if cell is None else swapped((values[cell] >> shift) & 0xFFFF, swap)
                                       for cell, shift, swap in words])
        else:
            body = packer(quantity)(*[0 if cell is None else (values[cell] >> shift) & 0xFFFF
                                       for cell, shift, _ in words])
        if self.reply_quirks:
            return encode_read_reply(code, body, self.reply_quirks)
        return bytes((code, 2 * quantity)) + body

    def _read_bits(self, unit: Unit, code: int, limit: int | None, data: bytes) -> bytes:
        address, quantity = self._read_request(code, limit, data)
        cells, words, _ = self._plan(unit, READ_TABLES[code], address, quantity)
        self.behaviour.on_read(unit, list(cells))
        values = unit.values
        packed = bytearray((quantity + 7) // 8)
        for i, (cell, _, _) in enumerate(words):
            if cell is not None and values[cell]:
                packed[i // 8] |= 1 << (i % 8)
        return bytes((code, len(packed))) + bytes(packed)

    def _read_plan(self, unit: Unit, table: str, address: int, quantity: int) -> ReadPlan | str:
        """What a read of ``quantity`` words at ``address`` of ``table`` returns in the unit's current pages.

        Either the refusal case or (cells read, per word (cell or None for a 0, shift, swap)).
        Depends only on the spec and the values of the page selectors, so it is cached per page state.
        """
        end = address + quantity
        for btable, start, stop in self._blocks:
            if btable == table and start < end and address < stop and not (address <= start and stop <= end):
                return "illegal_address"  # part of a block the device only reads whole
        words: list[tuple[str | None, int, bool]] = []
        for addr in range(address, end):
            slot = self._resolve(unit, table, addr)
            if slot is None:
                if not self._reads_as_zero(unit, table, addr):
                    return "illegal_address"
                words.append((None, 0, False))
                continue
            if not slot.reg.readable:
                return "write_only"
            reg = slot.reg
            words.append((slot.cell, word_shift(reg, slot.word), reg.byte_order == "low_first" and not reg.bit_table))
        cells = tuple(dict.fromkeys(cell for cell, _, _ in words if cell is not None))
        return cells, tuple(words), any(swap for _, _, swap in words)

    # ==== addresses ===========================================================================
    def _page_ok(self, unit: Unit, page: PageSpec | None) -> bool:
        if page is None:
            return True
        return bool(unit.values.get(page.selector, 0) == page.value)

    def _resolve(self, unit: Unit, table: str, address: int) -> Slot | None:
        static = self._static.get((table, address))
        if static is not None:
            return static
        for slot in self._by_address.get((table, address), ()):
            if self._page_ok(unit, slot.reg.page):
                return slot
        return None

    def _reads_as_zero(self, unit: Unit, table: str, address: int) -> bool:
        """Reserved addresses the map marks readable answer 0, as do undocumented ones in a gap the
        map's max_gap lets the client read across or in a min_read block; other unknown or unreadable
        ones are refused."""
        if any(r.table == table and r.start <= address <= r.end and r.readable is True and self._page_ok(unit, r.page)
               for r in self.spec.reserved):
            return True
        if (table, address) in self._gap_words:
            return True
        return any(t == table and s <= address < e for t, s, e in self._blocks)

    def mark_dirty(self) -> None:
        """An EEPROM-class value changed: the state file is saved after the request."""
        self._dirty = True

    # ==== names ===============================================================================
    def check_cell(self, name: str) -> str:
        """``name`` if it is a cell of the device (an array's element, not the array), else SimulatorError."""
        if name not in self._cells:
            if name in self._regs:
                raise SimulatorError(f"{name} is an array; name an element, e.g. {name}[0]")
            raise SimulatorError(f"{self.spec.name} has no register {name!r}")
        return name

    def register_of(self, name: str) -> RegisterSpec:
        """The register (or array) that cell ``name`` belongs to."""
        return self._cells[self.check_cell(name)][0]

    def bit_of(self, name: str, bit: str) -> BitSpec:
        """The bit field ``bit`` of cell ``name``."""
        for spec in self.register_of(name).bits:
            if spec.name == bit:
                return spec
        raise SimulatorError(f"{name} has no bit {bit!r}")
