"""10,000 hostile frames against the simulator over Modbus TCP (one bad peer must not stop the others): no connection is ever wedged.

For every frame, on a connection of its own:

1. a valid request on the new connection is answered within the map's response timeout (so the
   frames before it, on other connections, left the server in service); an answer up to
   :data:`WEDGED_AFTER_S` later counts as late (the allowance below), silence beyond fails;
2. the hostile frame goes out: a bad protocol id, a length field longer or shorter than the PDU,
   zero/one/huge lengths, random bytes, a truncated header, valid headers around malformed PDUs
   (03h with extra bytes, 06h short, 10h whose byte count lies, function codes 00h and 80h-FFh,
   random PDUs), requests to units the simulator does not serve and broadcasts, garbage behind a
   valid frame;
3. a valid request on the same connection: within the map's timeout it gets its reply (the server
   kept the connection) or the connection ends (the server gave it up). Late answers are allowed
   rarely (one in 200 frames); silence past the timeout and the grace fails the test. Whatever else arrives must be well-formed MBAP.

A length field longer than its frame is drawn for PDUs whose own fields fix their length (03h, 06h,
10h): for those the server sees the mismatch when the next request's bytes complete the frame. In
front of a PDU whose length nothing fixes (08h, codes the map does not list) a longer length field
that happens to swallow exactly the next request cannot be told from a well-formed frame; SECURITY.md
lists that under "Not promised".

Frames run 24 connections at a time from asyncio clients against a
:class:`~drivemap.runtime.sim.serve.ThreadedSimServer`; seeds are fixed; every wait is bounded by
the map's timeout and the whole run by :data:`RUN_LIMIT_S`. The tally shows both outcomes occur
(kept and closed) and that malformed PDUs were answered with exceptions.
"""

from __future__ import annotations

import asyncio
import importlib
import random
import struct
import time
from collections import Counter
from dataclasses import dataclass, field

import pytest

from drivemap.runtime.client.transport.bus import DEFAULT_RESPONSE_TIMEOUT_S
from drivemap.runtime.sim.serve import ThreadedSimServer
from drivemap.runtime.spec import DeviceSpec

RUNS = [("ev", 5000), ("edx", 5000)]
assert sum(n for _, n in RUNS) >= 10_000
UNITS = [1, 2]
PARALLEL = 24
RUN_LIMIT_S = 300.0
PROBE_TID = 0xBEEF
#: Seconds past the client's timeout after which a silent connection counts as wedged. An answer or a
#: close that comes after the timeout but before this is "late" (the server's thread was not scheduled
#: in time on a loaded machine, e.g. its 0.1 s partial-frame timer), which the test allows rarely.
WEDGED_AFTER_S = 5.0


def spec_of(model: str) -> DeviceSpec:
    spec: DeviceSpec = importlib.import_module(f"drivemap_models.{model}.spec").SPEC
    return spec


def timeout_of(spec: DeviceSpec) -> float:
    ms = spec.protocol.timing.response_timeout_ms
    return ms / 1000.0 if ms is not None else DEFAULT_RESPONSE_TIMEOUT_S


def mbap(tid: int, unit: int, pdu: bytes, *, pid: int = 0, length: int | None = None) -> bytes:
    return struct.pack(">HHHB", tid, pid, (len(pdu) + 1 if length is None else length) & 0xFFFF, unit) + pdu


@dataclass
class Frames:
    """Deterministic hostile frames for one model."""

    spec: DeviceSpec
    rng: random.Random
    kinds: Counter[str] = field(default_factory=Counter)

    def valid_pdu(self) -> bytes:
        regs = [r for r in self.spec.registers if r.readable]
        reg = self.rng.choice(regs)
        kind = self.rng.random()
        if kind < 0.5:
            return struct.pack(">BHH", 0x03, reg.element_address(self.rng.randrange(reg.count)), self.rng.choice([1, 1, 2]))
        if kind < 0.8:
            return struct.pack(">BHH", 0x06, reg.address, self.rng.randrange(0x10000))
        qty = self.rng.choice([1, 2])
        return struct.pack(">BHHB", 0x10, reg.address, qty, 2 * qty) + self.rng.randbytes(2 * qty)

    def frame(self) -> bytes:
        rng = self.rng
        tid = rng.randrange(0x10000)
        unit = rng.choice(UNITS)
        pdu = self.valid_pdu()
        kinds = {
            "protocol_id": lambda: mbap(tid, unit, pdu, pid=rng.randrange(1, 0x10000)),
            "length_longer": lambda: mbap(tid, unit, pdu, length=len(pdu) + 1 + rng.randrange(1, 20)),
            "length_shorter": lambda: mbap(tid, unit, pdu, length=rng.randrange(2, len(pdu) + 1)),
            "length_0_or_1": lambda: mbap(tid, unit, pdu, length=rng.choice([0, 1])),
            "length_huge": lambda: mbap(tid, unit, pdu, length=rng.randrange(255, 0x10000)),
            "random_bytes": lambda: rng.randbytes(rng.randrange(1, 41)),
            "truncated_header": lambda: mbap(tid, unit, pdu)[: rng.randrange(1, 7)],
            "03_extra": lambda: mbap(tid, unit, struct.pack(">BHH", 3, 0, 1) + rng.randbytes(rng.randrange(1, 6))),
            "06_short": lambda: mbap(tid, unit, struct.pack(">BH", 6, rng.randrange(0x10000)) + rng.randbytes(1)),
            "10_count_lies": lambda: mbap(tid, unit, struct.pack(">BHHB", 0x10, 0, 2, rng.choice([0, 1, 3, 5, 255]))
                                          + rng.randbytes(4)),
            "high_or_zero_code": lambda: mbap(tid, unit, bytes([rng.choice([0, *range(0x80, 0x100)])])
                                              + rng.randbytes(rng.randrange(0, 8))),
            "random_pdu": lambda: mbap(tid, unit, rng.randbytes(rng.randrange(1, 40))),
            "other_unit_or_broadcast": lambda: mbap(tid, rng.choice([0, 3, 17, 200, 255]), pdu),
            "garbage_after_valid": lambda: mbap(tid, unit, pdu) + rng.randbytes(rng.randrange(1, 12)),
            "valid": lambda: mbap(tid, unit, pdu),
        }
        name = rng.choice(sorted(kinds))
        self.kinds[name] += 1
        return kinds[name]()


@dataclass
class Tally:
    kept: int = 0
    closed: int = 0
    exceptions: int = 0
    other_replies: int = 0
    late: int = 0
    failures: list[str] = field(default_factory=list)


async def read_until(reader: asyncio.StreamReader, tid: int, deadline: float, tally: Tally) -> str:
    """'reply' when the reply with ``tid`` arrives, 'closed' at the end of the connection, 'silent' at the deadline."""
    buffer = b""
    while True:
        while len(buffer) >= 6 and len(buffer) >= 6 + int.from_bytes(buffer[4:6], "big"):
            size = 6 + int.from_bytes(buffer[4:6], "big")
            if buffer[2:4] != b"\x00\x00" or size < 8:
                raise AssertionError(f"malformed MBAP from the server: {buffer.hex(' ')}")
            if int.from_bytes(buffer[0:2], "big") == tid and buffer[7] == 0x03:
                return "reply"
            tally.other_replies += 1
            tally.exceptions += bool(buffer[7] & 0x80)
            buffer = buffer[size:]
        left = deadline - time.monotonic()
        if left <= 0:
            return "silent"
        try:
            data = await asyncio.wait_for(reader.read(4096), left)
        except TimeoutError:
            return "silent"
        except ConnectionError:
            return "closed"
        if not data:
            return "closed"
        buffer += data


async def one(host: str, port: int, probe: bytes, bad: bytes, timeout: float, tally: Tally) -> None:
    reader, writer = await asyncio.open_connection(host, port)
    try:
        writer.write(mbap(PROBE_TID, 1, probe))
        first = await read_until(reader, PROBE_TID, time.monotonic() + timeout, tally)
        if first == "silent":
            first = await read_until(reader, PROBE_TID, time.monotonic() + WEDGED_AFTER_S, tally)
            tally.late += first != "silent"
        if first != "reply":
            tally.failures.append(f"fresh connection: {first} (after the previous frames)")
            return
        writer.write(bad)
        writer.write(mbap(PROBE_TID + 1, 1, probe))
        with_bad = await read_until(reader, PROBE_TID + 1, time.monotonic() + timeout, tally)
        if with_bad == "silent":
            with_bad = await read_until(reader, PROBE_TID + 1, time.monotonic() + WEDGED_AFTER_S, tally)
            tally.late += with_bad != "silent"
        if with_bad == "reply":
            tally.kept += 1
        elif with_bad == "closed":
            tally.closed += 1
        else:
            tally.failures.append(f"silent for {timeout + WEDGED_AFTER_S} s after {bad.hex(' ')}")
    except ConnectionError:
        tally.closed += 1
    finally:
        writer.close()
        try:
            await writer.wait_closed()
        except ConnectionError:
            pass


async def fuzz(host: str, port: int, spec: DeviceSpec, frames: int, seed: str) -> tuple[Tally, Counter[str]]:
    gen = Frames(spec, random.Random(seed))
    reg = next(r for r in spec.registers if r.readable and r.page is None and r.words == 1)
    probe = struct.pack(">BHH", 0x03, reg.address, 1)
    timeout = timeout_of(spec)
    tally = Tally()
    queue: asyncio.Queue[bytes] = asyncio.Queue()
    for _ in range(frames):
        queue.put_nowait(gen.frame())

    async def worker() -> None:
        while not queue.empty():
            await one(host, port, probe, queue.get_nowait(), timeout, tally)

    await asyncio.gather(*(worker() for _ in range(PARALLEL)))
    return tally, gen.kinds


@pytest.mark.parametrize("model, frames", RUNS, ids=[f"{m}-{n}" for m, n in RUNS])
def test_tcp_fuzz_never_wedges_a_connection(model: str, frames: int) -> None:
    spec = spec_of(model)
    sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator(UNITS)
    started = time.monotonic()
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        tally, kinds = asyncio.run(asyncio.wait_for(fuzz(host, port, spec, frames, f"{model}-tcp-20"), RUN_LIMIT_S))
    elapsed = time.monotonic() - started
    print(f"{model}: {frames} frames in {elapsed:.1f} s: {tally.kept} kept, {tally.closed} closed, "
          f"{tally.exceptions} exception replies, {tally.other_replies} other replies, {tally.late} late; "
          f"kinds {dict(kinds)}")
    assert not tally.failures, tally.failures[:10]
    assert tally.late <= frames // 200, f"{tally.late} answers or closes came after the {timeout_of(spec)} s timeout"
    assert tally.kept + tally.closed == frames
    assert tally.kept > frames // 4 and tally.closed > frames // 10 and tally.exceptions > frames // 20
