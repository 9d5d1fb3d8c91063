"""The sync serial receiver (:mod:`drivemap.runtime.client.transport.serialrx`) reads the replies on the default path,
with the stale-reply guard (:mod:`drivemap.runtime.client.transport.staleguard`) on or automatic.

Every test checks :attr:`SerialReceiver.handled` (replies the receiver read itself, not through
pymodbus's polling receive) besides the values and counters, for RTU and ASCII:

* ``stale_guard=True`` on a paced line (characters at 9600 Bd, like a wire): the time rule drops what
  began before the request could be answered (an echo of our request, a duplicate, a late reply);
* ``stale_guard=None`` (auto, the default) on an unpaced pty: the guard has no time rule there (not a
  serial driver) but still drops bytes that arrive between transactions and the earlier of frames
  that come back to back; the receiver is used all the same.

The device is the ev simulator in this process on a :class:`VirtualSerialLine` (9600 Bd leaves
milliseconds of margin on every timing rule). On a paced line sharing the interpreter, a host too
busy to keep the line's pace now and then loses a request (the relay stalls in the middle of it and
pymodbus's server drops the pieces): those attempts time out and are retried, so the paced variants
allow timeouts (``retried``) and count the receiver's replies against the attempts answered.
"""

from __future__ import annotations

import os
import select
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from drivemap.runtime.client.transport import staleguard
from drivemap.runtime.client.transport.serialrx import SerialReceiver
from drivemap.runtime.errors import DeviceException
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import FrameFault, VirtualSerialLine
from tests.helpers_client import package, simulator
from tests.runtime.client.test_client_faults import ascii_frame, rtu

ev = package("ev")
BAUD = 9600
TIMEOUT = 0.3
MODES = [m for m in ("rtu", "ascii") if m in ev.SPEC.protocol.modes]
#: (stale_guard, paced line): the guard forced on a line paced like a wire; auto on a plain pty
GUARDS = [pytest.param(True, True, id="guard-on-paced"), pytest.param(None, False, id="guard-auto-pty")]


@contextmanager
def drive_on_line(mode: str, guard: bool | None, pace: bool, realistic: bool = False,
                  **kw: Any) -> Iterator[tuple[Any, VirtualSerialLine, Any]]:
    sim = ev.simulator.Simulator(units=[1], realistic_timing=True) if realistic else simulator("ev")
    with VirtualSerialLine(BAUD, pace=pace) as line, ThreadedSimServer(
        sim, serial=line.device_port, mode=mode, baudrate=BAUD, parity="none", stop_bits=1, data_bits=8
    ), ev.Client.serial(line.master_port, unit=1, mode=mode, baudrate=BAUD, parity="none", stopbits=1,
                        timeout=kw.pop("timeout", TIMEOUT), stale_guard=guard, **kw) as drive:
        yield sim, line, drive


def receiver_of(drive: Any) -> SerialReceiver:
    receiver = drive.bus._receiver
    assert isinstance(receiver, SerialReceiver)
    return receiver


def retried(drive: Any, pace: bool, expected: int = 0) -> bool:
    """No retry beyond ``expected`` but for timeouts a paced line may cause (see the module docstring)."""
    stats = drive.stats
    extra = stats.retries - expected
    return extra == 0 or (pace and extra == stats.timeouts - expected and stats.rejected == 0)


def frame(mode: str, hexbytes: str) -> bytes:
    return rtu(hexbytes) if mode == "rtu" else ascii_frame(hexbytes)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("guard,pace", GUARDS)
def test_receiver_reads_every_reply_on_the_default_path(mode: str, guard: bool | None, pace: bool) -> None:
    with drive_on_line(mode, guard, pace) as (sim, line, drive):
        receiver = receiver_of(drive)
        assert receiver.guard is not None  # the guard hands its rule to the receiver
        assert receiver.guard.mode is guard
        for i in range(5):
            sim.set("motor_speed", 100 + i)
            assert drive.motor_speed.read() == 100 + i
            drive.digital_speed_ram[0].write(200 + i)
        assert sim.get("digital_speed_ram[0]") == 204
        # every reply, none through pymodbus's polling receive
        assert receiver.handled == drive.stats.transactions - drive.stats.timeouts >= 10
        assert retried(drive, pace) and drive.stats.stale == 0
        # the receiver listened the guard's settle time after the last byte (a frame that follows would
        # have been seen) and told the bus, which counts its quiet time from that last byte
        assert receiver.guard.settle_s <= drive.bus._rx_quiet_s < 0.1


@pytest.mark.parametrize("mode", MODES)
def test_receiver_without_guard(mode: str) -> None:
    with drive_on_line(mode, False, False) as (sim, line, drive):
        receiver = receiver_of(drive)
        assert receiver.guard is None
        sim.set("motor_speed", 7)
        assert drive.motor_speed.read() == 7 and receiver.handled == 1


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("guard,pace", GUARDS)
def test_duplicated_reply_is_dropped(mode: str, guard: bool | None, pace: bool) -> None:
    with drive_on_line(mode, guard, pace) as (sim, line, drive):
        receiver = receiver_of(drive)
        sim.set("motor_speed", 5)
        line.faults.duplicate("to_master")
        assert drive.motor_speed.read() == 5
        sim.set("motor_speed", 6)
        if not pace:  # no time rule on a pty: the copy must come before the next request (not promised after)
            line.wait_idle(1.0)
        assert drive.motor_speed.read() == 6  # not the copy of the first reply
        assert drive.stats.stale >= 1 and retried(drive, pace)
        assert receiver.handled >= 2


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("guard,pace", GUARDS)
def test_late_reply_of_the_previous_attempt_is_not_the_answer(mode: str, guard: bool | None, pace: bool) -> None:
    """The first reply comes after the timeout, with the old value; the answer to the retry comes
    right behind it with the new one (the value changes while the first reply is held)."""
    with drive_on_line(mode, guard, pace, timeout=0.15, retries=1) as (sim, line, drive):
        receiver = receiver_of(drive)
        sim.set("motor_speed", 1)
        line.faults.delay("to_master", 0.2)  # lands well inside attempt 2's timeout
        timer = threading.Timer(0.08, sim.set, ("motor_speed", 2))  # after the device answered attempt 1
        timer.start()
        try:
            assert drive.motor_speed.read() == 2
        finally:
            timer.join()
        assert retried(drive, pace, 1) and drive.stats.stale >= 1
        assert receiver.handled >= 1  # attempt 1 timed out; the receiver read attempt 2's reply behind the late one


@pytest.mark.parametrize("mode", MODES)
def test_echo_of_the_request_is_dropped(mode: str) -> None:
    """A line that echoes our request (2-wire RS-485 adapters): the echo begins while the request is
    still going out, so the time rule drops it and the receiver reads the reply behind it. The device
    answers after its real turnaround (realistic timing), as a device on a wire does: a reply glued
    to the echo would be taken for the rest of it (staleguard.CONTINUATION_CHARS)."""
    with drive_on_line(mode, True, True, realistic=True) as (sim, line, drive):
        receiver = receiver_of(drive)
        sim.set("motor_speed", 11)
        assert drive.motor_speed.read() == 11
        line.wait_idle(1.0)
        request = line.frames("to_device")[-1]
        sent = len(line.captured("to_device"))

        def echo() -> None:
            if line.wait_captured("to_device", sent + len(request), timeout=5.0):
                line.faults.inject("to_master", request)

        thread = threading.Thread(target=echo, daemon=True)
        thread.start()
        sim.set("motor_speed", 12)
        assert drive.motor_speed.read() == 12
        thread.join(5.0)
        assert line.delivered("to_master").count(request) == 1  # the echo did reach the client
        assert drive.stats.stale >= 1 and retried(drive, True)
        assert receiver.handled >= 2


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("guard,pace", GUARDS)
def test_short_reply_garbage_and_bad_check_through_the_receiver(mode: str, guard: bool | None, pace: bool) -> None:
    with drive_on_line(mode, guard, pace) as (sim, line, drive):
        receiver = receiver_of(drive)
        sim.set("motor_speed", 21)
        # an exception reply is shorter than the reply expected: its head says so, it is typed at once
        line.faults.add("to_master", FrameFault(drop=True, prefix=frame(mode, "01 83 02")))
        with pytest.raises(DeviceException) as err:
            drive.motor_speed.read()
        assert err.value.code == 2 and retried(drive, pace) and receiver.handled >= 1
        # a reply cut short: the attempt times out, the retry is read
        line.faults.truncate("to_master", keep=4)
        assert drive.motor_speed.read() == 21
        assert retried(drive, pace, 1) and receiver.handled >= 3
        # a bad CRC/LRC: dropped by pymodbus's framer, the retry is read
        line.faults.corrupt("to_master", byte_index=3)
        assert drive.motor_speed.read() == 21
        assert retried(drive, pace, 2) and receiver.handled >= 5
        # garbage glued in front of the reply: never taken for a value
        line.faults.garbage("to_master", b"\x00\xff\x13" if mode == "rtu" else b"#!?")
        assert drive.motor_speed.read() == 21
        assert receiver.handled >= 6
        time.sleep(0.01)
        sim.set("motor_speed", 22)
        assert drive.motor_speed.read() == 22


def test_receiver_takes_only_the_first_receive_of_a_transaction() -> None:
    with drive_on_line("rtu", None, False) as (sim, line, drive):
        receiver = receiver_of(drive)
        assert receiver.takes(None) is None  # no transaction yet
        assert drive.motor_speed.read() is not None
        assert receiver.takes(None) is None and receiver.takes(4) is None  # that transaction is read
        assert staleguard.SETTLE_CHARS * receiver.char_s <= receiver.guard.settle_s


# ----------------------------------------------------------------------------- a copy past the time rule
@contextmanager
def scripted_device(script: list[tuple[float, bytes]]) -> Iterator[str]:
    """A pty whose device end answers every request by writing each ``(delay s, bytes)`` of ``script``
    that long after the request arrived (no relay: the timing is the script's)."""
    master, slave = os.openpty()
    port = os.ttyname(slave)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            if not select.select([master], [], [], 0.05)[0]:
                continue
            try:
                os.read(master, 256)  # the request (one write by pymodbus)
            except OSError:
                return
            arrived = time.monotonic()
            for delay, data in script:
                while (left := arrived + delay - time.monotonic()) > 0:
                    time.sleep(min(left, 0.0005) if left < 0.002 else left - 0.001)
                os.write(master, data)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield port
    finally:
        stop.set()
        thread.join(2.0)
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("guard", [True, None], ids=["guard-on", "guard-auto"])
def test_copy_past_the_time_rule_followed_by_the_reply(mode: str, guard: bool | None) -> None:
    """A copy of an earlier reply that begins after the request could have been answered (so the time
    rule cannot tell it), then the real reply 2 characters after the copy: longer than the
    receiver's own end-of-frame quiet time (1.5 characters), shorter than the guard's settle time (4).
    The receiver listens for the settle time, hands both frames over, and the guard keeps the last:
    the bug of a receiver that stopped after the first frame (the copy was the answer)."""
    char = 10 / BAUD
    copy, reply = frame(mode, "01 03 02 00 05"), frame(mode, "01 03 02 00 06")
    request = 17 if mode == "ascii" else 8  # characters of the 03h request
    # written at once, so by the time rule the copy began len(copy) - 1 characters before it was read:
    # even so after the earliest possible reply (request + 1 character)
    start = (request + 2 + len(copy)) * char
    script = [(start, copy), (start + 2 * char, reply)]
    with scripted_device(script) as port, ev.Client.serial(port, unit=1, mode=mode, baudrate=BAUD, parity="none",
                                                          stopbits=1, timeout=TIMEOUT, stale_guard=guard) as drive:
        receiver = receiver_of(drive)
        assert receiver.quiet_s < 2 * char < receiver.guard.settle_s
        for _ in range(3):
            assert drive.motor_speed.read() == 6
        assert drive.stats.stale == 3 and drive.stats.retries == 0 and receiver.handled == 3
