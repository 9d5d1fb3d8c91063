"""What a client asks a bus to carry out (:class:`Exchange`), the bus's counters (:class:`Stats`)
and the check that a reply answers the request sent (:func:`reply_mismatch`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pymodbus.pdu import ModbusPDU

from drivemap.runtime.spec import TimingSpec


@dataclass
class Stats:
    """Counters of one bus: requests sent (with retries), retries, broadcasts and bytes."""

    transactions: int = 0
    retries: int = 0
    timeouts: int = 0
    broadcasts: int = 0
    exceptions: int = 0
    rejected: int = 0
    """Replies that did not answer the request sent (see :func:`reply_mismatch`), never returned."""
    stale: int = 0
    """Serial lines: replies that began before the request could have been answered (a duplicate, an
    echo, a late reply) or arrived between transactions; dropped unread (see :mod:`.staleguard`)."""
    bytes_sent: int = 0
    bytes_received: int = 0
    bytes_garbled: int = 0
    """Bytes received during attempts that got no valid reply (noise, wrong baud rate or parity)."""
    by_function: dict[int, int] = field(default_factory=dict)
    """Requests sent per function code (retries included)."""
    split_reads: int = 0
    """Reads the device refused with 02h that the client split (adaptive reads)."""
    extra_requests: int = 0
    """Requests the splitting sent beyond the plan (counted once each, retries aside)."""


@dataclass(frozen=True)
class Exchange:
    """One request the client core asks the bus to carry out."""

    unit: int
    pdu: ModbusPDU
    timing: TimingSpec
    expect_reply: bool = True
    hold_ms: float = 0.0


def reply_mismatch(request: ModbusPDU, reply: ModbusPDU) -> str | None:  # noqa: C901 - one check per echoed field, in the order the frame has them
    """Why ``reply`` cannot be the answer to ``request`` (None when it can).

    RTU and ASCII frames carry no transaction id, so everything a reply echoes is checked: unit,
    function code (or its exception form), the address and value of 05h/06h, the address and
    quantity of 0Fh/10h, the register count of 03h/04h, the byte count of 01h/02h and the
    sub-function of 08h.
    """
    fc = request.function_code
    if reply.function_code == fc and reply.dev_id == request.dev_id:  # the common cases first
        if fc == 0x03 or fc == 0x04:  # a register read answered
            n = len(reply.registers)
            return None if n == request.count else f"reply has {n} registers, asked {request.count}"
        if fc == 0x06 and reply.address == request.address:  # a register write echoed
            if list(reply.registers) == list(request.registers):
                return None
            return f"reply echoes value {list(reply.registers)}, sent {list(request.registers)}"
    if reply.dev_id != request.dev_id:
        return f"reply from unit {reply.dev_id}, asked unit {request.dev_id}"
    if reply.function_code & 0x7F != fc:
        return f"reply has function 0x{reply.function_code:02X}, sent 0x{fc:02X}"
    if reply.isError():
        return None
    if fc in (0x03, 0x04) and len(reply.registers) != request.count:
        return f"reply has {len(reply.registers)} registers, asked {request.count}"
    if fc in (0x01, 0x02) and len(reply.bits) != (request.count + 7) // 8 * 8:
        return f"reply has {len(reply.bits) // 8} data bytes for {request.count} bits"
    if fc in (0x05, 0x06, 0x0F, 0x10) and reply.address != request.address:
        return f"reply echoes address 0x{reply.address:04X}, sent 0x{request.address:04X}"
    if fc == 0x06 and list(reply.registers) != list(request.registers):
        return f"reply echoes value {list(reply.registers)}, sent {list(request.registers)}"
    if fc == 0x05 and bool(reply.bits[0]) != bool(request.bits[0]):
        return f"reply echoes coil {reply.bits[0]}, sent {request.bits[0]}"
    if fc == 0x10 and reply.count != len(request.registers):
        return f"reply echoes quantity {reply.count}, sent {len(request.registers)}"
    if fc == 0x0F and reply.count != len(request.bits):
        return f"reply echoes quantity {reply.count}, sent {len(request.bits)}"
    if fc == 0x08 and getattr(reply, "sub_function_code", None) != getattr(request, "sub_function_code", None):
        return "reply has another diagnostics sub-function"
    return None


__all__ = ["Exchange", "Stats", "reply_mismatch"]
