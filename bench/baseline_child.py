"""The child of bench/baseline.py: runs one tree's own bench code (its ``overhead`` and ``imports``) and prints
one JSON line. ``PYTHONPATH`` is that tree's ``generator``, ``generated`` and ``bench``; this file's own folder
is taken off ``sys.path`` so the tree's bench modules are the ones imported (the parent checks the files).

    python bench/baseline_child.py overhead HOST PORT COUNT SECONDS SWAP STUB_CALLS
    python bench/baseline_child.py build FOLDER SIZE
    python bench/baseline_child.py import PATH PACKAGE CACHED
    python bench/baseline_child.py construct PATH PACKAGE   (import + the first ``Client.tcp()``, no connection)
    python bench/baseline_child.py wire        (the tree's section 3 in its quick form: efficiency by row name)
    python bench/baseline_child.py wirecalls N (section 3's rows counted on the tree's code: ``wirecalls.py``,
                                                this checkout's, loaded by path; the tree may predate it)
"""

from __future__ import annotations

import asyncio
import importlib
import importlib.util
import json
import sys
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    del sys.path[0]  # the tree's own bench modules, not this checkout's

import common  # noqa: E402
from pymodbus.client import AsyncModbusTcpClient, ModbusTcpClient  # noqa: E402

import drivemap  # noqa: E402


def _key(pdu: Any) -> tuple[Any, ...]:
    return pdu.function_code, getattr(pdu, "address", None), getattr(pdu, "count", None)


def _best(fn: Callable[[], Any], calls: int, reps: int = 5) -> float:
    """µs per call: the least of ``reps`` timed loops of ``calls`` (the CPU cost, least disturbed)."""
    best = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best.append((time.perf_counter() - t0) / calls * 1e6)
    return min(best)


async def _abest(fn: Callable[[], Awaitable[Any]], calls: int, reps: int = 5) -> float:
    best = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(calls):
            await fn()
        best.append((time.perf_counter() - t0) / calls * 1e6)
    return min(best)


def sync_part(overhead: Any, mod: Any, reg: Any, argv: list[str], out: dict[str, Any]) -> None:
    host, port, count, seconds, swap, stub_calls = argv[0], int(argv[1]), int(argv[2]), float(argv[3]), \
        argv[4] == "1", int(argv[5])
    client = mod.Client.tcp(host, port, 1, timeout=2.0)
    raw = ModbusTcpClient(host, port=port, timeout=2.0)
    with client:
        raw.connect()
        ops = overhead._ops_sync(client, raw, reg)
        for op, (ours, theirs) in ops.items():
            overhead.paired(ours, theirs, 20, 0.1, swap)  # warm
            ta, tb = overhead.paired(ours, theirs, count, seconds, swap)
            out["sync"][op] = [common.median(ta), common.median(tb)]
        pm = client.bus.client  # then pymodbus's execute() replaced by the replies it gave: the client's own CPU
        real, seen = pm.execute, {}
        pm.execute = lambda no_reply, pdu: seen.setdefault(_key(pdu), real(no_reply, pdu))
        for ours, _ in ops.values():
            ours()
        pm.execute = lambda no_reply, pdu: seen[_key(pdu)]
        out["stub sync"] = {op: _best(ours, stub_calls) for op, (ours, _) in ops.items()}
        raw.close()


async def async_part(overhead: Any, mod: Any, reg: Any, argv: list[str], out: dict[str, Any]) -> None:
    host, port, count, seconds, swap, stub_calls = argv[0], int(argv[1]), int(argv[2]), float(argv[3]), \
        argv[4] == "1", int(argv[5])
    client = mod.AsyncClient.tcp(host, port, 1, timeout=2.0)
    raw = AsyncModbusTcpClient(host, port=port, timeout=2.0)
    await client.connect()
    await raw.connect()
    try:
        ops = await overhead._ops_async(client, raw, reg)
        for op, (ours, theirs) in ops.items():
            await overhead.apaired(ours, theirs, 20, 0.1, swap)  # warm
            ta, tb = await overhead.apaired(ours, theirs, count, seconds, swap)
            out["async"][op] = [common.median(ta), common.median(tb)]
        pm = client.bus.client
        real, seen = pm.execute, {}

        async def record(no_reply: bool, pdu: Any) -> Any:
            return seen.setdefault(_key(pdu), await real(no_reply, pdu))

        async def replay(no_reply: bool, pdu: Any) -> Any:
            return seen[_key(pdu)]

        pm.execute = record
        for ours, _ in ops.values():
            await ours()
        pm.execute = replay
        out["stub async"] = {op: await _abest(ours, stub_calls) for op, (ours, _) in ops.items()}
    finally:
        client.close()
        raw.close()


def overhead_main(argv: list[str]) -> dict[str, Any]:
    overhead = importlib.import_module("overhead")
    mod = importlib.import_module(f"drivemap_models.{overhead.MODEL}.client")
    reg = overhead.pick_register(mod.SPEC)
    out: dict[str, Any] = {"files": [drivemap.__file__, mod.__file__, overhead.__file__, common.__file__],
                           "sync": {}, "async": {}}
    sync_part(overhead, mod, reg, argv, out)
    asyncio.run(asyncio.wait_for(async_part(overhead, mod, reg, argv, out), timeout=300))
    return out


def construct_main(path: str, package: str) -> dict[str, Any]:
    """Seconds to import ``package.client`` and make its first ``Client`` (section 8's import, plus what the
    client's constructor does: the baseline made every accessor there, the current tree on first use)."""
    sys.path.insert(0, path)
    importlib.import_module("drivemap.runtime.client")  # as section 8: the runtime is not counted
    importlib.import_module("pymodbus.client")
    t0 = time.perf_counter()
    mod = importlib.import_module(package + ".client")
    client = mod.Client.tcp("127.0.0.1", 1, 1)
    seconds = time.perf_counter() - t0
    client.close()
    return {"seconds": seconds, "files": [drivemap.__file__]}


def main(argv: list[str]) -> None:
    if argv[0] == "construct":
        print(json.dumps(construct_main(argv[1], argv[2])))
        return
    if argv[0] == "overhead":
        print(json.dumps(overhead_main(argv[1:])))
        return
    if argv[0] == "wirecalls":
        spec = importlib.util.spec_from_file_location("wirecalls", Path(__file__).resolve().parent / "wirecalls.py")
        assert spec is not None and spec.loader is not None
        wirecalls = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(wirecalls)
        print(json.dumps(wirecalls.measure(int(argv[1]))))
        return
    if argv[0] == "wire":
        wire = importlib.import_module("wire")
        sec = wire.run(True)
        print(json.dumps({"rows": {r.name: r.ratio for r in sec.rows}, "files": [drivemap.__file__, wire.__file__]}))
        return
    imports = importlib.import_module("imports")
    files = [drivemap.__file__, imports.__file__]
    if argv[0] == "build":
        out = {"built": imports.build(Path(argv[1]), int(argv[2])), "files": files}
    elif argv[0] == "import":
        out = {"import_s": imports._child(argv[1], argv[2], argv[3] == "1"), "files": files}
    else:
        raise SystemExit(f"unknown command {argv[0]!r}")
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1:])
