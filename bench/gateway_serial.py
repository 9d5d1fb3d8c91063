"""Gateway scale on paced virtual serial lines (the serial phase of ``bench/gateway.py``, section 6).

Parts, each in its own process so that each one's CPU is measured apart: the relays (one paced
:class:`drivemap.testing.vserial.VirtualSerialLine` per line, at 19200 Bd 8N1, in one process), the
simulators (the generated ev simulator with realistic timing, 4 ms per request, one Modbus RTU
server with units 1..10 per line; half the lines in each of two processes), the gateway
(``python -m drivemap gateway`` with ``serial:`` buses on the lines' master ends) and the broker; this
process subscribes. Only ptys and 127.0.0.1.

Polls/s per line are counted on the wire: the relay records every request frame the gateway wrote
(its start time and size) and every reply; a window's count is the requests that started in it.
The line's physical limit is computed from the frames actually seen (median request and reply
size), the device's 4 ms turnaround and the t3.5 silence before the next request.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT  # noqa: E402

BAUD = 19200
DRIVES = 10
MODEL = "ev"
PUBLISH = ["motor_state", "motor_speed", "alarm_no", "motor_direction", "command_speed"]
PROCESSING_S = 0.004  # ev: processing_ms 3..5, the simulator waits the midpoint
SIM_PROCS = 2
#: The relays wake at most every BURST_S inside a frame (vserial's ``burst_interval``): bytes are never
#: early and each frame's last byte arrives when the baud rate says, but a frame shorter than this
#: reaches the device in one piece (see the section text for why).
BURST_S = float(os.environ.get("DRIVEMAP_BENCH_BURST_S", "0.005"))


# ------------------------------------------------------------------------------ child: relays
def relays(count: int, baud: int, out: str) -> None:
    """``count`` paced virtual lines; print their ends; on stdin EOF dump the frames and exit."""
    from drivemap.testing.vserial import VirtualSerialLine

    lines = [VirtualSerialLine(baud, pace=True, burst_interval=BURST_S, name=f"bench{n}") for n in range(count)]
    print("READY", *[f"{ln.master_port},{ln.device_port}" for ln in lines], flush=True)
    sys.stdin.read()
    frames = []
    for ln in lines:
        per: dict[str, list[tuple[float, int]]] = {}
        for direction in ("to_device", "to_master"):
            chunks = ln.chunks(direction)
            starts: list[tuple[float, int]] = []
            last = -1.0
            for at, data in chunks:
                if starts and at - last <= ln.frame_gap:
                    starts[-1] = (starts[-1][0], starts[-1][1] + len(data))
                else:
                    starts.append((at, len(data)))
                last = at
            per[direction] = starts
        frames.append(per)
    for ln in lines:
        ln.close()
    Path(out).write_text(json.dumps(frames))


# ------------------------------------------------------------------------------ child: simulators
def sims(baud: int, change_every: float, log_path: str, devices: list[str]) -> None:
    """One RTU simulator (units 1..DRIVES) per device end; change motor_speed now and then; log it."""
    import importlib

    from drivemap.runtime.sim.serve import ThreadedSimServer

    sim_cls = importlib.import_module(f"drivemap_models.{MODEL}.simulator").Simulator
    servers = [ThreadedSimServer(sim_cls(list(range(1, DRIVES + 1)), realistic_timing=True), serial=dev,
                                 mode="rtu", baudrate=baud).start() for dev in devices]
    print("READY", flush=True)
    change_until_stdin_closes(servers, change_every, log_path, devices)


def change_until_stdin_closes(servers: list[Any], change_every: float, log_path: str, ports: list[Any]) -> None:
    """Change a random drive's motor_speed every ``change_every`` s until stdin closes, then log the
    changes (server index, unit, value, time) with ``ports`` to ``log_path`` and stop the servers.
    Shared by this bench's serial simulators and :mod:`gateway`'s TCP ones."""
    import os
    import random
    import threading

    changes: list[tuple[int, int, int, float]] = []
    stop = threading.Event()

    def changer() -> None:
        value = 1 + os.getpid() % 1000 * 60
        rng = random.Random(os.getpid())
        while not stop.wait(change_every):
            i, unit = rng.randrange(len(servers)), rng.randrange(1, DRIVES + 1)
            value += 1
            servers[i].sim.set("motor_speed", value % 60000, unit=unit)
            changes.append((i, unit, value % 60000, time.monotonic()))

    worker = threading.Thread(target=changer, daemon=True)
    worker.start()
    sys.stdin.read()
    stop.set()
    worker.join()
    Path(log_path).write_text(json.dumps({"ports": ports, "changes": changes}))
    for s in servers:
        s.stop()


# ------------------------------------------------------------------------------ parent
def config(folder: Path, broker: int, masters: list[str], interval: float) -> Path:
    out = [f"gateway: 1\nname: bench\nmqtt: {{host: 127.0.0.1, port: {broker}, prefix: bench, qos: 0, "
           "discovery: false}\nbuses:"]
    for n, port in enumerate(masters):
        out.append(f"  - name: line{n:02d}\n    serial: {{port: {port}, mode: rtu, baudrate: {BAUD}}}\n"
                   "    devices:")
        for unit in range(1, DRIVES + 1):
            out.append(f"      - {{name: l{n:02d}d{unit:02d}, model: {MODEL}, unit: {unit}, interval: {interval}, "
                       f"publish: [{', '.join(PUBLISH)}]}}")
    path = folder / f"gateway-serial-{len(masters)}-{interval}.yaml"
    path.write_text("\n".join(out) + "\n")
    return path


class Parts:
    """The relay process and the simulator processes of ``lines`` serial lines."""

    def __init__(self, folder: Path, lines: int, change_every: float = 0.02) -> None:
        self.folder = folder
        self.lines = lines
        env_cmd = [sys.executable, str(Path(__file__))]
        self.relay = subprocess.Popen([*env_cmd, "relays", str(lines), str(BAUD), str(folder / f"frames{lines}.json")],
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE, cwd=ROOT)
        assert self.relay.stdout is not None
        ends = [e.split(",") for e in self.relay.stdout.readline().decode().split()[1:]]
        self.masters = [m for m, _ in ends]
        devices = [d for _, d in ends]
        per = -(-lines // SIM_PROCS)
        groups = [devices[i:i + per] for i in range(0, lines, per)]
        self.sims = [subprocess.Popen([*env_cmd, "sims", str(BAUD), str(change_every),
                                       str(folder / f"changes-serial{lines}-{n}.json"), *g],
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE, cwd=ROOT)
                     for n, g in enumerate(groups)]
        for p in self.sims:
            assert p.stdout is not None
            if not p.stdout.readline().startswith(b"READY"):
                raise RuntimeError("serial simulators did not start")

    @property
    def pids(self) -> dict[str, list[int]]:
        return {"relays": [self.relay.pid], "simulators": [p.pid for p in self.sims]}

    def close(self) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """Stop everything; (frames per line, simulator change logs)."""
        for p in [*self.sims, self.relay]:
            assert p.stdin is not None
            p.stdin.close()
        for p in [*self.sims, self.relay]:
            p.wait(60)
        frames = json.loads((self.folder / f"frames{self.lines}.json").read_text())
        logs = [json.loads((self.folder / f"changes-serial{self.lines}-{n}.json").read_text())
                for n in range(len(self.sims))]
        return frames, logs


def wire_limit(request: float, reply: float, baud: int = BAUD) -> float:
    """Polls/s a line at ``baud`` 8N1 allows for one request/reply of these sizes (bytes): both
    frames on the wire (10 bits a byte), the device's turnaround (4 ms from the end of the request to
    its reply) and the t3.5 silence the master keeps before its next request (3.5 characters of 11
    bits, at least 1.75 ms above 19200 Bd)."""
    t35 = 3.5 * 11 / baud if baud <= 19200 else 0.00175
    return 1.0 / ((request + reply) * 10 / baud + PROCESSING_S + t35)


def frame_sizes(frames: list[dict[str, Any]], t0: float, t1: float) -> tuple[float, float]:
    """Median request and reply size (bytes) of the frames between t0 and t1."""
    req = [n for line in frames for at, n in line["to_device"] if t0 <= at < t1]
    rep = [n for line in frames for at, n in line["to_master"] if t0 <= at < t1]
    return float(statistics.median(req)), float(statistics.median(rep))


def polls_per_line(frames: list[dict[str, Any]], t0: float, t1: float) -> list[float]:
    """Requests per second each line carried between t0 and t1 (counted on the wire)."""
    return [sum(1 for at, _ in line["to_device"] if t0 <= at < t1) / (t1 - t0) for line in frames]


def unanswered(frames: list[dict[str, Any]], t0: float, t1: float) -> int:
    """Requests between t0 and t1 that no reply followed before the next request (timeouts)."""
    import bisect

    missing = 0
    for line in frames:
        replies = [at for at, _ in line["to_master"]]
        requests = line["to_device"]
        for k, (at, _) in enumerate(requests):
            if not t0 <= at < t1:
                continue
            following = requests[k + 1][0] if k + 1 < len(requests) else float("inf")
            j = bisect.bisect_left(replies, at)
            missing += j >= len(replies) or replies[j] >= following
    return missing


if __name__ == "__main__":
    if sys.argv[1] == "relays":
        relays(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
    elif sys.argv[1] == "sims":
        sims(int(sys.argv[2]), float(sys.argv[3]), sys.argv[4], sys.argv[5:])
