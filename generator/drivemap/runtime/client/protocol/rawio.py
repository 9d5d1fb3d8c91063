"""Raw register access: ``client.read_registers(table, address, count)`` -> the words on the wire.

For what the typed accessors cannot express: part of an element (the first 4 of the 16 registers
of a string, as a manual's example reads them), a word the map does not name, a quick look at the
drive. The words come back exactly as the device sends them (no word or byte order applied; 0/1
per coil or discrete input). Everything is checked before anything is sent, with the typed errors
of the rest of the client: the table and the read function the map lists for it
(:class:`UnsupportedFunction`), whole numbers in range (:class:`InvalidValue`,
:class:`ValueOutOfRange`), the request size the map allows, no word of a write-only register or of
a range the map marks unreadable (:class:`WriteOnlyRegister`), no broadcast client
(:class:`BroadcastRead`), no start address or quantity that breaks the map's alignment rules
(:class:`MisalignedRequest`). Paged addresses read whatever page the device shows: no page is switched.
"""

from __future__ import annotations

from drivemap.runtime.alignment import refuse_misaligned
from drivemap.runtime.client.protocol.planner import MODBUS_MAX_READ, MODBUS_MAX_READ_BITS
from drivemap.runtime.client.protocol.sansio import Core, Op
from drivemap.runtime.errors import (
    BroadcastRead,
    InvalidValue,
    UnsupportedFunction,
    ValueOutOfRange,
    WriteOnlyRegister,
)
from drivemap.runtime.spec import DeviceSpec

__all__ = ["TABLES", "check_read", "read_registers"]

#: table -> its read function code
TABLES = {"coil": 0x01, "discrete": 0x02, "holding": 0x03, "input": 0x04}


def _whole(what: str, value: object) -> int:
    if not isinstance(value, int) or isinstance(value, bool):
        raise InvalidValue(f"{what} must be an int, not {type(value).__name__}")
    return value


def _unreadable(spec: DeviceSpec, table: str, start: int, end: int) -> str | None:
    """The first thing in ``table`` words ``start``..``end - 1`` that the map says cannot be read."""
    for reg in spec.registers:
        if reg.table != table or reg.readable:
            continue
        for i in range(reg.count):
            a = reg.element_address(i)
            if a < end and start < a + reg.words:
                return f"{reg.element_name(i)} is write-only"
    for res in spec.reserved:
        if res.table == table and res.readable is False and res.start < end and start <= res.end:
            return f"0x{res.start:04X}..0x{res.end:04X} is unreadable (the map's reserved range)"
    return None


def check_read(spec: DeviceSpec, table: object, address: object, count: object, broadcast: bool = False) -> int:
    """Check a raw read before the wire; returns its function code."""
    if broadcast:
        raise BroadcastRead("a broadcast client cannot read (nobody answers a broadcast)")
    if not isinstance(table, str) or table not in TABLES:
        raise InvalidValue(f"table must be one of {', '.join(TABLES)}, not {table!r}")
    code = TABLES[table]
    function = spec.protocol.function(code)
    if function is None:
        raise UnsupportedFunction(f"the map does not list {code:02X}h (read {table})")
    address, count = _whole("address", address), _whole("count", count)
    limit = function.max_quantity or (MODBUS_MAX_READ_BITS if code <= 0x02 else MODBUS_MAX_READ)
    if not 1 <= count <= limit:
        raise ValueOutOfRange(f"count {count}: {code:02X}h reads 1..{limit} {'bits' if code <= 0x02 else 'registers'}")
    if not 0 <= address or address + count > 0x10000:
        raise ValueOutOfRange(f"address {address} (+{count}) is outside 0..0xFFFF")
    why = _unreadable(spec, table, address, address + count)
    if why is not None:
        raise WriteOnlyRegister(f"read {table} 0x{address:04X} x{count}: {why}")
    refuse_misaligned(spec, table, address, count, "read")
    return code


def read_registers(core: Core, table: str, address: int, count: int) -> Op[list[int]]:
    """The operation behind ``client.read_registers`` (checked before its first exchange)."""
    check_read(core.spec, table, address, count, core.broadcast)
    words = yield from core._read_words(table, address, count)
    return words
