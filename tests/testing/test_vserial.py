"""Tests of the virtual serial line (generator/drivemap/testing/vserial.py).

Only lower bounds on durations are asserted (physics); never upper wall-clock bounds.
"""

from __future__ import annotations

import asyncio
import os
import threading
import time
from typing import Any

import pytest
import serial
from pymodbus.exceptions import ModbusIOException

from drivemap.testing import DIRECTIONS, FrameFault, VirtualSerialLine, open_pair, split_frames

ALL_BYTES = bytes(range(256))


def read_exact(port: Any, n: int, timeout: float = 3.0) -> bytes:
    """Read n bytes from a pyserial port, bounded by timeout."""
    got = b""
    end = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < end:
        got += port.read(n - len(got))
    return got


def drain(line: VirtualSerialLine, direction: str, port: Any, sent: int) -> bytes:
    """After ``sent`` bytes were written in ``direction``: wait until the relay has read them
    all and delivered everything, then return all bytes the receiving ``port`` has."""
    assert line.wait_captured(direction, sent, timeout=5)
    assert line.wait_idle(timeout=5)
    got = b""
    port.timeout = 0.05
    while chunk := port.read(65536):
        got += chunk
    return got


def send_frames(port: Any, frames: list[bytes], gap: float = 0.02) -> None:
    for frame in frames:
        port.write(frame)
        port.flush()
        time.sleep(gap)


# --------------------------------------------------------------------------- pass-through


def test_ports_are_distinct_ttys() -> None:
    with VirtualSerialLine() as line:
        assert line.master_port != line.device_port
        assert line.master_port.startswith("/dev/")
        assert line.port("master") == line.master_port and line.port("device") == line.device_port
        assert "VirtualSerialLine" in repr(line)


@pytest.mark.parametrize("payload", [ALL_BYTES, b":010300000001FB\r\n", b"\r\n\n\r\x00\x11\x13\x03\x04\x7f\xff"])
def test_byte_exact_both_ways(payload: bytes) -> None:
    with open_pair() as (line, master, device):
        master.write(payload)
        assert read_exact(device, len(payload)) == payload
        device.write(payload[::-1])
        assert read_exact(master, len(payload)) == payload[::-1]
        assert line.wait_idle(2)
        assert line.captured("to_device") == payload
        assert line.captured("to_master") == payload[::-1]
        assert line.delivered("to_device") == payload
        assert line.delivered("to_master") == payload[::-1]


def test_large_transfer_all_byte_values() -> None:
    data = ALL_BYTES * 64  # 16 KiB, more than one pty buffer read
    with open_pair() as (line, master, device):
        writer = threading.Thread(target=master.write, args=(data,))
        writer.start()
        got = read_exact(device, len(data), timeout=10)
        writer.join(5)
        assert got == data
        assert line.captured("to_device") == data


def test_ends_can_reopen() -> None:
    with VirtualSerialLine() as line:
        for i in range(3):
            with serial.Serial(line.master_port, timeout=1) as m, serial.Serial(line.device_port, timeout=1) as d:
                m.write(bytes([i]) * 5)
                assert read_exact(d, 5) == bytes([i]) * 5


# --------------------------------------------------------------------------- capture


def test_capture_clear_and_frames() -> None:
    with open_pair() as (line, master, device):
        send_frames(master, [b"\x01\x03abc", b"\x01\x06xyz", b"\r\n"])
        assert read_exact(device, 12) == b"\x01\x03abc\x01\x06xyz\r\n"
        assert line.frames("to_device") == [b"\x01\x03abc", b"\x01\x06xyz", b"\r\n"]
        chunks = line.chunks("to_device")
        assert [t for t, _ in chunks] == sorted(t for t, _ in chunks)
        assert line.captured("to_master") == b""
        line.clear()
        assert line.captured("to_device") == b"" and line.delivered("to_device") == b""
        device.write(b"ok")
        assert read_exact(master, 2) == b"ok"
        assert line.wait_captured("to_master", 2, timeout=2)
        assert line.captured("to_master") == b"ok"


def test_split_frames_rule() -> None:
    chunks = [(0.0, b"a"), (0.001, b"b"), (0.010, b"c"), (0.0105, b"d")]
    assert split_frames(chunks, 0.002) == [b"ab", b"cd"]
    assert split_frames(chunks, 1.0) == [b"abcd"]
    assert split_frames([], 0.002) == []


def test_capture_can_be_disabled() -> None:
    with open_pair(capture=False) as (line, master, device):
        master.write(b"abc")
        assert read_exact(device, 3) == b"abc"
        assert line.captured("to_device") == b""


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        VirtualSerialLine(pace=True)
    with pytest.raises(ValueError):
        VirtualSerialLine(baudrate=0)
    with VirtualSerialLine() as line:
        with pytest.raises(ValueError):
            line.captured("sideways")
        with pytest.raises(ValueError):
            line.faults.drop("up")
        with pytest.raises(ValueError):
            line.faults.garbage("to_device", b"x", where="middle")  # type: ignore[arg-type]


def test_frame_gap_defaults() -> None:
    with VirtualSerialLine() as line:
        assert line.frame_gap == pytest.approx(0.002)
    with VirtualSerialLine(baudrate=1200) as line:
        assert line.frame_gap == pytest.approx(3.5 * 10 / 1200)
        assert line.byte_time == 0.0  # not paced
    with VirtualSerialLine(baudrate=115200, pace=True, bits_per_byte=11) as line:
        assert line.byte_time == pytest.approx(11 / 115200)
        assert line.frame_gap == pytest.approx(0.002)


# --------------------------------------------------------------------------- faults

FRAMES = [b"\x01\x03\x00\x00\x00\x01\x84\x0a", b"\x02\x03\x00\x10\x00\x02\xc5\xfd", b"\x03\x06\x00\x01\x00\x03\x98\x29"]


@pytest.mark.parametrize("direction", DIRECTIONS)
def test_fault_drop(direction: str) -> None:
    with open_pair() as (line, master, device):
        sender, receiver = (master, device) if direction == "to_device" else (device, master)
        line.faults.drop(direction, frames=2)
        assert line.faults.pending(direction) == 2
        send_frames(sender, FRAMES)
        assert drain(line, direction, receiver, 24) == FRAMES[2]
        assert line.captured(direction) == b"".join(FRAMES)
        assert line.faults.pending(direction) == 0


def test_fault_corrupt() -> None:
    with open_pair() as (line, master, device):
        line.faults.passthrough("to_master").corrupt("to_master", byte_index=3, mask=0x80)
        send_frames(device, FRAMES[:3])
        got = drain(line, "to_master", master, 24)
        bad = bytearray(FRAMES[1])
        bad[3] ^= 0x80
        assert got == FRAMES[0] + bytes(bad) + FRAMES[2]
        assert line.frames("to_master") == FRAMES  # capture shows what the sender wrote
        assert line.delivered("to_master") == got


def test_fault_corrupt_default_and_short_frame() -> None:
    with open_pair() as (line, master, device):
        line.faults.corrupt("to_device", frames=2)
        send_frames(master, [b"\x10\x20\x30", b"\x10"])
        assert drain(line, "to_device", device, 4) == b"\x10\x21\x30\x10"  # byte 1, bit 0; 1-byte frame untouched


def test_fault_truncate() -> None:
    with open_pair() as (line, master, device):
        line.faults.truncate("to_device", keep=5)
        send_frames(master, FRAMES[:2])
        assert drain(line, "to_device", device, 16) == FRAMES[0][:5] + FRAMES[1]


def test_fault_delay() -> None:
    with open_pair() as (line, master, device):
        line.faults.delay("to_master", 0.2)
        device.write(FRAMES[0])
        assert read_exact(master, 8) == FRAMES[0]
        assert line.wait_idle(2)
        (t_in, _), = line.chunks("to_master")
        t_out = line.chunks("to_master", "delivered")[0][0]
        assert t_out - t_in >= 0.2
        # the next frame is not delayed
        line.clear()
        device.write(FRAMES[1])
        assert read_exact(master, 8) == FRAMES[1]


def test_fault_delay_keeps_fifo_order() -> None:
    with open_pair() as (line, master, device):
        line.faults.delay("to_device", 0.15)
        send_frames(master, FRAMES[:2], gap=0.01)
        assert read_exact(device, 16) == FRAMES[0] + FRAMES[1]


def test_fault_duplicate() -> None:
    with open_pair() as (line, master, device):
        line.faults.duplicate("to_master")
        send_frames(device, FRAMES[:2], gap=0.05)
        assert drain(line, "to_master", master, 16) == FRAMES[0] + FRAMES[0] + FRAMES[1]
        delivered = line.frames("to_master", "delivered")
        assert delivered == [FRAMES[0], FRAMES[0], FRAMES[1]]  # the copy is a separate frame


def test_fault_garbage_and_inject() -> None:
    with open_pair() as (line, master, device):
        line.faults.garbage("to_device", b"\xff\x00", where="before")
        line.faults.garbage("to_device", b"\r\n", where="after")
        send_frames(master, FRAMES[:3])
        assert drain(line, "to_device", device, 24) == b"\xff\x00" + FRAMES[0] + FRAMES[1] + b"\r\n" + FRAMES[2]
        line.faults.inject("to_master", b"noise")
        assert read_exact(master, 5) == b"noise"
        assert line.captured("to_master") == b""  # nobody wrote it
        assert line.delivered("to_master") == b"noise"


def test_fault_combined_and_clear() -> None:
    with open_pair() as (line, master, device):
        line.faults.add("to_device", FrameFault(drop=True, prefix=b"ZZ"))
        line.faults.drop("to_device", frames=5)
        line.faults.clear("to_device")
        assert line.faults.pending("to_device") == 0
        line.faults.add("to_device", FrameFault(drop=True, prefix=b"ZZ"))
        send_frames(master, FRAMES[:2])
        assert drain(line, "to_device", device, 16) == b"ZZ" + FRAMES[1]


def test_faults_are_thread_safe() -> None:
    with open_pair() as (line, master, device):
        def queue_drops() -> None:
            for _ in range(50):
                line.faults.drop("to_device")

        threads = [threading.Thread(target=queue_drops) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(5)
        assert line.faults.pending("to_device") == 200
        line.faults.clear()
        assert line.faults.pending("to_device") == 0


# --------------------------------------------------------------------------- pacing


def test_pacing_lower_bound_9600() -> None:
    with open_pair(baudrate=9600, pace=True) as (line, master, device):
        start = time.monotonic()
        master.write(bytes(96))
        assert read_exact(device, 96) == bytes(96)
        assert time.monotonic() - start >= 96 * 10 / 9600 - 1e-3  # 0.1 s
        assert line.wait_idle(2)
        (t_in, _), = line.chunks("to_device")
        sent = 0
        for t_out, data in line.chunks("to_device", "delivered"):
            sent += len(data)
            assert t_out - t_in >= sent * 10 / 9600 - 1e-6  # no byte early


def test_pacing_accumulates_across_writes() -> None:
    # many small writes back to back: the line stays busy, the total obeys the rate
    with open_pair(baudrate=19200, pace=True) as (line, master, device):
        start = time.monotonic()
        for _ in range(24):
            master.write(b"\x55" * 8)
        assert read_exact(device, 192) == b"\x55" * 192
        assert time.monotonic() - start >= 192 * 10 / 19200 - 1e-3


def test_pacing_both_directions_and_bits_per_byte() -> None:
    with open_pair(baudrate=4800, pace=True, bits_per_byte=11) as (line, master, device):
        start = time.monotonic()
        device.write(ALL_BYTES[:48])
        assert read_exact(master, 48) == ALL_BYTES[:48]
        assert time.monotonic() - start >= 48 * 11 / 4800 - 1e-3


def test_paced_duplicate_has_silent_gap() -> None:
    with open_pair(baudrate=9600, pace=True) as (line, master, device):
        line.faults.duplicate("to_device")
        master.write(FRAMES[0])
        assert read_exact(device, 16) == FRAMES[0] * 2
        chunks = line.chunks("to_device", "delivered")
        # second copy starts at least frame_gap after the first copy finished
        first_end = next(t for t, _ in _cumulative(chunks) if _ >= 8)
        second_start = next(t for t, _ in _cumulative(chunks) if _ > 8)
        assert second_start - first_end >= line.frame_gap


def _cumulative(chunks: list[tuple[float, bytes]]) -> list[tuple[float, int]]:
    total, out = 0, []
    for t, data in chunks:
        total += len(data)
        out.append((t, total))
    return out


# --------------------------------------------------------------------------- lifecycle


def _fd_count() -> int:
    return len(os.listdir("/proc/self/fd"))


def test_no_leaked_threads_or_fds() -> None:
    fds = _fd_count()
    threads = threading.active_count()
    for i in range(30):
        with open_pair(baudrate=115200, pace=bool(i % 2)) as (line, master, device):
            master.write(b"x")
            assert read_exact(device, 1) == b"x"
    line = VirtualSerialLine()
    line.close()
    line.close()  # idempotent
    assert line.closed
    assert threading.active_count() <= threads
    assert _fd_count() <= fds


def test_close_with_ends_still_open() -> None:
    line = VirtualSerialLine()
    m = serial.Serial(line.master_port, timeout=0.1)
    try:
        line.close()
        assert not line.wait_idle(0.1)  # closed lines report False
    finally:
        m.close()


# --------------------------------------------------------------------------- real Modbus stacks


def _simdevice(values: list[int]) -> Any:
    from pymodbus.simulator import DataType, SimData, SimDevice

    return SimDevice(id=1, simdata=[SimData(address=0, values=values, datatype=DataType.REGISTERS)])


@pytest.mark.parametrize("framer_name", ["RTU", "ASCII"])
async def test_pymodbus_serial_client_server(framer_name: str) -> None:
    from pymodbus import FramerType
    from pymodbus.client import AsyncModbusSerialClient
    from pymodbus.server import ModbusSerialServer

    framer = FramerType[framer_name]
    with VirtualSerialLine(baudrate=115200, pace=True) as line:
        server = ModbusSerialServer(_simdevice([11, 22, 33, 44]), framer=framer, port=line.device_port, baudrate=115200)
        await asyncio.wait_for(server.serve_forever(background=True), 5)
        client = AsyncModbusSerialClient(line.master_port, framer=framer, baudrate=115200, timeout=2, retries=0)
        try:
            assert await asyncio.wait_for(client.connect(), 5)
            await asyncio.sleep(0.05)
            line.clear()
            rr = await asyncio.wait_for(client.read_holding_registers(1, count=2, device_id=1), 5)
            assert not rr.isError()
            assert rr.registers == [22, 33]
            if framer_name == "RTU":
                assert line.captured("to_device") == bytes.fromhex("010300010002 95cb")
            else:
                assert line.captured("to_device") == b":010300010002F9\r\n"
                assert line.captured("to_master").endswith(b"\r\n")
            # a corrupted response is rejected by the client (CRC/LRC) -> error, no hang
            line.faults.corrupt("to_master", byte_index=4)
            try:
                rr = await asyncio.wait_for(client.read_holding_registers(1, count=2, device_id=1), 8)
            except ModbusIOException:  # pymodbus 3.16 raises it when no valid response arrives
                pass
            else:
                assert rr.isError()
            await asyncio.sleep(0.1)
            rr = await asyncio.wait_for(client.read_holding_registers(0, count=1, device_id=1), 5)
            assert rr.registers == [11]
        finally:
            client.close()
            await asyncio.wait_for(server.shutdown(), 5)


def test_minimalmodbus_sync_client_against_pymodbus_server() -> None:
    import minimalmodbus
    from pymodbus.server import ModbusSerialServer

    with VirtualSerialLine(baudrate=19200, pace=True) as line:
        loop = asyncio.new_event_loop()
        servers: list[Any] = []
        ready = threading.Event()

        def run() -> None:
            asyncio.set_event_loop(loop)

            async def main() -> None:
                server = ModbusSerialServer(_simdevice([7, 8, 9]), port=line.device_port, baudrate=19200)
                servers.append(server)
                await server.serve_forever(background=True)
                ready.set()

            loop.run_until_complete(main())
            loop.run_forever()

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        try:
            assert ready.wait(5)
            time.sleep(0.05)
            inst = minimalmodbus.Instrument(line.master_port, 1)
            inst.serial.baudrate = 19200
            inst.serial.timeout = 1
            inst.clear_buffers_before_each_transaction = True
            try:
                assert inst.read_registers(0, 3) == [7, 8, 9]
                assert line.frames("to_device")[-1] == bytes.fromhex("010300000003 05cb")
            finally:
                inst.serial.close()
        finally:
            if servers:
                asyncio.run_coroutine_threadsafe(servers[0].shutdown(), loop).result(5)
            loop.call_soon_threadsafe(loop.stop)
            thread.join(5)
            loop.close()
