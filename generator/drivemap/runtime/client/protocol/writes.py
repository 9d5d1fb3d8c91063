"""Write programs: ``element.write(value)`` with its request prepared once per accessor (a single write is
the common case; building its request anew each time cost more than the wire).

A plain register (holding table, no scale-factor register, not a command, no page, no running
advice, written by 06h when it is one word or by 10h when the map allows it) gets a writer that
encodes and checks the value with its codec (the same checks, in the same order, as before), puts
the words into its prepared request, sends it through the bus and raises a device exception
through :meth:`Core.raise_for`; what the client notes after a write (page selectors, pending
configuration, power cycle) is done by :meth:`Core._after_write` only for registers that need it.
Every other register (and a broadcast client) writes through the core's general operation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest, WriteSingleRegisterRequest

from drivemap.runtime.client.protocol.sansio import Core
from drivemap.runtime.client.transport.exchange import Exchange
from drivemap.runtime.client.values.codec import Codec, EnumCodec, IntCodec
from drivemap.runtime.client.values.words import raw_bounds, raw_to_words
from drivemap.runtime.errors import DriveError
from drivemap.runtime.spec import RegisterSpec

Writer = Callable[[Any, Any], Any]


def _request(core: Core, reg: RegisterSpec) -> tuple[ModbusPDU, int] | None:
    """The prepared write request of a plain register and its function code, else None."""
    t = core.tables
    if (core.broadcast or not reg.writable or reg.table != "holding" or reg.command_value is not None
            or reg.running_advice is not None or reg.page is not None):
        return None
    address = reg.address
    if reg.words == 1 and t.fc06 is not None:
        return WriteSingleRegisterRequest(address=address, registers=[0], dev_id=core.unit), 0x06
    if reg.words > 1 and t.fc10 is not None and t.write_limits.get("holding", 0) > 0:
        return WriteMultipleRegistersRequest(address=address, registers=[0] * reg.words, dev_id=core.unit), 0x10
    return None


def _fast_raw(codec: Codec[Any], reg: RegisterSpec) -> tuple[type, int, int, dict[Any, int] | None] | None:
    """What lets a one-word write skip the codec for the values it accepts unchanged:
    (value type, lowest, highest, raw per enum member or None), else None.

    A plain integer register (scale 1, offset 0) writes an ``int`` from ``lowest`` to ``highest``
    (the type's bounds within the map's min/max, whole numbers) as itself; an enum register writes
    each member its codec accepts as its value. Anything else goes through ``codec.encode`` (its
    checks and its errors), so the result is the same either way.
    """
    if reg.words != 1 or reg.byte_order == "low_first" or reg.bit_table:
        return None
    lo, hi = raw_bounds(reg)
    if type(codec) is IntCodec and codec._scale == 1 and codec._offset == 0:
        if reg.min is not None:
            lo = max(lo, math.ceil(reg.min))
        if reg.max is not None:
            hi = min(hi, math.floor(reg.max))
        return int, lo, hi, None
    if type(codec) is EnumCodec:
        table: dict[Any, int] = {}
        for member in codec.enum_type:
            try:
                table[member] = codec.encode(member)
            except DriveError:
                continue
        return codec.enum_type, lo, hi, table
    return None


def element_writer(core: Core, acc: Any, asynchronous: bool) -> Writer | None:
    """The writer of ``acc`` (an element, not of an array) for ``core``'s client, or None (general path)."""
    codec = acc.codec
    try:
        reg = core.spec.register(acc.spec.name)  # the client's map (what the general path checks against)
    except KeyError:
        return None
    if codec.scale_key is not None or acc.index != 0 or reg.count != 1 or reg.review:
        return None  # (a register open for review: the general path refuses it)
    prepared = _request(core, reg)
    if prepared is None:
        return None
    pdu, code = prepared
    key = acc.key
    ex = Exchange(core.unit, pdu, core.spec.protocol.timing, True, reg.write_delay_ms or 0.0)
    encode = codec.encode
    after = reg.name in core.tables.selectors or reg.reflect in ("configuration", "power_cycle")
    fast = _fast_raw(codec, reg)
    vtype: type | None
    vtype, lo, hi, members = fast if fast is not None else (None, 0, -1, None)

    def words_of(value: Any) -> tuple[int, list[int]]:
        """(raw, words) of ``value``: what ``codec.encode`` and ``raw_to_words`` give, checked alike."""
        if type(value) is vtype:
            known: int = value if members is None else members.get(value, lo - 1)  # type: ignore[assignment]
            if lo <= known <= hi:
                return known, [known & 0xFFFF]
        raw: int = encode(value)
        return raw, raw_to_words(reg, raw)

    def write(client: Any, value: Any) -> None:
        raw, words = words_of(value)
        bus = client.bus
        with bus.lock:
            pdu.registers = words
            reply = bus.transact(ex)
            if reply is None or reply.function_code > 0x80:
                core.raise_for(reply, code)
            if after:
                core._after_write(reg, key, int(raw))

    async def awrite(client: Any, value: Any) -> None:
        raw, words = words_of(value)
        lock = client.bus.lock
        await lock.acquire()  # what ``async with`` does, without its __aenter__/__aexit__ coroutines
        try:
            pdu.registers = words
            reply = await client.bus.exchange(ex)
            if reply is None or reply.function_code > 0x80:
                core.raise_for(reply, code)
            if after:
                core._after_write(reg, key, int(raw))
        finally:
            lock.release()

    return awrite if asynchronous else write


def refusing_writer(core: Core, key: Any, asynchronous: bool) -> Writer:
    """The writer of a register open for review (``review:``): :class:`OpenForReview` before the value
    is looked at, nothing sent."""
    if asynchronous:
        async def refuse_async(client: Any, value: Any) -> None:
            core.check_write(key)
        return refuse_async

    def refuse(client: Any, value: Any) -> None:
        core.check_write(key)
    return refuse


__all__ = ["Writer", "element_writer", "refusing_writer"]
