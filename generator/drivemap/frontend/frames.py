"""Example frames: parse what the manual printed and verify checksums with pymodbus's framers."""

from __future__ import annotations

import re
from dataclasses import dataclass

from pymodbus.framer import FramerAscii, FramerRTU

_RTU = re.compile(r"^([0-9A-Fa-f?]{2})( [0-9A-Fa-f?]{2})*$")
_ASCII = re.compile(r"^:[0-9A-Fa-f?]*\r\n$")


@dataclass(frozen=True)
class Frame:
    """A printed frame: address+PDU bytes, the checksum as printed, and what could not be read."""

    mode: str
    body: bytes  # unit id + PDU (illegible bytes as 0)
    check: bytes  # CRC (2 bytes, wire order) or LRC (1 byte)
    illegible: bool

    def expected_check(self) -> bytes:
        if self.mode == "rtu":
            return FramerRTU.compute_CRC(self.body).to_bytes(2, "big")
        return bytes([FramerAscii.compute_LRC(self.body)])

    @property
    def check_ok(self) -> bool:
        return self.check == self.expected_check()

    def wire(self) -> bytes:
        """The bytes on the line."""
        if self.mode == "rtu":
            return self.body + self.check
        return b":" + (self.body + self.check).hex().upper().encode() + b"\r\n"


class FrameSyntaxError(ValueError):
    pass


def parse(text: str, mode: str) -> Frame:
    """Parse a printed frame (rtu: ``"01 03 .."``; ascii: ``":0103..\\r\\n"``)."""
    if mode == "rtu":
        if not _RTU.match(text):
            raise FrameSyntaxError("an RTU frame is hex byte pairs separated by single spaces")
        parts = text.split(" ")
        if len(parts) < 4:
            raise FrameSyntaxError("an RTU frame has at least 4 bytes (unit, function, CRC)")
        illegible = any("?" in p for p in parts)
        data = bytes(int(p, 16) if "?" not in p else 0 for p in parts)
        return Frame("rtu", data[:-2], data[-2:], illegible)
    if not _ASCII.match(text):
        raise FrameSyntaxError(r"an ASCII frame is ':' + hex digits + '\r\n'")
    digits = text[1:-2]
    if len(digits) % 2 or len(digits) < 6:
        raise FrameSyntaxError("an ASCII frame has an even number (at least 6) of hex digits")
    illegible = "?" in digits
    data = bytes(int(digits[i : i + 2], 16) if "?" not in digits[i : i + 2] else 0 for i in range(0, len(digits), 2))
    return Frame("ascii", data[:-1], data[-1:], illegible)


def export_form(text: str | None, mode: str) -> str | None:
    """The export contract's form: rtu hex without spaces; ascii the frame text."""
    if text is None:
        return None
    return text.replace(" ", "").upper() if mode == "rtu" else text


def structure_problem(frame: Frame, part: str) -> str | None:
    """Why a frame with a good checksum is still not a well-formed Modbus frame (None if it is).

    Lengths follow the Modbus application protocol: a request or reply of function 03/04/06/10
    has a fixed layout, and a read reply's byte count equals the data that follows it.
    """
    pdu = frame.body[1:]
    if not pdu:
        return "no function code"
    fc = pdu[0]
    if fc & 0x80:
        return None if len(pdu) == 2 and part == "response" else "an exception reply is function + one code byte"
    n = len(pdu)
    if part == "request":
        if fc in (3, 4, 6) and n != 5:
            return f"a function {fc:02X}h request has 5 PDU bytes, this one {n}"
        if fc == 16 and (n < 6 or pdu[5] != n - 6 or pdu[5] != 2 * int.from_bytes(pdu[3:5], "big")):
            return "a function 10h request's byte count must be twice its quantity and match the data"
        if fc == 8 and n < 3:
            return "a function 08h request has a sub-function"
        return None
    if fc in (3, 4) and (n < 2 or pdu[1] != n - 2):
        return f"a function {fc:02X}h reply has a one-byte count equal to the data length (printed {n - 2} bytes after the function code)"
    if fc in (6, 16) and n != 5:
        return f"a function {fc:02X}h reply has 5 PDU bytes, this one {n}"
    return None
