"""The client on a faulty virtual serial line, against the generated simulator.

* lost and corrupt (CRC/LRC) replies are retried as the map says (its ``timing.retries``, else the
  runtime default), then :class:`DriveTimeout`;
* a reply that is not the answer to the request just sent (another unit, another function code,
  another address/value/quantity echoed by 06h/10h, another register count, a late or duplicated
  reply to an earlier request) is never returned to the caller;
* a write that needs several requests and fails part-way raises :class:`PartialWrite` saying
  which elements were written, which are unconfirmed and which were not written;
* 50 concurrent async callers on one serial bus: the line capture shows strictly alternating
  request / response frames, and every caller gets exactly its own value back.

Every wait is bounded; response timeouts are short (``TIMEOUT``) so retries cost little.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from pymodbus.framer import FramerAscii, FramerRTU

from drivemap.runtime.client.transport.bus import DEFAULT_RETRIES
from drivemap.runtime.errors import DeviceException, DriveTimeout, PartialWrite
from drivemap.runtime.spec import DeviceSpec, FunctionSpec
from drivemap.testing.vserial import FrameFault, VirtualSerialLine
from tests.helpers_client import package, serial_server

TIMEOUT = 0.2  # response timeout of every client here (seconds)
BAUD = 38400
ev = package("ev")


def rtu(hexbytes: str) -> bytes:
    """An RTU frame with its CRC."""
    body = bytes.fromhex(hexbytes)
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


def ascii_frame(hexbytes: str) -> bytes:
    body = bytes.fromhex(hexbytes)
    return b":" + (body + bytes([FramerAscii.compute_LRC(body)])).hex().upper().encode() + b"\r\n"


def _client(pkg: Any, line: VirtualSerialLine, mode: str = "rtu", unit: int = 1, **kw: Any) -> Any:
    return pkg.Client.serial(line.master_port, unit=unit, mode=mode, baudrate=BAUD, parity="none", stopbits=1,
                             timeout=TIMEOUT, **kw)


def _async_client(pkg: Any, line: VirtualSerialLine, unit: int = 1, **kw: Any) -> Any:
    return pkg.AsyncClient.serial(line.master_port, unit=unit, baudrate=BAUD, parity="none", stopbits=1,
                                  timeout=TIMEOUT, **kw)


def _map_retries(spec: DeviceSpec) -> int:
    return spec.protocol.timing.retries if spec.protocol.timing.retries is not None else DEFAULT_RETRIES


def _with_spec(cls: Any, spec: DeviceSpec) -> Any:
    """The generated client class, but reading ``spec`` (a variant of its map)."""
    return type(cls.__name__, (cls,), {"SPEC": spec})


def _readable_u16(spec: DeviceSpec) -> Any:
    return next(r for r in spec.registers if r.readable and r.page is None and r.count == 1 and r.words == 1
                and not r.enum and not r.bits and r.scale == 1 and (r.max is None or r.max >= 321))


@contextlib.contextmanager
def inject_when_sent(line: VirtualSerialLine, nbytes: int, data: bytes) -> Iterator[threading.Thread]:
    """Put ``data`` on the line towards the master as soon as the master has sent ``nbytes``."""

    def run() -> None:
        if line.wait_captured("to_device", nbytes, timeout=5.0):
            line.faults.inject("to_master", data)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield thread
    finally:
        thread.join(6.0)
        assert not thread.is_alive()


def _delivered_after_request(line: VirtualSerialLine, data: bytes) -> bool:
    """``data`` reached the master after the master's first request of the capture went out."""
    sent = line.chunks("to_device")[0][0]
    return any(chunk.startswith(data) and stamp > sent for stamp, chunk in line.chunks("to_master", "delivered"))


# ----------------------------------------------------------------------------- retries per the map
@pytest.mark.parametrize("model,mode", [("ev", "rtu"), ("edx", "ascii")])
def test_lost_replies_retried_per_map_then_timeout(model: str, mode: str) -> None:
    pkg = package(model)
    reg = _readable_u16(pkg.SPEC)
    attempts = 1 + _map_retries(pkg.SPEC)  # ev: null in the map -> runtime default; edx: the map's 2
    with serial_server(model, mode) as (sim, line):
        sim.set(reg.name, 321)
        with _client(pkg, line, mode) as drive:
            line.faults.drop("to_master", frames=attempts - 1)
            assert drive.read_by_name(reg.name) == 321
            assert drive.stats.retries == attempts - 1 and drive.stats.timeouts == attempts - 1
            line.clear()
            line.faults.drop("to_master", frames=attempts)
            with pytest.raises(DriveTimeout):
                drive.read_by_name(reg.name)
            requests = line.frames("to_device")
            assert len(requests) == attempts and len(set(requests)) == 1  # the same request, resent
            assert line.delivered("to_master") == b""
            sim.set(reg.name, 322)
            assert drive.read_by_name(reg.name) == 322  # the line recovers


@pytest.mark.parametrize("model,mode", [("ev", "rtu"), ("ev", "ascii"), ("edx", "ascii")])
def test_corrupt_replies_crc_lrc_retried_then_timeout(model: str, mode: str) -> None:
    pkg = package(model)
    reg = _readable_u16(pkg.SPEC)
    attempts = 1 + _map_retries(pkg.SPEC)
    index = 4 if mode == "rtu" else 8  # a data byte (RTU) / a data hex digit (ASCII: stays a hex digit)
    with serial_server(model, mode) as (sim, line):
        sim.set(reg.name, 321)
        with _client(pkg, line, mode) as drive:
            line.faults.corrupt("to_master", frames=attempts - 1, byte_index=index, mask=0x01)
            assert drive.read_by_name(reg.name) == 321
            assert drive.stats.retries == attempts - 1
            line.clear()
            line.faults.corrupt("to_master", frames=attempts, byte_index=index, mask=0x01)
            with pytest.raises(DriveTimeout):
                drive.read_by_name(reg.name)
            replies = line.frames("to_master")
            assert len(replies) == attempts
            assert all(d != c for d, c in zip(line.frames("to_master", "delivered"), replies, strict=False))


@pytest.mark.parametrize("retries", [0, 4])
def test_retry_count_comes_from_the_map(retries: int) -> None:
    timing = dataclasses.replace(ev.SPEC.protocol.timing, retries=retries)
    spec = dataclasses.replace(ev.SPEC, protocol=dataclasses.replace(ev.SPEC.protocol, timing=timing))
    client_cls = _with_spec(ev.Client, spec)
    with serial_server("ev", "rtu") as (_sim, line):
        drive = client_cls.serial(line.master_port, unit=1, baudrate=BAUD, parity="none", timeout=TIMEOUT)
        with drive:
            line.faults.drop("to_master", frames=retries + 1)
            with pytest.raises(DriveTimeout):
                drive.motor_speed.read()
            assert drive.stats.transactions == retries + 1
            assert len(line.frames("to_device")) == retries + 1


# ----------------------------------------------------------------------------- replies that are not ours
# Each case replaces the simulator's real reply (to the first attempt) by a well-formed frame that
# answers something else. The client must reject it and retry; the value shown proves which reply
# was used. ``read`` reads motor_speed (03h, 1 register at 0x0002, value 321 = 0x0141).
FOREIGN_READ_REPLIES = {
    "other unit": "02 03 02 00 07",
    "06h echo to a read": "01 06 00 02 00 07",
    "10h echo to a read": "01 10 00 02 00 01",
    "two registers for one": "01 03 04 00 07 00 08",
    "exception to another function": "01 86 02",
}


@pytest.mark.parametrize("case", sorted(FOREIGN_READ_REPLIES))
def test_foreign_reply_to_read_never_accepted(case: str) -> None:
    foreign = rtu(FOREIGN_READ_REPLIES[case])
    with serial_server("ev", "rtu", units=(1, 2)) as (sim, line):
        sim.set("motor_speed", 321, unit=1)
        sim.set("motor_speed", 7, unit=2)
        with _client(ev, line, retries=1) as drive:
            line.faults.add("to_master", FrameFault(drop=True, prefix=foreign))
            assert drive.motor_speed.read() == 321
            assert drive.stats.retries == 1
            assert line.delivered("to_master").startswith(foreign)  # the foreign frame did reach the client
            line.clear()
            line.faults.add("to_master", FrameFault(drop=True, prefix=foreign), frames=2)
            with pytest.raises(DriveTimeout):
                drive.motor_speed.read()


# Writes of digital_speed_ram[2] (0x3F0A) = 1000 (06h) and of digital_speed_ram[0..1] (0x3F08, 10h).
FOREIGN_WRITE_REPLIES = {
    "06h echo of another address": ("single", "01 06 3F 0B 03 E8"),
    "06h echo of another value": ("single", "01 06 3F 0A 03 E9"),
    "06h answered from another unit": ("single", "02 06 3F 0A 03 E8"),
    "06h answered by a read reply": ("single", "01 03 02 03 E8"),
    "10h echo of another address": ("multi", "01 10 3F 09 00 02"),
    "10h echo of another quantity": ("multi", "01 10 3F 08 00 01"),
    "10h answered by a 06h echo": ("multi", "01 06 3F 08 03 E8"),
}


@pytest.mark.parametrize("case", sorted(FOREIGN_WRITE_REPLIES))
def test_foreign_reply_to_write_never_accepted(case: str) -> None:
    kind, frame = FOREIGN_WRITE_REPLIES[case]
    foreign = rtu(frame)

    def write(drive: Any) -> None:
        if kind == "single":
            drive.digital_speed_ram[2].write(1000)
        else:
            drive.write_many([(drive.digital_speed_ram[0], 1000), (drive.digital_speed_ram[1], 1001)])

    with serial_server("ev", "rtu", units=(1, 2)) as (_sim, line):
        with _client(ev, line, retries=1) as drive:
            line.faults.add("to_master", FrameFault(drop=True, prefix=foreign))
            write(drive)  # accepted only on the second attempt, with the real echo
            assert drive.stats.retries == 1
            assert drive.stats.by_function == {0x06 if kind == "single" else 0x10: 2}
            line.clear()
            line.faults.add("to_master", FrameFault(drop=True, prefix=foreign), frames=2)
            with pytest.raises(DriveTimeout):  # never confirmed by a foreign echo
                write(drive)
            assert line.delivered("to_master") == foreign * 2


def _previous_write(drive: Any) -> None:
    drive.digital_speed_ram[2].write(1000)  # reply: 06h echo


def _previous_double_read(drive: Any) -> None:
    drive.read(drive.motor_speed, drive.alarm_no)  # reply: 03h with 2 registers


@pytest.mark.parametrize("previous", [_previous_write, _previous_double_read], ids=["06h-echo", "03h-2-regs"])
def test_stale_reply_of_previous_request_during_next_transaction(previous: Any) -> None:
    """The real reply to the next request is lost and the previous reply arrives (again) while
    the client waits: it is rejected, the request is retried, the value is the right one."""
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        with _client(ev, line, retries=1) as drive:
            previous(drive)
            stale = line.frames("to_master")[-1]
            line.clear()
            line.faults.drop("to_master")
            with inject_when_sent(line, 8, stale):
                assert drive.motor_speed.read() == 321
            assert _delivered_after_request(line, stale)
            assert drive.stats.rejected == 1 and drive.stats.retries == 1
            request = rtu("01 03 00 02 00 01")
            assert line.frames("to_device") == [request, request]


async def test_async_stale_and_foreign_replies_rejected() -> None:
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        async with _async_client(ev, line, retries=1) as drive:
            await drive.digital_speed_ram[2].write(1000)
            stale = line.frames("to_master")[-1]
            line.clear()
            line.faults.drop("to_master")
            with inject_when_sent(line, 8, stale):
                assert await drive.motor_speed.read() == 321
            assert _delivered_after_request(line, stale)
            line.faults.add("to_master", FrameFault(drop=True, prefix=rtu("01 06 3F 0B 03 E9")))
            await drive.digital_speed_ram[2].write(1001)
            assert sim.get("digital_speed_ram[2]") == 1001
            assert drive.stats.rejected == 2 and drive.stats.retries == 2


def test_duplicated_and_late_replies_do_not_leak_into_later_transactions() -> None:
    with serial_server("ev", "rtu") as (sim, line):
        sim.set("motor_speed", 321)
        with _client(ev, line, retries=1) as drive:
            echo = rtu("01 06 3F 0A 03 E8")
            line.faults.duplicate("to_master")
            drive.digital_speed_ram[2].write(1000)
            assert drive.motor_speed.read() == 321  # not the duplicated echo
            line.wait_idle(1.0)
            assert line.delivered("to_master").count(echo) == 2
            # a reply later than the timeout: attempt 2 gets the (identical) late answer to attempt 1;
            # the answer to attempt 2 comes behind it and must not be taken by the next request
            # (whether the duplicate echo above was flushed before the read or rejected during it
            # depends on scheduling; either way it was not accepted, so count from here)
            before = drive.stats.retries
            line.faults.delay("to_master", TIMEOUT * 1.5)
            assert drive.motor_speed.read() == 321
            assert drive.stats.retries - before == 1
            drive.digital_speed_ram[2].write(1001)
            sim.set("motor_speed", 654)
            assert drive.motor_speed.read() == 654
            assert sim.get("digital_speed_ram[2]") == 1001


# ----------------------------------------------------------------------------- partial writes
def _small_10h(spec: DeviceSpec, max_quantity: int) -> DeviceSpec:
    codes = tuple(dataclasses.replace(f, max_quantity=max_quantity) if f.code == 0x10 else f
                  for f in spec.protocol.function_codes)
    assert any(isinstance(f, FunctionSpec) and f.code == 0x10 for f in codes)
    return dataclasses.replace(spec, protocol=dataclasses.replace(spec.protocol, function_codes=codes))


def test_split_10h_write_timeout_reports_written_unconfirmed_not_written() -> None:
    client_cls = _with_spec(ev.Client, _small_10h(ev.SPEC, 3))  # 8 elements -> 3 + 3 + 2
    with serial_server("ev", "rtu") as (sim, line):
        before = [sim.get(f"digital_speed_ram[{i}]") for i in range(8)]
        drive = client_cls.serial(line.master_port, unit=1, baudrate=BAUD, parity="none", timeout=TIMEOUT,
                                  retries=1)
        with drive:
            line.faults.passthrough("to_master").drop("to_master", frames=2)
            with pytest.raises(PartialWrite) as info:
                drive.digital_speed_ram.write([1000 + i for i in range(8)])
            err = info.value
            names = [f"digital_speed_ram[{i}]" for i in range(8)]
            assert err.written == tuple(names[:3])
            assert err.maybe_written == tuple(names[3:6])
            assert err.not_written == tuple(names[6:])
            assert isinstance(err.error, DriveTimeout) and err.__cause__ is err.error
            assert [f[1] for f in line.frames("to_device")] == [0x10] * 3  # request 3 is never sent
            after = [sim.get(n) for n in names]
            assert after[:3] == [1000, 1001, 1002]
            assert after[3:6] == [1003, 1004, 1005]  # the device did write them: the replies were lost
            assert after[6:] == before[6:]


def test_split_10h_write_device_exception_reports_not_written() -> None:
    client_cls = _with_spec(ev.Client, _small_10h(ev.SPEC, 3))
    with serial_server("ev", "rtu") as (sim, line):
        before = [sim.get(f"digital_speed_ram[{i}]") for i in range(8)]
        drive = client_cls.serial(line.master_port, unit=1, baudrate=BAUD, parity="none", timeout=TIMEOUT)
        with drive:
            # hold the first reply on the line while the simulator is told to refuse the next request
            line.faults.delay("to_master", 0.1)

            def refuse_second() -> None:
                if line.wait_captured("to_master", 8, timeout=5.0):
                    sim.inject_exception(0x04)

            thread = threading.Thread(target=refuse_second, daemon=True)
            thread.start()
            with pytest.raises(PartialWrite) as info:
                drive.digital_speed_ram.write([2000 + i for i in range(8)])
            thread.join(6.0)
            err = info.value
            names = [f"digital_speed_ram[{i}]" for i in range(8)]
            assert err.written == tuple(names[:3]) and err.maybe_written == ()
            assert err.not_written == tuple(names[3:])
            assert isinstance(err.error, DeviceException) and err.error.code == 0x04
            assert rtu("01 90 04") in line.frames("to_master")
            assert [sim.get(n) for n in names] == [2000, 2001, 2002] + before[3:]


async def test_async_write_many_several_requests_partial() -> None:
    with serial_server("ev", "rtu") as (sim, line):
        async with _async_client(ev, line, retries=1) as drive:
            old_torque = sim.get("digital_torque_limit_ram[0]")
            assert old_torque != 150
            line.faults.passthrough("to_master").drop("to_master", frames=2)
            with pytest.raises(PartialWrite) as info:
                await drive.write_many([(drive.digital_speed_ram[0], 1500), (drive.digital_accel_time_ram[0], 2.5),
                                        (drive.digital_torque_limit_ram[0], 150)])
            # sorted by address: 0x3F08, 0x4000, 0x4300 -> three requests
            assert info.value.written == ("digital_speed_ram[0]",)
            assert info.value.maybe_written == ("digital_accel_time_ram[0]",)
            assert info.value.not_written == ("digital_torque_limit_ram[0]",)
            assert sim.get("digital_speed_ram[0]") == 1500
            assert sim.get("digital_accel_time_ram[0]") == 2.5  # written, though the replies were lost
            assert sim.get("digital_torque_limit_ram[0]") == old_torque  # never sent


def test_single_request_write_keeps_its_own_error() -> None:
    with serial_server("ev", "rtu") as (_sim, line):
        with _client(ev, line, retries=0) as drive:
            line.faults.drop("to_master")
            with pytest.raises(DriveTimeout):
                drive.digital_speed_ram.write([1000 + i for i in range(8)])  # one 10h request
            assert len(line.frames("to_device")) == 1


# ----------------------------------------------------------------------------- 50 concurrent callers
def _rtu_frame_len(data: bytes, request: bool) -> int:
    fc = data[1]
    if fc & 0x80:
        return 5
    if request:
        return 9 + data[6] if fc == 0x10 else 8
    return 5 + data[2] if fc in (0x03, 0x04) else 8


def _split_rtu(data: bytes, request: bool) -> list[bytes]:
    frames = []
    while data:
        size = _rtu_frame_len(data, request)
        frame, data = data[:size], data[size:]
        assert len(frame) == size and FramerRTU.check_CRC(frame[:-2], int.from_bytes(frame[-2:], "big")), frame
        frames.append(frame)
    return frames


def _bursts(line: VirtualSerialLine) -> list[tuple[str, bytes]]:
    """Both directions merged in capture order; consecutive chunks of one direction joined."""
    events = sorted([(t, d, b) for d in ("to_device", "to_master") for t, b in line.chunks(d)],
                    key=lambda e: e[0])
    out: list[tuple[str, bytes]] = []
    for _t, direction, data in events:
        if out and out[-1][0] == direction:
            out[-1] = (direction, out[-1][1] + data)
        else:
            out.append((direction, data))
    return out


async def test_fifty_concurrent_async_callers_on_one_serial_line() -> None:
    regs = ["digital_speed_ram", "digital_accel_time_ram", "digital_decel_time_ram", "digital_torque_limit_ram",
            "digital_duty_ram"]

    def slot(i: int) -> tuple[int, str, float]:
        unit = 1 + (i // 5) % 2
        name = f"{regs[i % 5]}[{i // 10}]"
        value = 100.0 + i if i % 5 == 0 else (round(0.1 + i * 0.1, 1) if i % 5 in (1, 2) else float(i))
        return unit, name, value

    with serial_server("ev", "rtu", units=(1, 2)) as (sim, line):
        bus = ev.AsyncBus.serial(line.master_port, ev.SPEC.protocol.serial, baudrate=BAUD, parity="none", timeout=1.0)
        async with bus:
            clients = {1: ev.AsyncClient(bus, unit=1), 2: ev.AsyncClient(bus, unit=2)}

            async def caller(i: int) -> tuple[int, Any, Any]:
                unit, name, value = slot(i)
                drive = clients[unit]
                await drive.write_by_name(name, value)
                return i, await drive.read_by_name(name), await drive.read_by_name(name)

            results = await asyncio.wait_for(asyncio.gather(*(caller(i) for i in range(50))), timeout=45)
        for i, first, second in results:
            unit, name, value = slot(i)
            assert first == pytest.approx(value) and second == pytest.approx(value), (i, name)
            assert sim.get(name, unit=unit) == pytest.approx(value)
        assert bus.stats.transactions == 150 and bus.stats.retries == 0 and bus.stats.rejected == 0
        line.wait_idle(2.0)
        bursts = _bursts(line)
        assert len(bursts) == 300
        assert [d for d, _ in bursts] == ["to_device", "to_master"] * 150  # strictly one at a time
        for (_, req_bytes), (_, rep_bytes) in zip(bursts[::2], bursts[1::2], strict=True):
            (request,) = _split_rtu(req_bytes, request=True)  # exactly one request in flight
            (reply,) = _split_rtu(rep_bytes, request=False)
            assert reply[:2] == request[:2]  # same unit, same function, no exception
            if request[1] == 0x06:
                assert reply == request
            else:
                assert reply[2] == 2 * int.from_bytes(request[4:6], "big")
