"""Frames for tests/runtime/sim/test_simulator_fuzz.py: RTU/ASCII framing and checksums, finding the checked
requests that were on the line, splitting and checking the device's replies, and :class:`Fuzzer`, which
makes deterministic valid, mutated and random frames for one model and framing."""

from __future__ import annotations

import random
import struct
from dataclasses import dataclass, field

from pymodbus.framer import FramerAscii, FramerRTU

from drivemap.runtime.spec import DeviceSpec, RegisterSpec

#: The simulated units.
UNITS = [1, 2]


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
        self.codes = [f.code for f in self.spec.protocol.function_codes]

    # ---- valid requests (unit + PDU) -----------------------------------------------------------
    def unit(self) -> int:
        r = self.rng.random()
        if r < 0.75:
            return self.rng.choice(UNITS)
        if r < 0.85:
            return 0  # broadcast
        return self.rng.choice([3, 4, 17, self.spec.protocol.unit_max, 255])

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
