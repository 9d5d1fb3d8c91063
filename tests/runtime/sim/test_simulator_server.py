"""Simulators as real servers: TCP on 127.0.0.1 (pymodbus client) and a virtual serial line in
RTU and ASCII (minimalmodbus and raw bytes), plus ``drivemap simulate`` as a subprocess.

Every wait is bounded; nothing asserts wall-clock times (behaviours are polled until they
reach their target or a generous deadline passes).
"""

from __future__ import annotations

import importlib
import os
import selectors
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import minimalmodbus
import pytest
from pymodbus.client import AsyncModbusTcpClient, ModbusTcpClient
from pymodbus.exceptions import ModbusIOException
from pymodbus.framer import FramerRTU

from drivemap.runtime.sim.cli import parse_tcp
from drivemap.runtime.sim.serve import SimServer, ThreadedSimServer, is_loopback
from drivemap.runtime.sim.simulator import SimulatorError
from drivemap.testing.vserial import VirtualSerialLine
from tests.waits import wait_until

ROOT = Path(__file__).resolve().parents[3]


def sim_class(model: str) -> Any:
    return importlib.import_module(f"drivemap_models.{model}.simulator").Simulator


def rtu(hexbytes: str) -> bytes:
    body = bytes.fromhex(hexbytes)
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


def wait_for(pred: Callable[[], bool], timeout: float = 5.0, step: float = 0.02) -> bool:
    return wait_until(pred, timeout, step)


@contextmanager
def tcp_server(sim: Any) -> Iterator[ModbusTcpClient]:
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        client = ModbusTcpClient(host, port=port, timeout=1, retries=0)
        assert client.connect()
        try:
            yield client
        finally:
            client.close()


# ==== TCP =========================================================================================
def test_tcp_reads_writes_and_exceptions_ev() -> None:
    sim = sim_class("ev")([1, 2], refuse_advised_while_running=True)  # the opt-in busy refusal, below
    with tcp_server(sim) as client:
        rr = client.read_holding_registers(0x0308, count=2, device_id=1)
        assert not rr.isError() and rr.registers == [3000, 3000]
        assert not client.write_register(0x3F08, 300, device_id=2).isError()
        assert sim.get("digital_speed_ram[0]", 2) == 300 and sim.get("digital_speed_ram[0]", 1) == 3000
        wr = client.write_registers(0x3F08, [300, 600, 300, 600], device_id=2)
        assert not wr.isError() and wr.count == 4
        cases = [
            (client.read_input_registers(0, count=1, device_id=1), 0x01),  # 04h unsupported
            (client.read_holding_registers(0xFFF0, count=1, device_id=1), 0x02),  # bad address
            (client.read_holding_registers(0x0308, count=17, device_id=1), 0x03),  # > 16
            (client.write_register(0x0308, 5, device_id=1), 0x04),  # below min 60
            (client.write_register(0x0000, 1, device_id=1), 0x02),  # read-only (map choice 02h)
        ]
        for response, code in cases:
            assert response.isError() and response.exception_code == code
        history = client.read_holding_registers(0x4800, count=4, device_id=1).registers
        assert history == [0x8C, 0x8C, 0x88, 0]  # 02h cases record nothing
        assert not client.write_register(0x1400, 1, device_id=1).isError()  # START
        busy = client.write_register(0x0308, 1000, device_id=1)
        assert busy.isError() and busy.exception_code == 0x04
        assert client.read_holding_registers(0x4800, count=1, device_id=1).registers == [0x8D]


def test_tcp_vendor_exception_codes_v2() -> None:
    sim = sim_class("v2")()
    with tcp_server(sim) as client:
        for response, code in [
            (client.read_input_registers(0, count=1, device_id=1), 0x51),
            (client.read_holding_registers(0x0121, count=1, device_id=1), 0x52),
            (client.read_holding_registers(0x0000, count=17, device_id=1), 0x53),
            (client.write_register(0x0120, 1, device_id=1), 0x55),
        ]:
            assert response.isError() and response.exception_code == code
        sim.inject_exception(0x52)
        fault = client.write_register(0x0102, 0x1770, device_id=1)
        assert fault.isError() and fault.exception_code == 0x52
        ok = client.write_register(0x0102, 0x1770, device_id=1)
        assert not ok.isError()
        assert client.read_holding_registers(0x0123, count=1, device_id=1).registers == [0x1770]
        loop = client.diag_query_data(b"\xa5\x37", device_id=1)  # 08h sub-function 0000h
        assert not loop.isError() and loop.message == b"\xa5\x37"


def test_tcp_other_units_and_broadcast_get_no_reply() -> None:
    sim = sim_class("ev")([1, 2])
    with tcp_server(sim) as client:
        with pytest.raises(ModbusIOException):  # no reply for a unit that is not simulated
            client.read_holding_registers(0x0308, count=1, device_id=3)
    with tcp_server(sim) as client:
        client.write_registers(0x3F08, [1000, 500], device_id=0, no_response_expected=True)
        assert wait_for(lambda: sim.get("digital_speed_ram[1]", 2) == 500)
        for unit in (1, 2):
            assert sim.get("digital_speed_ram[0]", unit) == 1000
            assert sim.get("digital_speed_ram[1]", unit) == 500
        # the server is still in step with the client after the silent broadcast
        assert client.read_holding_registers(0x3F08, count=2, device_id=1).registers == [1000, 500]


def test_tcp_behaviour_observed_from_outside_ev() -> None:
    sim = sim_class("ev")()
    with tcp_server(sim) as client:
        assert not client.write_register(0x3F08, 1200, device_id=1).isError()
        assert not client.write_register(0x1400, 1, device_id=1).isError()

        def speed() -> int:
            return int(client.read_holding_registers(0x0002, count=1, device_id=1).registers[0])

        assert wait_for(lambda: speed() == 1200)
        assert client.read_holding_registers(0x0000, count=1, device_id=1).registers == [2]  # RUN
        assert not client.write_register(0x1400, 0, device_id=1).isError()
        assert wait_for(lambda: client.read_holding_registers(0x0000, count=1, device_id=1).registers == [0])
        assert speed() == 0


def test_tcp_behaviour_v2_and_vfd1000() -> None:
    v2 = sim_class("v2")()
    with tcp_server(v2) as client:
        assert not client.write_registers(0x0101, [0x0003, 0x1770], device_id=1).isError()
        assert client.read_holding_registers(0x0120, count=1, device_id=1).registers == [0b111]
        assert client.read_holding_registers(0x0123, count=1, device_id=1).registers == [0x1770]
        busy = client.write_register(0x0010, 1, device_id=1)
        assert busy.isError() and busy.exception_code == 0x55
    vfd = sim_class("vfd1000")()
    with tcp_server(vfd) as client:
        assert not client.write_register(0x2000, 10000, device_id=1).isError()
        assert not client.write_register(0x1000, 0x0001, device_id=1).isError()
        assert client.read_holding_registers(0x1001, count=1, device_id=1).registers == [1]
        assert wait_for(lambda: client.read_holding_registers(0x3000, count=1, device_id=1).registers == [5000])


async def test_async_server_and_realistic_timing() -> None:
    sim = sim_class("edx")(realistic_timing=True)
    sim.set("frequency_command_monitor", 60.0)
    async with SimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        client = AsyncModbusTcpClient(server.address[0], port=server.address[1], timeout=2, retries=0)
        assert await client.connect()
        try:
            rr = await client.read_holding_registers(0x00F2, count=1, device_id=1)
            assert rr.registers == [0x1770]
        finally:
            client.close()


def test_state_persists_across_server_restart(tmp_path: Path) -> None:
    state = tmp_path / "ev.json"
    with tcp_server(sim_class("ev")([1, 2], state_file=state)) as client:
        assert not client.write_register(0x0309, 2500, device_id=2).isError()  # EEPROM
        assert not client.write_register(0x3F0A, 777, device_id=2).isError()  # RAM
    with tcp_server(sim_class("ev")([1, 2], state_file=state)) as client:
        assert client.read_holding_registers(0x0308, count=2, device_id=2).registers == [3000, 2500]
        assert client.read_holding_registers(0x0308, count=2, device_id=1).registers == [3000, 3000]
        assert client.read_holding_registers(0x3F0A, count=1, device_id=2).registers == [3000]


def test_non_loopback_bind_refused() -> None:
    with pytest.raises(SimulatorError):
        SimServer(sim_class("ev")(), tcp=("0.0.0.0", 0))
    SimServer(sim_class("ev")(), tcp=("0.0.0.0", 0), allow_remote=True)  # allowed when asked
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("192.0.2.1")
    assert parse_tcp("[::1]:5020") == ("::1", 5020)
    with pytest.raises(SimulatorError):
        parse_tcp("5020")


# ==== serial ======================================================================================
@contextmanager
def serial_server(sim: Any, mode: str) -> Iterator[VirtualSerialLine]:
    with VirtualSerialLine(baudrate=19200) as line:
        with ThreadedSimServer(sim, serial=line.device_port, mode=mode, baudrate=19200):
            yield line


def instrument(line: VirtualSerialLine, unit: int, mode: str) -> minimalmodbus.Instrument:
    inst = minimalmodbus.Instrument(line.master_port, unit, mode=mode, close_port_after_each_call=False)
    inst.serial.baudrate = 19200
    inst.serial.timeout = 0.5
    inst.clear_buffers_before_each_transaction = True
    return inst


def exchange(port: Any, frame: bytes, expect: int, timeout: float = 0.5) -> bytes:
    """Write a frame, read up to ``expect`` bytes (fewer on silence)."""
    port.reset_input_buffer()
    port.write(frame)
    port.flush()
    deadline = time.monotonic() + timeout
    data = b""
    while len(data) < expect and time.monotonic() < deadline:
        data += port.read(expect - len(data))
    return data


@pytest.mark.parametrize("model", ["ev", "edx"])
def test_rtu_minimalmodbus_read_write(model: str) -> None:
    sim = sim_class(model)([1, 2])
    with serial_server(sim, "rtu") as line:
        inst = instrument(line, 2, "rtu")
        try:
            if model == "ev":
                assert inst.read_registers(0x0308, 2) == [3000, 3000]
                inst.write_register(0x3F08, 300, functioncode=6)
                inst.write_registers(0x3F09, [600, 900])
                assert inst.read_registers(0x3F08, 3) == [300, 600, 900]
                with pytest.raises(minimalmodbus.IllegalRequestError):
                    inst.read_registers(0x0308, 17)
            else:
                inst.write_registers(0x00E6, [0x0001, 0x1770])
                assert inst.read_register(0x00F2) == 0x1770
                assert inst.read_register(0x00EF) & 0b101 == 0b101
                with pytest.raises(minimalmodbus.SlaveReportedException):
                    inst.read_register(0x00F0 + 0x100)  # 52h: bad address
            assert sim.get_raw("digital_speed_ram[0]" if model == "ev" else "frequency_command", 1) == (3000 if model == "ev" else 0)
        finally:
            inst.serial.close()


def test_rtu_exact_bytes_bad_crc_and_broadcast_v2() -> None:
    sim = sim_class("v2")()
    sim.set("frequency_command_monitor", 60.0)
    with serial_server(sim, "rtu") as line:
        port = line.open_serial("master", baudrate=19200, timeout=0.05)
        try:
            request = bytes.fromhex("01 03 01 23 00 01 74 3C")
            assert exchange(port, request, 7) == bytes.fromhex("01 03 02 17 70 B6 50")
            sim.inject_exception(0x52)
            assert exchange(port, request, 5) == bytes.fromhex("01 83 52 C0 CD")
            sim.inject_exception(0x20)
            assert exchange(port, bytes.fromhex("01 08 00 00 A5 37 DA 8D"), 5) == bytes.fromhex("01 88 20 47 D8")
            assert exchange(port, bytes.fromhex("01 08 00 00 A5 37 DA 8D"), 8) == bytes.fromhex("01 08 00 00 A5 37 DA 8D")
            assert exchange(port, bytes.fromhex("01 03 01 23 00 01 74 3D"), 7, timeout=0.3) == b""  # bad CRC
            assert exchange(port, rtu("02 03 01 23 00 01"), 7, timeout=0.3) == b""  # not our unit
            assert exchange(port, rtu("01 04 00 00 00 01"), 5) == rtu("01 84 51")  # 51H
            assert exchange(port, request, 7) == bytes.fromhex("01 03 02 17 70 B6 50")  # still in step
        finally:
            port.close()


def test_rtu_broadcast_two_units_and_bad_crc_record_ev() -> None:
    sim = sim_class("ev")([1, 2])
    with serial_server(sim, "rtu") as line:
        port = line.open_serial("master", baudrate=19200, timeout=0.05)
        try:
            frame = bytes.fromhex("00 10 3F 08 00 02 04 03 E8 01 F4 63 63")
            assert exchange(port, frame, 8, timeout=0.3) == b""
            assert wait_for(lambda: sim.get("digital_speed_ram[1]", 2) == 500, timeout=2)
            assert sim.get("digital_speed_ram[0]", 1) == 1000
            assert exchange(port, bytes.fromhex("01 03 03 08 00 02 45 8E"), 9, timeout=0.3) == b""
            assert sim.get("comm_error_history[0]", 1) == 0x84  # frame error recorded
            # a partial frame followed by silence is dropped; the next request is answered
            port.write(bytes.fromhex("01 03 03"))
            port.flush()
            time.sleep(0.2)
            assert exchange(port, bytes.fromhex("01 03 03 08 00 02 45 8D"), 9) == bytes.fromhex("01 03 04 0B B8 0B B8 7F 70")
        finally:
            port.close()


def test_ascii_exact_bytes_lrc_and_minimalmodbus_edx() -> None:
    sim = sim_class("edx")()
    sim.set("frequency_command_monitor", 60.0)
    with serial_server(sim, "ascii") as line:
        port = line.open_serial("master", baudrate=19200, timeout=0.05)
        try:
            assert exchange(port, b":010300F2000109\r\n", 15) == b":010302177073\r\n"
            sim.inject_exception(0x52)
            assert exchange(port, b":010300F2000109\r\n", 11) == b":0183522A\r\n"
            assert exchange(port, b":01080000A5371B\r\n", 17) == b":01080000A5371B\r\n"
            assert exchange(port, b":010300F2000108\r\n", 15, timeout=0.3) == b""  # bad LRC
            assert exchange(port, b":011000E6000204000117707B\r\n", 17) == b":011000E6000207\r\n"
        finally:
            port.close()
        inst = instrument(line, 1, "ascii")
        try:
            assert inst.read_register(0x00EF) & 0b1 == 1  # RUNNING after the 10H write above
            inst.write_register(0x00E7, 3000, functioncode=6)
            assert inst.read_register(0x00F2) == 3000
        finally:
            inst.serial.close()


def test_serial_mode_must_be_spoken() -> None:
    with pytest.raises(SimulatorError):
        SimServer(sim_class("v2")(), serial="/dev/null", mode="ascii")


# ==== drivemap simulate ==============================================================================
def _read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    assert proc.stdout is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        if not sel.select(timeout):
            return ""
        return proc.stdout.readline()
    finally:
        sel.close()


def _simulate(*args: str) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen(
        [sys.executable, "-m", "drivemap.cli", "simulate", *args],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )


def test_cli_simulate_serves_a_stock_client_and_exits_on_sigint() -> None:
    proc = _simulate("ev", "--tcp", "127.0.0.1:0", "--unit", "1", "--unit", "2")
    try:
        line = _read_line(proc, 20)
        assert "listening on tcp 127.0.0.1:" in line, (line, proc.stderr.read() if proc.poll() is not None and proc.stderr else "")
        port = int(line.split("127.0.0.1:")[1].split()[0])
        client = ModbusTcpClient("127.0.0.1", port=port, timeout=1, retries=0)
        assert client.connect()
        try:
            assert client.read_holding_registers(0x0308, count=2, device_id=2).registers == [3000, 3000]
        finally:
            client.close()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5)


def test_cli_simulate_refuses_remote_bind() -> None:
    proc = _simulate("ev", "--tcp", "0.0.0.0:0")
    try:
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5)
    assert proc.returncode == 1 and "--allow-remote" in err
