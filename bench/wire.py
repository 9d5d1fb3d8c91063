"""(3) Wire efficiency: requests per second on a paced virtual serial line vs the physical limit.

Setup: a :class:`VirtualSerialLine` paced at 115200 baud, 8N1 (10 bits per byte), in its own
process, recording the time of every chunk it reads from a sender and writes to a receiver; on the
device end, in its own process, either the generated ``MODEL`` simulator with realistic timing on
pymodbus's serial server (``simulator``) or a lean reference device (``lean``: one loop framing with
pymodbus's ``FramerRTU``, a precise processing delay, the simulator's own reply bytes, see
``servers.py``); on the master end the generated client and raw pymodbus, sync and async, 8N1.

Physical limit of one transaction (nothing can be faster on this line with this device):

    T = (request bytes + response bytes) x 10 / 115200
        + max(t3.5, device processing)      (the reply cannot start sooner)
        + t3.5                               (silence before the next request)

t3.5 is the silent interval the map gives at 115200 baud (``TimingSpec``: 3.5 characters, or the
map's floor above its threshold baud rate); device processing is what the simulator applies
(``Simulator.reply_delay()``). Limit = 1 / T requests per second.

Where the time goes, from the line's timestamps (``time.monotonic()``, one clock for every process)
and the client's own trace hooks: each transaction is split into request on the wire (first byte
read from the client -> last byte handed to the device), device turnaround (-> first reply byte
read from the device), reply on the wire (-> last byte handed to the client) and client
turnaround (-> first byte of the next request), the last one split again at the moment pymodbus
hands the complete reply to its framer (``trace_packet``) and the moment it hands over the next
request. The generated sync client reads replies with ``drivemap.runtime.client.transport.serialrx`` (not pymodbus's
polling receive) and, with the stale-reply guard on (the default), hands a reply over after the
guard's settle time of silence; the bus counts its t3.5 from the reply's last byte, so that wait
overlaps the t3.5 rather than adding to it.
"""

from __future__ import annotations

import asyncio
import importlib
import json
import logging
import os
import tempfile
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

from common import Row, Section, abounded, bounded, median, spread
from servers import Child

MODEL = "ev"
BAUD = 115200
BITS = 10
GOAL = 0.90
#: The sync client is held to more (issue 37: 0.95 on read 16 and write one; the general 0.90 stays for the rest).
GOALS = {("sync", "read 16"): 0.95, ("sync", "write one"): 0.95}
BYTE = BITS / BAUD
DEVICES = ("simulator", "lean")
MODES = ("sync", "raw-sync", "async", "raw-async")
PHASES = ("request on the wire", "device turnaround", "reply on the wire", "client turnaround",
          "reply end seen by client", "client work + quiet", "request to the line")


def silent_interval(timing: Any) -> float:
    """t3.5 at BAUD as the map defines it."""
    if timing.silent_interval_floor_above_bps is not None and BAUD > timing.silent_interval_floor_above_bps:
        return (timing.silent_interval_floor_ms or 0.0) / 1000.0
    chars = timing.silent_interval_chars if timing.silent_interval_chars is not None else 3.5
    return chars * BITS / BAUD


def pick(client_cls: Any) -> tuple[Any, Any]:
    """(a 16-word unpaged read request of the plan, a plain writable u16 register)."""
    plan = [r for r in client_cls.plan() if r.page is None]
    read = max(plan, key=lambda r: (r.count == 16, r.count))
    spec = client_cls.SPEC
    reg = next(r for r in spec.registers if r.access == "rw" and r.count == 1 and r.type == "u16" and r.page is None
               and r.command_value is None and not any(x.page and x.page.selector == r.name for x in spec.registers))
    return read, reg


def trace(pymodbus_client: Any, marks: list[tuple[float, bool]]) -> None:
    """Record (time, sending) each time pymodbus hands bytes out or gets bytes in (its trace hook)."""
    mgr = getattr(pymodbus_client, "transaction", None) or pymodbus_client.ctx
    original = mgr.trace_packet
    clock = time.monotonic

    def hook(sending: bool, data: bytes) -> bytes:
        marks.append((clock(), sending))
        return original(sending, data)  # type: ignore[no-any-return]

    mgr.trace_packet = hook


def frame_edges(chunks: list[tuple[float, int]], size: int) -> tuple[list[float], list[float]]:
    """Times of the chunks holding the first and the last byte of each ``size``-byte frame."""
    firsts: list[float] = []
    lasts: list[float] = []
    pos = 0
    for stamp, n in chunks:
        for b in range(pos, pos + n):
            if b % size == 0:
                firsts.append(stamp)
            if b % size == size - 1:
                lasts.append(stamp)
        pos += n
    return firsts, lasts


def split(capture: dict[str, list[tuple[float, int]]], req: int, resp: int,
          marks: list[tuple[float, bool]]) -> dict[str, float]:
    """Median seconds of each phase over the captured transactions (see the module docstring)."""
    q0, _ = frame_edges(capture["to_device captured"], req)
    _, q1 = frame_edges(capture["to_device delivered"], req)
    r0, _ = frame_edges(capture["to_master captured"], resp)
    _, r1 = frame_edges(capture["to_master delivered"], resp)
    n = min(len(q0), len(q1), len(r0), len(r1))
    rx = [t for t, sending in marks if not sending]
    tx = [t for t, sending in marks if sending]
    phases: dict[str, list[float]] = {p: [] for p in PHASES}
    phases["period"] = []
    for i in range(n - 1):
        if not q0[i] <= q1[i] <= r0[i] <= r1[i] <= q0[i + 1]:
            continue  # a frame out of step (a lost or split frame): not a clean transaction
        phases["request on the wire"].append(q1[i] - q0[i])
        phases["device turnaround"].append(r0[i] - q1[i])
        phases["reply on the wire"].append(r1[i] - r0[i])
        phases["client turnaround"].append(q0[i + 1] - r1[i])
        phases["period"].append(q0[i + 1] - q0[i])
        seen = [t for t in rx if r1[i] - 0.0005 <= t <= q0[i + 1]]
        sent = [t for t in tx if seen and seen[-1] <= t <= q0[i + 1]]
        if seen and sent:
            phases["reply end seen by client"].append(seen[-1] - r1[i])
            phases["client work + quiet"].append(sent[-1] - seen[-1])
            phases["request to the line"].append(q0[i + 1] - sent[-1])
    out = {k: median(v) for k, v in phases.items()}
    out["transactions"] = float(len(phases["period"]))
    return out


class Line:
    """The paced line child, with its recorder."""

    def __init__(self, child: Child) -> None:
        self.child = child
        self.master, self.device = child.fields[0], child.fields[1]
        fd, self.path = tempfile.mkstemp(prefix="drivemap-wire-", suffix=".json")
        os.close(fd)

    def clear(self) -> None:
        self.child.command("clear")

    def dump(self) -> dict[str, list[tuple[float, int]]]:
        self.child.command(f"dump {self.path}")
        with open(self.path, encoding="utf-8") as fh:
            data: dict[str, list[tuple[float, int]]] = json.load(fh)
        return data

    def remove(self) -> None:
        os.unlink(self.path)


Results = dict[tuple[str, str, str], dict[str, Any]]
Marks = list[tuple[float, bool]]


@dataclass
class _Sweep:
    """Timed rounds of each operation of one client against one device, recorded in ``results``."""

    device: str
    line: Line
    frames: dict[str, tuple[int, int]]
    results: Results
    rounds: int
    count: int
    seconds: float

    def record(self, mode: str, op: str, rates: list[float], marks: Marks) -> None:
        req, resp = self.frames[op]
        self.results[(self.device, mode, op)] = {"rates": rates, "phases": split(self.line.dump(), req, resp, marks)}

    def sync(self, mode: str, ops: dict[str, Callable[[], Any]], marks: Marks) -> None:
        for op, fn in ops.items():
            fn()
            self.line.clear()
            marks.clear()
            rates = []
            for _ in range(self.rounds):
                n, t = bounded(fn, self.count, self.seconds)
                rates.append(n / t)
            self.record(mode, op, rates, marks)

    async def asynchronous(self, mode: str, ops: dict[str, Callable[[], Awaitable[Any]]], marks: Marks) -> None:
        for op, afn in ops.items():
            await afn()
            self.line.clear()
            marks.clear()
            rates = []
            for _ in range(self.rounds):
                n, t = await abounded(afn, self.count, self.seconds)
                rates.append(n / t)
            self.record(mode, op, rates, marks)


def _sync_generated(sweep: _Sweep, client_mod: Any, read_req: Any, reg: Any, facts: dict[str, Any]) -> int:
    """The generated sync client; records its retries and timeouts; the write's raw value for the raw clients."""
    spec = client_mod.SPEC
    client = client_mod.Client.serial(sweep.line.master, 1, timeout=1.0, baudrate=BAUD, parity="none", stop_bits=1)
    with client:
        accs = [client.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
        wacc = client.accessor(reg.name)
        value = wacc.read()
        raw_value: int = wacc.read_raw() & 0xFFFF
        ops: dict[str, Callable[[], Any]] = {"read 16": lambda: client.read(*accs),
                                             "write one": lambda: wacc.write(value)}
        before = client.stats.transactions
        ops["read 16"]()
        assert client.stats.transactions - before == 1, "the 16-register read must be one request"
        marks: Marks = []
        trace(client.bus.client, marks)
        sweep.sync("sync", ops, marks)
        facts["retries"], facts["timeouts"] = client.stats.retries, client.stats.timeouts
    return raw_value


def _sync_raw(sweep: _Sweep, read_req: Any, reg: Any, raw_value: int, t35: float) -> None:
    """Raw pymodbus, sync, keeping the same t3.5 after each reply."""
    from pymodbus.client import ModbusSerialClient

    raw = ModbusSerialClient(sweep.line.master, baudrate=BAUD, parity="N", stopbits=1, bytesize=8, timeout=1.0,
                             retries=0)
    raw.connect()
    try:
        raw_ops: dict[str, Callable[[], Any]] = {
            "read 16": lambda: (raw.read_holding_registers(read_req.address, count=read_req.count, device_id=1),
                                time.sleep(t35)),
            "write one": lambda: (raw.write_register(reg.address, raw_value, device_id=1), time.sleep(t35)),
        }
        marks: Marks = []
        trace(raw, marks)
        sweep.sync("raw-sync", raw_ops, marks)
    finally:
        raw.close()


async def _async_generated(sweep: _Sweep, client_mod: Any, read_req: Any, reg: Any) -> None:
    """The generated async client."""
    spec = client_mod.SPEC
    aclient = client_mod.AsyncClient.serial(sweep.line.master, 1, timeout=1.0, baudrate=BAUD, parity="none",
                                            stop_bits=1)
    await aclient.connect()
    try:
        aaccs = [aclient.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
        awacc = aclient.accessor(reg.name)
        avalue = await awacc.read()
        amarks: Marks = []
        trace(aclient.bus.client, amarks)
        aops = {"read 16": lambda: aclient.read(*aaccs), "write one": lambda: awacc.write(avalue)}
        await sweep.asynchronous("async", aops, amarks)
    finally:
        aclient.close()


async def _async_raw(sweep: _Sweep, read_req: Any, reg: Any, raw_value: int, t35: float) -> None:
    """Raw pymodbus, async, keeping the same t3.5 after each reply."""
    from pymodbus.client import AsyncModbusSerialClient

    araw = AsyncModbusSerialClient(sweep.line.master, baudrate=BAUD, parity="N", stopbits=1, bytesize=8,
                                   timeout=1.0, retries=0)
    await araw.connect()
    try:
        async def aread() -> None:
            await araw.read_holding_registers(read_req.address, count=read_req.count, device_id=1)
            await asyncio.sleep(t35)

        async def awrite() -> None:
            await araw.write_register(reg.address, raw_value, device_id=1)
            await asyncio.sleep(t35)

        amarks: Marks = []
        trace(araw, amarks)
        await sweep.asynchronous("raw-async", {"read 16": aread, "write one": awrite}, amarks)
    finally:
        araw.close()


async def _async_part(sweep: _Sweep, client_mod: Any, read_req: Any, reg: Any, raw_value: int, t35: float) -> None:
    await _async_generated(sweep, client_mod, read_req, reg)
    await _async_raw(sweep, read_req, reg, raw_value, t35)


def run_device(device: str, line: Line, client_mod: Any, read_req: Any, reg: Any, rounds: int, count: int,
               seconds: float, frames: dict[str, tuple[int, int]],
               results: dict[tuple[str, str, str], dict[str, Any]]) -> dict[str, Any]:
    """Every client mode and operation against one device; fills ``results``; facts about the run."""
    spec = client_mod.SPEC
    kind = ("serial", MODEL, line.device, str(BAUD)) if device == "simulator" else ("lean", MODEL, line.device,
                                                                                    str(BAUD))
    facts: dict[str, Any] = {}
    sweep = _Sweep(device, line, frames, results, rounds, count, seconds)
    with Child(*kind, max_seconds=200) as server:
        facts["processing"] = float(server.fields[1])
        # ---- sync: the generated client, then raw pymodbus with the same t3.5 after each reply
        raw_value = _sync_generated(sweep, client_mod, read_req, reg, facts)
        t35 = facts["t35"] = silent_interval(spec.protocol.timing)
        _sync_raw(sweep, read_req, reg, raw_value, t35)
        # ---- async
        asyncio.run(asyncio.wait_for(_async_part(sweep, client_mod, read_req, reg, raw_value, t35), timeout=120))
    return facts


def _limit_t(op: str, frames: dict[str, tuple[int, int]], t35: float, processing: float) -> float:
    """Physical limit of one transaction of ``op`` (see the module docstring), seconds."""
    req, resp = frames[op]
    return (req + resp) * BYTE + max(t35, processing) + t35


def _efficiency_table(sec: Section, results: Results, frames: dict[str, tuple[int, int]], t35: float,
                      processing: float) -> None:
    """Efficiency per device, client and operation: the table and the goal rows; stores ``eff`` in results."""
    sec.detail.append("| device | client | operation | frame bytes (req + resp) | limit T (ms) | limit req/s "
                      "| achieved req/s | efficiency (range) | lost per request (ms) | rounds |")
    sec.detail.append("|---|---|---|---|---:|---:|---:|---:|---:|---:|")
    for (device, mode, op), data in results.items():
        req, resp = frames[op]
        t_limit = _limit_t(op, frames, t35, processing)
        lim = 1.0 / t_limit
        rates = data["rates"]
        effs = [r / lim for r in rates]
        eff = median(effs)
        achieved = median(rates)
        data["eff"] = eff
        baseline = mode.startswith("raw") or device != "simulator"
        name = f"{mode} {op}" if device == "simulator" else f"{mode} {op} on the lean device"
        if mode.startswith("raw"):
            name += " (raw pymodbus, reference)"
        elif device != "simulator":
            name += " (reference)"
        goal = GOALS.get((mode, op), GOAL)
        sec.rows.append(Row("3 wire", name, eff, f"≥ {goal:.2f}" if not baseline else "—",
                            eff >= goal if not baseline else None, f"{achieved:.1f} of {lim:.1f} req/s"))
        sec.detail.append(f"| {device} | {mode} | {op} | {req} + {resp} | {t_limit * 1000:.3f} | {lim:.1f} "
                          f"| {achieved:.1f} | {eff:.3f} ({spread(effs)}) | {(1 / achieved - t_limit) * 1000:.3f} "
                          f"| {len(rates)} |")


def _phase_table(sec: Section, results: Results, frames: dict[str, tuple[int, int]], t35: float,
                 processing: float) -> None:
    """Where each transaction's time goes, per phase, against the ideal."""
    sec.detail.append("Where each transaction's time goes (medians over the timed rounds, ms), from the line's own "
                      "timestamps and the client's pymodbus trace hook; `ideal` is the physical limit's share. "
                      "Request/reply on the wire: first byte read from the sender -> last byte handed to the "
                      "receiver (ideal: bytes x 86.8 µs). Device turnaround: last request byte handed to the device "
                      "-> first reply byte read from it (ideal: max(t3.5, processing)). Client turnaround: last "
                      "reply byte handed to the client -> first byte of the next request read from it (ideal: "
                      "t3.5), split into: reply end seen (-> pymodbus hands the complete reply to its framer; "
                      "for the generated sync client this includes the stale-reply guard's settle time, "
                      "max(4 characters, 1 ms) of silence after the last byte, which the t3.5 then overlaps), "
                      "client work + quiet (-> pymodbus hands over the next request), request to the line "
                      "(-> the line reads it). The generated sync client keeps its quiet time in the request's "
                      "send (`Bus._quiet_at_send`): pymodbus builds the frame while the line is still quiet, "
                      "so its `client work + quiet` is the client's work alone and its `request to the line` "
                      "is the rest of the t3.5 (slept, its last 0.2 ms waited by the clock) plus the write; "
                      "what its turnaround keeps above t3.5 is the wake-up after the reply's last byte and "
                      "the write's way to the line (the `raw-sync` rows' `request to the line`).")
    sec.detail.append("")
    sec.detail.append("| device | client | operation | request on the wire | device turnaround | reply on the wire "
                      "| client turnaround | = reply end seen | + client work + quiet | + request to the line "
                      "| period | transactions |")
    sec.detail.append("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for op in frames:
        req, resp = frames[op]
        sec.detail.append(f"| ideal | — | {op} | {req * BYTE * 1000:.2f} | {max(t35, processing) * 1000:.2f} "
                          f"| {resp * BYTE * 1000:.2f} | {t35 * 1000:.2f} | 0 | {t35 * 1000:.2f} | 0 "
                          f"| {_limit_t(op, frames, t35, processing) * 1000:.2f} | — |")
        for device in DEVICES:
            for mode in MODES:
                ph = results.get((device, mode, op), {}).get("phases")
                if not ph:
                    continue
                cells = " | ".join(f"{ph[p] * 1000:.2f}" for p in PHASES)
                sec.detail.append(f"| {device} | {mode} | {op} | {cells} | {ph['period'] * 1000:.2f} "
                                  f"| {int(ph['transactions'])} |")


def run(quick: bool) -> Section:
    sec = Section("Wire efficiency (paced virtual serial line, 115200 8N1)")
    logging.getLogger("drivemap").setLevel(logging.ERROR)  # no baud-rate warnings in the table
    client_mod = importlib.import_module(f"drivemap_models.{MODEL}.client")
    spec = client_mod.SPEC
    read_req, reg = pick(client_mod.Client)
    rounds = 2 if quick else 5
    count, seconds = (30, 0.4) if quick else (120, 0.8)
    t35 = silent_interval(spec.protocol.timing)
    frames = {"read 16": (8, 5 + 2 * read_req.count), "write one": (8, 8)}
    results: Results = {}
    facts: dict[str, dict[str, Any]] = {}
    with Child("line", str(BAUD), max_seconds=250) as child:
        line = Line(child)
        try:
            for device in DEVICES:
                facts[device] = run_device(device, line, client_mod, read_req, reg, rounds, count, seconds, frames,
                                           results)
        finally:
            line.remove()
    processing = facts["simulator"]["processing"]
    sec.detail.append(f"Model `{MODEL}` (realistic timing: reply {processing * 1000:.2f} ms after the request); "
                      f"t3.5 at {BAUD} Bd = {t35 * 1000:.3f} ms (the map's floor); read = {read_req.count} registers "
                      f"at 0x{read_req.address:04X}, write = 06h to `{reg.name}` (0x{reg.address:04X}). Devices: "
                      "`simulator` = the generated simulator on pymodbus's serial server (`drivemap simulate`); "
                      "`lean` = the reference device of `bench/servers.py` (same reply bytes, precise delay).")
    sec.detail.append("")
    _efficiency_table(sec, results, frames, t35, processing)
    # ---- where the time goes
    sec.detail.append("")
    _phase_table(sec, results, frames, t35, processing)
    sec.detail.append("")
    retries = sum(f["retries"] for f in facts.values())
    timeouts = sum(f["timeouts"] for f in facts.values())
    sec.detail.append(f"Generated sync client retries {retries}, timeouts {timeouts} over the run.")
    sec.explanation = explain(results, frames, t35, processing)
    return sec


def explain(results: dict[tuple[str, str, str], dict[str, Any]], frames: dict[str, tuple[int, int]], t35: float,
            processing: float) -> str:
    """The shortfall paragraph, with this run's medians."""

    def ph(device: str, mode: str, op: str, phase: str) -> float:
        value = results.get((device, mode, op), {}).get("phases", {}).get(phase, float("nan"))
        return float(value) * 1000

    def over(device: str, mode: str, op: str, phase: str, ideal: float) -> str:
        return f"{ph(device, mode, op, phase) - ideal * 1000:+.2f}"

    lines = []
    for op, (req, resp) in frames.items():
        bits = []
        for device in DEVICES:
            for mode in MODES:
                if (device, mode, op) not in results:
                    continue
                bits.append(f"{device}/{mode}: device {over(device, mode, op, 'device turnaround', max(t35, processing))}, "
                            f"wire {ph(device, mode, op, 'request on the wire') + ph(device, mode, op, 'reply on the wire') - (req + resp) * BYTE * 1000:+.2f}, "
                            f"client {over(device, mode, op, 'client turnaround', t35)}")
        lines.append(f"* `{op}`, ms above the ideal per phase: " + "; ".join(bits) + ".")
    return "\n".join(lines)


if __name__ == "__main__":
    import sys

    s = run("--quick" in sys.argv)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
    print(s.explanation)
