"""An in-process loopback: a :class:`~drivemap.runtime.client.transport.bus.Bus` whose line is a simulator's handler.

The request PDU a client builds is encoded by pymodbus, handed to the simulator's request handler
(the same :meth:`Simulator.handle` its TCP and serial servers call) and the reply is decoded by
pymodbus's client-side decoder. No socket, no thread, no timing: a test of protocol behaviour
(planning, scaling, exceptions, pages, programs) runs in microseconds. What only a real line shows
(framing, CRC, timing, stale replies) is tested over TCP and virtual serial lines instead.

    sim = Simulator(units=[1])
    with loopback_bus(sim) as bus:
        drive = Client(bus, unit=1)
        drive.digital_speed_ram[0].write(1000)

A request the simulator leaves unanswered (a unit it does not serve, a map's "no reply" case) is a
timeout for the bus at once, so its retries and :class:`DriveTimeout` behave as on a line.
"""

from __future__ import annotations

from typing import Any, Protocol

from pymodbus.exceptions import ModbusIOException
from pymodbus.pdu import DecodePDU, ModbusPDU

from drivemap.runtime.client.transport.bus import Bus

__all__ = ["LoopbackClient", "loopback_bus"]


class Handler(Protocol):
    def handle(self, unit_id: int, pdu: bytes, *, always_answer: bool = False) -> bytes | None: ...


class _Params:
    timeout_connect: float = 0.0


class LoopbackClient:
    """The part of a pymodbus sync client that :class:`Bus` uses, answered by ``handler``."""

    def __init__(self, handler: Handler, *, always_answer: bool = True) -> None:
        self.handler = handler
        self.always_answer = always_answer
        self.connected = False
        self.comm_params = _Params()
        self.requests: list[tuple[int, bytes]] = []
        """Every request PDU (unit, bytes with the function code) in the order sent."""
        self._decoder = DecodePDU(is_server=False)

    def set_max_no_responses(self, count: int) -> None:
        """pymodbus's disconnect-after-N-timeouts; nothing to disconnect here."""

    def connect(self) -> bool:
        self.connected = True
        return True

    def close(self) -> None:
        self.connected = False

    def execute(self, no_response_expected: bool, request: ModbusPDU) -> ModbusPDU | None:
        frame = bytes([request.function_code]) + request.encode()
        self.requests.append((request.dev_id, frame))
        answer = self.handler.handle(request.dev_id, frame, always_answer=self.always_answer)
        if no_response_expected:
            return None
        if answer is None:
            raise ModbusIOException("no reply (loopback)")
        reply = self._decoder.decode(answer)
        if reply is None:
            raise ModbusIOException(f"undecodable reply {answer.hex()} (loopback)")
        reply.dev_id = request.dev_id
        return reply


def loopback_bus(handler: Handler, *, always_answer: bool = True, retries: int = 0, **bus_options: Any) -> Bus:
    """A :class:`Bus` on :class:`LoopbackClient` (``always_answer``: Modbus TCP's rule, see ``Simulator.handle``)."""
    return Bus(LoopbackClient(handler, always_answer=always_answer), retries=retries, name="loopback", **bus_options)
