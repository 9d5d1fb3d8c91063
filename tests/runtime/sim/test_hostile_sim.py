"""The simulator's idle timeout (issue 38, item 20): ``drivemap simulate --idle-timeout S`` closes every
connection that sends nothing for S seconds, real sockets against the real command; a client that keeps
talking keeps its connection; the option is checked."""

from __future__ import annotations

import os
import select
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.waits import free_port, wait_port

ROOT = Path(__file__).resolve().parents[3]
IDLE_CLIENTS = 300
READ = bytes([0x03, 0x00, 0x00, 0x00, 0x01])  # read one holding register at 0


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "generator"), str(ROOT / "generated")]),
                PYTHONIOENCODING="utf-8")


def _mbap(tid: int, pdu: bytes, unit: int = 1) -> bytes:
    return tid.to_bytes(2, "big") + b"\x00\x00" + (len(pdu) + 1).to_bytes(2, "big") + bytes([unit]) + pdu


def _closed(sock: socket.socket) -> bool:
    """The server closed the connection: readable, and the read gives nothing (or a reset)."""
    ready, _, _ = select.select([sock], [], [], 0)
    if not ready:
        return False
    try:
        return sock.recv(64) == b""
    except ConnectionResetError:
        return True


@pytest.mark.slow
def test_idle_connections_are_closed_and_a_busy_one_is_kept() -> None:
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "drivemap.cli", "simulate", "ev", "--tcp", f"127.0.0.1:{port}",
                             "--idle-timeout", "3"], cwd=ROOT, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    idle: list[socket.socket] = []
    try:
        wait_port(port, 60, proc)
        busy = socket.create_connection(("127.0.0.1", port), timeout=5)
        idle = [socket.create_connection(("127.0.0.1", port), timeout=5) for _ in range(IDLE_CLIENTS)]
        started = time.monotonic()
        tid = 0
        # the busy client asks every 0.3 s, ten times as often as the 3 s timeout (a loaded machine may
        # stall the simulator's process for a second or two: its timer and the pending bytes then race)
        while time.monotonic() - started < 5.0:
            tid += 1
            busy.sendall(_mbap(tid, READ))
            reply = busy.recv(256)
            assert reply[:2] == tid.to_bytes(2, "big") and reply[7] == 0x03, reply
            time.sleep(0.3)
        assert sum(_closed(s) for s in idle) == IDLE_CLIENTS
        busy.sendall(_mbap(tid + 1, READ))
        assert busy.recv(256)[:2] == (tid + 1).to_bytes(2, "big")  # still served
        busy.close()
        fresh = socket.create_connection(("127.0.0.1", port), timeout=5)  # a closed client reconnects
        fresh.sendall(_mbap(7, READ))
        assert fresh.recv(256)[:2] == b"\x00\x07"
        fresh.close()
    finally:
        for sock in idle:
            sock.close()
        proc.terminate()
        proc.communicate(timeout=30)


@pytest.mark.slow
def test_without_the_option_a_connection_is_kept_for_the_default() -> None:
    """The default (60 s) holds: a connection silent for 2 s is still open and served."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "drivemap.cli", "simulate", "ev", "--tcp", f"127.0.0.1:{port}"],
                            cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        wait_port(port, 60, proc)
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            time.sleep(2.0)
            assert not _closed(sock)
            sock.sendall(_mbap(3, READ))
            assert sock.recv(256)[:2] == b"\x00\x03"
    finally:
        proc.terminate()
        proc.communicate(timeout=30)
