"""Write programs: ``element.write(value)`` with its request prepared once per accessor (issue 18).

A plain register (holding table, no scale-factor register, not a command, no page, no running
advice, written by 06h when it is one word or by 10h when the map allows it) gets a writer that
encodes and checks the value with its codec (the same checks, in the same order, as before), puts
the words into its prepared request, sends it through the bus and raises a device exception
through :meth:`Core.raise_for`; what the client notes after a write (page selectors, pending
configuration, power cycle) is done by :meth:`Core._after_write` only for registers that need it.
Every other register (and a broadcast client) writes through the core's general operation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pymodbus.pdu import ModbusPDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest, WriteSingleRegisterRequest

from .bus import Exchange
from .core import Core
from .spec import RegisterSpec
from .words import raw_to_words

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


def element_writer(core: Core, acc: Any, asynchronous: bool) -> Writer | None:
    """The writer of ``acc`` (an element, not of an array) for ``core``'s client, or None (general path)."""
    codec = acc.codec
    try:
        reg = core.spec.register(acc.spec.name)  # the client's map (what the general path checks against)
    except KeyError:
        return None
    if codec.scale_key is not None or acc.index != 0 or reg.count != 1:
        return None
    prepared = _request(core, reg)
    if prepared is None:
        return None
    pdu, code = prepared
    key = acc.key
    ex = Exchange(core.unit, pdu, core.spec.timing, True, reg.write_delay_ms or 0.0)
    encode = codec.encode
    after = reg.name in core.tables.selectors or reg.reflect in ("configuration", "power_cycle")

    def write(client: Any, value: Any) -> None:
        raw = encode(value)
        words = raw_to_words(reg, raw)
        bus = client.bus
        with bus.lock:
            pdu.registers = words
            reply = bus.transact(ex)
            if reply is None or reply.function_code > 0x80:
                core.raise_for(reply, code)
            if after:
                core._after_write(reg, key, int(raw))

    async def awrite(client: Any, value: Any) -> None:
        raw = encode(value)
        words = raw_to_words(reg, raw)
        bus = client.bus
        async with bus.lock:
            pdu.registers = words
            reply = await bus.exchange(ex)
            if reply is None or reply.function_code > 0x80:
                core.raise_for(reply, code)
            if after:
                core._after_write(reg, key, int(raw))

    return awrite if asynchronous else write


__all__ = ["Writer", "element_writer"]
