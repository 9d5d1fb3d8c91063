"""Reply quirks: non-standard reply forms a map says a device may send (``protocol.reply_quirks``).

``two_byte_byte_count``: a 03h/04h reply whose byte count is two bytes (high, low) instead of one,
as vfd1000's worked example prints it (002 §Example read 03H: ``01 03 00 04 00 00 00 00 43 07``).
A client of such a map accepts it *besides* the standard form: a standard byte count is never 0
(a read asks for 1 register or more), so a 0 where the count stands can only be the high byte of a
two-byte count, and the two forms cannot be confused. The reply PDU classes below are registered
on the pymodbus client of the bus (``client.register``), so the framers (RTU, ASCII, TCP) size and
decode both forms; on a bus shared with other models they accept the same two forms.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from typing import Any

from pymodbus.exceptions import ModbusIOException
from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.register_message import ReadHoldingRegistersResponse, ReadInputRegistersResponse

TWO_BYTE_BYTE_COUNT = "two_byte_byte_count"
#: Every quirk the runtime knows (the schema's enum).
KNOWN = frozenset({TWO_BYTE_BYTE_COUNT})


class _TwoByteCountMixin(ModbusPDU):
    """Sizes and decodes a 03h/04h reply with a one- or two-byte byte count (placed before the
    standard reply class in the bases, whose ``decode`` it calls for the standard form)."""

    @classmethod
    def calculateRtuFrameSize(cls, data: bytes) -> int:  # noqa: N802 (pymodbus API)
        """RTU frame size from the start of ``data`` (address, function, count...); 0: need more bytes."""
        if len(data) < 3:
            return 0
        if data[2] != 0:
            return data[2] + 5  # address, function, count, data, CRC (2)
        if len(data) < 4:
            return 0
        return data[3] + 6  # address, function, count high, count low, data, CRC (2)

    def decode(self, data: bytes) -> None:
        if len(data) < 2 or data[0] != 0 or data[1] == 0:  # the standard form: its count is never 0
            super().decode(data)
            return
        count = data[1]
        if count + 2 > len(data):
            raise ModbusIOException(f"byte_count {count} > length of packet {len(data)}", function_code=self.function_code)
        body = data[2 : 2 + count]
        self.registers = [value for (value,) in struct.iter_unpack(">H", body[: len(body) // 2 * 2])]


class TwoByteCountHoldingResponse(_TwoByteCountMixin, ReadHoldingRegistersResponse):
    """03h reply, standard or with a two-byte byte count."""


class TwoByteCountInputResponse(_TwoByteCountMixin, ReadInputRegistersResponse):
    """04h reply, standard or with a two-byte byte count."""


def accept(pymodbus_client: Any, quirks: Iterable[str]) -> None:
    """Make ``pymodbus_client`` accept the reply forms of ``quirks`` (besides the standard ones)."""
    wanted = set(quirks)
    unknown = wanted - KNOWN
    if unknown:
        raise ValueError(f"unknown reply quirk(s): {', '.join(sorted(unknown))}")
    if TWO_BYTE_BYTE_COUNT in wanted:
        pymodbus_client.register(TwoByteCountHoldingResponse)
        pymodbus_client.register(TwoByteCountInputResponse)


def encode_read_reply(code: int, body: bytes, quirks: Iterable[str]) -> bytes:
    """A 03h/04h reply PDU for ``body`` (the register bytes), in the form ``quirks`` ask for."""
    if TWO_BYTE_BYTE_COUNT in quirks:
        return bytes((code,)) + len(body).to_bytes(2, "big") + body
    return bytes((code, len(body))) + body


__all__ = ["KNOWN", "TWO_BYTE_BYTE_COUNT", "TwoByteCountHoldingResponse", "TwoByteCountInputResponse", "accept",
           "encode_read_reply"]
