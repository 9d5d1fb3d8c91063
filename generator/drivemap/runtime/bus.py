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
with it: the bus notes when pymodbus hands it the complete reply (its ``trace_packet`` hook), and
pymodbus's sync serial client hands a reply over only after polling ``in_waiting`` once more
without a new byte (``ModbusSerialClient._wait_for_data``), so that reply's last byte reached the
port at least one poll interval (``_recv_interval``) earlier. Without a reply (timeouts,
broadcasts, rejected replies) it counts from the end of the attempt.

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
from typing import Any

from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient, ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.framer import FramerAscii, FramerType
from pymodbus.pdu import ModbusPDU

from . import staleguard
from .errors import DriveTimeout, InvalidArgument, TransportError
from .exchange import Exchange, Stats, reply_mismatch
from .serialrx import SerialReceiver
from .spec import SerialSpec, TimingSpec

log = logging.getLogger("drivemap")
_DEBUG = logging.DEBUG
_monotonic = time.monotonic

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


class _BusBase:
    """What the sync and async buses share: counters, frame logging, timing arithmetic."""

    serial_line: bool = _Setting()  # type: ignore[assignment]
    baudrate: int | None = _Setting()  # type: ignore[assignment]
    bits_per_char: int = _Setting()  # type: ignore[assignment]
    timeout_override: float | None = _Setting()  # type: ignore[assignment]
    retries_override: int | None = _Setting()  # type: ignore[assignment]

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
            self._rx_at = _monotonic()
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
            if baudrate:  # runtime.serialrx: sees the end of a reply as it arrives (quiet_s of silence)
                self._receiver = SerialReceiver(client, bits_per_char / baudrate, isinstance(client.framer, FramerAscii))
                self._rx_quiet_s = min(self._rx_quiet_s, self._receiver.quiet_s)

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
        guard = bus._stale_guard(stale_guard)
        if guard.mode is not False and bus._receiver is not None:
            # The stale-reply guard must see every byte up to pymodbus's own end-of-reply silence (a
            # duplicate followed by the real reply); the fast receiver would stop after the first
            # frame. Correctness first: with the guard on, pymodbus's receive is used.
            del bus.client.recv  # the receiver's instance attribute; the class method again
            bus._receiver = None
            bus._rx_quiet_s = float(getattr(bus.client, "_recv_interval", 0.0))
        staleguard.guard_sync_client(bus.client, guard)
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
            return self.transact(ex)

    def transact(self, ex: Exchange) -> ModbusPDU | None:
        """:meth:`exchange` for a caller that holds :attr:`lock` (a client's read or write program)."""
        client = self.client
        if not client.connected:
            self.connect()
        last = self._last_shape  # the same exchange again (a read or write program's): its shape as last time
        if last[0] is ex:
            hit = last[1]
        else:
            hit = self._shapes.get((id(ex.timing), ex.expect_reply, ex.hold_ms))
            if hit is None or hit[0] is not ex.timing:
                hit = self._shape(ex)
            self._last_shape = (ex, hit)
        _, timeout, attempts, quiet = hit
        params = client.comm_params
        if params.timeout_connect != timeout:
            params.timeout_connect = timeout
        stats = self.stats
        pdu = ex.pdu
        fc = pdu.function_code
        try:
            for attempt in range(attempts):
                if attempt:
                    stats.retries += 1
                if self._ready_at and (wait := self._wait_s()) > 0:
                    time.sleep(wait)
                stats.transactions += 1
                stats.by_function[fc] = stats.by_function.get(fc, 0) + 1
                self._rx = b""
                self._rx_at = 0.0
                pdu.dev_id = ex.unit
                if self._receiver is not None:
                    self._receiver.expect(pdu)
                started = _monotonic()
                try:
                    reply = client.execute(not ex.expect_reply, pdu)
                except ConnectionException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except (ModbusIOException, TimeoutError) as exc:
                    self._no_reply(ex, exc, attempt, attempts, quiet)
                    continue
                except ModbusException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except OSError as exc:  # e.g. ConnectionResetError from the socket: reconnect next time
                    client.close()
                    raise TransportError(f"{self.name}: connection lost: {exc!r}") from exc
                if not ex.expect_reply:
                    self._mark_done(quiet)
                    stats.broadcasts += 1
                    return None
                if reply is not None and not (  # the common case first, without a call: a register read answered
                        reply.function_code == fc and (fc == 0x03 or fc == 0x04) and reply.dev_id == pdu.dev_id
                        and len(reply.registers) == pdu.count) and (problem := reply_mismatch(pdu, reply)):
                    time.sleep(self._rejected(ex, reply, problem, started))
                    self._mark_done(quiet)
                    continue
                if quiet > 0:
                    self._mark_done(quiet, replied=reply is not None)
                else:
                    self.last_quiet_s = quiet
                if reply is not None and reply.function_code > 0x80:  # reply.isError()
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
        last = self._last_shape  # the same exchange again (a read or write program's): its shape as last time
        if last[0] is ex:
            hit = last[1]
        else:
            hit = self._shapes.get((id(ex.timing), ex.expect_reply, ex.hold_ms))
            if hit is None or hit[0] is not ex.timing:
                hit = self._shape(ex)
            self._last_shape = (ex, hit)
        _, timeout, attempts, quiet = hit
        params = client.comm_params
        if params.timeout_connect != timeout:
            params.timeout_connect = timeout
        stats = self.stats
        pdu = ex.pdu
        fc = pdu.function_code
        try:
            for attempt in range(attempts):
                if attempt:
                    stats.retries += 1
                if self._ready_at and self._wait_s() > 0:
                    await sleep_until(self._ready_at)
                stats.transactions += 1
                stats.by_function[fc] = stats.by_function.get(fc, 0) + 1
                self._rx = b""
                self._rx_at = 0.0
                pdu.dev_id = ex.unit
                started = _monotonic()
                try:
                    reply = await client.execute(not ex.expect_reply, pdu)
                except ConnectionException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except (ModbusIOException, TimeoutError) as exc:
                    self._no_reply(ex, exc, attempt, attempts, quiet)
                    continue
                except ModbusException as exc:
                    raise TransportError(f"{self.name}: {exc}") from exc
                except OSError as exc:  # e.g. ConnectionResetError from the transport: reconnect next time
                    client.close()
                    raise TransportError(f"{self.name}: connection lost: {exc!r}") from exc
                if not ex.expect_reply:
                    self._mark_done(quiet)
                    stats.broadcasts += 1
                    return None
                if reply is not None and not (  # the common case first, without a call: a register read answered
                        reply.function_code == fc and (fc == 0x03 or fc == 0x04) and reply.dev_id == pdu.dev_id
                        and len(reply.registers) == pdu.count) and (problem := reply_mismatch(pdu, reply)):
                    await asyncio.sleep(self._rejected(ex, reply, problem, started))
                    self._mark_done(quiet)
                    continue
                if quiet > 0:
                    self._mark_done(quiet, replied=reply is not None)
                else:
                    self.last_quiet_s = quiet
                if reply is not None and reply.function_code > 0x80:  # reply.isError()
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
