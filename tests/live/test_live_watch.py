"""`drivemap watch`: the refreshed screen as a person sees it (a pseudo terminal rendered by the pyte
terminal emulator), stale values through timeouts, and the CSV log."""

from __future__ import annotations

import csv
import fcntl
import os
import pty
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Callable
from pathlib import Path

import pyte
from helpers_client import serial_server, tcp_server
from helpers_live import ENV, ROOT, cli

ROWS, COLS = 30, 150


class Terminal:
    """A process on a pseudo terminal, its output rendered on a pyte screen."""

    def __init__(self, argv: list[str]) -> None:
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
        env = {k: v for k, v in ENV.items() if k not in ("COLUMNS", "LINES")} | {"TERM": "xterm-256color"}
        self.proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=ROOT, env=env,
                                     start_new_session=True)
        os.close(slave)
        self.master = master
        self.screen = pyte.Screen(COLS, ROWS)
        self.stream = pyte.ByteStream(self.screen)

    def pump(self, until: Callable[[], bool], timeout: float = 20.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if until():
                return True
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                try:
                    self.stream.feed(os.read(self.master, 65536))
                except OSError:
                    return until()
        return until()

    def text(self) -> str:
        return "\n".join(self.screen.display)

    def row(self, name: str) -> tuple[int, str]:
        for y, line in enumerate(self.screen.display):
            if f"│ {name} " in line:
                return y, line
        return -1, ""

    def reversed_row(self, name: str) -> bool:
        y, line = self.row(name)
        if y < 0:
            return False
        x = line.index(name)
        return bool(self.screen.buffer[y][x].reverse)

    def close(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        self.pump(lambda: self.proc.poll() is not None, 10)
        try:
            code = self.proc.wait(timeout=10)
        finally:
            os.close(self.master)
        return code


def test_watch_refreshes_in_place_and_highlights_changes() -> None:
    with tcp_server("ev") as (sim, host, port):
        term = Terminal([sys.executable, "-m", "drivemap", "watch", "ev", "--tcp", f"{host}:{port}", "--interval",
                         "0.2", "motor_state", "digital_speed_ram[0]", "bus_voltage"])
        try:
            assert term.pump(lambda: "cycle 3 " in term.text()), term.text()
            first = term.text()
            assert first.count("digital_speed_ram[0]") == 1  # refreshed in place, not scrolled
            assert "ev unit 1 on tcp 127.0.0.1" in first and "requests" in first and "busy" in first
            assert "timeouts 0" in first
            sim.set("digital_speed_ram[0]", 1234)
            assert term.pump(lambda: "1234" in term.row("digital_speed_ram[0]")[1]), term.text()
            assert term.reversed_row("digital_speed_ram[0]") and not term.reversed_row("motor_state")
            changed_at = int(term.text().split("cycle ")[1].split()[0])
            assert term.pump(lambda: f"cycle {changed_at + 2} " in term.text())
            assert not term.reversed_row("digital_speed_ram[0]")  # highlighted only in the cycle it changed
            assert term.text().count("digital_speed_ram[0]") == 1
        finally:
            code = term.close()
    assert code == 0
    assert "watched" in term.text() and "without an answer" in term.text()


def test_watch_keeps_going_through_timeouts_and_logs_csv(tmp_path: Path) -> None:
    log = tmp_path / "watch.csv"
    with serial_server("ev", "rtu", baudrate=38400) as (sim, line):
        line.faults.passthrough("to_master", 2).drop("to_master", 3)  # 2 good cycles, then 3 lost replies
        proc = cli("watch", "ev", "--serial", line.master_port, "--baudrate", "38400", "--timeout", "0.1",
                   "--retries", "0", "--interval", "0.05", "--count", "7", "--log", str(log), "digital_speed[0]")
    assert proc.returncode == 0, proc.stderr
    assert "watched 7 cycles, 3 without an answer" in proc.stdout
    assert proc.stdout.count("STALE") == 3
    rows = list(csv.DictReader(log.open(encoding="utf-8")))
    assert [r["stale"] for r in rows] == ["0", "0", "1", "1", "1", "0", "0"]
    assert {r["digital_speed[0]"] for r in rows} == {"3000"}
    again = cli("watch", "ev", "--serial", "/dev/null", "--baudrate", "9600", "--log", str(log), "motor_state")
    assert again.returncode == 1 and "exists with other columns; not overwritten" in again.stderr
