"""Transports: one pymodbus client per line, one transaction at a time, timing and retries.

A :class:`Bus` (sync) or :class:`AsyncBus` (asyncio) owns one pymodbus client: serial RTU/ASCII
(``ModbusSerialClient`` with ``FramerType.RTU``/``ASCII``), Modbus TCP (``ModbusTcpClient``) or
RTU over TCP for serial gateways (``ModbusTcpClient`` with ``FramerType.RTU``). Several drive
clients (units) may share one bus; the bus serialises their transactions with a lock.

Retries are done here, not in pymodbus (pymodbus gets ``retries=0``), so :attr:`Bus.stats` counts
every request actually sent. Timing, from the map (:class:`TimingSpec`) of the client that asks:

* response timeout: ``response_timeout_ms``, else :data:`DEFAULT_RESPONSE_TIMEOUT_S`;
* retries on timeout or a corrupt reply (pymodbus drops frames with a bad CRC/LRC, which then
  time out): ``retries``, else :data:`DEFAULT_RETRIES`;
* a reply that does not answer the request sent (another unit, another function code, another
  address or value echoed by 06h/10h, another register count; e.g. a late reply to an earlier
  request) is never returned: it is logged, counted in :attr:`Stats.rejected`, and the attempt
  counts as unanswered (the bus waits out its response timeout, so a real reply still on its way
  is discarded before the retry);
* on a serial line, a reply that began before the request could have been answered (a copy
  delivered again by the line, a late reply) is dropped and counted in :attr:`Stats.stale`, and
  the bus waits on for the real one (:mod:`drivemap.runtime.staleguard`; ``stale_guard=`` of
  :meth:`Bus.serial`);
* on a serial line (RTU/ASCII) and on RTU over TCP, after every transaction the line stays quiet
  for ``inter_frame_gap_ms`` plus the silent interval (``silent_interval_chars`` at the line's baud
  rate, or the map's floor; on RTU over TCP, where the baud rate is unknown, the floor);
* on Modbus TCP (MBAP framing) neither applies: both are serial-line rules (the manuals state them
  for their RS-485 port, Modbus over Serial Line v1.02 2.5.1.1), and an MBAP frame is delimited by
  its length field, not by silence. RTU over TCP keeps them because a transparent gateway puts the
  frames on a serial line as they come;
* after a broadcast, on every transport: ``broadcast_gap_ms`` (else
  :data:`DEFAULT_BROADCAST_GAP_MS`), since nobody answers and the devices need the time to act
  (plus the silent interval where it applies);
* after an EEPROM write, on every transport: the register's ``write_delay_ms`` (the client passes
  it as ``hold_ms``).

The quiet time counts from the end of the reply on the line, not from when the client has finished
with it: the bus notes when pymodbus hands it the complete reply (its ``trace_packet`` hook), less
the silence seen after the reply's last byte: the sync serial receiver
(:mod:`drivemap.runtime.serialrx`) reports it; pymodbus's own receive hands a reply over only after
polling ``in_waiting`` once more without a new byte (``ModbusSerialClient._wait_for_data``), so
that reply's last byte reached the port at least one poll interval (``_recv_interval``) earlier.
Without a reply (timeouts, broadcasts, rejected replies) it counts from the end of the attempt.

:meth:`Bus.quiet_after` gives that quiet time for an exchange; :attr:`Bus.last_quiet_s` records the
quiet time kept after the last transaction.

Every frame is logged in hex at DEBUG on the ``drivemap`` logger.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient, ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.framer import FramerAscii, FramerType
from pymodbus.pdu import ModbusPDU

from . import staleguard
from .errors import DriveTimeout, InvalidArgument, TransportError
from .serialrx import SerialReceiver
from .spec import SerialSpec, TimingSpec

log = logging.getLogger("drivemap")

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


@dataclass
class Stats:
    """Counters of one bus: requests sent (with retries), retries, broadcasts and bytes."""

    transactions: int = 0
    retries: int = 0
    timeouts: int = 0
    broadcasts: int = 0
    exceptions: int = 0
    rejected: int = 0
    """Replies that did not answer the request sent (see :func:`reply_mismatch`), never returned."""
    stale: int = 0
    """Serial lines: replies that began before the request could have been answered (a duplicate, an
    echo, a late reply) or arrived between transactions; dropped unread (see :mod:`.staleguard`)."""
    bytes_sent: int = 0
    bytes_received: int = 0
    bytes_garbled: int = 0
    """Bytes received during attempts that got no valid reply (noise, wrong baud rate or parity)."""
    by_function: dict[int, int] = field(default_factory=dict)
    """Requests sent per function code (retries included)."""
    split_reads: int = 0
    """Reads the device refused with 02h that the client split (adaptive reads)."""
    extra_requests: int = 0
    """Requests the splitting sent beyond the plan (counted once each, retries aside)."""


@dataclass(frozen=True)
class Exchange:
    """One request the client core asks the bus to carry out."""

    unit: int
    pdu: ModbusPDU
    timing: TimingSpec
    expect_reply: bool = True
    hold_ms: float = 0.0


def reply_mismatch(request: ModbusPDU, reply: ModbusPDU) -> str | None:
    """Why ``reply`` cannot be the answer to ``request`` (None when it can).

    RTU and ASCII frames carry no transaction id, so everything a reply echoes is checked: unit,
    function code (or its exception form), the address and value of 05h/06h, the address and
    quantity of 0Fh/10h, the register count of 03h/04h, the byte count of 01h/02h and the
    sub-function of 08h.
    """
    if reply.dev_id != request.dev_id:
        return f"reply from unit {reply.dev_id}, asked unit {request.dev_id}"
    fc = request.function_code
    if reply.function_code & 0x7F != fc:
        return f"reply has function 0x{reply.function_code:02X}, sent 0x{fc:02X}"
    if reply.isError():
        return None
    if fc in (0x03, 0x04) and len(reply.registers) != request.count:
        return f"reply has {len(reply.registers)} registers, asked {request.count}"
    if fc in (0x01, 0x02) and len(reply.bits) != (request.count + 7) // 8 * 8:
        return f"reply has {len(reply.bits) // 8} data bytes for {request.count} bits"
    if fc in (0x05, 0x06, 0x0F, 0x10) and reply.address != request.address:
        return f"reply echoes address 0x{reply.address:04X}, sent 0x{request.address:04X}"
    if fc == 0x06 and list(reply.registers) != list(request.registers):
        return f"reply echoes value {list(reply.registers)}, sent {list(request.registers)}"
    if fc == 0x05 and bool(reply.bits[0]) != bool(request.bits[0]):
        return f"reply echoes coil {reply.bits[0]}, sent {request.bits[0]}"
    if fc == 0x10 and reply.count != len(request.registers):
        return f"reply echoes quantity {reply.count}, sent {len(request.registers)}"
    if fc == 0x0F and reply.count != len(request.bits):
        return f"reply echoes quantity {reply.count}, sent {len(request.bits)}"
    if fc == 0x08 and getattr(reply, "sub_function_code", None) != getattr(request, "sub_function_code", None):
        return "reply has another diagnostics sub-function"
    return None


class _BusBase:
    """What the sync and async buses share: counters, frame logging, timing arithmetic."""

    def __init__(self, *, serial: bool, baudrate: int | None, bits_per_char: int, timeout: float | None,
                 retries: int | None, name: str) -> None:
        self.stats = Stats()
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
        # per TimingSpec (by identity): (timing, timeout s, retries, quiet after a reply, after a broadcast)
        self._timing_cache: dict[int, tuple[TimingSpec, float, int, float, float]] = {}
        self._timing_settings: tuple[Any, ...] = ()

    # pymodbus trace hooks: every byte that goes out or comes in passes here.
    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if sending:
            self.stats.bytes_sent += len(data)
            if log.isEnabledFor(logging.DEBUG):
                log.debug("%s TX %s", self.name, data.hex(" "))
        else:
            self._rx = data
            self._rx_at = time.monotonic()
        return data

    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if not sending and self._rx:
            self._flush_rx("RX")
        return pdu

    def _flush_rx(self, what: str) -> None:
        if self._rx:
            self.stats.bytes_received += len(self._rx)
            if log.isEnabledFor(logging.DEBUG):
                log.debug("%s %s %s", self.name, what, self._rx.hex(" "))
            self._rx = b""

    def _timing(self, timing: TimingSpec) -> tuple[TimingSpec, float, int, float, float]:
        """(timing, timeout s, retries, quiet s after a reply, quiet s after a broadcast), cached."""
        settings = (self.timeout_override, self.retries_override, self.serial_line, self.baudrate,
                    self.bits_per_char)
        if settings != self._timing_settings:  # a setting changed since the cache was filled
            self._timing_cache.clear()
            self._timing_settings = settings
        hit = self._timing_cache.get(id(timing))
        if hit is None or hit[0] is not timing:
            hit = (timing, self.timeout_for(timing), self.retries_for(timing), self._quiet_s(timing, True),
                   self._quiet_s(timing, False))
            self._timing_cache[id(timing)] = hit
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
        cached = self._timing(ex.timing)
        quiet = cached[3] if ex.expect_reply else cached[4]
        return max(quiet, ex.hold_ms / 1000.0)

    def _rejected(self, ex: Exchange, reply: ModbusPDU, problem: str, started: float) -> float:
        """Count and log a reply that is not ours; the seconds left of the attempt's timeout."""
        self.stats.rejected += 1
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


def _serial_kwargs(serial: SerialSpec, overrides: dict[str, Any]) -> tuple[dict[str, Any], str, int]:
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


class Bus(_BusBase):
    """A synchronous line (serial port or TCP connection) shared by the clients on it."""

    def __init__(self, client: Any, *, serial: bool = False, baudrate: int | None = None, bits_per_char: int = 11,
                 timeout: float | None = None, retries: int | None = None, name: str = "bus") -> None:
        super().__init__(serial=serial, baudrate=baudrate, bits_per_char=bits_per_char, timeout=timeout,
                         retries=retries, name=name)
        self.client = client
        client.set_max_no_responses(1 << 30)  # retries and disconnects are ours
        self.lock = threading.RLock()
        self._receiver: SerialReceiver | None = None
        if isinstance(client, ModbusSerialClient):  # see the module docstring: pymodbus's end-of-reply poll
            self._rx_quiet_s = float(getattr(client, "_recv_interval", 0.0))
            if baudrate:  # runtime.serialrx: sees the end of a reply as it arrives, reports the silence after it
                self._receiver = SerialReceiver(client, bits_per_char / baudrate, isinstance(client.framer, FramerAscii),
                                                on_silence=self._reply_silence)
                self._rx_quiet_s = min(self._rx_quiet_s, self._receiver.quiet_s)

    def _reply_silence(self, seconds: float) -> None:
        """The receiver saw the line silent for ``seconds`` after the reply's last byte (see :meth:`_mark_done`)."""
        self._rx_quiet_s = seconds

    @classmethod
    def tcp(cls, host: str, port: int = 502, *, timeout: float | None = None, retries: int | None = None) -> Bus:
        """Modbus TCP (MBAP framing)."""
        return cls._make(ModbusTcpClient, dict(host=host, port=port, framer=FramerType.SOCKET), False, None, 11,
                         timeout, retries, f"tcp:{host}:{port}")

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, *, timeout: float | None = None, retries: int | None = None) -> Bus:
        """RTU frames over a TCP connection (serial gateways)."""
        return cls._make(ModbusTcpClient, dict(host=host, port=port, framer=FramerType.RTU), True, None, 11,
                         timeout, retries, f"rtu-over-tcp:{host}:{port}")

    @classmethod
    def serial(cls, port: str, serial: SerialSpec | None = None, *, timeout: float | None = None,
               retries: int | None = None, stale_guard: bool | None = None, **overrides: Any) -> Bus:
        """A serial line; ``serial`` gives the map's defaults, ``overrides`` (mode, baudrate, parity,
        stopbits, bytesize) win over them. ``stale_guard``: drop replies that began before the request
        could be answered (None: when the port shows it carries real characters; see :mod:`.staleguard`)."""
        kwargs, mode, bits = _serial_kwargs(serial or SerialSpec(), dict(overrides))
        bus = cls._make(ModbusSerialClient, dict(port=port, **kwargs), True, kwargs["baudrate"], bits,
                        timeout, retries, f"{mode}:{port}")
        # the receiver drops stale bytes through the guard as they arrive and listens the guard's
        # settle time after a reply, so a frame that follows a stale one is seen (see .staleguard)
        staleguard.guard_sync_client(bus.client, bus._stale_guard(stale_guard), bus._receiver)
        return bus

    @classmethod
    def _make(cls, factory: Any, kwargs: dict[str, Any], serial: bool, baudrate: int | None, bits: int,
              timeout: float | None, retries: int | None, name: str) -> Bus:
        bus = cls.__new__(cls)
        client = factory(
            **kwargs, timeout=timeout if timeout is not None else DEFAULT_RESPONSE_TIMEOUT_S, retries=0,
            trace_packet=bus._trace_packet, trace_pdu=bus._trace_pdu,
        )
        cls.__init__(bus, client, serial=serial, baudrate=baudrate, bits_per_char=bits, timeout=timeout,
                     retries=retries, name=name)
        return bus

    def connect(self) -> None:
        with self.lock:
            if not self.client.connected and not self.client.connect():
                raise TransportError(f"{self.name}: cannot connect")

    def close(self) -> None:
        with self.lock:
            self.client.close()

    def __enter__(self) -> Bus:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def exchange(self, ex: Exchange) -> ModbusPDU | None:
        """Send one request (retrying on timeout); the reply PDU, or None for a broadcast."""
        with self.lock:
            client = self.client
            if not client.connected:
                self.connect()
            _, timeout, retries, quiet_reply, quiet_broadcast = self._timing(ex.timing)
            quiet = max(quiet_reply if ex.expect_reply else quiet_broadcast, ex.hold_ms / 1000.0)
            params = client.comm_params
            if params.timeout_connect != timeout:
                params.timeout_connect = timeout
            attempts = 1 + (0 if not ex.expect_reply else retries)
            stats = self.stats
            try:
                for attempt in range(attempts):
                    if attempt:
                        stats.retries += 1
                    if self._ready_at and (wait := self._wait_s()) > 0:
                        time.sleep(wait)
                    stats.transactions += 1
                    fc = ex.pdu.function_code
                    stats.by_function[fc] = stats.by_function.get(fc, 0) + 1
                    self._rx = b""
                    self._rx_at = 0.0
                    ex.pdu.dev_id = ex.unit
                    if self._receiver is not None:
                        self._receiver.expect(ex.pdu)
                    started = time.monotonic()
                    try:
                        reply = client.execute(not ex.expect_reply, ex.pdu)
                    except ConnectionException as exc:
                        raise TransportError(f"{self.name}: {exc}") from exc
                    except (ModbusIOException, TimeoutError) as exc:
                        self.stats.timeouts += 1
                        self.stats.bytes_garbled += len(self._rx)
                        self._flush_rx("RX (no valid reply)")
                        log.debug("%s no valid reply to unit %d (attempt %d of %d): %s", self.name, ex.unit,
                                  attempt + 1, attempts, exc)
                        self._mark_done(quiet)
                        continue
                    except ModbusException as exc:
                        raise TransportError(f"{self.name}: {exc}") from exc
                    except OSError as exc:  # e.g. ConnectionResetError from the socket: reconnect next time
                        client.close()
                        raise TransportError(f"{self.name}: connection lost: {exc!r}") from exc
                    if ex.expect_reply and reply is not None and (problem := reply_mismatch(ex.pdu, reply)):
                        time.sleep(self._rejected(ex, reply, problem, started))
                        self._mark_done(quiet)
                        continue
                    self._mark_done(quiet, replied=ex.expect_reply and reply is not None)
                    if not ex.expect_reply:
                        stats.broadcasts += 1
                        return None
                    if reply is not None and reply.isError():
                        stats.exceptions += 1
                    return reply  # type: ignore[no-any-return]
            finally:
                if self._rx:
                    self._flush_rx("RX (unused)")
            raise DriveTimeout(f"{self.name}: no valid reply from unit {ex.unit} after {attempts} attempt(s)")


class AsyncBus(_BusBase):
    """The asyncio twin of :class:`Bus`: one transaction at a time under an ``asyncio.Lock``."""

    def __init__(self, client: Any, *, serial: bool = False, baudrate: int | None = None, bits_per_char: int = 11,
                 timeout: float | None = None, retries: int | None = None, name: str = "bus") -> None:
        super().__init__(serial=serial, baudrate=baudrate, bits_per_char=bits_per_char, timeout=timeout,
                         retries=retries, name=name)
        self.client = client
        client.set_max_no_responses(1 << 30)
        self.lock = asyncio.Lock()

    @classmethod
    def tcp(cls, host: str, port: int = 502, *, timeout: float | None = None, retries: int | None = None) -> AsyncBus:
        """Modbus TCP (MBAP framing)."""
        return cls._make(AsyncModbusTcpClient, dict(host=host, port=port, framer=FramerType.SOCKET), False, None, 11,
                         timeout, retries, f"tcp:{host}:{port}")

    @classmethod
    def rtu_over_tcp(cls, host: str, port: int, *, timeout: float | None = None,
                     retries: int | None = None) -> AsyncBus:
        """RTU frames over a TCP connection (serial gateways)."""
        return cls._make(AsyncModbusTcpClient, dict(host=host, port=port, framer=FramerType.RTU), True, None, 11,
                         timeout, retries, f"rtu-over-tcp:{host}:{port}")

    @classmethod
    def serial(cls, port: str, serial: SerialSpec | None = None, *, timeout: float | None = None,
               retries: int | None = None, stale_guard: bool | None = None, **overrides: Any) -> AsyncBus:
        """A serial line; see :meth:`Bus.serial`."""
        kwargs, mode, bits = _serial_kwargs(serial or SerialSpec(), dict(overrides))
        bus = cls._make(AsyncModbusSerialClient, dict(port=port, **kwargs), True, kwargs["baudrate"], bits,
                        timeout, retries, f"{mode}:{port}")
        staleguard.guard_async_client(bus.client, bus._stale_guard(stale_guard))
        return bus

    @classmethod
    def _make(cls, factory: Any, kwargs: dict[str, Any], serial: bool, baudrate: int | None, bits: int,
              timeout: float | None, retries: int | None, name: str) -> AsyncBus:
        try:
            asyncio.get_running_loop()
        except RuntimeError:
            raise TransportError(f"{name}: an asyncio bus is made inside a running event loop "
                                 "(in a coroutine); use Bus for synchronous code") from None
        bus = cls.__new__(cls)
        client = factory(
            **kwargs, timeout=timeout if timeout is not None else DEFAULT_RESPONSE_TIMEOUT_S, retries=0,
            reconnect_delay=0, trace_packet=bus._trace_packet, trace_pdu=bus._trace_pdu,
        )
        cls.__init__(bus, client, serial=serial, baudrate=baudrate, bits_per_char=bits, timeout=timeout,
                     retries=retries, name=name)
        return bus

    async def connect(self) -> None:
        if not self.client.connected and not await self.client.connect():
            raise TransportError(f"{self.name}: cannot connect")

    def close(self) -> None:
        self.client.close()

    async def __aenter__(self) -> AsyncBus:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.close()

    async def exchange(self, ex: Exchange) -> ModbusPDU | None:
        """Send one request (retrying on timeout); the caller holds :attr:`lock`."""
        client = self.client
        if not client.connected:
            await self.connect()
        _, timeout, retries, quiet_reply, quiet_broadcast = self._timing(ex.timing)
        quiet = max(quiet_reply if ex.expect_reply else quiet_broadcast, ex.hold_ms / 1000.0)
        params = client.comm_params
        if params.timeout_connect != timeout:
            params.timeout_connect = timeout
        attempts = 1 + (0 if not ex.expect_reply else retries)
        stats = self.stats
        try:
            for attempt in range(attempts):
                if attempt:
                    stats.retries += 1
                if self._ready_at and self._wait_s() > 0:
                    await sleep_until(self._ready_at)
                stats.transactions += 1
                fc = ex.pdu.function_code
                stats.by_function[fc] = stats.by_function.get(fc, 0) + 1
                self._rx = b""
                self._rx_at = 0.0
                ex.pdu.dev_id = ex.unit
                started = time.monotonic()
                try:
                    reply = await client.execute(not ex.expect_reply, ex.pdu)
                except ConnectionException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except (ModbusIOException, TimeoutError) as exc:
                    self.stats.timeouts += 1
                    self.stats.bytes_garbled += len(self._rx)
                    self._flush_rx("RX (no valid reply)")
                    log.debug("%s no valid reply to unit %d (attempt %d of %d): %s", self.name, ex.unit,
                              attempt + 1, attempts, exc)
                    self._mark_done(quiet)
                    continue
                except ModbusException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except OSError as exc:  # e.g. ConnectionResetError from the transport: reconnect next time
                    client.close()
                    raise TransportError(f"{self.name}: connection lost: {exc!r}") from exc
                if ex.expect_reply and reply is not None and (problem := reply_mismatch(ex.pdu, reply)):
                    await asyncio.sleep(self._rejected(ex, reply, problem, started))
                    self._mark_done(quiet)
                    continue
                self._mark_done(quiet, replied=ex.expect_reply and reply is not None)
                if not ex.expect_reply:
                    stats.broadcasts += 1
                    return None
                if reply is not None and reply.isError():
                    stats.exceptions += 1
                return reply  # type: ignore[no-any-return]
        finally:
            if self._rx:
                self._flush_rx("RX (unused)")
        raise DriveTimeout(f"{self.name}: no valid reply from unit {ex.unit} after {attempts} attempt(s)")


__all__ = [
    "AsyncBus",
    "Bus",
    "DEFAULT_BAUDRATE",
    "DEFAULT_BROADCAST_GAP_MS",
    "DEFAULT_RESPONSE_TIMEOUT_S",
    "DEFAULT_RETRIES",
    "Exchange",
    "Stats",
    "reply_mismatch",
    "sleep_until",
]
