"""Gateway scale: one ``drivemap gateway`` process, 20 lines x 10 simulated drives, a real MQTT broker.

    python bench/gateway.py            # standalone (prints the section)
    python bench/run.py --only gateway # as a section of bench/RESULTS.md

Parts, each in its own process: the broker (mosquitto, else amqtt), the simulators (the generated
ev simulator with realistic timing, 4 ms processing per request; 10 Modbus TCP servers with 10 units
each per process, two processes), the gateway (``python -m drivemap gateway``), and this process as
the MQTT subscriber. Only 127.0.0.1.

Two phases. *Saturated*: every drive is polled as often as its line allows (interval 1 ms): polls/s
per line (counted from the per-poll ``state`` snapshots the subscriber receives) against the line's
limit, and the gateway's CPU. *Steady*: every drive polled once a second (a plant's usual rate):
CPU % per 100 drives, memory, and the latency from a value change in a simulator (``motor_speed``
set to a counter, timed with the shared monotonic clock) to its MQTT message.
"""

from __future__ import annotations

import asyncio
import json
import os
import random
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section  # noqa: E402

LINES, DRIVES, SIM_PROCS = 20, 10, 2
MODEL = "ev"
PUBLISH = ["motor_state", "motor_speed", "alarm_no", "motor_direction", "command_speed"]
PROCESSING_S = 0.004  # ev: processing_ms 3..5, the simulator waits the midpoint
TICK = os.sysconf("SC_CLK_TCK")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# ------------------------------------------------------------------------------ child: simulators
def serve(count: int, log_path: str, change_every: float) -> None:
    """Run ``count`` TCP simulators (units 1..DRIVES); change motor_speed now and then; log the changes."""
    import importlib

    from drivemap.runtime.simserve import ThreadedSimServer

    sim_cls = importlib.import_module(f"drivemap_models.{MODEL}.simulator").Simulator
    servers = []
    for _ in range(count):
        sim = sim_cls(list(range(1, DRIVES + 1)), realistic_timing=True)
        servers.append(ThreadedSimServer(sim, tcp=("127.0.0.1", 0)).start())
    print("READY", *[s.address[1] for s in servers], flush=True)  # type: ignore[index]
    changes: list[tuple[int, int, int, float]] = []
    stop = threading.Event()

    def changer() -> None:
        value = 1 + os.getpid() % 1000 * 60
        rng = random.Random(os.getpid())
        while not stop.wait(change_every):
            i, unit = rng.randrange(count), rng.randrange(1, DRIVES + 1)
            value += 1
            servers[i].sim.set("motor_speed", value % 60000, unit=unit)
            changes.append((i, unit, value % 60000, time.monotonic()))

    worker = threading.Thread(target=changer, daemon=True)
    worker.start()
    sys.stdin.read()
    stop.set()
    worker.join()
    Path(log_path).write_text(json.dumps({"ports": [s.address[1] for s in servers], "changes": changes}))  # type: ignore[index]
    for s in servers:
        s.stop()


# ------------------------------------------------------------------------------ parent
def _broker(folder: Path) -> tuple[subprocess.Popen[bytes], int, str]:
    port = free_port()
    exe = shutil.which("mosquitto") or ("/usr/sbin/mosquitto" if os.path.exists("/usr/sbin/mosquitto") else None)
    if exe:
        (folder / "m.conf").write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        cmd, kind = [exe, "-c", str(folder / "m.conf")], "mosquitto"
    else:
        (folder / "a.yaml").write_text(f"listeners:\n  default:\n    type: tcp\n    bind: 127.0.0.1:{port}\n")
        cmd, kind = [sys.executable, "-c", "from amqtt.scripts.broker_script import main; main()", "-c",
                     str(folder / "a.yaml")], "amqtt"
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(200):
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return proc, port, kind
        except OSError:
            time.sleep(0.05)
    raise RuntimeError("broker did not start")


def _config(folder: Path, broker: int, ports: list[int], interval: float) -> Path:
    lines = [f"gateway: 1\nname: bench\nmqtt: {{host: 127.0.0.1, port: {broker}, prefix: bench, qos: 0, "
             "discovery: false}\nbuses:"]
    for n, port in enumerate(ports):
        lines.append(f"  - name: line{n:02d}\n    tcp: 127.0.0.1:{port}\n    devices:")
        for unit in range(1, DRIVES + 1):
            lines.append(f"      - {{name: l{n:02d}d{unit:02d}, model: {MODEL}, unit: {unit}, interval: {interval}, "
                         f"publish: [{', '.join(PUBLISH)}]}}")
    path = folder / f"gateway-{interval}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def _rss_mib(pid: int) -> tuple[float, float]:
    info = {ln.split(":")[0]: ln.split(":")[1] for ln in Path(f"/proc/{pid}/status").read_text().splitlines() if ":" in ln}
    return int(info["VmRSS"].split()[0]) / 1024, int(info["VmHWM"].split()[0]) / 1024


class _Collector:
    def __init__(self) -> None:
        self.states: dict[str, int] = {}
        self.speed: list[tuple[str, int, float]] = []
        self.recording = False

    async def run(self, port: int, ready: asyncio.Event) -> None:
        import aiomqtt

        async with aiomqtt.Client("127.0.0.1", port, identifier="bench-sub", max_queued_incoming_messages=0) as c:
            await c.subscribe("bench/+/state")
            await c.subscribe("bench/+/motor_speed")
            ready.set()
            async for m in c.messages:
                now = time.monotonic()
                topic = m.topic.value
                if not self.recording:
                    continue
                dev = topic.split("/")[1]
                if topic.endswith("/state"):
                    self.states[dev] = self.states.get(dev, 0) + 1
                else:
                    payload = m.payload if isinstance(m.payload, bytes) else str(m.payload).encode()
                    self.speed.append((dev, int(payload), now))


async def _phase(folder: Path, broker: int, ports: list[int], interval: float, seconds: float) -> dict[str, Any]:
    cfg = _config(folder, broker, ports, interval)
    collector = _Collector()
    ready = asyncio.Event()
    sub = asyncio.create_task(collector.run(broker, ready))
    await asyncio.wait_for(ready.wait(), 10)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "generator"), str(ROOT / "generated")]))
    gw = subprocess.Popen([sys.executable, "-m", "drivemap", "gateway", str(cfg), "--log-level", "error"],
                          stdout=subprocess.DEVNULL, stderr=open(folder / "gateway.log", "ab"), env=env, cwd=ROOT)
    try:
        await asyncio.sleep(4.0)  # connect, first polls
        collector.recording = True
        cpu0, t0 = _cpu_s(gw.pid), time.monotonic()
        await asyncio.sleep(seconds)
        cpu1, t1 = _cpu_s(gw.pid), time.monotonic()
        collector.recording = False
        rss, peak = _rss_mib(gw.pid)
    finally:
        gw.terminate()
        gw.wait(15)
        sub.cancel()
        await asyncio.gather(sub, return_exceptions=True)
    return {"t0": t0, "t1": t1, "cpu": (cpu1 - cpu0) / (t1 - t0), "rss": rss, "peak": peak,
            "states": collector.states, "speed": collector.speed}


def _latencies(result: dict[str, Any], logs: list[dict[str, Any]]) -> list[float]:
    port_line = {}
    for proc_no, log in enumerate(logs):
        for i in range(len(log["ports"])):
            port_line[(proc_no, i)] = proc_no * len(logs[0]["ports"]) + i
    arrivals: dict[tuple[str, int], float] = {}
    for dev, value, at in result["speed"]:
        arrivals.setdefault((dev, value), at)
    out = []
    for proc_no, log in enumerate(logs):
        for i, unit, value, at in log["changes"]:
            if not result["t0"] <= at <= result["t1"] - 2.0:
                continue
            dev = f"l{port_line[(proc_no, i)]:02d}d{unit:02d}"
            seen = arrivals.get((dev, value))
            if seen is not None and seen >= at:
                out.append((seen - at) * 1000.0)
    return out


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


async def _measure(quick: bool) -> dict[str, Any]:
    folder = Path(tempfile.mkdtemp(prefix="drivemap-bench-gw-"))
    broker, bport, kind = _broker(folder)
    sims = []
    try:
        per = LINES // SIM_PROCS
        for n in range(SIM_PROCS):
            sims.append(subprocess.Popen([sys.executable, str(Path(__file__)), "serve", str(per),
                                          str(folder / f"changes{n}.json"), "0.02"], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, cwd=ROOT))
        ports = []
        for p in sims:
            assert p.stdout is not None
            ports += [int(x) for x in p.stdout.readline().split()[1:]]
        seconds = 6.0 if quick else 20.0
        saturated = await _phase(folder, bport, ports, 0.001, seconds)
        steady = await _phase(folder, bport, ports, 1.0, seconds)
    finally:
        for p in sims:
            assert p.stdin is not None
            p.stdin.close()
        for p in sims:
            p.wait(30)
        broker.terminate()
        broker.wait(10)
    logs = [json.loads((folder / f"changes{n}.json").read_text()) for n in range(SIM_PROCS)]
    return {"saturated": saturated, "steady": steady, "logs": logs, "broker": kind, "seconds": seconds}


def _per_line(result: dict[str, Any]) -> list[float]:
    span = result["t1"] - result["t0"]
    return [sum(result["states"].get(f"l{n:02d}d{u:02d}", 0) for u in range(1, DRIVES + 1)) / span
            for n in range(LINES)]


def serial_limit(baud: int = 19200) -> float:
    """Polls/s of one RS-485 line at ``baud`` 8N1 for this poll (one 03h request, 5 registers)."""
    request, reply = 8, 5 + 2 * len(PUBLISH)
    wire = (request + reply) * 10 / baud
    t35 = 3.5 * 11 / baud
    return 1.0 / (wire + PROCESSING_S + t35)


def run(quick: bool = False) -> Section:
    sec = Section("Gateway scale (20 lines x 10 drives, MQTT)")
    m = asyncio.run(_measure(quick))
    sat, steady = m["saturated"], m["steady"]
    per_line = _per_line(sat)
    tcp_limit = 1.0 / PROCESSING_S
    med = statistics.median(per_line)
    drives = LINES * DRIVES
    lat_sat = _latencies(sat, m["logs"])
    lat = _latencies(steady, m["logs"])
    sec.rows += [
        Row("6 gateway", "saturated polls/s per line / line limit (TCP, 4 ms device)", med / tcp_limit, "info", None,
            f"median {med:.1f} of {tcp_limit:.0f} polls/s (lines {min(per_line):.1f}..{max(per_line):.1f}); "
            f"{sum(per_line):.0f} polls/s in all; gateway CPU {sat['cpu'] * 100:.0f} %"),
        Row("6 gateway", "saturated polls/s per line / RS-485 19200 Bd limit", med / serial_limit(), "info", None,
            f"{med:.1f} vs {serial_limit():.1f} polls/s a 19200 Bd line allows"),
        Row("6 gateway", "steady (1 poll/s per drive): CPU % per 100 drives", None, "info", None,
            f"{steady['cpu'] * 100 / (drives / 100):.1f} % of one core per 100 drives; RSS {steady['rss']:.0f} MiB "
            f"(peak {max(steady['peak'], sat['peak']):.0f} MiB)"),
        Row("6 gateway", "steady: latency value change -> MQTT (median / p99)", None, "info", None,
            f"{_pct(lat, 0.5):.0f} / {_pct(lat, 0.99):.0f} ms over {len(lat)} changes (saturated: "
            f"{_pct(lat_sat, 0.5):.0f} / {_pct(lat_sat, 0.99):.0f} ms)"),
    ]
    sec.detail += [
        f"Broker: {m['broker']}. Measured for {m['seconds']:.0f} s per phase after 4 s of warm-up. "
        f"{drives} drives (model {MODEL}, 5 registers per poll = one 03h request each), QoS 0, no discovery.",
        "",
        "| phase | polls/s (all lines) | per line (median, min..max) | gateway CPU (% of one core) | RSS MiB |",
        "|---|---:|---|---:|---:|",
        f"| saturated (interval 1 ms) | {sum(per_line):.0f} | {med:.1f} ({min(per_line):.1f}..{max(per_line):.1f}) | "
        f"{sat['cpu'] * 100:.0f} | {sat['rss']:.0f} |",
        f"| steady (interval 1 s) | {sum(_per_line(steady)):.0f} | {statistics.median(_per_line(steady)):.1f} | "
        f"{steady['cpu'] * 100:.0f} | {steady['rss']:.0f} |",
        "",
        f"Line limits for this poll: Modbus TCP to a device that needs 4 ms per request: {tcp_limit:.0f} polls/s; "
        f"RS-485 at 19200 Bd 8N1 (23 bytes on the wire + 4 ms + t3.5): {serial_limit():.1f} polls/s; at 9600 Bd: "
        f"{serial_limit(9600):.1f}. The machine has 2 cores shared by the broker, the simulators (2 processes), "
        "the subscriber and the gateway: in the saturated phase the gateway's own CPU is reported beside the "
        "polls it achieved, and what is left of the two cores bounds the simulators (10 servers and 100 units "
        "per process, each request waited out precisely), not the lines.",
        "",
        f"Latency: {len(lat)} changes in the steady phase, median {_pct(lat, 0.5):.0f} ms, p90 {_pct(lat, 0.9):.0f} ms, "
        f"p99 {_pct(lat, 0.99):.0f} ms, max {max(lat) if lat else float('nan'):.0f} ms (a change waits for the next "
        "poll of its drive: half the 1 s interval on average). Saturated phase: median "
        f"{_pct(lat_sat, 0.5):.0f} ms, p99 {_pct(lat_sat, 0.99):.0f} ms over {len(lat_sat)} changes.",
    ]
    return sec


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "serve":
        serve(int(sys.argv[2]), sys.argv[3], float(sys.argv[4]))
    else:
        s = run("--quick" in sys.argv)
        for r in s.rows:
            print(f"{r.name}: {r.absolute}")
        print("\n".join(s.detail))
