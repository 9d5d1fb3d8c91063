"""Runtime misuse (bad runtime input gets a clear typed error before anything is sent): every error a caller can cause is a drivemap error class,
raised before anything is sent.

* a flags register refuses bits its map does not define (``NetIn(0x8000)``);
* an array index is 0..count-1: ``drive.digital_speed_ram[-1]`` is not element 7 but an
  :class:`IndexOutOfRange` (also an ``IndexError``) naming the register and its count;
* a command register is written only with the map's command value (``.execute()``); any other
  value, by any route (``write``, ``write_raw``, ``write_many``, ``write_by_name``, broadcast),
  is refused;
* ``write(10**400)`` is :class:`ValueOutOfRange` (not ``OverflowError``), ``page_policy="bogus"``
  and bad serial settings are :class:`InvalidArgument` (not ``ValueError``/``TypeError``/``KeyError``);
* a peer that resets the connection gives :class:`TransportError`, never ``ConnectionResetError``,
  and the next call reconnects.

"Before the wire" is checked on the bus counters (no request sent, no byte) and on the simulator
(nothing changed).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from drivemap.runtime.client import ReadWriteCommand
from drivemap.runtime.client.transport.bus import AsyncBus, Bus
from drivemap.runtime.errors import (
    DriveError,
    IndexOutOfRange,
    InvalidArgument,
    InvalidValue,
    TransportError,
    ValueOutOfRange,
)
from tests.helpers_client import TIMEOUT, package, tcp_server

ev = package("ev")
edx = package("edx")


@pytest.fixture
def ev_drive() -> Iterator[tuple[Any, Any]]:
    with tcp_server("ev") as (sim, host, port):
        with ev.Client.tcp(host, port, unit=1, timeout=TIMEOUT) as drive:
            yield sim, drive


@contextlib.contextmanager
def nothing_sent(drive: Any) -> Iterator[None]:
    before = (drive.stats.transactions, drive.stats.bytes_sent)
    yield
    assert (drive.stats.transactions, drive.stats.bytes_sent) == before, "a refused call reached the wire"


# --------------------------------------------------------------------------------- flags
def test_flags_refuse_bits_the_map_does_not_define(ev_drive: tuple[Any, Any]) -> None:
    sim, drive = ev_drive
    for bad in (ev.NetIn(0x8000), ev.NetIn(0x0100) | ev.NetIn.X0, ev.NetIn(0xFF00)):
        with nothing_sent(drive), pytest.raises(ValueOutOfRange, match="not defined by the map"):
            drive.net_in.write(bad)
        with nothing_sent(drive), pytest.raises(ValueOutOfRange):
            drive.write_by_name("net_in", int(bad))
        with nothing_sent(drive), pytest.raises(ValueOutOfRange):
            drive.write_many([(drive.net_in, bad), (drive.digital_speed_ram[0], 100)])
    assert sim.get_raw("net_in") == 0
    drive.net_in.write(ev.NetIn.X0 | ev.NetIn.X7)  # every defined bit still goes out
    assert sim.get_raw("net_in") == 0x81


# --------------------------------------------------------------------------------- array index
@pytest.mark.parametrize("index", [-1, -8, -9, 8, 100])
def test_array_index_outside_0_to_count_minus_1(ev_drive: tuple[Any, Any], index: int) -> None:
    sim, drive = ev_drive
    before = [sim.get(f"digital_speed_ram[{i}]") for i in range(8)]
    with nothing_sent(drive):
        with pytest.raises(IndexOutOfRange) as info:
            drive.digital_speed_ram[index].write(1000)
        assert isinstance(info.value, IndexError) and isinstance(info.value, DriveError)
        assert "digital_speed_ram" in str(info.value) and "8 elements" in str(info.value)
        with pytest.raises(IndexOutOfRange):
            drive.digital_speed_ram[index].read()
    assert [sim.get(f"digital_speed_ram[{i}]") for i in range(8)] == before


def test_array_index_of_another_type(ev_drive: tuple[Any, Any]) -> None:
    _, drive = ev_drive
    for index in ("1", 1.0, slice(0, 2), None):
        with nothing_sent(drive), pytest.raises(InvalidValue):
            drive.digital_speed_ram[index]
    assert [e.name for e in drive.digital_speed_ram] == [f"digital_speed_ram[{i}]" for i in range(8)]
    assert drive.digital_speed_ram[7].name == "digital_speed_ram[7]"


async def test_async_array_index() -> None:
    with tcp_server("ev") as (_, host, port):
        async with ev.AsyncClient.tcp(host, port, timeout=TIMEOUT) as drive:
            with nothing_sent(drive), pytest.raises(IndexOutOfRange):
                await drive.digital_speed_ram[-1].write(5)


# --------------------------------------------------------------------------------- commands
def test_command_register_is_written_only_with_its_command_value(ev_drive: tuple[Any, Any]) -> None:
    sim, drive = ev_drive
    assert isinstance(drive.alarm_reset, ReadWriteCommand)
    for value in (0, 2, 65535):
        with nothing_sent(drive), pytest.raises(ValueOutOfRange, match="only 1 may be written"):
            drive.alarm_reset.write(value)
        with nothing_sent(drive), pytest.raises(ValueOutOfRange):
            drive.alarm_reset.write_raw(value)
        with nothing_sent(drive), pytest.raises(ValueOutOfRange):
            drive.write_by_name("alarm_reset", value)
        with nothing_sent(drive), pytest.raises(ValueOutOfRange):
            drive.write_many([(drive.alarm_reset, value), (drive.alarm_history_clear, 1)])
    writes = sim.spec  # the simulator saw no write at all
    assert writes is not None
    sent = drive.stats.transactions
    drive.alarm_reset.execute()
    drive.alarm_reset.write(1)  # the command value itself is a valid write
    drive.write_by_name("configuration", 1)
    assert drive.stats.transactions == sent + 3


def test_command_refused_on_a_broadcast_client_too() -> None:
    with tcp_server("ev", units=(1, 2)) as (_, host, port):
        bus = Bus.tcp(host, port, timeout=TIMEOUT)
        with bus:
            everyone = ev.Client.broadcast(bus)
            if not hasattr(everyone, "alarm_reset"):
                pytest.fail("ev's alarm_reset (06h, broadcast allowed) must be on the broadcast client")
            with nothing_sent(everyone), pytest.raises(ValueOutOfRange):
                everyone.alarm_reset.write(2)
            everyone.alarm_reset.execute()
            assert bus.stats.broadcasts == 1


async def test_async_command() -> None:
    with tcp_server("ev") as (sim, host, port):
        async with ev.AsyncClient.tcp(host, port, timeout=TIMEOUT) as drive:
            with nothing_sent(drive), pytest.raises(ValueOutOfRange):
                await drive.alarm_reset.write(2)
            await drive.alarm_reset.execute()
            assert drive.stats.by_function.get(0x06) == 1


# --------------------------------------------------------------------------------- untyped errors
@pytest.mark.parametrize("value", [10**400, -(10**400), 10**5000], ids=["1e400", "-1e400", "1e5000"])
def test_huge_ints_are_out_of_range(ev_drive: tuple[Any, Any], value: int) -> None:
    _, drive = ev_drive
    int_reg = drive.digital_speed_ram[0]
    with nothing_sent(drive), pytest.raises(ValueOutOfRange):
        int_reg.write(value)
    with nothing_sent(drive), pytest.raises(ValueOutOfRange):
        int_reg.write_raw(value)
    with nothing_sent(drive), pytest.raises(ValueOutOfRange):
        drive.write_by_name("digital_speed_ram[1]", value)


def test_huge_int_on_a_float_register() -> None:
    reg = next(r for r in edx.SPEC.registers if r.writable and r.scale != 1 and r.count == 1 and not r.enum
               and not r.bits and r.page is None and r.command_value is None)
    with tcp_server("edx") as (_, host, port), edx.Client.tcp(host, port, timeout=TIMEOUT) as drive:
        for value in (10**400, float("inf"), float("nan")):
            with nothing_sent(drive), pytest.raises(ValueOutOfRange):
                getattr(drive, reg.name).write(value)


@pytest.mark.parametrize("policy", ["bogus", "", None, 1, "RAISE"])
async def test_bad_page_policy(policy: Any) -> None:
    with pytest.raises(InvalidArgument, match="page_policy"):
        ev.Client.tcp("127.0.0.1", 1, page_policy=policy)
    with pytest.raises(InvalidArgument, match="page_policy"):
        ev.AsyncClient.tcp("127.0.0.1", 1, page_policy=policy)


def test_async_client_outside_an_event_loop() -> None:
    with pytest.raises(TransportError, match="event loop"):
        ev.AsyncClient.tcp("127.0.0.1", 1)


@pytest.mark.parametrize("overrides", [
    {"parity": "bogus"}, {"parity": 3}, {"mode": "tcp"}, {"stopbits": 3}, {"bytesize": 9}, {"baudrate": -1},
    {"baudrate": "fast"}, {"flow": "rts"},
])
def test_bad_serial_settings(overrides: dict[str, Any]) -> None:
    with pytest.raises(InvalidArgument):
        ev.Client.serial("/dev/null-no-such-port", **overrides)
    with pytest.raises(InvalidArgument):
        AsyncBus.serial("/dev/null-no-such-port", ev.SPEC.protocol.serial, **overrides)


@contextlib.contextmanager
def resetting_peer() -> Iterator[tuple[str, int]]:
    """A TCP peer on 127.0.0.1 that reads each request and resets the connection (RST, no reply)."""
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(16)
    listener.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except OSError:
                continue
            with conn:
                conn.settimeout(2.0)
                with contextlib.suppress(OSError):
                    while conn.recv(260):
                        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                        break  # closing with linger 0 sends RST

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield listener.getsockname()
    finally:
        stop.set()
        thread.join(2.0)
        listener.close()


@pytest.mark.slow  # a real peer resetting TCP connections
def test_connection_reset_is_a_transport_error() -> None:
    with resetting_peer() as (host, port), ev.Client.tcp(host, port, timeout=TIMEOUT, retries=0) as drive:
        for _ in range(6):  # every read, not every second one: the bus reconnects after a reset
            with pytest.raises(TransportError):
                drive.motor_speed.read()


@pytest.mark.slow  # a real peer resetting TCP connections
async def test_async_connection_reset_is_a_transport_error() -> None:
    with resetting_peer() as (host, port):
        drive = ev.AsyncClient.tcp(host, port, timeout=TIMEOUT, retries=0)
        try:
            for _ in range(4):
                with pytest.raises(TransportError):
                    await drive.motor_speed.read()
        finally:
            drive.close()
