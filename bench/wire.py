"""(3) Wire efficiency: requests per second on a paced virtual serial line vs the physical limit.

Setup: a :class:`VirtualSerialLine` paced at 115200 baud, 8N1 (10 bits per byte), in its own
process; the generated ``MODEL`` simulator with realistic timing on the device end, in its own
process; the generated client (sync, then async) on the master end, 8N1 at 115200.

Physical limit of one transaction (nothing can be faster on this line with this device):

    T = (request bytes + response bytes) x 10 / 115200
        + max(t3.5, device processing)      (the reply cannot start sooner)
        + t3.5                               (silence before the next request)

t3.5 is the silent interval the map gives at 115200 baud (``TimingSpec``: 3.5 characters, or the
map's floor above its threshold baud rate); device processing is what the simulator applies
(``Simulator.reply_delay()``). Limit = 1 / T requests per second.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import time
from typing import Any

from common import Row, Section, abounded, bounded, median, profile_text, spread
from servers import Child

MODEL = "ev"
BAUD = 115200
BITS = 10
GOAL = 0.90


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


def run(quick: bool) -> Section:
    sec = Section("Wire efficiency (paced virtual serial line, 115200 8N1)")
    logging.getLogger("drivemap").setLevel(logging.ERROR)  # no baud-rate warnings in the table
    client_mod = importlib.import_module(f"generated.{MODEL}.client")
    spec = client_mod.SPEC
    read_req, reg = pick(client_mod.Client)
    rounds = 2 if quick else 5
    count, seconds = (30, 0.4) if quick else (200, 1.0)
    t35 = silent_interval(spec.timing)
    frames = {"read 16": (8, 5 + 2 * read_req.count), "write one": (8, 8)}
    results: dict[str, dict[str, list[float]]] = {}
    with Child("line", str(BAUD), max_seconds=200) as line, \
            Child("serial", MODEL, line.fields[1], str(BAUD), max_seconds=200) as server:
        processing = float(server.fields[1])
        master = line.fields[0]
        # ---- sync
        client = client_mod.Client.serial(master, 1, timeout=1.0, baudrate=BAUD, parity="none", stop_bits=1)
        with client:
            accs = [client.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
            wacc = client.accessor(reg.name)
            value = wacc.read()
            raw_value = wacc.read_raw() & 0xFFFF
            ops_sync = {"read 16": lambda: client.read(*accs), "write one": lambda: wacc.write(value)}
            before = client.stats.transactions
            ops_sync["read 16"]()
            assert client.stats.transactions - before == 1, "the 16-register read must be one request"
            for op, fn in ops_sync.items():
                rates = []
                for _ in range(rounds):
                    n, t = bounded(fn, count, seconds)
                    rates.append(n / t)
                results[f"sync {op}"] = {"rates": rates}
            shortfall_profile = {op: fn for op, fn in ops_sync.items()}
            stats = client.stats

            def limit(op: str) -> float:
                req, resp = frames[op]
                return 1.0 / ((req + resp) * BITS / BAUD + max(t35, processing) + t35)

            missed = [op for op in ops_sync if median(results[f"sync {op}"]["rates"]) / limit(op) < GOAL]
            for op in missed:
                fn = shortfall_profile[op]
                sec.profiles.append(f"sync `{op}` over the paced line: cProfile of 50 calls (top by own time):\n\n"
                                    f"```\n{profile_text(lambda f=fn: [f() for _ in range(50)], top=12)}\n```")
            retries, timeouts = stats.retries, stats.timeouts

        # ---- raw pymodbus baseline, same line and device, t3.5 of silence after each reply as the map asks
        from pymodbus.client import AsyncModbusSerialClient, ModbusSerialClient

        raw = ModbusSerialClient(master, baudrate=BAUD, parity="N", stopbits=1, bytesize=8, timeout=1.0, retries=0)
        raw.connect()
        try:
            raw_ops = {
                "read 16": lambda: (raw.read_holding_registers(read_req.address, count=read_req.count, device_id=1),
                                    time.sleep(t35)),
                "write one": lambda: (raw.write_register(reg.address, raw_value,
                                                         device_id=1), time.sleep(t35)),
            }
            for op, fn in raw_ops.items():
                rates = []
                for _ in range(rounds):
                    n, t = bounded(fn, count, seconds)
                    rates.append(n / t)
                results[f"raw-sync {op}"] = {"rates": rates}
        finally:
            raw.close()

        # ---- async
        async def async_part() -> None:
            aclient = client_mod.AsyncClient.serial(master, 1, timeout=1.0, baudrate=BAUD, parity="none",
                                                    stop_bits=1)
            await aclient.connect()
            try:
                aaccs = [aclient.accessor(spec.register(k[0]).element_name(k[1])) for k, _ in read_req.cells]
                awacc = aclient.accessor(reg.name)
                avalue = await awacc.read()
                ops = {"read 16": lambda: aclient.read(*aaccs), "write one": lambda: awacc.write(avalue)}
                for op, fn in ops.items():
                    await fn()
                    rates = []
                    for _ in range(rounds):
                        n, t = await abounded(fn, count, seconds)
                        rates.append(n / t)
                    results[f"async {op}"] = {"rates": rates}
            finally:
                aclient.close()
            araw = AsyncModbusSerialClient(master, baudrate=BAUD, parity="N", stopbits=1, bytesize=8, timeout=1.0,
                                           retries=0)
            await araw.connect()
            try:
                async def aread() -> None:
                    await araw.read_holding_registers(read_req.address, count=read_req.count, device_id=1)
                    await asyncio.sleep(t35)

                async def awrite() -> None:
                    await araw.write_register(reg.address, raw_value, device_id=1)
                    await asyncio.sleep(t35)

                for op, afn in (("read 16", aread), ("write one", awrite)):
                    await afn()
                    rates = []
                    for _ in range(rounds):
                        n, t = await abounded(afn, count, seconds)
                        rates.append(n / t)
                    results[f"raw-async {op}"] = {"rates": rates}
            finally:
                araw.close()

        started = time.perf_counter()
        asyncio.run(asyncio.wait_for(async_part(), timeout=120))
        async_s = time.perf_counter() - started

    sec.detail.append(f"Model `{MODEL}` (simulator with realistic timing: reply after {processing * 1000:.2f} ms); "
                      f"t3.5 at {BAUD} Bd = {t35 * 1000:.3f} ms (the map's floor); read = {read_req.count} registers "
                      f"at 0x{read_req.address:04X}, write = 06h to `{reg.name}` (0x{reg.address:04X}).")
    sec.detail.append("")
    sec.detail.append("| mode | operation | frame bytes (req + resp) | limit T (ms) | limit req/s | achieved req/s "
                      "| efficiency (range) | lost per request (ms) | rounds |")
    sec.detail.append("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for key, data in results.items():
        mode, op = key.split(" ", 1)
        req, resp = frames[op]
        t_limit = (req + resp) * BITS / BAUD + max(t35, processing) + t35
        lim = 1.0 / t_limit
        rates = data["rates"]
        effs = [r / lim for r in rates]
        eff = median(effs)
        achieved = median(rates)
        baseline = mode.startswith("raw")
        sec.rows.append(Row("3 wire", key if not baseline else f"{key} (raw pymodbus, reference)", eff,
                            f"≥ {GOAL:.2f}" if not baseline else "—", eff >= GOAL if not baseline else None,
                            f"{achieved:.1f} of {lim:.1f} req/s"))
        sec.detail.append(f"| {mode} | {op} | {req} + {resp} | {t_limit * 1000:.3f} | {lim:.1f} | {achieved:.1f} "
                          f"| {eff:.3f} ({spread(effs)}) | {(1 / achieved - t_limit) * 1000:.3f} | {len(rates)} |")
    sec.detail.append("")
    sec.detail.append("Where the time lost per request goes: raw pymodbus on the same line and device loses the part "
                      "below drivemap's client (pymodbus transport, simulator server, line relay); the rest is "
                      "drivemap's client and bus.")
    sec.detail.append("")
    sec.detail.append("| mode | operation | lost by drivemap (ms) | lost by raw pymodbus (ms) | share below the client "
                      "| drivemap's own (ms) |")
    sec.detail.append("|---|---|---:|---:|---:|---:|")
    for mode in ("sync", "async"):
        for op in frames:
            ours, raw_ = results.get(f"{mode} {op}"), results.get(f"raw-{mode} {op}")
            if not ours or not raw_:
                continue
            req, resp = frames[op]
            t_limit = (req + resp) * BITS / BAUD + max(t35, processing) + t35
            lost_ours = 1 / median(ours["rates"]) - t_limit
            lost_raw = 1 / median(raw_["rates"]) - t_limit
            share = lost_raw / lost_ours if lost_ours > 0 else float("nan")
            sec.detail.append(f"| {mode} | {op} | {lost_ours * 1000:.2f} | {lost_raw * 1000:.2f} | {share:.0%} "
                              f"| {(lost_ours - lost_raw) * 1000:.2f} |")
    sec.detail.append("")
    sec.detail.append(f"Sync client retries {retries}, timeouts {timeouts} over the run; async part {async_s:.0f} s.")
    return sec


if __name__ == "__main__":
    import sys

    s = run("--quick" in sys.argv)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
    print("\n\n".join(s.profiles))
