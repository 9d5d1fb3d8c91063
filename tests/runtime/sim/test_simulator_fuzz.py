"""Hostile frames against the simulator (a device on an open bus sees anything): it never crashes, never answers a
corrupt frame, and still answers a valid request afterwards.

Two levels:

* pure (hypothesis, cheap): ``Simulator.handle(unit, pdu)`` never raises for any bytes, and the
  server's framers (pymodbus's RTU/ASCII framers as :mod:`drivemap.runtime.sim.serve` extends
  them) never raise for any byte stream and only ever hand over a request whose own CRC/LRC is
  right;
* on the line: 10,000 frames (random bytes, random ``:``-hex lines, and valid requests - from
  the maps' printed examples and generated from the spec - mutated by bit flips, truncation,
  extension, wrong unit ids, garbage before and between frames) go over a
  :class:`~drivemap.testing.vserial.VirtualSerialLine` to a generated simulator served by
  :class:`~drivemap.runtime.sim.serve.ThreadedSimServer` in RTU and in ASCII.

Line fuzz, how it stays fast: frames are written in batches with a few milliseconds between them
(frames that get no answer cost no timeout); each batch ends with a valid probe request, and the
probe's answer is the synchronisation point. Everything the device sent during the batch is then
split into replies and each reply must (1) carry a correct CRC/LRC (pymodbus's
``FramerRTU.compute_CRC`` / ``FramerAscii.compute_LRC``), (2) come from a simulated unit and
(3) fit a request with a correct CRC/LRC that was really on the line in that batch (same unit and
function; the echo of 06h/08h/10h, the byte count of 03h/04h). A probe that is not answered at
once is repeated after the RTU silence (bytes of an unfinished frame are dropped then, as a device
does); it must be answered within three tries. Seeds are fixed; nothing asserts wall-clock times.

The framing helpers and the frame generator (:class:`~tests.fuzz_frames.Fuzzer`) are in tests/fuzz_frames.py.
"""

from __future__ import annotations

import importlib
import logging
import random
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivemap.runtime.sim import serve as simserve
from drivemap.runtime.sim.simulator import Simulator
from drivemap.runtime.spec import DeviceSpec
from drivemap.testing.vserial import VirtualSerialLine
from tests.fuzz_frames import (
    UNITS,
    Fuzzer,
    ascii_frame,
    ascii_requests_on_line,
    check_reply,
    crc_ok,
    printed_examples,
    rtu,
    rtu_requests_on_line,
    split_ascii_replies,
    split_rtu_replies,
)
from tests.waits import wait_until

MODELS = ["ev", "v2", "edx", "vfd1000"]
BAUDRATE = 19200
#: (model, mode, frames): 10,000 frames in all, both framings, four dialects.
LINE_RUNS = [("ev", "rtu", 2500), ("v2", "rtu", 2500), ("edx", "ascii", 2500), ("ev", "ascii", 2500)]
assert sum(n for _, _, n in LINE_RUNS) == 10_000
BATCH = 40  # fuzz frames between two probes
GAP = 0.0025  # seconds between two fuzz frames (> the line's 2 ms frame gap)
#: RTU silence after which the server drops an unfinished frame. The server's own floor (50 ms,
#: for USB adapters that split frames) would make 5,000 quiet periods take minutes; the rule is
#: the same, and here every frame is one write() on a pty, which is never split.
SILENCE = 0.005


def sim_class(model: str) -> Any:
    return importlib.import_module(f"drivemap_models.{model}.simulator").Simulator


def spec_of(model: str) -> DeviceSpec:
    spec: DeviceSpec = importlib.import_module(f"drivemap_models.{model}.spec").SPEC
    return spec


# ==== pure level (hypothesis) =========================================================================
_SIMS = {model: sim_class(model)(UNITS) for model in MODELS}


@pytest.mark.parametrize("model", MODELS)
@settings(max_examples=400, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    unit=st.integers(0, 255),
    pdu=st.one_of(
        st.binary(max_size=260),
        st.tuples(st.sampled_from([0x03, 0x04, 0x06, 0x08, 0x10, 0x00, 0x80, 0x83, 0xFF]), st.binary(max_size=40)).map(
            lambda t: bytes([t[0]]) + t[1]
        ),
    ),
)
def test_handle_never_raises(model: str, unit: int, pdu: bytes) -> None:
    sim = _SIMS[model]
    answer = sim.handle(unit, pdu)
    if unit not in sim.unit_ids or not pdu:
        assert answer is None
    if answer is not None:
        assert answer[0] in (pdu[0], pdu[0] | 0x80)
        if answer[0] & 0x80:
            assert len(answer) == 2


def _server_framer(sim: Simulator, mode: str) -> Any:
    """The framer ``SimServer`` installs, with the decoder its pymodbus server builds."""
    decoder = simserve.request_decoder(sim)
    if mode == "rtu":
        return simserve._WatchRTU(decoder, simulator=sim, silence=0.05)
    return simserve._WatchAscii(decoder, simulator=sim)


def _break(frame: bytes, where: int, bit: int) -> bytes:
    """Truncate ``frame`` at ``where`` (bit -1) or flip one bit there."""
    i = where % len(frame)
    if bit < 0:
        return frame[:i]
    return frame[:i] + bytes([frame[i] ^ (1 << bit)]) + frame[i + 1 :]


def _pieces(mode: str) -> st.SearchStrategy[bytes]:
    """Byte streams of valid, broken and random frames glued together."""
    bodies = st.tuples(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=12)).map(
        lambda t: bytes([t[0], t[1]]) + t[2]
    )
    encode = rtu if mode == "rtu" else ascii_frame
    frames = bodies.map(encode)
    broken = st.tuples(frames, st.integers(0, 200), st.integers(-1, 7)).map(lambda t: _break(*t))
    noise = st.binary(max_size=30)
    hexline = st.text("0123456789ABCDEFabcdefZ: ", max_size=30).map(lambda s: b":" + s.encode() + b"\r\n")
    return st.lists(st.one_of(frames, broken, noise, hexline), max_size=8).map(b"".join)


@pytest.mark.parametrize("mode", ["rtu", "ascii"])
@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_framer_never_raises_and_passes_only_checked_requests(mode: str, data: st.DataObject) -> None:
    sim = _SIMS["ev"]
    framer = _server_framer(sim, mode)
    stream = data.draw(_pieces(mode))
    buffer = b""
    chunks = data.draw(st.lists(st.integers(1, 64), max_size=6))
    cut = 0
    for size in [*chunks, len(stream)]:
        buffer += stream[cut : cut + size]
        cut += size
        for _ in range(20):  # as the transport: decode what arrived, keep the rest
            used, pdu = framer.handleFrame(buffer, 0, 0)
            buffer = buffer[used:]
            if pdu is None:
                break
            assert 0x00 <= pdu.function_code <= 0xFF  # 00h and 80h-FFh too: answered with illegal function
            body = bytes([pdu.dev_id, pdu.function_code]) + pdu.encode()
            found = (rtu_requests_on_line if mode == "rtu" else ascii_requests_on_line)(stream, body[0], body[1])
            assert body in found, f"framer passed {body.hex(' ')}, which is not a checked frame of {stream!r}"
        if cut >= len(stream):
            break


# ==== on the line ======================================================================================
@dataclass
class Stats:
    frames: int = 0
    replies: int = 0
    exceptions: int = 0
    probes: int = 0
    probe_retries: int = 0


def _probe(spec: DeviceSpec) -> bytes:
    """A read of one readable, page-less register of unit 1 (unit + PDU)."""
    reg = next(r for r in spec.registers if r.readable and r.page is None and r.words == 1)
    return struct.pack(">BBHH", 1, 0x03, reg.address, 1)


def _wait(pred: Callable[[], bool], timeout: float) -> bool:
    return wait_until(pred, timeout, step=0.001)


@dataclass
class LineRun:
    """The master's side of one fuzz run on the line: what it writes, and the checks of what the device sent."""

    mode: str
    sim: Simulator
    line: VirtualSerialLine
    port: Any
    probe_body: bytes
    probe: bytes
    #: A model of the server's framer: it tells which frames leave an unfinished frame behind; only
    #: those need the RTU silence before the next one (ASCII restarts at every ':').
    shadow: Any
    stats: Stats = field(default_factory=Stats)

    def leaves_rest(self, frame: bytes) -> bool:
        buffer = frame
        try:
            for _ in range(8):
                used, pdu = self.shadow.handleFrame(buffer, 0, 0)
                buffer = buffer[used:]
                if pdu is None or not buffer:
                    break
        except Exception:  # only a timing hint: the server itself is what is tested
            return True
        return self.mode == "rtu" and bool(buffer)

    def probe_answered(self) -> bool:
        got = self.line.captured("to_master")
        if self.mode == "rtu":
            return len(got) >= 7 and got[-7:-4] == self.probe_body[:2] + b"\x02" and crc_ok(got[-7:])
        start = ascii_frame(self.probe_body[:2] + b"\x02")[:7]
        return got.endswith(b"\r\n") and got[got.rfind(b":") :].startswith(start)

    def split(self, stream: bytes) -> list[bytes]:
        return split_rtu_replies(stream) if self.mode == "rtu" else split_ascii_replies(stream)

    def on_line(self, stream: bytes, unit: int, code: int) -> list[bytes]:
        return (rtu_requests_on_line if self.mode == "rtu" else ascii_requests_on_line)(stream, unit, code)

    def send_batch(self, fuzz: Fuzzer, count: int) -> None:
        for _ in range(count):
            frame = fuzz.frame()
            self.port.write(frame)
            time.sleep(SILENCE + GAP if self.leaves_rest(frame) else GAP)

    def synchronise(self, sent: int) -> None:
        """The probe's answer ends the batch (retry after the RTU silence)."""
        for attempt in range(3):
            time.sleep(SILENCE + GAP if attempt else 0.0)
            self.port.write(self.probe)
            self.stats.probes += 1
            if _wait(self.probe_answered, 0.1 if attempt == 0 else 2.0):
                return
            self.stats.probe_retries += 1
        raise AssertionError(f"no answer to a valid request after {sent} frames")

    def check_batch(self, previous_probe: bytes) -> None:
        """Every reply the device sent in the batch answers a checked request that was on the line."""
        assert self.line.wait_idle(2.0)
        time.sleep(0.003)  # a late duplicate of the probe's answer, if any, is in this batch
        to_device = previous_probe + self.line.captured("to_device")
        to_master = self.line.captured("to_master")
        self.line.clear()
        self.port.reset_input_buffer()
        try:
            replies = self.split(to_master)
            for reply in replies:
                asked = self.on_line(to_device, reply[0], reply[1] & 0x7F)
                if reply[1] & 0x80:  # the illegal-function answer to a request with code 80h-FFh
                    asked += self.on_line(to_device, reply[0], reply[1])
                check_reply(reply, asked, self.sim.unit_ids)
                self.stats.exceptions += bool(reply[1] & 0x80)
        except AssertionError as exc:
            raise AssertionError(f"{exc}\nto device: {to_device!r}\nfrom device: {to_master!r}") from None
        self.stats.replies += len(replies)

    def check_final_probe(self) -> None:
        """At the end: the exact answer the device gives to the probe."""
        expected = [bytes([1]) + a for a in (self.sim.handle(1, self.probe_body[1:]),) if a is not None]
        self.port.write(self.probe)
        assert _wait(self.probe_answered, 2.0)
        expected += [bytes([1]) + a for a in (self.sim.handle(1, self.probe_body[1:]),) if a is not None]
        assert self.split(self.line.captured("to_master"))[-1] in expected


@pytest.mark.parametrize("model, mode, frames", LINE_RUNS, ids=[f"{m}-{mode}-{n}" for m, mode, n in LINE_RUNS])
def test_line_fuzz(model: str, mode: str, frames: int, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    caplog.set_level(logging.WARNING)
    monkeypatch.setattr(simserve, "_silence_seconds", lambda sim, baudrate: SILENCE)
    spec = spec_of(model)
    sim = sim_class(model)(UNITS)
    fuzz = Fuzzer(spec, mode, random.Random(f"{model}-{mode}-8"), printed_examples(model))
    probe_body = _probe(spec)
    with VirtualSerialLine(baudrate=BAUDRATE) as line, simserve.ThreadedSimServer(
        sim, serial=line.device_port, mode=mode, baudrate=BAUDRATE
    ):
        port = line.open_serial("master", baudrate=BAUDRATE, timeout=0)
        shadow = _server_framer(sim_class(model)(UNITS), mode)
        run = LineRun(mode, sim, line, port, probe_body, fuzz.encode(probe_body), shadow)
        try:
            previous_probe = b""
            sent = 0
            while sent < frames:
                count = min(BATCH, frames - sent)
                run.send_batch(fuzz, count)
                sent += count
                run.synchronise(sent)
                run.check_batch(previous_probe)
                previous_probe = run.probe
            run.stats.frames = sent
            run.check_final_probe()
        finally:
            port.close()
    stats = run.stats
    print(f"{model}/{mode}: {stats}")
    # the fuzz is not vacuous: valid requests in it were answered, some with exceptions
    assert stats.replies - stats.probes > frames // 50 and stats.exceptions > 0
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, [r.getMessage() for r in errors[:5]]
