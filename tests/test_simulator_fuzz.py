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
from pymodbus.framer import FramerAscii, FramerRTU

from drivemap.runtime.sim import serve as simserve
from drivemap.runtime.sim.simulator import Simulator
from drivemap.runtime.spec import DeviceSpec, RegisterSpec
from drivemap.testing.vserial import VirtualSerialLine
from tests.waits import wait_until

MODELS = ["ev", "v2", "edx", "vfd1000"]
BAUDRATE = 19200
UNITS = [1, 2]
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


# ==== framing helpers ===============================================================================
def crc_ok(frame: bytes) -> bool:
    return len(frame) >= 4 and FramerRTU.compute_CRC(frame[:-2]) == int.from_bytes(frame[-2:], "big")


def rtu(body: bytes) -> bytes:
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


def ascii_frame(body: bytes) -> bytes:
    return b":" + (body + bytes([FramerAscii.compute_LRC(body)])).hex().upper().encode() + b"\r\n"


def ascii_body(line: bytes) -> bytes | None:
    """unit + PDU of a ``:...LRC`` line (no CR LF) whose hex and LRC are right, else None."""
    if not line.startswith(b":"):
        return None
    try:
        raw = bytes.fromhex(line[1:].decode("ascii"))
    except (ValueError, UnicodeDecodeError):
        return None
    if len(raw) < 3 or FramerAscii.compute_LRC(raw[:-1]) != raw[-1]:
        return None
    return raw[:-1]


_CRC_TABLE = FramerRTU.crc16_table


def rtu_requests_on_line(stream: bytes, unit: int, code: int) -> list[bytes]:
    """Every stretch of ``stream`` (unit + PDU, CRC stripped) with a correct CRC, for unit/code."""
    found = []
    for start in range(len(stream) - 3):
        if stream[start] != unit or stream[start + 1] != code:
            continue
        crc = 0xFFFF
        for end in range(start, len(stream) - 2):
            crc = ((crc >> 8) & 0xFF) ^ _CRC_TABLE[(crc ^ stream[end]) & 0xFF]
            if end - start >= 1 and ((crc << 8) & 0xFF00 | crc >> 8) == int.from_bytes(stream[end + 1 : end + 3], "big"):
                found.append(stream[start : end + 1])
    return found


def ascii_requests_on_line(stream: bytes, unit: int, code: int) -> list[bytes]:
    """Every ``:`` .. CR LF stretch of ``stream`` with right hex and LRC, for unit/code (unit + PDU)."""
    found = []
    start = stream.find(b":")
    while start != -1:
        end = stream.find(b"\r\n", start)
        while end != -1:
            body = ascii_body(stream[start:end])
            if body is not None and body[0] == unit and body[1] == code:
                found.append(body)
            end = stream.find(b"\r\n", end + 1)
        start = stream.find(b":", start + 1)
    return found


def split_rtu_replies(stream: bytes) -> list[bytes]:
    """Split what the device sent into RTU replies (unit + PDU); bytes that do not parse fail the test.

    The length of a reply follows from its function code, except for the 08h echo, whose every
    CRC-correct length is tried (a CRC-correct frame followed by 00h is CRC-correct too).
    """

    def sizes(rest: bytes) -> list[int]:
        code = rest[1] if len(rest) >= 2 else -1
        if code == -1:
            return []
        if code & 0x80:
            return [5]
        if code in (0x03, 0x04):
            return [5 + rest[2]] if len(rest) >= 3 else []
        if code in (0x06, 0x10):
            return [8]
        if code == 0x08:
            return list(range(6, len(rest) + 1))
        return []

    def walk(pos: int) -> list[bytes] | None:
        if pos == len(stream):
            return []
        rest = stream[pos:]
        for size in sizes(rest):
            if size <= len(rest) and crc_ok(rest[:size]):
                tail = walk(pos + size)
                if tail is not None:
                    return [rest[: size - 2], *tail]
        return None

    replies = walk(0)
    assert replies is not None, f"malformed reply from the device in {stream.hex(' ')}"
    return replies


def split_ascii_replies(stream: bytes) -> list[bytes]:
    replies = []
    assert not stream or stream.endswith(b"\r\n"), f"unterminated reply: {stream!r}"
    for line in stream.split(b"\r\n")[:-1]:
        body = ascii_body(line)
        assert body is not None and line == line.upper(), f"malformed reply from the device: {line!r}"
        replies.append(body)
    return replies


def check_reply(reply: bytes, requests: list[bytes], units: list[int]) -> None:
    """``reply`` (unit + PDU) answers one of ``requests`` (unit + PDU, checksums right)."""
    unit, code = reply[0], reply[1]
    assert unit in units, f"reply from unit {unit}, which is not simulated: {reply.hex(' ')}"
    assert requests, f"reply to a request that was never on the line with a right checksum: {reply.hex(' ')}"
    if code & 0x80:
        assert len(reply) == 3, f"malformed exception reply {reply.hex(' ')}"
    elif code in (0x03, 0x04):
        assert len(reply) == 3 + reply[2] and reply[2] % 2 == 0, f"malformed read reply {reply.hex(' ')}"
        assert any(len(r) == 6 and 2 * int.from_bytes(r[4:6], "big") == reply[2] for r in requests), reply.hex(" ")
    elif code == 0x06 or code == 0x08:
        assert reply in requests, f"echo of no request on the line: {reply.hex(' ')}"
    elif code == 0x10:
        assert len(reply) == 6 and any(r[:6] == reply for r in requests), reply.hex(" ")
    else:
        raise AssertionError(f"reply with function code {code:02X}h: {reply.hex(' ')}")


# ==== frame generation ===============================================================================
def printed_examples(model: str) -> list[bytes]:
    """unit + PDU of every legible printed example request of the map (none if it does not compile)."""
    from drivemap.compiler import compile_map, map_paths
    from drivemap.frontend.frames import parse

    bodies: list[bytes] = []
    for path in map_paths():
        if path.stem != model:
            continue
        try:
            compiled = compile_map(path)
        except Exception:  # the map may be mid-edit; the spec-generated requests still run
            return bodies
        for ex in compiled.examples:
            if ex.wire_request and ex.illegible is None:
                frame = parse(ex.wire_request, ex.mode)
                if not frame.illegible and len(frame.body) >= 2:
                    bodies.append(frame.body)
    return bodies


@dataclass
class Fuzzer:
    """Deterministic frames for one model and framing."""

    spec: DeviceSpec
    mode: str
    rng: random.Random
    examples: list[bytes] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.readable = [r for r in self.spec.registers if r.readable]
        self.writable = [r for r in self.spec.registers if r.writable]
        self.codes = [f.code for f in self.spec.function_codes]

    # ---- valid requests (unit + PDU) -----------------------------------------------------------
    def unit(self) -> int:
        r = self.rng.random()
        if r < 0.75:
            return self.rng.choice(UNITS)
        if r < 0.85:
            return 0  # broadcast
        return self.rng.choice([3, 4, 17, self.spec.unit_max, 255])

    def _address(self, pool: list[RegisterSpec]) -> int:
        if pool and self.rng.random() < 0.9:
            reg = self.rng.choice(pool)
            return reg.element_address(self.rng.randrange(reg.count))
        return self.rng.randrange(0x10000)

    def _value(self, reg: RegisterSpec | None) -> int:
        if reg is not None and self.rng.random() < 0.7:
            if reg.enum_values:
                return self.rng.choice(reg.enum_values) & 0xFFFF
            if reg.min is not None and reg.max is not None:
                low, high = sorted(((reg.min - reg.offset) / reg.scale, (reg.max - reg.offset) / reg.scale))
                return int(self.rng.uniform(low, high)) & 0xFFFF
        return self.rng.randrange(0x10000)

    def request(self) -> bytes:
        if self.examples and self.rng.random() < 0.25:
            return self.rng.choice(self.examples)
        unit = self.unit()
        kind = self.rng.random()
        if kind < 0.35:
            code = self.rng.choice([0x03, 0x03, 0x03, 0x04])
            qty = self.rng.choice([1, 1, 2, 3, 8, self.rng.randrange(0, 130)])
            return struct.pack(">BBHH", unit, code, self._address(self.readable), qty)
        if kind < 0.6:
            reg = self.rng.choice(self.writable) if self.writable else None
            address = reg.address if reg is not None and self.rng.random() < 0.9 else self._address(self.writable)
            return struct.pack(">BBHH", unit, 0x06, address, self._value(reg))
        if kind < 0.8:
            reg = self.rng.choice(self.writable) if self.writable else None
            qty = reg.words if reg is not None and self.rng.random() < 0.7 else self.rng.randrange(0, 20)
            address = reg.address if reg is not None else self._address(self.writable)
            words = [self._value(reg) for _ in range(qty)]
            count = 2 * qty if self.rng.random() < 0.9 else self.rng.randrange(256)
            body = b"".join(w.to_bytes(2, "big") for w in words)
            return struct.pack(">BBHHB", unit, 0x10, address, qty, count & 0xFF) + body
        if kind < 0.9:
            sub = 0 if self.rng.random() < 0.8 else self.rng.randrange(0x10000)
            return struct.pack(">BBH", unit, 0x08, sub) + self.rng.randbytes(self.rng.choice([2, 2, 0, 1, 4]))
        # other codes, 00h and exception-reply codes (80h-FFh) included: a master never sends those
        code = self.rng.choice(self.codes + [0x00, 0x01, 0x02, 0x05, 0x0F, 0x11, 0x17, 0x2B, 0x80, 0x83, 0x90, 0xFF])
        code = self.rng.randrange(0x100) if self.rng.random() < 0.3 else code
        return bytes([unit, code]) + self.rng.randbytes(self.rng.randrange(0, 8))

    def encode(self, body: bytes) -> bytes:
        return rtu(body) if self.mode == "rtu" else ascii_frame(body)

    # ---- hostile frames --------------------------------------------------------------------------
    def frame(self) -> bytes:
        """One write on the line: 2/3 mutated valid requests (some left valid), 1/3 random."""
        if self.rng.random() < 0.34:
            return self.random_frame()
        body = self.request()
        frame = self.encode(body)
        how = self.rng.randrange(9)
        if how == 0:
            return frame  # valid
        if how == 1:  # flipped bits (anywhere, checksum included)
            data = bytearray(frame)
            for _ in range(self.rng.choice([1, 1, 2, 3])):
                data[self.rng.randrange(len(data))] ^= 1 << self.rng.randrange(8)
            return bytes(data)
        if how == 2:  # truncated
            return frame[: self.rng.randrange(1, len(frame))]
        if how == 3:  # extended
            return frame + self.tail()
        if how == 4:  # another unit, checksum right (must be silence: not ours, or broadcast)
            other = self.rng.choice([0, 3, 9, 15, 200, 247, 255])
            return self.encode(bytes([other]) + body[1:])
        if how == 5:  # garbage before the frame
            return self.tail() + frame
        if how == 6:  # a byte dropped or doubled inside
            i = self.rng.randrange(len(frame))
            return frame[:i] + frame[i + 1 :] if self.rng.random() < 0.5 else frame[: i + 1] + frame[i:]
        if how == 7 and self.mode == "ascii":  # hex case, CR/LF and ':' games
            text = frame.decode("ascii")
            choice = self.rng.randrange(4)
            if choice == 0:
                return text.lower().encode()
            if choice == 1:
                return frame.replace(b"\r\n", self.rng.choice([b"\r", b"\n", b"\n\r", b""]))
            if choice == 2:
                i = self.rng.randrange(1, len(frame) - 2)
                return frame[:i] + b":" + frame[i:]
            i = self.rng.randrange(1, len(frame) - 2)
            return frame[:i] + self.rng.choice(b"0123456789ABCDEFGZz :\x00\xff").to_bytes(1, "big") + frame[i + 1 :]
        return self.tail()  # garbage between frames

    def tail(self) -> bytes:
        if self.mode == "ascii" and self.rng.random() < 0.5:
            return self.rng.choice([b":", b"\r\n", b"::", b":01", b"\r", b"\n"]) + self.rng.randbytes(self.rng.randrange(0, 4))
        return self.rng.randbytes(self.rng.randrange(1, 9))

    def random_frame(self) -> bytes:
        if self.mode == "rtu" or self.rng.random() < 0.25:
            return self.rng.randbytes(self.rng.randrange(1, 41))
        hexes = "".join(self.rng.choice("0123456789ABCDEF") for _ in range(self.rng.randrange(0, 40)))
        end = b"\r\n" if self.rng.random() < 0.9 else self.rng.choice([b"", b"\r", b"\n"])
        return b":" + hexes.encode() + end


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
        watch = type("SimFramerRTU", (simserve._WatchRTU,), {"simulator": sim, "silence": 0.05})
    else:
        watch = type("SimFramerAscii", (simserve._WatchAscii,), {"simulator": sim})
    return watch(decoder)


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


@pytest.mark.parametrize("model, mode, frames", LINE_RUNS, ids=[f"{m}-{mode}-{n}" for m, mode, n in LINE_RUNS])
def test_line_fuzz(model: str, mode: str, frames: int, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    caplog.set_level(logging.WARNING)
    monkeypatch.setattr(simserve, "_silence_seconds", lambda sim, baudrate: SILENCE)
    spec = spec_of(model)
    sim = sim_class(model)(UNITS)
    fuzz = Fuzzer(spec, mode, random.Random(f"{model}-{mode}-8"), printed_examples(model))
    probe_body = _probe(spec)
    probe = fuzz.encode(probe_body)
    split = split_rtu_replies if mode == "rtu" else split_ascii_replies
    on_line = rtu_requests_on_line if mode == "rtu" else ascii_requests_on_line
    # A model of the server's framer tells which frames leave an unfinished frame behind: only
    # those need the RTU silence before the next one (ASCII restarts at every ':').
    shadow = _server_framer(sim_class(model)(UNITS), mode)
    stats = Stats()

    def leaves_rest(frame: bytes) -> bool:
        buffer = frame
        try:
            for _ in range(8):
                used, pdu = shadow.handleFrame(buffer, 0, 0)
                buffer = buffer[used:]
                if pdu is None or not buffer:
                    break
        except Exception:  # only a timing hint: the server itself is what is tested
            return True
        return mode == "rtu" and bool(buffer)

    def probe_answered(line: VirtualSerialLine) -> bool:
        got = line.captured("to_master")
        if mode == "rtu":
            return len(got) >= 7 and got[-7:-4] == probe_body[:2] + b"\x02" and crc_ok(got[-7:])
        return got.endswith(b"\r\n") and got[got.rfind(b":") :].startswith(ascii_frame(probe_body[:2] + b"\x02")[:7])

    with VirtualSerialLine(baudrate=BAUDRATE) as line, simserve.ThreadedSimServer(
        sim, serial=line.device_port, mode=mode, baudrate=BAUDRATE
    ):
        port = line.open_serial("master", baudrate=BAUDRATE, timeout=0)
        try:
            previous_probe = b""
            sent = 0
            while sent < frames:
                rest = False
                for _ in range(min(BATCH, frames - sent)):
                    frame = fuzz.frame()
                    port.write(frame)
                    sent += 1
                    rest = leaves_rest(frame)
                    time.sleep(SILENCE + GAP if rest else GAP)
                # synchronise: the probe's answer ends the batch (retry after the RTU silence)
                for attempt in range(3):
                    time.sleep(SILENCE + GAP if attempt else 0.0)
                    port.write(probe)
                    stats.probes += 1
                    if _wait(lambda: probe_answered(line), 0.1 if attempt == 0 else 2.0):
                        break
                    stats.probe_retries += 1
                else:
                    raise AssertionError(f"no answer to a valid request after {sent} frames")
                assert line.wait_idle(2.0)
                time.sleep(0.003)  # a late duplicate of the probe's answer, if any, is in this batch
                to_device = previous_probe + line.captured("to_device")
                to_master = line.captured("to_master")
                line.clear()
                port.reset_input_buffer()
                try:
                    replies = split(to_master)
                    for reply in replies:
                        asked = on_line(to_device, reply[0], reply[1] & 0x7F)
                        if reply[1] & 0x80:  # the illegal-function answer to a request with code 80h-FFh
                            asked += on_line(to_device, reply[0], reply[1])
                        check_reply(reply, asked, sim.unit_ids)
                        stats.exceptions += bool(reply[1] & 0x80)
                except AssertionError as exc:
                    raise AssertionError(f"{exc}\nto device: {to_device!r}\nfrom device: {to_master!r}") from None
                stats.replies += len(replies)
                previous_probe = probe
            stats.frames = sent
            # at the end: the exact answer the device gives to the probe
            expected = [bytes([1]) + a for a in (sim.handle(1, probe_body[1:]),) if a is not None]
            port.write(probe)
            assert _wait(lambda: probe_answered(line), 2.0)
            expected += [bytes([1]) + a for a in (sim.handle(1, probe_body[1:]),) if a is not None]
            assert split(line.captured("to_master"))[-1] in expected
        finally:
            port.close()
    print(f"{model}/{mode}: {stats}")
    # the fuzz is not vacuous: valid requests in it were answered, some with exceptions
    assert stats.replies - stats.probes > frames // 50 and stats.exceptions > 0
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, [r.getMessage() for r in errors[:5]]
