"""``drivemap simulate`` as a process: ``--state`` files survive a kill in the
middle of a write, and the simulator listens only on loopback unless told otherwise.

* A ``drivemap simulate ev --state FILE`` process is fed EEPROM writes as fast as the stock
  pymodbus TCP client can send them and is killed (SIGKILL) at a random moment, several times in a
  row on the same file. After every kill the file is absent or valid JSON that a new simulator
  loads, and no acknowledged write is lost: the value in the file is the last acknowledged one or
  the one in flight at the kill. Each next process starts from that file.
* ``--tcp`` with a non-loopback host is refused (clear message, exit 2) unless ``--allow-remote``
  is given; with it, the process binds (port 0) and is stopped at once.

Every wait is bounded; seeds are fixed.
"""

from __future__ import annotations

import importlib
import json
import os
import random
import selectors
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from drivemap.runtime.spec import DeviceSpec, RegisterSpec

ROOT = Path(__file__).resolve().parents[3]
MODEL = "ev"  # the seed model with EEPROM-class registers
ROUNDS = 6


def spec() -> DeviceSpec:
    value: DeviceSpec = importlib.import_module(f"drivemap_models.{MODEL}.spec").SPEC
    return value


def sim_class() -> Any:
    return importlib.import_module(f"drivemap_models.{MODEL}.simulator").Simulator


def eeprom_registers() -> list[RegisterSpec]:
    """Writable one-word EEPROM registers outside any page, with a range of at least 100 raw values."""
    regs = [
        r for r in spec().registers
        if r.storage == "eeprom" and r.writable and r.words == 1 and r.page is None
        and r.min is not None and r.max is not None and (r.max - r.min) / r.scale >= 100
    ]
    if not regs:
        pytest.skip(f"{MODEL} has no plain writable EEPROM register")
    return regs


def raw_range(reg: RegisterSpec) -> tuple[int, int]:
    assert reg.min is not None and reg.max is not None
    low, high = sorted((round((reg.min - reg.offset) / reg.scale), round((reg.max - reg.offset) / reg.scale)))
    return low, high


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def simulate(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "drivemap.cli", "simulate", *args],
        cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )


def read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    assert proc.stdout is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    try:
        return proc.stdout.readline() if sel.select(timeout) else ""
    finally:
        sel.close()


@contextmanager
def running(*args: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """A ``drivemap simulate`` process and its first line of output; killed on the way out."""
    proc = simulate(*args)
    try:
        line = read_line(proc, 30)
        if not line:  # no output: it stopped; its message is on stderr
            proc.wait(timeout=20)
            line = proc.stderr.read() if proc.stderr is not None else ""
        yield proc, line
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


def port_of(line: str) -> int:
    assert "listening on tcp 127.0.0.1:" in line, line
    return int(line.split("127.0.0.1:")[1].split()[0])


# ==== atomic state =====================================================================================
def check_state(path: Path, reg: RegisterSpec, allowed: set[int]) -> None:
    """The file is absent or valid JSON that a new simulator accepts; no acknowledged write is lost."""
    if not path.exists():
        assert allowed == {-1}, "state file vanished after acknowledged writes"
        return
    data = json.loads(path.read_text(encoding="utf-8"))  # never a torn file
    assert data["model"] == MODEL
    sim = sim_class()([1], state_file=path)
    if -1 not in allowed:
        value = sim.get_raw(reg.element_name(0), 1)
        assert value in allowed, f"state has {value}, acknowledged/in flight: {sorted(allowed)}"


def test_state_file_survives_sigkill_mid_write(tmp_path: Path) -> None:
    regs = eeprom_registers()
    reg = regs[0]
    low, high = raw_range(reg)
    state = tmp_path / "state" / f"{MODEL}.json"
    rng = random.Random(8)
    allowed = {-1}  # -1: nothing acknowledged yet (file may be absent)
    value = low
    total_writes = 0
    for round_no in range(ROUNDS):
        with running(MODEL, "--tcp", "127.0.0.1:0", "--state", str(state)) as (proc, line):
            client = ModbusTcpClient("127.0.0.1", port=port_of(line), timeout=1, retries=0)
            assert client.connect()
            stop = threading.Event()

            def kill(proc: subprocess.Popen[str] = proc, stop: threading.Event = stop) -> None:
                proc.send_signal(signal.SIGKILL)
                stop.set()

            killer = threading.Timer(rng.uniform(0.05, 0.6), kill)
            killer.start()
            acked: int | None = None
            in_flight: int | None = None
            deadline = time.monotonic() + 10
            try:
                while not stop.is_set() and time.monotonic() < deadline:
                    value = low + (value - low + 1) % (high - low + 1)
                    in_flight = value
                    try:
                        # the first element by 06h, sometimes with its neighbours by 10h
                        if reg.count > 1 and rng.random() < 0.3:
                            reply = client.write_registers(reg.address, [value & 0xFFFF] * reg.count, device_id=1)
                        else:
                            reply = client.write_register(reg.address, value & 0xFFFF, device_id=1)
                    except (ModbusException, OSError):
                        break  # the process is gone
                    if reply.isError():
                        break
                    acked, in_flight = value, None
                    total_writes += 1
            finally:
                killer.join(5)
                client.close()
            assert proc.wait(timeout=10) == -signal.SIGKILL, f"round {round_no}: the process ended by itself"
        if acked is not None:
            allowed = {acked} | ({in_flight} if in_flight is not None else set())
        elif in_flight is not None:
            allowed = allowed | {in_flight}
        check_state(state, reg, allowed)
    assert total_writes > ROUNDS  # the kills really landed among writes
    leftovers = [p.name for p in state.parent.iterdir() if p != state]
    # a kill may leave a temporary file behind, never a half-written state file
    assert all(name.startswith(f".{state.name}.") and name.endswith(".tmp") for name in leftovers), leftovers


def test_state_of_a_killed_process_is_served_again(tmp_path: Path) -> None:
    """The value last written before a SIGKILL is what the next process answers."""
    reg = eeprom_registers()[0]
    low, high = raw_range(reg)
    value = (low + high) // 2
    state = tmp_path / f"{MODEL}.json"
    with running(MODEL, "--tcp", "127.0.0.1:0", "--state", str(state)) as (proc, line):
        client = ModbusTcpClient("127.0.0.1", port=port_of(line), timeout=1, retries=0)
        assert client.connect()
        try:
            assert not client.write_register(reg.address, value, device_id=1).isError()
        finally:
            client.close()
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=10) == -signal.SIGKILL
    with running(MODEL, "--tcp", "127.0.0.1:0", "--state", str(state)) as (proc, line):
        client = ModbusTcpClient("127.0.0.1", port=port_of(line), timeout=1, retries=0)
        assert client.connect()
        try:
            assert client.read_holding_registers(reg.address, count=1, device_id=1).registers == [value]
        finally:
            client.close()


def test_corrupt_state_file_is_refused_clearly(tmp_path: Path) -> None:
    """A torn file (as a non-atomic writer would leave) stops the simulator with a message, no traceback."""
    state = tmp_path / f"{MODEL}.json"
    state.write_text('{"model": "ev", "version": 1, "units": {"1": {', encoding="utf-8")
    with running(MODEL, "--tcp", "127.0.0.1:0", "--state", str(state)) as (proc, line):
        assert proc.wait(timeout=20) == 1
        assert "cannot read simulator state" in line and "Traceback" not in line, line


# ==== loopback only unless told ===========================================================================
@pytest.mark.parametrize("where", ["0.0.0.0:0", "0.0.0.0:15020", "[::]:0", "192.0.2.1:0", ":0"])
def test_non_loopback_bind_is_refused(where: str) -> None:
    with running(MODEL, "--tcp", where) as (proc, line):
        assert proc.wait(timeout=20) == 1
        assert line.startswith("drivemap simulate: error:"), line
        if where != ":0":
            assert "--allow-remote" in line and "non-loopback" in line, line
        assert "Traceback" not in line


def test_generated_module_refuses_non_loopback_too() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", f"drivemap_models.{MODEL}.simulator", "--tcp", "0.0.0.0:0"],
        cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=30,
    )
    assert proc.returncode == 1 and "--allow-remote" in proc.stderr, proc.stderr


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost"])
def test_loopback_binds(host: str) -> None:
    with running(MODEL, "--tcp", f"{host}:0") as (proc, line):
        assert "listening on tcp" in line, line
        address = line.split("listening on tcp ")[1].split()[0]
        assert address.startswith(("127.", "[::1]")), address
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0


def test_allow_remote_binds_and_stops() -> None:
    with running(MODEL, "--tcp", "0.0.0.0:0", "--allow-remote") as (proc, line):
        assert "listening on tcp 0.0.0.0:" in line, line
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
