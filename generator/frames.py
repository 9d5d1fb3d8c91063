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


def to_wire(text: str, mode: str) -> bytes:
    """Wire bytes of a legible printed frame."""
    return parse(text, mode).wire()


def export_form(text: str | None, mode: str) -> str | None:
    """The export contract's form: rtu hex without spaces; ascii the frame text."""
    if text is None:
        return None
    return text.replace(" ", "").upper() if mode == "rtu" else text
