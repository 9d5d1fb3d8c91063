"""``client.read_registers(table, address, count)``: raw words from a real server, typed errors before the wire."""

from __future__ import annotations

import struct

import pytest

from drivemap.runtime.errors import (
    BroadcastRead,
    InvalidValue,
    UnsupportedFunction,
    ValueOutOfRange,
    WriteOnlyRegister,
)
from tests.helpers_client import package, tcp_server


def test_reads_part_of_a_string_and_float_words() -> None:
    with tcp_server("fronius_symo_hybrid") as (sim, host, port):
        sim.set("manufacturer", "Fronius")
        with package("fronius_symo_hybrid").Client.tcp(host, port, 1, timeout=2.0) as client:
            assert client.read_registers("holding", 40004, 4) == [0x4672, 0x6F6E, 0x6975, 0x7300]
            assert client.manufacturer.read() == "Fronius"  # the typed read of the whole element agrees
    with tcp_server("sdm630") as (sim, host, port):
        sim.set("phase_1_voltage", 230.5)
        with package("sdm630").Client.tcp(host, port, 1, timeout=2.0) as client:
            words = client.read_registers("input", 0, 2)
            assert struct.unpack(">f", struct.pack(">HH", *words))[0] == 230.5
            assert client.stats.by_function.get(0x04) == 1


async def test_async_twin_reads_the_same_words() -> None:
    with tcp_server("fronius_symo_hybrid") as (sim, host, port):
        sim.set("manufacturer", "Fronius")
        async with package("fronius_symo_hybrid").AsyncClient.tcp(host, port, 1, timeout=2.0) as client:
            assert await client.read_registers("holding", 40004, 4) == [0x4672, 0x6F6E, 0x6975, 0x7300]
            with pytest.raises(InvalidValue):
                await client.read_registers("holdings", 40004, 4)


@pytest.mark.parametrize(("args", "error"), [
    (("holdings", 0, 1), InvalidValue),          # no such table
    (("input", "0", 2), InvalidValue),           # address not an int
    (("input", 0, True), InvalidValue),          # a bool is not a count
    (("input", 0, 0), ValueOutOfRange),
    (("input", 0, 126), ValueOutOfRange),        # more than 04h reads
    (("input", 0xFFFF, 2), ValueOutOfRange),     # past the address space
    (("coil", 0, 1), UnsupportedFunction),       # the meter's map lists no 01h
    (("holding", 0xF010, 1), WriteOnlyRegister),  # reset: a write-only command register
])
def test_bad_requests_are_refused_before_the_wire(args: tuple[object, ...], error: type[Exception]) -> None:
    with tcp_server("sdm630") as (_sim, host, port):
        with package("sdm630").Client.tcp(host, port, 1, timeout=2.0) as client:
            with pytest.raises(error):
                client.read_registers(*args)  # type: ignore[arg-type]
            assert client.stats.transactions == 0


def test_broadcast_client_cannot_read_raw() -> None:
    pkg = package("ev")  # ev allows broadcast writes, so a broadcast client exists
    with tcp_server("ev") as (_sim, host, port):
        with pkg.Client.tcp(host, port, 1, timeout=2.0) as client:
            bc = pkg.Client.broadcast(client.bus)
            with pytest.raises(BroadcastRead):
                bc.read_registers("holding", 0, 1)
            assert client.stats.transactions == 0
