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
  the bus waits on for the real one (:mod:`drivemap.runtime.client.transport.staleguard`; ``stale_guard=`` of
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
(:mod:`drivemap.runtime.client.transport.serialrx`) reports it; pymodbus's own receive hands a reply over only after
polling ``in_waiting`` once more without a new byte (``ModbusSerialClient._wait_for_data``), so
that reply's last byte reached the port at least one poll interval (``_recv_interval``) earlier.
Without a reply (timeouts, broadcasts, rejected replies) it counts from the end of the attempt.

:meth:`Bus.quiet_after` gives that quiet time for an exchange; :attr:`Bus.last_quiet_s` records the
quiet time kept after the last transaction.

Every frame is logged in hex at DEBUG on the ``drivemap`` logger.
"""

from __future__ import annotations

import asyncio
import threading
import time
from typing import Any

from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient, ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.framer import FramerAscii, FramerType
from pymodbus.pdu import ModbusPDU

from drivemap.runtime.client.transport import staleguard
from drivemap.runtime.client.transport.busbase import (
    DEFAULT_BAUDRATE,
    DEFAULT_BROADCAST_GAP_MS,
    DEFAULT_RESPONSE_TIMEOUT_S,
    DEFAULT_RETRIES,
    BusBase,
    clock,
    serial_kwargs,
    sleep_until,
)
from drivemap.runtime.client.transport.exchange import Exchange, Stats, reply_mismatch
from drivemap.runtime.client.transport.serialrx import SerialReceiver
from drivemap.runtime.errors import DriveTimeout, TransportError
from drivemap.runtime.spec import SerialSpec

#: The last part of the quiet time before a request (s) that the sync serial bus waits for by reading
#: the clock rather than sleeping (a sleep of under a millisecond ends 50-150 µs late on Linux).
SPIN_S = 0.0002


class Bus(BusBase):
    """A synchronous line (serial port or TCP connection) shared by the clients on it."""

    def __init__(self, client: Any, *, serial: bool = False, baudrate: int | None = None, bits_per_char: int = 11,
                 timeout: float | None = None, retries: int | None = None, name: str = "bus") -> None:
        super().__init__(serial=serial, baudrate=baudrate, bits_per_char=bits_per_char, timeout=timeout,
                         retries=retries, name=name)
        self.client = client
        client.set_max_no_responses(1 << 30)  # retries and disconnects are ours
        self.lock = threading.RLock()
        self._receiver: SerialReceiver | None = None
        #: the quiet time is kept in the request's send (:meth:`_quiet_at_send`), not before the call
        self._waits_at_send = False
        self._sent_at = 0.0
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
        kwargs, mode, bits = serial_kwargs(serial or SerialSpec(), dict(overrides))
        bus = cls._make(ModbusSerialClient, dict(port=port, **kwargs), True, kwargs["baudrate"], bits,
                        timeout, retries, f"{mode}:{port}")
        # the receiver drops stale bytes through the guard as they arrive and listens the guard's
        # settle time after a reply, so a frame that follows a stale one is seen (see .staleguard)
        staleguard.guard_sync_client(bus.client, bus._stale_guard(stale_guard), bus._receiver)
        bus._quiet_at_send()
        return bus

    def _quiet_at_send(self) -> None:
        """Keep the quiet time after the last transaction where the request goes out, not before the
        client's call: pymodbus builds the frame (and the guard reads what arrived unasked) while the
        line is still quiet, and the bytes go out as soon as the quiet time is over (the per-transaction
        work then overlaps the t3.5 instead of following it; bench section 3)."""
        ctx = self.client.transaction
        inner = ctx.low_level_send

        def send(request: bytes, addr: Any = None) -> int:
            due = self._ready_at
            if due and (left := self._wait_s()) > 0:
                if left > SPIN_S:
                    time.sleep(left - SPIN_S)  # wakes up late by tens of microseconds or more ...
                while clock() < due:  # ... so the last of the quiet time is waited for by the clock
                    pass
            self._sent_at = clock()
            size: int = inner(request, addr=addr)
            return size

        ctx.low_level_send = send
        self._waits_at_send = True

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

    def transact(self, ex: Exchange) -> ModbusPDU | None:  # noqa: C901 - one flat pass on every transaction: a helper per branch would add calls to each (bench section 12 counts them)
        """:meth:`exchange` for a caller that holds :attr:`lock` (a client's read or write program)."""
        client = self.client
        if not client.connected:
            self.connect()
        last = self._last_shape  # the same exchange again (a read or write program's): its shape as last time
        _, timeout, attempts, quiet = last[1] if last[0] is ex else self._shape(ex)
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
                if self._ready_at and not self._waits_at_send and (wait := self._wait_s()) > 0:
                    time.sleep(wait)
                stats.transactions += 1
                stats.by_function[fc] = stats.by_function.get(fc, 0) + 1
                self._rx = b""
                self._rx_at = 0.0
                pdu.dev_id = ex.unit
                if self._receiver is not None:
                    self._receiver.expect(pdu)
                started = clock()
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
                    time.sleep(self._rejected(ex, reply, problem, max(started, self._sent_at)))
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


class AsyncBus(BusBase):
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
        kwargs, mode, bits = serial_kwargs(serial or SerialSpec(), dict(overrides))
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
        _, timeout, attempts, quiet = last[1] if last[0] is ex else self._shape(ex)
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
                started = clock()
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
