"""Errors a person at the drive can act on: one line each, documented exit codes, no tracebacks."""

from __future__ import annotations

import os
import shutil
import socket
from pathlib import Path

import pytest
from helpers_client import serial_server, simulator, tcp_server
from helpers_live import cli, no_traceback, simulate, wrong_map

from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.testing.vserial import VirtualSerialLine


def _one_error_line(proc: object, code: int) -> str:
    no_traceback(proc)  # type: ignore[arg-type]
    lines = proc.stderr.strip().splitlines()  # type: ignore[attr-defined]
    assert proc.returncode == code and len(lines) == 1, (proc.returncode, proc.stderr)  # type: ignore[attr-defined]
    return str(lines[0])


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_unreachable_port() -> None:
    line = _one_error_line(cli("read", "ev", "--tcp", f"127.0.0.1:{_closed_port()}", "motor_state"), 2)
    assert line.startswith("drivemap read: error: cannot connect to 127.0.0.1:") and "connection refused" in line


def test_no_such_serial_device_and_missing_settings() -> None:
    line = _one_error_line(cli("read", "ev", "--serial", "/dev/ttyNOPE0", "--baudrate", "9600", "motor_state"), 2)
    assert "no serial device /dev/ttyNOPE0" in line
    line = _one_error_line(cli("read", "ev", "--serial", "/dev/ttyNOPE0", "motor_state"), 1)
    assert "no default baud rate; pass --baudrate N (the map lists 9600, 19200, 38400, 57600, 115200" in line


def test_permission_denied_on_the_serial_device() -> None:
    prefix: tuple[str, ...] = ()
    if os.geteuid() == 0:  # root ignores file modes: drop the capabilities that let it
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            pytest.skip("LOUD SKIP: running as root without setpriv, cannot take away CAP_DAC_OVERRIDE")
        prefix = (setpriv, "--bounding-set=-dac_override,-dac_read_search")
    with VirtualSerialLine(9600) as line:
        os.chmod(line.master_port, 0)
        proc = cli("read", "ev", "--serial", line.master_port, "--baudrate", "9600", "motor_state", prefix=prefix)
    line_text = _one_error_line(proc, 2)
    assert "permission denied on /dev/" in line_text and "dialout" in line_text


def test_wrong_parity_gives_garbled_replies() -> None:
    sim = simulator("ev", (1,))
    with VirtualSerialLine(19200, device_parity="O") as line:  # the drive is set to 8O1; we ask 8N1
        with ThreadedSimServer(sim, serial=line.device_port, mode="rtu", baudrate=19200, parity="none"):
            proc = cli("read", "ev", "--serial", line.master_port, "--baudrate", "19200", "--parity", "none",
                       "--timeout", "0.2", "motor_state")
    line_text = _one_error_line(proc, 4)
    assert "are garbled (wrong baud rate or parity?" in line_text and "drivemap scan --serial" in line_text


def test_rtu_over_tcp_against_a_modbus_tcp_server_gets_no_answer() -> None:
    # a Modbus TCP server drops RTU frames (bad MBAP protocol id) without a reply
    with tcp_server("ev") as (_, host, port):
        proc = cli("read", "ev", "--rtu-over-tcp", f"{host}:{port}", "--timeout", "0.2", "motor_state")
    assert "no answer from unit 1 on rtu-over-tcp" in _one_error_line(proc, 3)


def test_no_answer_from_that_unit_tcp_and_serial() -> None:
    with tcp_server("ev", units=(1,)) as (_, host, port):
        proc = cli("read", "ev", "--tcp", f"{host}:{port}", "--unit", "5", "--timeout", "0.1", "motor_state")
    line = _one_error_line(proc, 3)
    assert "no answer from unit 5 on tcp" in line and "drivemap scan --tcp" in line
    with serial_server("ev", "rtu", units=(1,), baudrate=38400) as (_, vline):
        proc = cli("read", "ev", "--serial", vline.master_port, "--baudrate", "38400", "--unit", "4",
                   "--timeout", "0.1", "motor_state")
    assert "no answer from unit 4 on serial" in _one_error_line(proc, 3)
    bad_unit = _one_error_line(cli("read", "ev", "--tcp", "127.0.0.1:9", "--unit", "99", "motor_state"), 1)
    assert "--unit 99: outside ev's unit ids 1..15 (or fixed port units 17)" in bad_unit


WRITE_ONLY_TIMEOUT = ("    group: comm_parameters\n    access: rw\n    unit: ms\n    min: 0\n    max: 1000\n",
                      "    group: comm_parameters\n    access: w\n    unit: ms\n    min: 0\n    max: 1000\n")


def test_device_exception_with_its_map_meaning(tmp_path: Path) -> None:
    device = wrong_map(tmp_path, "no_timeout_read", [WRITE_ONLY_TIMEOUT])  # this firmware refuses reads of 090Bh
    with simulate(str(device)) as port:
        proc = cli("read", "ev", "--tcp", f"127.0.0.1:{port}", "rs485_timeout")
    line = _one_error_line(proc, 5)
    assert "unit 1 answered exception 02h illegal_data_address to function 03h" in line
    assert "不正確資料位址" in line and "[maps/ev.yaml:" in line


def test_help_documents_the_exit_codes() -> None:
    proc = cli("watch", "--help")
    assert proc.returncode == 0
    for text in ("exit codes:", "2    cannot reach the device", "3    no answer from that unit",
                 "4    garbled replies", "5    the device answered with an exception", "6    verify"):
        assert text in proc.stdout, text


class _WrongReplies:
    """A Modbus TCP device that answers every request, but never what was asked: another function
    code (``fc``) or one register more than asked (``count``)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = int(self.sock.getsockname()[1])
        import threading

        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                while (head := conn.recv(7)) and len(head) == 7:
                    pdu = conn.recv(int.from_bytes(head[4:6], "big") - 1)
                    count = int.from_bytes(pdu[3:5], "big")
                    if self.kind == "fc":
                        body = bytes([0x04, 2 * count]) + b"\x00\x01" * count
                    else:
                        body = bytes([pdu[0], 2 * (count + 1)]) + b"\x00\x01" * (count + 1)
                    conn.sendall(head[:4] + (len(body) + 1).to_bytes(2, "big") + head[6:7] + body)

    def close(self) -> None:
        self.sock.close()


@pytest.mark.parametrize(("kind", "said"), [("fc", "reply has function 0x04, sent 0x03"),
                                            ("count", "reply has 2 registers, asked 1")])
def test_a_device_answering_something_else_is_named_not_silent(kind: str, said: str) -> None:
    device = _WrongReplies(kind)
    try:
        proc = cli("read", "ev", "--tcp", f"127.0.0.1:{device.port}", "--timeout", "0.2", "--retries", "0",
                   "motor_state")
    finally:
        device.close()
    line = _one_error_line(proc, 4)
    assert "answered, but not what was asked" in line and said in line, line
    assert "no answer" not in line
