"""What a client puts on the wire and takes off it: the request class of each read function, a
value to write (raw, or deferred until its scale factor is read), the words of a read reply."""

from __future__ import annotations

import dataclasses
from typing import Any

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.bit_message import ReadCoilsRequest, ReadDiscreteInputsRequest
from pymodbus.pdu.register_message import ReadHoldingRegistersRequest, ReadInputRegistersRequest

from drivemap.runtime.client.protocol.planner import Key
from drivemap.runtime.client.values.codec import Codec
from drivemap.runtime.errors import InexactValue, TransportError

__all__ = ["ILLEGAL_ADDRESS", "READ_REQUESTS", "Deferred", "RawItem", "reply_words"]


#: The request class of each read function code.
READ_REQUESTS: dict[int, type[ModbusPDU]] = {
    0x01: ReadCoilsRequest, 0x02: ReadDiscreteInputsRequest,
    0x03: ReadHoldingRegistersRequest, 0x04: ReadInputRegistersRequest,
}
#: Exception code that makes the client split a read (02h, illegal data address).
ILLEGAL_ADDRESS = 0x02


@dataclasses.dataclass(frozen=True)
class Deferred:
    """A value to write whose raw value needs its scale factor, read just before the write."""

    value: Any
    codec: Codec[Any]
    #: round a value between two steps to the nearer (an explicit request); else it is refused
    round: bool = False

    def encode(self, factor: int | None) -> int:
        """The raw value given the scale factor's raw value."""
        try:
            return self.codec.encode_scaled(self.value, factor)
        except InexactValue as exc:
            if not self.round or exc.rounded_raw is None:
                raise
            return exc.rounded_raw


RawItem = tuple[Key, "int | Deferred"]


def reply_words(reply: ModbusPDU, code: int, address: int, count: int) -> list[int]:
    """The words of a read reply; for 01h/02h its first ``count`` bits as 0/1."""
    if code <= 0x02:
        bits = reply.bits
        if len(bits) < count:
            raise TransportError(f"asked {count} bits at 0x{address:04X}, got {len(bits)}")
        return [1 if b else 0 for b in bits[:count]]
    registers = reply.registers
    if len(registers) != count:
        raise TransportError(f"asked {count} registers at 0x{address:04X}, got {len(registers)}")
    return list(registers)
