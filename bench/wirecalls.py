"""Deterministic cost of one transaction of section 3's generated-client rows: Python calls and waits.

Section 3 times the generated client on a paced line; that figure moves with the machine's load. This
module counts instead, for the same client calls (``wire.pick``'s 16-register read through
``client.read(*accessors)``, and ``accessor.write(value)`` of a plain u16 register; sync and async,
``Client.serial(port, 1, timeout=1.0, baudrate=115200, parity="none", stop_bits=1)``), on a pty whose
other end a thread answers with the tree's generated simulator (no delay, no pacing):

* **calls**: Python and built-in function calls per transaction (``cProfile``, in the client's thread,
  after a warm-up), with the bus's quiet time already over when each transaction starts (a pause
  between transactions, not profiled), so that no wait loop (``time.sleep``, ``sleep_until``'s
  yielding) adds a number of calls that depends on the machine's speed;
* **waits**: what the request path is set to wait, from the tree's own objects: the quiet time after
  a reply and whether it counts from the reply's last byte, the stale-reply guard's settle time and
  its other times, the serial receiver's inter-character and quiet times, pymodbus's poll interval
  and inter-byte timeout, the response timeout; and the ``select`` timeouts and ``time.sleep`` calls
  per sync transaction, recorded in a run of back-to-back transactions.

Run on one tree's code (``PYTHONPATH`` = that tree's ``generator``, ``generated`` and ``bench``; its
``wire`` module picks the registers): ``python bench/wirecalls.py [TRANSACTIONS]`` prints one JSON line.
"""

from __future__ import annotations

import asyncio
import cProfile
import functools
import importlib
import json
import os
import re
import select
import sys
import threading
import time
import tty
from collections import Counter
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

ROWS = ("sync read 16", "sync write one", "async read 16", "async write one")
#: Pause between profiled transactions (s): longer than any quiet time, so no wait runs in them.
PAUSE_S = 0.004
#: This module's own frames (the driver: its loops and the lambdas that make the client's calls) are not counted.
_OWN = "wirecalls.py:"
_IGNORED = ("<method 'enable' of '_lsprof.Profiler' objects>", "<method 'disable' of '_lsprof.Profiler' objects>")


class Device:
    """A pty whose other end a thread answers with the tree's simulator (the client opens ``port``)."""

    def __init__(self, model: str) -> None:
        from pymodbus.framer import FramerRTU
        from pymodbus.pdu import DecodePDU

        self.sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator([1])
        self.framer = FramerRTU(DecodePDU(True))
        self.fd, slave = os.openpty()
        tty.setraw(slave)
        self.port = os.ttyname(slave)
        self._slave = slave
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        buf = b""
        while not self._stop.is_set():
            if not select.select([self.fd], [], [], 0.05)[0]:
                continue
            try:
                buf += os.read(self.fd, 512)
            except OSError:
                return
            while buf:
                used, dev_id, _tid, pdu = self.framer.decode(buf)
                if not used:
                    break
                buf = buf[used:]
                reply = self.sim.handle(dev_id, pdu) if pdu else None
                if reply is not None:
                    os.write(self.fd, self.framer.encode(reply, dev_id, 0))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        os.close(self.fd)
        os.close(self._slave)


def _label(code: Any) -> str:
    """A function's name independent of the tree's folder (modules moved between trees keep their name)."""
    if isinstance(code, str):
        return re.sub(r" at 0x[0-9a-f]+", "", code)
    path = Path(code.co_filename)
    parts = path.parts
    for anchor in ("drivemap", "drivemap_models", "pymodbus", "asyncio", "serial"):
        if anchor in parts:
            i = len(parts) - 1 - parts[::-1].index(anchor)
            return f"{'/'.join(parts[i:])}:{code.co_name}"
    return f"{path.name}:{code.co_name}"


def _group(label: str) -> str:
    if label.startswith("<drivemap"):  # the client's compiled read programs
        return "drivemap"
    if label.startswith("<"):
        return "built-in"
    for group in ("drivemap_models", "drivemap", "pymodbus", "serial"):
        if label.startswith(group + "/"):
            return "generated client" if group == "drivemap_models" else group
    return "stdlib"


def _counts(prof: cProfile.Profile, n: int) -> dict[str, Any]:
    calls: Counter[str] = Counter()
    for entry in prof.getstats():
        label = _label(entry.code)
        if label not in _IGNORED and not label.startswith(_OWN):
            calls[label] += entry.callcount
    groups: Counter[str] = Counter()
    for label, c in calls.items():
        groups[_group(label)] += c
    return {"calls": sum(calls.values()) / n, "groups": {g: c / n for g, c in sorted(groups.items())},
            "functions": {k: c / n for k, c in sorted(calls.items())}}


class _Opcodes:
    """Bytecode instructions executed, per function (``sys.settrace`` with opcode events, this thread)."""

    def __init__(self) -> None:
        self.counts: Counter[Any] = Counter()

    def _local(self, frame: Any, event: str, arg: Any) -> Any:
        if event == "opcode":
            self.counts[frame.f_code] += 1
        return self._local

    def _global(self, frame: Any, event: str, arg: Any) -> Any:
        frame.f_trace_opcodes = True
        return self._local

    def enable(self) -> None:
        sys.settrace(self._global)

    def disable(self) -> None:
        sys.settrace(None)

    def result(self, n: int) -> dict[str, Any]:
        by: Counter[str] = Counter()
        for code, c in self.counts.items():
            by[_label(code)] += c
        by = Counter({k: c for k, c in by.items() if not k.startswith(_OWN)})
        groups: Counter[str] = Counter()
        for label, c in by.items():
            groups[_group(label)] += c
        return {"opcodes": sum(by.values()) / n, "opcode groups": {g: c / n for g, c in sorted(groups.items())},
                "opcodes by function": {k: c / n for k, c in sorted(by.items())}}


def _profile_sync(fn: Callable[[], Any], n: int) -> dict[str, Any]:
    for _ in range(20):
        fn()
    prof, ops = cProfile.Profile(), _Opcodes()
    for meter in (prof, ops):
        for _ in range(n):
            time.sleep(PAUSE_S)
            meter.enable()
            fn()
            meter.disable()
    return _counts(prof, n) | ops.result(n)


async def _profile_async(fn: Callable[[], Awaitable[Any]], n: int) -> dict[str, Any]:
    for _ in range(20):
        await fn()
    prof, ops = cProfile.Profile(), _Opcodes()
    for meter in (prof, ops):
        for _ in range(n):
            await asyncio.sleep(PAUSE_S)
            meter.enable()
            await fn()
            meter.disable()
    return _counts(prof, n) | ops.result(n)


def _sync_waits(fn: Callable[[], Any], n: int) -> dict[str, Any]:
    """select timeouts (ms, rounded to 0.01 ms; a wait bounded by the response timeout as "response
    timeout") and time.sleep calls per transaction, back to back. The sleeps are the bus's quiet time
    still running when the next request starts: their number depends on the machine's speed."""
    real_select, real_sleep = select.select, time.sleep
    selects: Counter[str] = Counter()
    sleeps = [0]

    me = threading.get_ident()

    def rec_select(r: Any, w: Any, x: Any, timeout: float | None = None) -> Any:
        if threading.get_ident() == me:  # not the device's thread
            key = "none" if timeout is None else "response timeout" if timeout > 0.5 else f"{timeout * 1000:.2f}"
            selects[key] += 1
        return real_select(r, w, x, timeout)

    def rec_sleep(seconds: float) -> None:
        sleeps[0] += 1
        real_sleep(seconds)

    fn()
    select.select, time.sleep = rec_select, rec_sleep  # type: ignore[assignment]
    try:
        for _ in range(n):
            fn()
    finally:
        select.select, time.sleep = real_select, real_sleep
    return {"select timeouts (ms) per transaction": {k: v / n for k, v in sorted(selects.items())},
            "time.sleep calls per transaction": sleeps[0] / n}


def device_cost(wire: Any, mod: Any, n: int) -> dict[str, Any]:
    """The simulator's own work per request (``Simulator.handle``, as section 3's serial server runs it with
    realistic timing): it runs inside the device's processing delay, so it costs wire time only past it."""
    read_req, reg = wire.pick(mod.Client)
    sim = importlib.import_module(f"drivemap_models.{wire.MODEL}.simulator").Simulator([1], realistic_timing=True)
    value = sim.handle(1, bytes([0x03]) + reg.address.to_bytes(2, "big") + (1).to_bytes(2, "big"))
    assert value is not None and value[0] == 0x03, value
    pdus = {"read 16": bytes([read_req.code]) + read_req.address.to_bytes(2, "big") + read_req.count.to_bytes(2, "big"),
            "write one": bytes([0x06]) + reg.address.to_bytes(2, "big") + value[2:4]}
    out: dict[str, Any] = {"reply delay": sim.reply_delay()}
    for op, pdu in pdus.items():
        counted = _profile_sync(functools.partial(sim.handle, 1, pdu), n)
        out[op] = {k: v for k, v in counted.items() if k in ("calls", "opcodes", "opcodes by function")}
    return out


def _design(client: Any, spec: Any) -> dict[str, Any]:
    """What the request path is set to wait (seconds), from the tree's bus, receiver, guard and pymodbus."""
    bus, pm = client.bus, client.bus.client
    timing = spec.protocol.timing if hasattr(spec, "protocol") else spec.timing  # the baseline's spec is flat
    out: dict[str, Any] = {
        "quiet after a reply": bus._quiet_s(timing, True),
        "silent interval (t3.5)": bus.silent_interval_s(timing),
        "response timeout": bus.timeout_for(timing),
        "retries": bus.retries_for(timing),
        "pymodbus poll interval (_recv_interval)": getattr(pm, "_recv_interval", None),
        "pymodbus inter_byte_timeout": getattr(pm, "inter_byte_timeout", None),
        "pymodbus timeout_connect": pm.comm_params.timeout_connect,
        "pymodbus framer": type(getattr(pm, "framer", None) or pm.ctx.framer).__name__,
        "line": [pm.comm_params.baudrate, pm.comm_params.bytesize, pm.comm_params.parity,
                 pm.comm_params.stopbits, pm.comm_params.handle_local_echo],
    }
    rx = getattr(bus, "_receiver", None)
    if rx is not None:
        out |= {"receiver gap": rx.gap_s, "receiver quiet": rx.quiet_s}
        guard = rx.guard
        if guard is not None:
            out |= {"guard settle": guard.settle_s, "guard gap": guard.gap_s, "guard turnaround": guard.turnaround_s,
                    "guard mode": guard.mode}
    port = getattr(pm, "socket", None)
    if port is not None:
        out["pyserial timeout, inter_byte_timeout"] = [port.timeout, port.inter_byte_timeout]
    return out


def _after_reply(client: Any) -> float:
    """The quiet kept after the last reply, counted from its last byte (s): ready time - last byte."""
    bus = client.bus
    return float(bus._ready_at - (bus._rx_at - bus._rx_quiet_s))


def sync_part(wire: Any, mod: Any, port: str, n: int, out: dict[str, Any]) -> None:
    read_req, reg = wire.pick(mod.Client)
    spec = mod.SPEC
    client = mod.Client.serial(port, 1, timeout=1.0, baudrate=wire.BAUD, parity="none", stop_bits=1)
    with client:
        accs = [client.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
        wacc = client.accessor(reg.name)
        value = wacc.read()
        ops: dict[str, Callable[[], Any]] = {"read 16": lambda: client.read(*accs), "write one": lambda: wacc.write(value)}
        before = client.stats.transactions
        for op, fn in ops.items():
            out[f"sync {op}"] = _profile_sync(fn, n)
            fn()
            out[f"sync {op}"]["quiet from the reply's last byte"] = _after_reply(client)
            out[f"sync {op}"]["waits"] = _sync_waits(fn, n)
        out["transactions per call"] = (client.stats.transactions - before) / (len(ops) * (2 * n + 21))
        out["sync design"] = _design(client, spec)
        out["sync retries, timeouts"] = [client.stats.retries, client.stats.timeouts]


async def async_part(wire: Any, mod: Any, port: str, n: int, out: dict[str, Any]) -> None:
    read_req, reg = wire.pick(mod.Client)
    spec = mod.SPEC
    client = mod.AsyncClient.serial(port, 1, timeout=1.0, baudrate=wire.BAUD, parity="none", stop_bits=1)
    await client.connect()
    try:
        accs = [client.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
        wacc = client.accessor(reg.name)
        value = await wacc.read()
        ops = {"read 16": lambda: client.read(*accs), "write one": lambda: wacc.write(value)}
        for op, fn in ops.items():
            out[f"async {op}"] = await _profile_async(fn, n)
        out["async design"] = _design(client, spec)
        out["async retries, timeouts"] = [client.stats.retries, client.stats.timeouts]
    finally:
        client.close()


#: Differences below this, per transaction, are the event loop's (an extra turn now and then), not the path's.
TOLERANCE = 0.5
#: Facts of a run that depend on the machine's speed, left out of :func:`compare`.
_TIMED = ("time.sleep calls per transaction",)


def _by_name(functions: dict[str, float]) -> dict[str, float]:
    """Counts per function name (modules moved between the trees: the file is left out)."""
    out: dict[str, float] = {}
    for label, count in functions.items():
        name = label.rpartition(":")[2] if ":" in label else label
        out[name] = out.get(name, 0.0) + count
    return out


def _differing(base: dict[str, float], cur: dict[str, float]) -> list[str]:
    b, c = _by_name(base), _by_name(cur)
    return [f"{k} {b.get(k, 0.0):g}→{c.get(k, 0.0):g}" for k in sorted(set(b) | set(c))
            if abs(b.get(k, 0.0) - c.get(k, 0.0)) >= TOLERANCE]


def _waits(result: dict[str, Any]) -> dict[str, Any]:
    """The waits of a run (see the module docstring), keyed for comparison; timed facts left out."""
    out: dict[str, Any] = {}
    for side in ("sync design", "async design"):
        out |= {f"{side}: {k}": v for k, v in result.get(side, {}).items()}
    for row in ROWS:
        data = result.get(row, {})
        if "quiet from the reply's last byte" in data:
            out[f"{row}: quiet from the reply's last byte"] = round(data["quiet from the reply's last byte"], 6)
        out |= {f"{row}: {k}": v for k, v in data.get("waits", {}).items() if k not in _TIMED}
    return out


def compare(base: dict[str, Any], cur: dict[str, Any]) -> list[str]:
    """Markdown lines: per row, calls and bytecode instructions per transaction of both trees and the functions
    whose counts differ; the simulator's own work per request; the waits that differ (or that none does)."""
    lines = ["| row | Python calls / transaction, baseline → current | bytecode instructions, baseline → current "
             "| functions whose counts differ (by name, per transaction) |", "|---|---:|---:|---|"]
    rows = [(row, base.get(row), cur.get(row)) for row in ROWS]
    rows += [(f"simulator's work, {op} (inside its {cur['device']['reply delay'] * 1000:g} ms processing delay)",
              base["device"][op], cur["device"][op]) for op in ("read 16", "write one")]
    for name, b, c in rows:
        if not b or not c:
            lines.append(f"| {name} | not measured in {'the baseline' if not b else 'the current tree'} | | |")
            continue
        differ = _differing(b.get("opcodes by function", {}), c.get("opcodes by function", {})) \
            if "opcodes by function" in b else []
        same = abs(b["calls"] - c["calls"]) < TOLERANCE and abs(b["opcodes"] - c["opcodes"]) < TOLERANCE
        lines.append(f"| {name} | {b['calls']:.1f} → {c['calls']:.1f} | {b['opcodes']:.1f} → {c['opcodes']:.1f} "
                     f"| {'; '.join(differ) if differ else ('none' if same else '—')} |")
    wb, wc = _waits(base), _waits(cur)
    changed = [f"{k}: {wb.get(k)!r} → {wc.get(k)!r}" for k in sorted(set(wb) | set(wc)) if wb.get(k) != wc.get(k)]
    lines.append("")
    lines.append("Waits on the request path (quiet time after a reply and from when it counts, stale-reply guard "
                 "settle/gap/turnaround, serial receiver gap/quiet, pymodbus poll interval, inter-byte and "
                 "response timeouts, line settings, `select` timeouts per transaction): "
                 + ("the same in both trees." if not changed else "DIFFERENT: " + "; ".join(changed) + "."))
    return lines


def measure(n: int = 200) -> dict[str, Any]:
    """Every row's counts on the tree whose code is on ``sys.path`` (see the module docstring)."""
    import logging

    import drivemap

    logging.getLogger("drivemap").setLevel(logging.ERROR)
    wire = importlib.import_module("wire")
    mod = importlib.import_module(f"drivemap_models.{wire.MODEL}.client")
    out: dict[str, Any] = {"files": [drivemap.__file__, mod.__file__, wire.__file__], "transactions": n}
    out["device"] = device_cost(wire, mod, n)
    device = Device(wire.MODEL)
    try:
        sync_part(wire, mod, device.port, n, out)
        asyncio.run(asyncio.wait_for(async_part(wire, mod, device.port, n, out), timeout=120))
    finally:
        device.close()
    return out


if __name__ == "__main__":
    if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
        del sys.path[0]  # the tree's own bench modules (its ``wire``), not this checkout's
    print(json.dumps(measure(int(sys.argv[1]) if len(sys.argv) > 1 else 200)))
