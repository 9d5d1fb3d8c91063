"""Serve a :class:`~drivemap.runtime.sim.simulator.Simulator` with pymodbus: TCP, RTU or ASCII.

pymodbus does the transports, the framing and the CRC/LRC; every request PDU goes, through
``custom_pdu`` request classes registered for every function code 00h-FFh, to
:meth:`Simulator.handle`, which answers in the device's dialect (vendor exception codes such as
51h-55H or 20h included: pymodbus's ``ExceptionResponse`` carries any code byte). Requests the
device must not answer (other units, broadcasts, error cases whose code is null) leave through
pymodbus's ``ignore_missing_devices`` path, so nothing is sent.

Two small framer subclasses watch the serial line: a frame with a bad CRC/LRC is dropped by
pymodbus (no reply) and reported to the simulator (ev records 84h); in RTU, bytes followed by
more than the 3.5-character silence without forming a frame are dropped, as a device does.

With realistic timing, a reply leaves the simulator's processing time after the request arrived:
on a serial line counted from the moment the complete request's last bytes were read from the port
(:func:`_stamp_reads`; on TCP from the moment the request is handled), and waited precisely
(:func:`drivemap.runtime.client.transport.bus.sleep_until`), since ``asyncio.sleep`` alone wakes up to a millisecond late. On a serial line the reply is written to the
port the moment it is ready (:func:`_write_at_once`), as a device's UART starts sending, not one
event-loop turn later through pymodbus's writer callback.

Use from code::

    sim = Simulator(SPEC, units=[1, 2])
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        host, port = server.address
        ...

or ``async with SimServer(sim, serial=port, mode="rtu") as server: ...``; from the shell,
``drivemap simulate MODEL --tcp 127.0.0.1:5020`` (:mod:`drivemap.runtime.sim.cli`).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import threading
import time
from types import TracebackType
from typing import Any, ClassVar

from pymodbus.exceptions import NoSuchIdException
from pymodbus.framer import FramerAscii, FramerRTU, FramerType
from pymodbus.pdu import DecodePDU, ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import SimData, SimDevice

from drivemap.runtime.client.transport.bus import sleep_until
from drivemap.runtime.sim.listen import is_loopback, why_not_listening
from drivemap.runtime.sim.simulator import Simulator, SimulatorError
from drivemap.runtime.sim.tcp import SimTcpServer

__all__ = ["SimServer", "ThreadedSimServer", "is_loopback", "request_decoder"]

_PARITY = {None: "N", "none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"}
_DEFAULT_BAUDRATE = 9600
#: RTU request sizes of standard function codes (unit + PDU + CRC); None = byte count at that position.
_RTU_FIXED = {0x01: 8, 0x02: 8, 0x03: 8, 0x04: 8, 0x05: 8, 0x06: 8, 0x07: 4, 0x08: 8, 0x0B: 4, 0x0C: 4,
              0x11: 4, 0x16: 10, 0x18: 6, 0x2B: 7}
_RTU_COUNT_POS = {0x0F: 6, 0x10: 6, 0x14: 2, 0x15: 2, 0x17: 10}
_RTU_MAX = 256


class _Arrival:
    """When the serial framer of one server last found a complete request (0.0: not yet, or taken),
    and how far the reply's way to the port (pymodbus's server after ``datastore_update``: framing,
    CRC, the write) is measured to take: ``lead``, what the wait ends early so that the reply reaches
    the port when it is due (``due``), learnt from each reply written (:func:`_write_at_once`)."""

    __slots__ = ("at", "due", "lead", "read_at")

    #: the most the wait ends early (s): the reply's way to the port is tens of microseconds
    MAX_LEAD = 0.0002

    def __init__(self) -> None:
        self.at = 0.0
        self.due = 0.0
        self.lead = 0.0
        #: when the bytes being framed were read from the port (0.0: not known; see :func:`_write_at_once`)
        self.read_at = 0.0

    def found(self, now: float) -> None:
        """The framer found a complete request at ``now``: it arrived when its last bytes were read, before
        pymodbus's receive path handed them to the framer (``now`` when that is not known)."""
        read_at, self.read_at = self.read_at, 0.0
        self.at = read_at if now - 0.002 <= read_at <= now else now

    def written(self, now: float) -> None:
        """A reply reached the port at ``now``: move the lead by half of how late (or early) it was."""
        if self.due:
            self.lead = min(max(self.lead + 0.5 * (now - self.due), 0.0), self.MAX_LEAD)
            self.due = 0.0

    def take(self, now: float, within: float) -> float:
        """The arrival time of the request being handled (``now`` when unknown or stale)."""
        at, self.at = self.at, 0.0
        return at if now - within <= at <= now else now


class _NoReply(NoSuchIdException):
    """Raised from a request's datastore_update: pymodbus sends nothing (ignore_missing_devices)."""


class _SimResponse(ModbusPDU):
    """A response PDU built by the simulator (function code + data, exception replies included)."""

    def __init__(self, pdu: bytes = b"\x00") -> None:
        super().__init__()
        self.function_code = pdu[0]
        self.payload = pdu[1:]

    def encode(self) -> bytes:
        return self.payload


class _SimRequest(ModbusPDU):
    """Any request PDU: kept as bytes and handed to the simulator."""

    simulator: ClassVar[Simulator]
    arrival: ClassVar[_Arrival] = _Arrival()  # replaced per server by one shared with its request classes

    def __init__(self, dev_id: int = 0, transaction_id: int = 0) -> None:
        super().__init__(dev_id=dev_id, transaction_id=transaction_id)
        self.payload = b""

    def decode(self, data: bytes) -> None:
        self.payload = bytes(data)

    def encode(self) -> bytes:
        return self.payload

    @classmethod
    def calculateRtuFrameSize(cls, data: bytes) -> int:  # noqa: N802 (pymodbus API)
        """Size of the RTU request at the start of ``data`` (0: wait for more bytes)."""
        code = cls.function_code
        if code in _RTU_FIXED:
            return _RTU_FIXED[code]
        if code in _RTU_COUNT_POS:
            pos = _RTU_COUNT_POS[code]
            return data[pos] + pos + 3 if len(data) > pos else 0
        # Unknown function code: the frame ends where a CRC fits (a device uses the silence).
        for size in range(4, min(len(data), _RTU_MAX) + 1):
            if FramerRTU.compute_CRC(data[: size - 2]) == int.from_bytes(data[size - 2 : size], "big"):
                return size
        return len(data) if len(data) >= _RTU_MAX else 0

    async def datastore_update(self, context: Any, device_id: int) -> ModbusPDU:
        sim = self.simulator
        delay = sim.reply_delay()
        arrived = self.arrival.take(time.monotonic(), delay) if delay > 0 else 0.0
        response = sim.handle(device_id, bytes([self.function_code]) + self.payload)
        if response is None:
            raise _NoReply(f"unit {device_id}: no reply")
        if delay > 0:
            due = arrived + delay
            await sleep_until(due - self.arrival.lead)
            self.arrival.due = due
        return _SimResponse(response)


def _request_classes(sim: Simulator, arrival: _Arrival | None = None) -> list[type[ModbusPDU]]:
    """One request class per function code 01h-FFh, bound to ``sim`` (registered per server).

    ``arrival`` is shared with the server's serial framer (without one: delays count from handling).
    Codes 80h-FFh are requests too (a device answers them with its illegal-function exception);
    only :class:`_SimDecoder` hands them over, pymodbus's own decoder takes them for replies.
    """
    arrival = arrival or _Arrival()
    return [
        type(f"SimRequest{code:02X}", (_SimRequest,), {"function_code": code, "simulator": sim, "arrival": arrival})
        for code in range(0x00, 0x100)
    ]


class _SimDecoder(DecodePDU):
    """The server's PDU decoder: function codes 01h-FFh are all requests for the simulator.

    pymodbus decodes a frame with a code of 80h or more as an exception *reply* (a server then
    answers 04h, device failure); a device answers such a request with its illegal-function
    exception (Modbus Application Protocol v1.1b3, 7: codes 128-255 are no request codes).
    """

    def __init__(self, classes: list[type[ModbusPDU]]) -> None:
        super().__init__(True)
        for cls in classes:
            self.register(cls)
        # 00h and 80h-FFh are no request codes; a device answers them with illegal function
        self._high = {cls.function_code: cls for cls in classes if cls.function_code >= 0x80 or cls.function_code == 0}

    def lookupPduClass(self, data: bytes) -> type[ModbusPDU] | None:  # noqa: N802 (pymodbus API)
        high = self._high.get(data[1]) if len(data) > 1 else None
        return high if high is not None else super().lookupPduClass(data)

    def decode(self, frame: bytes) -> ModbusPDU | None:
        high = self._high.get(frame[0]) if frame else None
        if high is None:
            return super().decode(frame)
        pdu = high()
        pdu.decode(frame[1:])
        return pdu


def request_decoder(sim: Simulator, arrival: _Arrival | None = None) -> _SimDecoder:
    """The decoder a serial server of ``sim`` uses (its request classes, 80h-FFh included)."""
    return _SimDecoder(_request_classes(sim, arrival))


class _WatchRTU(FramerRTU):
    """pymodbus's RTU framer, plus: report bad CRCs; drop stale partial frames after the silent interval;
    find a request that follows noise without that silence.

    A frame whose CRC is wrong makes pymodbus drop everything received. When the silence before a
    request was shorter than the interval the framer measures (the host decides when bytes are seen
    here, give or take a few milliseconds), the noise and the request arrive together: the framer
    then looks behind the broken frame for a request to one of the simulated units (or the broadcast
    address) and takes it when its CRC is right, or keeps its bytes while it is still incomplete.
    """

    def __init__(self, decoder: Any, *, simulator: Simulator, silence: float, arrival: _Arrival | None = None) -> None:
        """pymodbus makes one framer per connection by calling ``server.framer(decoder)``: the server
        sets a :func:`functools.partial` of this class with its simulator, silent interval and the
        arrival record it shares with its request classes."""
        super().__init__(decoder)
        self.simulator = simulator
        self.silence = silence
        self.arrival = arrival or _Arrival()
        self._waiting = 0
        self._since = 0.0

    def decode(self, data: bytes) -> tuple[int, int, int, bytes]:
        now = time.monotonic()
        stale = 0
        whole: tuple[int, int, int, bytes] | None = None
        if self._waiting and len(data) > self._waiting and now - self._since > self.silence:
            # these bytes never became a frame before the line went quiet: a new frame starts after
            # them, unless old and new bytes are one frame that the host delivered in two pieces
            whole = super().decode(data)
            if not whole[3]:
                whole = None
                stale = self._waiting
        used, dev_id, tid, frame = whole if whole is not None else super().decode(data[stale:])
        if used and not frame:
            self.simulator.frame_error(data[stale] if len(data) > stale else None)
            skip, found = self._behind_noise(data[stale:])
            if found is not None:
                used, dev_id, tid, frame = skip + found[0], found[1], found[2], found[3]
            elif skip:  # an unfinished request behind the noise: keep its bytes, wait for the rest
                self._waiting = len(data) - stale - skip
                self._since = now
                return stale + skip, 0, 0, self.EMPTY
        if frame:
            self.arrival.found(now)
        if used or frame:
            self._waiting = 0
            return used + stale, dev_id, tid, frame
        self._waiting = len(data) - stale
        self._since = now
        return stale, dev_id, tid, frame

    def _behind_noise(self, data: bytes) -> tuple[int, tuple[int, int, int, bytes] | None]:
        """After a broken frame at the start of ``data``: (offset, decoded request) of the first request to a
        simulated unit with a right CRC, or (offset, None) of the first one still incomplete, or (0, None)."""
        sim = self.simulator
        units = set(sim.unit_ids)
        if sim.spec.protocol.broadcast_address is not None:
            units.add(sim.spec.protocol.broadcast_address)
        for start in range(1, len(data) - 1):
            if data[start] not in units:
                continue
            found = super().decode(data[start:])
            if found[3] and found[3][0]:
                return start, found
            if not found[0]:
                return start, None  # not complete yet
        return 0, None


class _WatchAscii(FramerAscii):
    """pymodbus's ASCII framer, fed one frame at a time; frames whose LRC, hex or code is bad are reported.

    Framing follows the Modbus serial line spec (2.5.2.1): a ':' always starts a new frame (the
    bytes of an unfinished one before it are dropped) and the end marker ends it. Each frame is
    then decoded by pymodbus alone, so a broken frame never takes the next one with it.
    """

    def __init__(self, decoder: Any, *, simulator: Simulator, arrival: _Arrival | None = None) -> None:
        """Made per connection by pymodbus through the server's :func:`functools.partial` (see :class:`_WatchRTU`)."""
        super().__init__(decoder)
        self.simulator = simulator
        self.arrival = arrival or _Arrival()

    def decode(self, data: bytes) -> tuple[int, int, int, bytes]:
        now = time.monotonic()
        total = 0
        while True:
            used, dev_id, tid, frame = self._decode_one(data[total:])
            total += used
            if frame:
                self.arrival.found(now)
            if frame or not used or total >= len(data):
                return total, dev_id, tid, frame

    def _decode_one(self, data: bytes) -> tuple[int, int, int, bytes]:
        end = data.find(self.end)
        if end == -1:
            last = data.rfind(self.START)  # keep only the frame being received
            return (last if last != -1 else len(data)), 0, 0, self.EMPTY
        start = data.rfind(self.START, 0, end)
        stop = end + len(self.end)
        if start == -1:
            return stop, 0, 0, self.EMPTY  # a line without a start: noise
        candidate = data[start:stop]
        try:
            _, dev_id, tid, frame = super().decode(candidate)
        except ValueError:  # pymodbus parses the unit id outside its try block: non-hex raises
            dev_id, tid, frame = 0, 0, self.EMPTY
        if not frame:  # bad hex/LRC or too short (00h is a request: answered with illegal function)
            try:
                unit: int | None = bytes.fromhex(candidate[1:3].decode("ascii"))[0]
            except (ValueError, UnicodeDecodeError, IndexError):
                unit = None
            self.simulator.frame_error(unit)
            frame = self.EMPTY
        return stop, dev_id, tid, frame


def _write_at_once(transport: Any, arrival: _Arrival) -> None:
    """Make pymodbus's serial transport write a reply to the port when it is handed over.

    pymodbus's ``SerialTransport.write`` queues the bytes and writes them from a writer callback,
    one event-loop turn later: about 0.1 ms that a device's reply does not wait (bench section 3).
    Here the bytes go to the port at once, with the same non-blocking write pymodbus makes; what
    the port does not take, or anything while bytes are still queued, goes through pymodbus's queue
    as before (so the order of replies is kept), and a port error closes the transport as
    pymodbus does. Without a port (polling transports on Windows) nothing changes. Each write tells
    ``arrival`` when a reply reached the port, so the next reply's wait can end that much earlier."""
    import serial  # pyserial: present wherever a serial server runs

    port = getattr(transport, "sync_serial", None)
    queued = transport.write
    if port is None or getattr(transport, "force_poll", True):
        return

    def write(data: bytes) -> None:
        if transport.intern_write_buffer or transport.sync_serial is not port:
            queued(data)
            return
        arrival.written(time.monotonic())
        try:
            sent = port.write(data) or 0
        except (BlockingIOError, InterruptedError):
            sent = 0
        except serial.SerialException as exc:
            transport.close(exc=exc)
            return
        if sent < len(data):
            queued(data[sent:])

    transport.write = write


def _stamp_reads(transport: Any, arrival: _Arrival) -> None:
    """Tell ``arrival`` when each chunk left the port, before pymodbus's receive path hands it on, so a
    request's processing time counts from the read that brought its last bytes (see :meth:`_Arrival.found`)."""
    protocol = getattr(transport, "intern_protocol", None)
    received = getattr(protocol, "data_received", None)
    if received is None:
        return

    def data_received(data: bytes) -> None:
        arrival.read_at = time.monotonic()
        received(data)

    setattr(protocol, "data_received", data_received)  # noqa: B010 (a bound method replaced on one object)


def _silence_seconds(sim: Simulator, baudrate: int) -> float:
    """How long the line must be quiet before unfinished bytes are dropped: the map's silent interval
    (3.5 characters at ``baudrate``, or its floor above the baud rate the map names; Modbus over
    Serial Line v1.02, 2.5.1.1).

    When the host delivers one frame in two pieces further apart than this, the framer keeps them
    together because together they form a frame with a right CRC (see :class:`_WatchRTU`).
    """
    timing = sim.spec.protocol.timing
    floor_above = timing.silent_interval_floor_above_bps
    if floor_above is not None and baudrate > floor_above and timing.silent_interval_floor_ms:
        return timing.silent_interval_floor_ms / 1000.0
    chars = timing.silent_interval_chars or 3.5
    floor = 0.00175 if baudrate > 19200 else 0.0  # the standard's fixed 1.75 ms above 19200 Bd
    return max(chars * 11 / baudrate, floor)


class SimServer:
    """A running simulator: a pymodbus server on TCP or a serial device, plus a ticker.

    Exactly one of ``tcp=(host, port)`` (port 0 = any free port) and ``serial=DEVICE``.
    """

    def __init__(
        self,
        sim: Simulator,
        *,
        tcp: tuple[str, int] | None = None,
        serial: str | None = None,
        mode: str | None = None,
        baudrate: int | None = None,
        parity: str | None = None,
        stop_bits: int | None = None,
        data_bits: int | None = None,
        allow_remote: bool = False,
        tick_interval: float = 0.02,
        idle_timeout: float | None = None,
    ) -> None:
        if (tcp is None) == (serial is None):
            raise SimulatorError("give exactly one of tcp=(host, port) and serial=DEVICE")
        if tcp is not None and not allow_remote and not is_loopback(tcp[0]):
            raise SimulatorError(f"refusing to listen on non-loopback address {tcp[0]!r} (use --allow-remote)")
        self.sim = sim
        self.tcp = tcp
        self.idle_timeout = idle_timeout
        """Seconds a TCP connection may stay silent before it is closed (None: 60 s, tcp.IDLE_TIMEOUT_S)."""
        self.serial = serial
        spec_serial = sim.spec.protocol.serial
        self.mode = mode or spec_serial.mode or "rtu"
        if serial is not None and self.mode not in ("rtu", "ascii"):
            raise SimulatorError(f"serial mode must be rtu or ascii, not {self.mode!r}")
        if serial is not None and self.mode not in sim.spec.protocol.modes:
            raise SimulatorError(f"{sim.spec.name} does not speak Modbus {self.mode.upper()} (modes: {', '.join(sim.spec.protocol.modes)})")
        self.baudrate = baudrate or spec_serial.baudrate or _DEFAULT_BAUDRATE
        self.parity = _PARITY.get(parity if parity is not None else spec_serial.parity, "N")
        self.stop_bits = stop_bits or spec_serial.stop_bits or 1
        self.data_bits = data_bits or spec_serial.data_bits or 8
        self.tick_interval = tick_interval
        self._server: ModbusTcpServer | ModbusSerialServer | None = None
        self._ticker: asyncio.Task[None] | None = None
        self.address: tuple[str, int] | None = None

    def describe(self) -> str:
        units = ", ".join(str(u) for u in self.sim.unit_ids)
        if self.address is not None:
            host, port = self.address
            shown = f"[{host}]" if ":" in host else host
            return f"{self.sim.spec.name} simulator listening on tcp {shown}:{port} (units {units})"
        return (
            f"{self.sim.spec.name} simulator listening on serial {self.serial} "
            f"({self.mode}, {self.baudrate} baud, {self.data_bits}{self.parity}{self.stop_bits}, units {units})"
        )

    async def start(self) -> None:
        context = [SimDevice(id=uid, simdata=[SimData(0)]) for uid in self.sim.unit_ids]
        arrival = _Arrival()
        custom = _request_classes(self.sim, arrival)
        server: ModbusTcpServer | ModbusSerialServer
        if self.tcp is not None:
            server = SimTcpServer(
                self.sim, context, framer=FramerType.SOCKET, address=self.tcp, ignore_missing_devices=True,
                custom_pdu=custom, idle_timeout=self.idle_timeout,
            )
        else:
            server = ModbusSerialServer(
                context,
                framer=FramerType.RTU if self.mode == "rtu" else FramerType.ASCII,
                port=self.serial or "",
                baudrate=self.baudrate,
                parity=self.parity,
                stopbits=self.stop_bits,
                bytesize=self.data_bits,
                ignore_missing_devices=True,
                custom_pdu=custom,
            )
            server.decoder = _SimDecoder(custom)
            # pymodbus types the attribute as a framer class; it only calls it: ``framer(decoder)``
            if self.mode == "rtu":
                server.framer = functools.partial(_WatchRTU, simulator=self.sim, arrival=arrival,  # type: ignore[assignment]
                                                  silence=_silence_seconds(self.sim, self.baudrate))
            else:
                server.framer = functools.partial(_WatchAscii, simulator=self.sim, arrival=arrival)  # type: ignore[assignment]
        try:
            await server.serve_forever(background=True)
        except RuntimeError as exc:  # pymodbus: "Could not start listen, please check address."
            raise SimulatorError(why_not_listening(self.tcp, self.serial, self.baudrate, exc)) from None
        self._server = server
        if self.tcp is not None:
            sockets = getattr(server.transport, "sockets", None) or []
            name = sockets[0].getsockname() if sockets else self.tcp
            self.address = (str(name[0]), int(name[1]))
        else:
            _write_at_once(server.transport, arrival)
            _stamp_reads(server.transport, arrival)
        self._ticker = asyncio.create_task(self._tick_forever())

    async def _tick_forever(self) -> None:
        last = time.monotonic()
        while True:
            await asyncio.sleep(self.tick_interval)
            now = time.monotonic()
            self.sim.tick(now - last)
            last = now

    async def stop(self) -> None:
        if self._ticker is not None:
            self._ticker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._ticker
            self._ticker = None
        if self._server is not None:
            await self._server.shutdown()  # type: ignore[no-untyped-call]
            self._server = None
        self.sim.save_state()

    async def __aenter__(self) -> SimServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()


class ThreadedSimServer:
    """A :class:`SimServer` on its own event loop in a background thread (for synchronous code)."""

    def __init__(self, sim: Simulator, **options: Any) -> None:
        self.server = SimServer(sim, **options)
        self.sim = sim
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    @property
    def address(self) -> tuple[str, int] | None:
        return self.server.address

    def start(self, timeout: float = 10.0) -> ThreadedSimServer:
        self._thread = threading.Thread(target=self._run, name=f"{self.sim.spec.name}-simulator", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("simulator server did not start")
        if self._error is not None:
            raise self._error
        return self

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self.server.start())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._ready.set()
            loop.close()
            return
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            loop.run_until_complete(self.server.stop())
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    def stop(self, timeout: float = 10.0) -> None:
        if self._loop is not None and self._thread is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout)
        self._thread = None

    def __enter__(self) -> ThreadedSimServer:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.stop()
