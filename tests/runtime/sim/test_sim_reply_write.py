"""The serial simulator's reply path (runtime/sim/serve): a reply goes to the port when it is handed
over (not one event-loop turn later), in order, and the wait before it learns how long the way to
the port takes, within a bound, so the reply reaches the port when the map's timing says."""

from __future__ import annotations

from typing import Any

import pytest
import serial

from drivemap.runtime.sim.serve import _Arrival, _stamp_reads, _write_at_once


class Port:
    """A pyserial port that takes at most ``room`` bytes per write (None: all)."""

    def __init__(self, room: int | None = None, error: Exception | None = None) -> None:
        self.room, self.error, self.wire = room, error, b""

    def write(self, data: bytes) -> int:
        if self.error is not None:
            raise self.error
        taken = data if self.room is None else data[: self.room]
        self.wire += taken
        return len(taken)


class Transport:
    """What pymodbus's SerialTransport offers the patch: its queue, its port, close()."""

    force_poll = False

    def __init__(self, port: Port) -> None:
        self.sync_serial: Any = port
        self.intern_write_buffer: list[bytes] = []
        self.closed: Exception | None = None

    def write(self, data: bytes) -> None:  # pymodbus: queued until the port is writable
        self.intern_write_buffer.append(data)

    def close(self, exc: Exception | None = None) -> None:
        self.closed = exc


def test_a_reply_reaches_the_port_when_handed_over() -> None:
    transport = Transport(Port())
    _write_at_once(transport, _Arrival())
    transport.write(b"\x01\x03\x02\x00\x01")
    assert transport.sync_serial.wire == b"\x01\x03\x02\x00\x01" and transport.intern_write_buffer == []


def test_what_the_port_does_not_take_is_queued_and_order_is_kept() -> None:
    transport = Transport(Port(room=2))
    _write_at_once(transport, _Arrival())
    transport.write(b"abcde")
    assert transport.sync_serial.wire == b"ab" and transport.intern_write_buffer == [b"cde"]
    transport.write(b"fg")  # bytes still queued: behind them, never before
    assert transport.sync_serial.wire == b"ab" and transport.intern_write_buffer == [b"cde", b"fg"]


def test_a_port_error_closes_the_transport_as_pymodbus_does() -> None:
    error = serial.SerialException("gone")
    transport = Transport(Port(error=error))
    _write_at_once(transport, _Arrival())
    transport.write(b"x")
    assert transport.closed is error


def test_a_polling_transport_is_left_as_it_is() -> None:
    transport = Transport(Port())
    transport.force_poll = True
    write = transport.write
    _write_at_once(transport, _Arrival())
    assert transport.write == write


def test_the_lead_follows_the_lateness_within_its_bound() -> None:
    arrival = _Arrival()
    arrival.written(10.0)  # nothing was due: nothing learnt
    assert arrival.lead == 0.0
    for _ in range(20):  # replies reach the port 80 µs late, then the wait ends earlier
        arrival.due = 5.0
        arrival.written(5.0 + 0.00008 - arrival.lead)
    assert arrival.lead == pytest.approx(0.00008, abs=1e-6)
    arrival.due = 5.0
    arrival.written(5.1)  # one very late reply (the machine was busy): the lead stays bounded
    assert arrival.lead == _Arrival.MAX_LEAD
    for _ in range(40):  # early replies bring it back down, never below 0
        arrival.due = 5.0
        arrival.written(4.99)
    assert arrival.lead == 0.0


class Protocol:
    """pymodbus's protocol: the transport hands it each chunk it reads from the port."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def data_received(self, data: bytes) -> None:
        self.chunks.append(data)


def test_a_request_arrives_when_its_bytes_are_read_not_when_framed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The processing time counts from the read that completed the request: pymodbus's receive path
    between the read and the framer is the simulator's own time, which a device's UART does not add."""
    import drivemap.runtime.sim.serve as serve

    clock = iter([7.0, 9.0])
    monkeypatch.setattr(serve.time, "monotonic", lambda: next(clock))
    transport, protocol, arrival = Transport(Port()), Protocol(), _Arrival()
    transport.intern_protocol = protocol  # type: ignore[attr-defined]
    _stamp_reads(transport, arrival)
    transport.intern_protocol.data_received(b"\x01\x06")  # type: ignore[attr-defined]
    assert protocol.chunks == [b"\x01\x06"] and arrival.read_at == 7.0
    arrival.found(7.0004)  # framed 0.4 ms after the read
    assert arrival.at == 7.0 and arrival.read_at == 0.0
    arrival.found(8.0)  # a frame found with no read just before it (or a stale one): the framer's time
    assert arrival.at == 8.0
    arrival.read_at = 5.0
    arrival.found(8.0)
    assert arrival.at == 8.0
