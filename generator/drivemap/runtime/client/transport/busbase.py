"""What the sync and async buses share (:class:`BusBase`): counters, frame logging, the timing
arithmetic per transaction shape, quiet times; the serial settings and the precise asyncio sleep.

The rules it implements are described in :mod:`drivemap.runtime.client.transport.bus`.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from typing import Any

from pymodbus.framer import FramerType
from pymodbus.pdu import ModbusPDU

from drivemap.runtime.client.transport import staleguard
from drivemap.runtime.client.transport.exchange import Exchange, Stats
from drivemap.runtime.errors import InvalidArgument
from drivemap.runtime.spec import SerialSpec, TimingSpec

log = logging.getLogger("drivemap")
_DEBUG = logging.DEBUG
clock = time.monotonic

#: Response timeout when the map gives none (seconds). Generous for slow drives at 9600 Bd.
DEFAULT_RESPONSE_TIMEOUT_S = 1.0
#: Retries after the first attempt when the map gives none.
DEFAULT_RETRIES = 2
#: Quiet time after a broadcast when the map gives none: the Modbus serial-line guide's
#: typical turnaround delay (Modbus over Serial Line v1.02, 2.4.1: 100 ms to 200 ms).
DEFAULT_BROADCAST_GAP_MS = 100.0
#: Baud rate used by ``serial()`` when neither the map nor the caller gives one (logged).
DEFAULT_BAUDRATE = 9600

_PARITY = {"none": "N", "even": "E", "odd": "O", "N": "N", "E": "E", "O": "O", None: "N"}


class _Setting:
    """A bus setting the cached transaction shapes depend on: setting it empties the cache."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.attr = "_" + name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        return self if obj is None else obj.__dict__[self.attr]

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.attr] = value
        obj._shapes = {}
        obj._last_shape = (None, None)


class BusBase:
    """What the sync and async buses share: counters, frame logging, timing arithmetic."""

    serial_line: bool = _Setting()  # type: ignore[assignment]
    baudrate: int | None = _Setting()  # type: ignore[assignment]
    bits_per_char: int = _Setting()  # type: ignore[assignment]
    timeout_override: float | None = _Setting()  # type: ignore[assignment]
    retries_override: int | None = _Setting()  # type: ignore[assignment]

    def __init__(self, *, serial: bool, baudrate: int | None, bits_per_char: int, timeout: float | None,
                 retries: int | None, name: str) -> None:
        self.stats = Stats()
        #: Why the last reply that did not answer its request was refused (what came back instead).
        self.last_rejected: str | None = None
        self.serial_line = serial
        self.baudrate = baudrate
        self.bits_per_char = bits_per_char
        self.timeout_override = timeout
        self.retries_override = retries
        self.name = name
        self._ready_at = 0.0
        self._rx = b""
        self._rx_at = 0.0  # time.monotonic() when pymodbus last handed received bytes to its framer
        #: Seconds the line has been silent, at least, when pymodbus hands over a reply (sync serial).
        self._rx_quiet_s = 0.0
        #: Quiet time (seconds) the bus kept, or is keeping, after the last transaction.
        self.last_quiet_s = 0.0
        #: per transaction shape (timing by identity, reply expected, hold ms): see :meth:`_shape`
        self._shapes: dict[tuple[int, bool, float], tuple[TimingSpec, float, int, float]] = {}
        #: the last exchange carried out and its shape (see :meth:`Bus.transact`)
        self._last_shape: tuple[Exchange | None, Any] = (None, None)

    # pymodbus trace hooks: every byte that goes out or comes in passes here (kept lean: a counter,
    # and the hex dump only when the drivemap logger shows DEBUG).
    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if sending:
            self.stats.bytes_sent += len(data)
            if log.isEnabledFor(_DEBUG):
                log.debug("%s TX %s", self.name, data.hex(" "))
        else:
            self._rx = data
            self._rx_at = clock()
        return data

    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if not sending and self._rx:
            self.stats.bytes_received += len(self._rx)
            if log.isEnabledFor(_DEBUG):
                log.debug("%s RX %s", self.name, self._rx.hex(" "))
            self._rx = b""
        return pdu

    def _flush_rx(self, what: str) -> None:
        if self._rx:
            self.stats.bytes_received += len(self._rx)
            if log.isEnabledFor(logging.DEBUG):
                log.debug("%s %s %s", self.name, what, self._rx.hex(" "))
            self._rx = b""

    def _shape(self, ex: Exchange) -> tuple[TimingSpec, float, int, float]:
        """(timing, timeout s, attempts, quiet s after it) of the exchange's transaction shape (its
        timing, whether it expects a reply, its hold time): computed once per shape and bus settings."""
        timing, expect = ex.timing, ex.expect_reply
        key = (id(timing), expect, ex.hold_ms)
        hit = self._shapes.get(key)
        if hit is None or hit[0] is not timing:
            quiet = max(self._quiet_s(timing, expect), ex.hold_ms / 1000.0)
            hit = self._shapes[key] = (timing, self.timeout_for(timing), 1 + (self.retries_for(timing) if expect else 0),
                                       quiet)
        self._last_shape = (ex, hit)
        return hit

    def timeout_for(self, timing: TimingSpec) -> float:
        if self.timeout_override is not None:
            return self.timeout_override
        if timing.response_timeout_ms is not None:
            return timing.response_timeout_ms / 1000.0
        return DEFAULT_RESPONSE_TIMEOUT_S

    def retries_for(self, timing: TimingSpec) -> int:
        if self.retries_override is not None:
            return self.retries_override
        return timing.retries if timing.retries is not None else DEFAULT_RETRIES

    def silent_interval_s(self, timing: TimingSpec) -> float:
        """3.5 characters (the map's count) at the line's baud rate, or the map's floor."""
        if not self.serial_line:
            return 0.0
        floor = (timing.silent_interval_floor_ms or 0.0) / 1000.0
        if self.baudrate is None:
            return floor
        if timing.silent_interval_floor_above_bps is not None and self.baudrate > timing.silent_interval_floor_above_bps:
            return floor
        chars = timing.silent_interval_chars if timing.silent_interval_chars is not None else 3.5
        return max(chars * self.bits_per_char / self.baudrate, 0.0)

    def _quiet_s(self, timing: TimingSpec, expect_reply: bool) -> float:
        # inter-frame gap and silent interval: serial-line rules (also RTU over TCP), not Modbus TCP
        gap = (timing.inter_frame_gap_ms or 0.0) / 1000.0 if self.serial_line else 0.0
        if not expect_reply:
            bgap = timing.broadcast_gap_ms if timing.broadcast_gap_ms is not None else DEFAULT_BROADCAST_GAP_MS
            gap = max(gap, bgap / 1000.0)
        return gap + self.silent_interval_s(timing)

    def quiet_after(self, ex: Exchange) -> float:
        """Seconds the line stays quiet after ``ex`` (see the module docstring for the rules)."""
        return self._shape(ex)[3]

    def _no_reply(self, ex: Exchange, exc: Exception, attempt: int, attempts: int, quiet: float) -> None:
        """Count and log an attempt that got no valid reply (timeout, corrupt frame)."""
        self.stats.timeouts += 1
        self.stats.bytes_garbled += len(self._rx)
        self._flush_rx("RX (no valid reply)")
        log.debug("%s no valid reply to unit %d (attempt %d of %d): %s", self.name, ex.unit, attempt + 1, attempts, exc)
        self._mark_done(quiet)

    def _rejected(self, ex: Exchange, reply: ModbusPDU, problem: str, started: float) -> float:
        """Count and log a reply that is not ours; the seconds left of the attempt's timeout."""
        self.stats.rejected += 1
        self.last_rejected = problem
        self._flush_rx("RX (not ours)")
        log.warning("%s reply rejected (unit %d, function 0x%02X): %s", self.name, ex.unit,
                    ex.pdu.function_code, problem)
        return max(0.0, started + self.timeout_for(ex.timing) - time.monotonic())

    def _stale_guard(self, mode: bool | None) -> staleguard.StaleGuard:
        """The guard that drops replies arriving too early on this serial line (see :mod:`.staleguard`)."""
        if mode is not None and not isinstance(mode, bool):
            raise InvalidArgument(f"stale_guard must be True, False or None, not {mode!r}")
        char_s = self.bits_per_char / float(self.baudrate or DEFAULT_BAUDRATE)
        return staleguard.StaleGuard(char_s, self._stale, mode)

    def _stale(self, data: bytes, first: bool) -> None:
        """Count and log bytes the guard dropped (once per transaction in :attr:`Stats.stale`)."""
        self.stats.bytes_received += len(data)
        if first:
            self.stats.stale += 1
            log.warning("%s stale reply dropped (it began before the request could be answered): %s",
                        self.name, data.hex(" "))
        elif log.isEnabledFor(logging.DEBUG):
            log.debug("%s stale bytes dropped: %s", self.name, data.hex(" "))

    def _mark_done(self, quiet: float, replied: bool = False) -> None:
        """The transaction is over: keep the line quiet for ``quiet`` seconds (:meth:`quiet_after`),
        counted from the end of the reply when ``replied`` (see the module docstring), else from now."""
        self.last_quiet_s = quiet
        if quiet > 0:
            now = time.monotonic()
            since = min(now, self._rx_at - self._rx_quiet_s) if replied and self._rx_at else now
            self._ready_at = max(self._ready_at, since + quiet)

    def _wait_s(self) -> float:
        if not self._ready_at:
            return 0.0
        left = self._ready_at - time.monotonic()
        if left <= 0:
            self._ready_at = 0.0
            return 0.0
        return left


async def sleep_until(due: float) -> None:
    """Wait until ``time.monotonic()`` reaches ``due``, late by tens of microseconds rather than a millisecond.

    The event loop rounds a timer's wait up to whole milliseconds (the selector's timeout), so
    ``asyncio.sleep`` covers whole milliseconds only and the rest (under 1.2 ms) passes yielding to
    the loop (``asyncio.sleep(0)``), which keeps serving other tasks meanwhile.
    """
    whole_ms = math.floor((due - time.monotonic() - 0.0002) * 1000.0)
    if whole_ms > 0:
        await asyncio.sleep(whole_ms / 1000.0)
    while time.monotonic() < due:
        await asyncio.sleep(0)


def serial_kwargs(serial: SerialSpec, overrides: dict[str, Any]) -> tuple[dict[str, Any], str, int]:
    mode = overrides.pop("mode", serial.mode)
    baudrate = overrides.pop("baudrate", serial.baudrate)
    if baudrate is None:
        log.warning("the map gives no default baud rate; using %d (pass baudrate= to choose)", DEFAULT_BAUDRATE)
        baudrate = DEFAULT_BAUDRATE
    parity_setting = overrides.pop("parity", serial.parity)
    parity = _PARITY.get(parity_setting) if isinstance(parity_setting, (str, type(None))) else None
    stopbits = overrides.pop("stopbits", overrides.pop("stop_bits", serial.stop_bits)) or 1
    bytesize = overrides.pop("bytesize", overrides.pop("data_bits", serial.data_bits))
    if overrides:
        raise InvalidArgument(f"unknown serial settings: {', '.join(sorted(overrides))}")
    if mode not in ("rtu", "ascii"):
        raise InvalidArgument(f"serial mode must be 'rtu' or 'ascii', not {mode!r}")
    if parity is None:
        raise InvalidArgument(f"parity must be one of 'none', 'even', 'odd', not {parity_setting!r}")
    for what, value, allowed in (("stop bits", stopbits, (1, 1.5, 2)), ("data bits", bytesize, (7, 8))):
        if isinstance(value, bool) or value not in allowed:
            raise InvalidArgument(f"{what} must be one of {allowed}, not {value!r}")
    if isinstance(baudrate, bool) or not isinstance(baudrate, int) or baudrate <= 0:
        raise InvalidArgument(f"baud rate must be a positive int, not {baudrate!r}")
    kwargs = {
        "framer": FramerType.RTU if mode == "rtu" else FramerType.ASCII,
        "baudrate": baudrate, "parity": parity, "stopbits": stopbits, "bytesize": bytesize,
    }
    bits = 1 + bytesize + (0 if parity == "N" else 1) + stopbits
    return kwargs, mode, bits


__all__ = ["DEFAULT_BAUDRATE", "DEFAULT_BROADCAST_GAP_MS", "DEFAULT_RESPONSE_TIMEOUT_S", "DEFAULT_RETRIES", "sleep_until"]
