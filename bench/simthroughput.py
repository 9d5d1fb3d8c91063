"""(4) Simulator throughput: the generated simulator vs a plain pymodbus ``SimDevice`` server.

Both servers run at once, each in its own process on 127.0.0.1, holding the same register words
(the plain server is filled with the words the generated simulator answers for every request of
``read_all``'s plan). The same raw pymodbus client (sync, one request at a time) sends the same
requests — the read_all plan of ``MODEL``, cycled — to both, the servers taking turns in blocks of
25 requests (who starts alternates between rounds). Figure: requests per second; median over rounds.
"""

from __future__ import annotations

import importlib
import itertools
import time
from typing import Any

from common import Row, Section, median, spread
from servers import Child

MODEL = "edx"
GOAL = 0.90


def _connect(servers: tuple[tuple[str, Child], ...]) -> dict[str, Any]:
    """One raw sync pymodbus client per server, connected."""
    from pymodbus.client import ModbusTcpClient

    clients: dict[str, Any] = {}
    for name, child in servers:
        c = ModbusTcpClient(child.fields[0], port=int(child.fields[1]), timeout=2.0)
        if not c.connect():
            raise RuntimeError(f"cannot connect to the {name} server")
        clients[name] = c
    return clients


def _check_same(clients: dict[str, Any], requests: list[tuple[int, int]]) -> None:
    """Both servers must answer the same words."""
    for address, n in requests:
        a = clients["drivemap"].read_holding_registers(address, count=n, device_id=1)
        b = clients["simdevice"].read_holding_registers(address, count=n, device_id=1)
        if a.isError() or b.isError() or a.registers != b.registers:
            raise RuntimeError(f"servers disagree at 0x{address:04X}: {a} vs {b}")


def _measure(clients: dict[str, Any], requests: list[tuple[int, int]], rounds: int, count: int,
             seconds: float) -> tuple[dict[str, list[float]], list[float]]:
    """Rounds of both servers taking turns: (req/s per server per round, per-round ratios)."""
    rates: dict[str, list[float]] = {"drivemap": [], "simdevice": []}
    ratios: list[float] = []
    block = 25  # requests per turn: the servers take turns, so load bursts hit both alike
    for i in range(rounds):
        order = ["drivemap", "simdevice"] if i % 2 == 0 else ["simdevice", "drivemap"]
        done = {name: 0 for name in order}
        spent = {name: 0.0 for name in order}
        deadline = time.perf_counter() + 2 * seconds
        cycles = {name: itertools.cycle(requests) for name in order}
        while done[order[0]] < count and time.perf_counter() < deadline:
            for name in order:
                c, cycle = clients[name], cycles[name]
                t0 = time.perf_counter()
                for _ in range(block):
                    address, n = next(cycle)
                    c.read_holding_registers(address, count=n, device_id=1)
                spent[name] += time.perf_counter() - t0
                done[name] += block
        for name in order:
            rates[name].append(done[name] / spent[name])
        ratios.append(rates["drivemap"][-1] / rates["simdevice"][-1])
    return rates, ratios


def run(quick: bool) -> Section:
    sec = Section("Simulator throughput (TCP loopback)")
    rounds = 3 if quick else 7
    count, seconds = (200, 0.3) if quick else (3000, 1.0)
    plan = importlib.import_module(f"drivemap_models.{MODEL}.client").Client.plan()
    requests = [(r.address, r.count) for r in plan]
    with Child("tcp", MODEL, "drivemap") as ours, Child("tcp", MODEL, "simdevice") as plain:
        clients = _connect((("drivemap", ours), ("simdevice", plain)))
        try:
            _check_same(clients, requests)
            rates, ratios = _measure(clients, requests, rounds, count, seconds)
        finally:
            for c in clients.values():
                c.close()
    r = median(ratios)
    sec.rows.append(Row("4 simulator", "generated / plain SimDevice", r, f"≥ {GOAL:.2f}×", r >= GOAL,
                        f"{median(rates['drivemap']):.0f} vs {median(rates['simdevice']):.0f} req/s"))
    sec.detail.append(f"Model `{MODEL}`: the {len(requests)} requests of read_all's plan "
                      f"({sum(n for _, n in requests)} registers), cycled; sync raw pymodbus client; "
                      f"{rounds} rounds of at most {count} requests / {2 * seconds} s, in turns of 25 requests.")
    sec.detail.append("")
    sec.detail.append("| server | req/s (median) | range | ratio to plain (median of per-round ratios) |")
    sec.detail.append("|---|---:|---:|---:|")
    sec.detail.append(f"| generated simulator | {median(rates['drivemap']):.0f} | {spread(rates['drivemap'])} "
                      f"| {r:.3f} ({spread(ratios)}) |")
    sec.detail.append(f"| plain pymodbus SimDevice | {median(rates['simdevice']):.0f} | {spread(rates['simdevice'])} "
                      f"| 1 |")
    if r < GOAL:
        sec.profiles.append(profile_simulator(requests))
    return sec


def profile_simulator(requests: list[tuple[int, int]]) -> str:
    """cProfile of the generated simulator's request handling (the core, in process)."""
    from common import profile_text

    sim = importlib.import_module(f"drivemap_models.{MODEL}.simulator").Simulator([1])
    pdus = [bytes([3]) + a.to_bytes(2, "big") + n.to_bytes(2, "big") for a, n in requests]

    def work() -> None:
        for _ in range(300):
            for pdu in pdus:
                sim.handle(1, pdu)

    return (f"cProfile of `Simulator.handle` for {300 * len(pdus)} read requests, in process (top by own time):"
            f"\n\n```\n{profile_text(work)}\n```")


if __name__ == "__main__":
    import sys

    s = run("--quick" in sys.argv)
    print("\n".join(s.detail))
    for row in s.rows:
        print(row)
    print("\n\n".join(s.profiles))
