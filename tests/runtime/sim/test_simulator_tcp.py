"""The simulator over Modbus TCP and its dialect (it must answer as the device does, byte for byte), with raw sockets on 127.0.0.1.

* requests sent back to back (in one segment, more than pymodbus's 264-byte buffer, or byte by
  byte) are each answered, in order: a broadcast and an unknown function code before two reads
  no longer swallow the reads' replies;
* an MBAP header that cannot start a frame (protocol id, length 0/1/255+, random bytes) or a frame
  announced longer than it is closes the connection at once (or after
  :data:`~drivemap.runtime.sim.tcp.PARTIAL_FRAME_TIMEOUT_S` without a byte): the client sees the end
  of the connection, never silence; a new connection is served at once;
* malformed PDUs (03h with extra bytes, 06h one byte short, 10h whose byte count does not match)
  get the exception the map's exception_policy names, or the standard code where the map says the
  device is silent (silence is for serial lines); as their length disagrees with the MBAP header,
  the connection then closes (what follows them may be part of them);
* function codes 80h-FFh (and 00h) get the map's illegal-function code, over TCP and on RTU and
  ASCII lines;
* on an RTU line, a valid request 5-30 ms after a truncated frame is answered (the simulator drops
  the unfinished bytes after the 3.5-character silence, not after 50 ms).
"""

from __future__ import annotations

import socket
import struct
import time
from typing import Any

import pytest
from pymodbus.framer import FramerAscii, FramerRTU

from drivemap.runtime.sim.simulator import STANDARD_CODES
from drivemap.runtime.sim.tcp import PARTIAL_FRAME_TIMEOUT_S
from tests.helpers_client import package, serial_server, tcp_server

READ = bytes.fromhex("03 0002 0001")  # ev: motor_speed (0x0002), one register
EOF = b"<EOF>"


def mbap(tid: int, unit: int, pdu: bytes, *, pid: int = 0, length: int | None = None) -> bytes:
    return struct.pack(">HHHB", tid, pid, len(pdu) + 1 if length is None else length, unit) + pdu


def read_frames(sock: socket.socket, count: int, timeout: float) -> list[tuple[int, int, bytes] | bytes]:
    """Up to ``count`` MBAP replies (tid, unit, PDU), ending early with ``EOF`` when the server closes."""
    deadline = time.monotonic() + timeout
    buffer = b""
    frames: list[tuple[int, int, bytes] | bytes] = []
    while len(frames) < count:
        while len(buffer) >= 6 and len(buffer) >= 6 + int.from_bytes(buffer[4:6], "big"):
            size = 6 + int.from_bytes(buffer[4:6], "big")
            assert buffer[2:4] == b"\x00\x00", buffer.hex(" ")
            frames.append((int.from_bytes(buffer[0:2], "big"), buffer[6], buffer[7:size]))
            buffer = buffer[size:]
        if len(frames) >= count:
            break
        left = deadline - time.monotonic()
        if left <= 0:
            break
        sock.settimeout(left)
        try:
            data = sock.recv(4096)
        except TimeoutError:
            break
        except ConnectionResetError:
            data = b""
        if not data:
            frames.append(EOF)
            break
        buffer += data
    return frames


def connect(host: str, port: int) -> socket.socket:
    sock = socket.create_connection((host, port), timeout=2.0)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def ev_reply(sim: Any) -> bytes:
    return bytes([0x03, 0x02]) + sim.get_raw("motor_speed").to_bytes(2, "big")


# --------------------------------------------------------------------------------- back-to-back requests
def test_broadcast_and_unknown_function_do_not_swallow_later_replies() -> None:
    with tcp_server("ev", units=(1, 2)) as (sim, host, port), connect(host, port) as sock:
        illegal = sim.exception_code("illegal_function")
        sock.sendall(mbap(11, 0, bytes.fromhex("06 1400 0001")) + mbap(22, 1, bytes.fromhex("41 00"))
                     + mbap(33, 1, READ) + mbap(44, 2, READ))
        frames = read_frames(sock, 3, 1.0)
        assert frames == [(22, 1, bytes([0xC1, illegal])), (33, 1, ev_reply(sim)), (44, 2, ev_reply(sim))]
        assert sim.get_raw("net_in", 1) == sim.get_raw("net_in", 2) == 1  # the broadcast reached every unit


def test_many_requests_in_one_segment_and_byte_by_byte() -> None:
    with tcp_server("ev") as (sim, host, port), connect(host, port) as sock:
        burst = b"".join(mbap(100 + i, 1, READ) for i in range(40))
        assert len(burst) > 264  # more than pymodbus's receive buffer, which it would empty
        sock.sendall(burst)
        frames = read_frames(sock, 40, 2.0)
        assert [f[0] for f in frames if f != EOF] == [100 + i for i in range(40)]
        for byte in mbap(7, 1, READ) + mbap(8, 1, READ):
            sock.sendall(bytes([byte]))
            time.sleep(0.002)
        assert read_frames(sock, 2, 1.0) == [(7, 1, ev_reply(sim)), (8, 1, ev_reply(sim))]


# --------------------------------------------------------------------------------- framing lost
BAD_HEADERS = {
    "protocol_id": mbap(5, 1, READ, pid=7),
    "length_0": mbap(5, 1, READ, length=0),
    "length_1": mbap(5, 1, b"", length=1),
    "length_255": mbap(5, 1, READ, length=255),
    "length_65535": mbap(5, 1, READ, length=65535),
    "random_bytes": bytes(range(200, 230)),
}


@pytest.mark.parametrize("case", sorted(BAD_HEADERS))
def test_a_header_that_cannot_start_a_frame_closes_the_connection(case: str) -> None:
    with tcp_server("ev") as (sim, host, port):
        with connect(host, port) as sock:
            sock.sendall(BAD_HEADERS[case])
            started = time.monotonic()
            assert read_frames(sock, 1, 1.0) == [EOF]
            assert time.monotonic() - started < 0.5
        with connect(host, port) as fresh:  # a reconnecting client is served at once
            fresh.sendall(mbap(9, 1, READ))
            assert read_frames(fresh, 1, 1.0) == [(9, 1, ev_reply(sim))]


@pytest.mark.parametrize("then_valid", [False, True])
def test_a_frame_announced_longer_than_it_is_never_leaves_the_client_waiting(then_valid: bool) -> None:
    with tcp_server("ev") as (sim, host, port):
        with connect(host, port) as sock:
            sock.sendall(mbap(5, 1, READ, length=12))
            started = time.monotonic()
            if then_valid:  # its bytes are taken as the rest of the broken frame: the server gives up
                sock.sendall(mbap(6, 1, READ))
            frames = read_frames(sock, 3, 1.0)
            assert frames[-1] == EOF and (6, 1, ev_reply(sim)) not in frames
            assert time.monotonic() - started < PARTIAL_FRAME_TIMEOUT_S + 0.4
        with connect(host, port) as fresh:
            fresh.sendall(mbap(9, 1, READ))
            assert read_frames(fresh, 1, 1.0) == [(9, 1, ev_reply(sim))]


# --------------------------------------------------------------------------------- malformed PDUs
MALFORMED = {  # PDU, error case
    "03_extra_bytes": (bytes.fromhex("03 0002 0001 0000"), "bad_length"),
    "03_one_short": (bytes.fromhex("03 0002 00"), "bad_length"),
    "06_one_short": (bytes.fromhex("06 3F08 00"), "bad_length"),
    "10_count_mismatch": (bytes.fromhex("10 3F08 0001 04 0001"), "bad_length"),
    "10_bytes_missing": (bytes.fromhex("10 3F08 0002 04 0001"), "bad_length"),
    "03_quantity_0": (bytes.fromhex("03 0002 0000"), "illegal_quantity"),
}


@pytest.mark.parametrize("model", ["ev", "edx", "v2", "vfd1000"])
def test_malformed_pdus_get_the_dialects_exception_over_tcp(model: str) -> None:
    """The exception reply, then the end of the connection when the PDU's own length disagrees with its
    MBAP length (the bytes around it may be another request's); a well-framed refusal keeps it."""
    spec = package(model).SPEC
    reg = next(r for r in spec.registers if r.readable and r.writable and r.page is None and r.words == 1)
    with tcp_server(model) as (sim, host, port):
        for name, (template, case) in MALFORMED.items():
            pdu = template[:1] + reg.address.to_bytes(2, "big") + template[3:]
            if pdu[0] not in {f.code for f in spec.protocol.function_codes}:
                continue
            code = sim.exception_code(case)
            expected = code if code is not None else STANDARD_CODES[case]  # silence is for serial lines
            with connect(host, port) as sock:
                sock.sendall(mbap(3, 1, pdu))
                frames = read_frames(sock, 2, 1.0)
                assert frames[0] == (3, 1, bytes([pdu[0] | 0x80, expected])), name
                if case == "bad_length":
                    assert frames[1:] == [EOF], name
                else:
                    assert frames[1:] == [], name
                    sock.sendall(mbap(4, 1, bytes([0x03]) + reg.address.to_bytes(2, "big") + b"\x00\x01"))
                    assert read_frames(sock, 1, 1.0)[0][:2] == (4, 1)  # type: ignore[index]


def test_ev_stays_silent_on_its_serial_line_for_a_bad_length() -> None:
    """The map's null (no reply) still holds where it belongs: on the serial line."""
    with serial_server("ev", "rtu") as (sim, line):
        assert sim.exception_code("bad_length") is None
        port = line.open_serial("master", baudrate=38400, timeout=0)
        try:
            body = bytes.fromhex("01 03 0002 0001 0000")
            port.write(body + FramerRTU.compute_CRC(body).to_bytes(2, "big"))
            time.sleep(0.3)
            assert port.read(100) == b""
        finally:
            port.close()


# --------------------------------------------------------------------------------- dialect
@pytest.mark.parametrize("model", ["ev", "edx"])
def test_function_codes_80_to_ff_get_the_illegal_function_code_over_tcp(model: str) -> None:
    with tcp_server(model) as (sim, host, port), connect(host, port) as sock:
        illegal = sim.exception_code("illegal_function")
        codes = [0x00, *range(0x80, 0x100)]
        sock.sendall(b"".join(mbap(code + 1, 1, bytes([code, 0x00, 0x02, 0x00, 0x01])) for code in codes))
        frames = read_frames(sock, len(codes), 2.0)
        assert frames == [(code + 1, 1, bytes([code | 0x80, illegal])) for code in codes]


def _rtu(body: bytes) -> bytes:
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


def _ascii(body: bytes) -> bytes:
    return b":" + (body + bytes([FramerAscii.compute_LRC(body)])).hex().upper().encode() + b"\r\n"


@pytest.mark.parametrize("mode", ["rtu", "ascii"])
def test_function_codes_80_to_ff_get_the_illegal_function_code_on_a_serial_line(mode: str) -> None:
    encode = _rtu if mode == "rtu" else _ascii
    with serial_server("ev", mode) as (sim, line):
        illegal = sim.exception_code("illegal_function")
        port = line.open_serial("master", baudrate=38400, timeout=0.5)
        try:
            for code in (0x00, 0x80, 0x83, 0x90, 0xFF):  # 00h too: SECURITY.md promises it on every framing
                port.write(encode(bytes([1, code, 0x00, 0x02, 0x00, 0x01])))
                want = encode(bytes([1, code | 0x80, illegal]))
                assert port.read(len(want)) == want, hex(code)
                time.sleep(0.01)
        finally:
            port.close()


def test_rtu_request_right_after_a_truncated_frame_is_answered() -> None:
    """9600 Bd: 3.5 characters are 4 ms. A request 5-30 ms after the noise must be served."""
    baud = 9600
    with serial_server("ev", "rtu", baudrate=baud) as (sim, line):
        request = _rtu(bytes.fromhex("01 03 0002 0001"))
        reply = _rtu(bytes([1]) + ev_reply(sim))
        port = line.open_serial("master", baudrate=baud, timeout=0.5)
        lost = []
        try:
            for trial, gap_ms in enumerate([5, 6, 8, 10, 12, 15, 20, 25, 30] * 2):
                port.write(request[: 2 + trial % 5])  # a truncated frame (noise on the line)
                assert line.wait_idle(1.0)
                time.sleep(gap_ms / 1000)
                port.write(request)
                if port.read(len(reply)) != reply:
                    lost.append(gap_ms)
                port.reset_input_buffer()
                time.sleep(0.01)
        finally:
            port.close()
        assert not lost, f"requests after a truncated frame were lost (gaps in ms): {lost}"


def test_an_idle_connection_is_closed(monkeypatch: pytest.MonkeyPatch) -> None:
    from drivemap.runtime.sim import tcp

    monkeypatch.setattr(tcp, "IDLE_TIMEOUT_S", 0.6)
    with tcp_server("ev") as (sim, host, port):
        with connect(host, port) as idle, connect(host, port) as busy:
            started = time.monotonic()
            for tid in range(8):  # a client that keeps talking keeps its connection
                busy.sendall(mbap(tid, 1, READ))
                assert read_frames(busy, 1, 1.0) == [(tid, 1, ev_reply(sim))]
                time.sleep(0.15)
            assert read_frames(idle, 1, 2.0) == [EOF]
            assert 0.5 < time.monotonic() - started < 2.5
