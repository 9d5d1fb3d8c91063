"""The simulator's write requests (05h, 06h, 0Fh, 10h) and the loopback diagnostic (08h): each word
checked against the map (access, broadcast, running state, range, value set) before any is applied."""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivemap.runtime.client.values.codec import raw_bounds
from drivemap.runtime.client.values.display import is_allowed
from drivemap.runtime.sim.cells import Refused, Slot
from drivemap.runtime.sim.unit import Unit, to_value, unwire_words
from drivemap.runtime.spec import DeviceSpec, RegisterSpec

if TYPE_CHECKING:
    from drivemap.runtime.sim.behaviours import Behaviour

__all__ = ["WriteRequests"]


class WriteRequests:
    """Mixed into :class:`~drivemap.runtime.sim.simulator.Simulator`, which provides what is declared here."""

    spec: DeviceSpec
    behaviour: Behaviour
    refuse_advised_while_running: bool
    _dirty: bool

    if TYPE_CHECKING:
        def _aligned(self, table: str, address: int, quantity: int, operation: str) -> None: ...
        def _max_quantity(self, code: int, limit: int | None) -> int: ...
        def _resolve(self, unit: Unit, table: str, address: int) -> Slot | None: ...

    def _write_single(self, unit: Unit, data: bytes, broadcast: bool) -> bytes:
        if len(data) != 4:
            raise Refused("bad_length")
        address = int.from_bytes(data[0:2], "big")
        word = int.from_bytes(data[2:4], "big")
        self._aligned("holding", address, 1, "write")
        self._write(unit, address, [word], broadcast)
        return bytes([0x06]) + data

    def _write_multiple(self, unit: Unit, limit: int | None, data: bytes, broadcast: bool) -> bytes:
        if len(data) < 5:
            raise Refused("bad_length")
        address = int.from_bytes(data[0:2], "big")
        quantity = int.from_bytes(data[2:4], "big")
        count = data[4]
        if not 1 <= quantity <= self._max_quantity(0x10, limit):
            raise Refused("illegal_quantity")
        if count != 2 * quantity or len(data) != 5 + count:
            raise Refused("bad_length")
        words = [int.from_bytes(data[5 + 2 * i : 7 + 2 * i], "big") for i in range(quantity)]
        if address + quantity > 0x10000:
            raise Refused("illegal_address")
        self._aligned("holding", address, quantity, "write")
        self._write(unit, address, words, broadcast)
        return bytes([0x10]) + data[0:4]

    def _write_coil(self, unit: Unit, data: bytes, broadcast: bool) -> bytes:
        if len(data) != 4:
            raise Refused("bad_length")
        address = int.from_bytes(data[0:2], "big")
        value = int.from_bytes(data[2:4], "big")
        if value not in (0x0000, 0xFF00):
            raise Refused("out_of_range")
        self._write(unit, address, [1 if value else 0], broadcast, "coil")
        return bytes([0x05]) + data

    def _write_coils(self, unit: Unit, limit: int | None, data: bytes, broadcast: bool) -> bytes:
        if len(data) < 5:
            raise Refused("bad_length")
        address = int.from_bytes(data[0:2], "big")
        quantity = int.from_bytes(data[2:4], "big")
        count = data[4]
        if not 1 <= quantity <= self._max_quantity(0x0F, limit):
            raise Refused("illegal_quantity")
        if count != (quantity + 7) // 8 or len(data) != 5 + count:
            raise Refused("bad_length")
        if address + quantity > 0x10000:
            raise Refused("illegal_address")
        bits = [(data[5 + i // 8] >> (i % 8)) & 1 for i in range(quantity)]
        self._write(unit, address, bits, broadcast, "coil")
        return bytes([0x0F]) + data[0:4]

    def _loopback(self, data: bytes) -> bytes:
        if len(data) < 2:
            raise Refused("bad_length")
        if int.from_bytes(data[0:2], "big") != 0:
            raise Refused("illegal_function")
        return bytes([0x08]) + data

    def _write(self, unit: Unit, address: int, words: list[int], broadcast: bool, table: str = "holding") -> None:
        """Validate every word (coil), then apply all of them (a refused request changes nothing)."""
        changes: list[tuple[str, RegisterSpec, int]] = []
        i = 0
        while i < len(words):
            slot = self._resolve(unit, table, address + i)
            if slot is None:
                raise Refused("illegal_address")
            reg = slot.reg
            if slot.word != 0 or i + reg.words > len(words):
                raise Refused("illegal_address")  # part of a multi-word register
            if broadcast and not reg.broadcast:
                raise Refused("illegal_address")
            if not reg.writable:
                raise Refused("read_only")
            raw = words[i] if reg.bit_table else unwire_words(reg, words[i : i + reg.words])
            changes.append((slot.cell, reg, raw))
            i += reg.words
        if any(self._refused_while_running(reg) for _, reg, _ in changes) and self.behaviour.is_running(unit):
            raise Refused("busy")
        for _, reg, raw in changes:
            if not self._in_range(unit, reg, raw):
                raise Refused("out_of_range")
        for cell, reg, raw in changes:
            unit.values[cell] = raw
            if reg.storage == "eeprom":
                self._dirty = True
            if (
                self.spec.protocol.configuration is not None
                and reg.name == self.spec.protocol.configuration.register
                and raw == self.spec.protocol.configuration.value
            ):
                unit.apply_configuration()
            self.behaviour.on_write(unit, cell, raw)

    def _refused_while_running(self, reg: RegisterSpec) -> bool:
        """Documented refusals always; the manual's mere advice only when the option asks for it."""
        return reg.refuse_while_running or (self.refuse_advised_while_running and reg.running_advice is not None)

    def _in_range(self, unit: Unit, reg: RegisterSpec, raw: int) -> bool:
        low, high = raw_bounds(reg)
        if not low <= raw <= high:
            return False
        if reg.values and raw not in reg.not_available and not is_allowed(reg, to_value(reg, raw, unit._factor(reg))):
            return False  # outside the map's value set
        if raw in reg.not_available or reg.type in ("string", "bool"):
            return True
        if reg.enum_values and raw not in reg.enum_values:
            return False
        factor = unit._factor(reg)
        value = to_value(reg, raw, factor)
        if not isinstance(value, (int, float)):
            return True
        if value != value:  # NaN: only where the map sets no range
            return reg.min is None and reg.max is None
        step = abs(reg.scale) * (10.0 ** factor if factor is not None else 1.0)
        tolerance = 0.0 if reg.type in ("f32", "f64") else step / 2
        if reg.min is not None and value < reg.min - tolerance:
            return False
        if reg.max is not None and value > reg.max + tolerance:
            return False
        return True
