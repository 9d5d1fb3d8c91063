"""Stale replies on a serial line (a late reply must never be taken for the next one): a reply delivered twice by the line, or one whose first
byte arrived before our request could have been answered, is dropped, counted in ``stats.stale`` and
never taken for the answer; the client waits for the real one.

The line is :class:`~drivemap.testing.vserial.VirtualSerialLine` with its ``duplicate`` fault on
every reply: each reply arrives twice, the copy right behind the original, i.e. while the client
sends its next request of the same shape (two one-register reads, alternately). The simulator's
values change before every read, so a duplicate taken for an answer shows as a wrong value.

* on a paced line (characters at the baud rate, like a real wire) with the time rule on
  (``stale_guard=True``; a real serial port turns it on by itself), sync and asyncio clients read
  120 values, every one right;
* on an unpaced line (a pty: the default of the test helpers, and what ``socat`` gives) the time
  rule stays off, so answers that come back faster than a wire could carry them are kept; copies
  that arrive between transactions or in front of the answer are still dropped;

The paced line and its simulator run in a process of their own (as a device does), so the client's
timing is not bent by the line emulation sharing its interpreter.
* :func:`~drivemap.runtime.client.transport.staleguard.last_reply` keeps the last of several complete frames.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from pymodbus.framer import FramerAscii, FramerRTU
from pymodbus.pdu import DecodePDU

from drivemap.runtime.client.transport import staleguard
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import VirtualSerialLine
from tests.helpers_client import package, simulator

ev = package("ev")
READS = 60  # pairs of reads: 120 values
#: A copy is caught when it starts before our request has crossed the wire (8 characters): 8.3 ms at
#: 9600 Bd, 4.2 ms at 19200. The virtual line emits its copy a few milliseconds after the original,
#: and on a busy host that moment itself jitters by milliseconds; at 38400 Bd (2 ms per request) a
#: copy that late is, by timing, indistinguishable from the reply (SECURITY.md: not promised).
BAUDS = [9600, 19200]
ROOT = Path(__file__).resolve().parents[3]


@contextmanager
def line_with_duplicates(baud: int, pace: bool) -> Iterator[tuple[Any, VirtualSerialLine]]:
    sim = simulator("ev")
    with VirtualSerialLine(baud, pace=pace) as line, ThreadedSimServer(
        sim, serial=line.device_port, mode="rtu", baudrate=baud, parity="none", stop_bits=1, data_bits=8
    ):
        yield sim, line


#: The device end in a process of its own, as on a real line: a paced virtual line whose every
#: reply is delivered twice, and the ev simulator behind it. Prints the master port, serves until
#: its stdin closes.
DEVICE = """
import importlib, sys
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import VirtualSerialLine
baud = int(sys.argv[1])
sim = importlib.import_module("drivemap_models.ev.simulator").Simulator(units=[1])
with VirtualSerialLine(baud, pace=True) as line, ThreadedSimServer(
        sim, serial=line.device_port, mode="rtu", baudrate=baud, parity="none", stop_bits=1, data_bits=8):
    line.faults.duplicate("to_master", frames=1_000_000)
    print(line.master_port, flush=True)
    sys.stdin.read()
"""


@contextmanager
def device_process(baud: int) -> Iterator[str]:
    proc = subprocess.Popen([sys.executable, "-c", DEVICE, str(baud)], cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdin is not None
        port = proc.stdout.readline().strip()
        assert port.startswith("/dev/"), port
        yield port
    finally:
        if proc.stdin is not None:
            proc.stdin.close()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()


def _serial_kwargs(baud: int, guard: bool | None) -> dict[str, Any]:
    return dict(unit=1, baudrate=baud, parity="none", stopbits=1, timeout=0.3, stale_guard=guard)


REGS = ("digital_speed_ram[0]", "digital_speed_ram[1]")  # two one-register reads of the same shape


@pytest.mark.parametrize("baud", BAUDS)
def test_duplicated_replies_on_a_paced_line_sync(baud: int) -> None:
    with device_process(baud) as port, ev.Client.serial(port, **_serial_kwargs(baud, True)) as drive:
        wrong = []
        for i in range(READS):
            drive.write_by_name(REGS[0], 100 + i)
            drive.write_by_name(REGS[1], 1000 + i)
            got = (drive.read_by_name(REGS[0]), drive.read_by_name(REGS[1]))
            if got != (100 + i, 1000 + i):
                wrong.append((i, *got))
        assert not wrong, f"duplicates taken for answers (i, first, second): {wrong}"
        assert drive.stats.stale >= 2 * READS  # most copies, counted once per transaction


@pytest.mark.parametrize("baud", BAUDS)
def test_duplicated_replies_on_a_paced_line_async(baud: int) -> None:
    async def run(port: str) -> None:
        async with ev.AsyncClient.serial(port, **_serial_kwargs(baud, True)) as drive:
            wrong = []
            for i in range(READS):
                await drive.write_by_name(REGS[0], 100 + i)
                await drive.write_by_name(REGS[1], 1000 + i)
                got = (await drive.read_by_name(REGS[0]), await drive.read_by_name(REGS[1]))
                if got != (100 + i, 1000 + i):
                    wrong.append((i, *got))
            assert not wrong, f"duplicates taken for answers (i, first, second): {wrong}"
            assert drive.stats.stale >= 2 * READS

    with device_process(baud) as port:
        asyncio.run(run(port))


def read_pairs_sync(sim: Any, drive: Any, line: VirtualSerialLine) -> list[tuple[int, int, int]]:
    line.faults.duplicate("to_master", frames=10_000)
    wrong = []
    for i in range(READS):
        sim.set("motor_speed", i)
        sim.set("alarm_no", 1000 + i)
        speed, alarm = drive.motor_speed.read(), drive.alarm_no.read()
        if (speed, alarm) != (i, 1000 + i):
            wrong.append((i, speed, alarm))
    return wrong


def test_unpaced_line_keeps_fast_answers_and_drops_copies() -> None:
    """On a pty the time rule is off: answers faster than a wire are kept (no retry, no timeout);
    copies that arrive between transactions are dropped and counted. (A copy that arrives after
    the request went out cannot be told from the answer there: not promised.)"""
    with line_with_duplicates(38400, pace=False) as (sim, line):
        with ev.Client.serial(line.master_port, **_serial_kwargs(38400, None)) as drive:
            assert not staleguard.real_port(drive.bus.client.socket)  # a pty: the time rule is off
            read_pairs_sync(sim, drive, line)
            assert drive.stats.retries == 0 and drive.stats.timeouts == 0
            assert drive.stats.stale > 0


def test_no_guard_when_asked() -> None:
    with line_with_duplicates(38400, pace=False) as (sim, line):
        with ev.Client.serial(line.master_port, **_serial_kwargs(38400, False)) as drive:
            sim.set("motor_speed", 5)
            assert drive.motor_speed.read() == 5 and drive.stats.stale == 0


def test_time_rule() -> None:
    dropped: list[tuple[bytes, bool]] = []
    guard = staleguard.StaleGuard(0.001, lambda data, first: dropped.append((data, first)), mode=True)
    guard.sent(8, 10.0, port=None)
    assert guard.earliest == pytest.approx(10.0 + 8 * 0.001 + 0.001)
    assert guard.stale(10.005)  # during our request: stale
    assert guard.stale(10.0085)
    assert guard.stale(10.0095)  # after the earliest time, but the rest of that stale frame
    assert not guard.stale(10.0125)  # after a silence: the reply
    guard.sent(8, 20.0, port=None)
    assert guard.stale(20.0100, nbytes=7)  # 7 bytes seen at once: the first came 6 characters earlier
    guard.sent(8, 30.0, port=None)
    assert not guard.stale(30.0160, nbytes=7)
    guard.drop(b"\x01")
    guard.drop(b"\x02")
    assert dropped == [(b"\x01", True), (b"\x02", False)]  # counted once per transaction
    off = staleguard.StaleGuard(0.001, lambda data, first: None, mode=None)
    off.sent(8, 10.0, port=None)  # not a serial driver: only what was there before the request
    assert off.earliest == 10.0 and not off.stale(10.0001)


def _rtu(hexbytes: str) -> bytes:
    body = bytes.fromhex(hexbytes)
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


def _ascii(hexbytes: str) -> bytes:
    body = bytes.fromhex(hexbytes)
    return b":" + (body + bytes([FramerAscii.compute_LRC(body)])).hex().upper().encode() + b"\r\n"


def test_last_of_several_complete_frames_is_the_reply() -> None:
    rtu = FramerRTU(DecodePDU(False))
    old, new = _rtu("01 03 02 00 05"), _rtu("01 03 02 00 06")
    assert staleguard.last_reply(rtu, old + new) == (new, old)
    assert staleguard.last_reply(rtu, old + old + new) == (new, old + old)
    assert staleguard.last_reply(rtu, new) == (new, b"")
    assert staleguard.last_reply(rtu, old + new[:4]) == (old + new[:4], b"")  # the second is not complete
    assert staleguard.last_reply(rtu, old[:-1] + b"\x00" + new) == (old[:-1] + b"\x00" + new, b"")  # bad CRC
    asc = FramerAscii(DecodePDU(False))
    a_old, a_new = _ascii("01 03 02 00 05"), _ascii("01 03 02 00 06")
    assert staleguard.last_reply(asc, a_old + a_new) == (a_new, a_old)
    assert staleguard.last_reply(asc, a_new) == (a_new, b"")
