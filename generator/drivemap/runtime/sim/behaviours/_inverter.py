"""Shared behaviour of inverters driven by a run/stop bit word and a frequency command (v2, edx).

The command word's RUN and REVERSE bits show up in the status word's RUNNING and REVERSE bits,
EXTERNAL_FAULT raises and FAULT_RESET clears the fault bit, the frequency command is mirrored
into the frequency-command monitor, and (where the map has one) the output frequency ramps
toward the frequency command while running and back to 0 when stopped.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivemap.runtime.sim.behaviours import Behaviour

if TYPE_CHECKING:
    from drivemap.runtime.sim.view import UnitView as Unit


def has_bit(unit: Unit, name: str, bit: str) -> bool:
    """True when the unit's map has register ``name`` with bit ``bit``."""
    if not unit.has(name):
        return False
    return any(b.name == bit for b in unit.spec.register(name).bits)


def start_ramp(unit: Unit, name: str) -> None:
    """Start a ramp at the register's present value (call from ``on_start``)."""
    unit.scratch[f"ramp:{name}"] = (float(unit.raw(name)), unit.raw(name))


def ramp(unit: Unit, name: str, target: float, step: float) -> None:
    """Move register ``name`` toward ``target`` by at most ``step`` raw units.

    The exact (fractional) value is kept in the unit's scratch; the register is only written
    when the ramp's rounded value changes, so a value preset from outside stays until the
    ramp moves.
    """
    key = f"ramp:{name}"
    current, shown = unit.scratch.get(key, (float(unit.raw(name)), unit.raw(name)))
    current = min(target, current + step) if current < target else max(target, current - step)
    new = int(round(current))
    if new != shown:
        unit.set_raw(name, new)
    unit.scratch[key] = (current, new)


class BitCommandInverter(Behaviour):
    """Run/stop and direction bits -> status word; frequency command -> monitors."""

    command = "run_command"
    frequency = "frequency_command"
    status = "status"
    monitor = "frequency_command_monitor"
    output: str | None = None
    fault_bit = "FAULT"
    #: Simulator choice (the manuals give no ramp): output frequency changes 100 Hz per second,
    #: in raw units of the frequency command (0.01 Hz).
    ramp_raw_per_s = 10000.0

    def _set_bit(self, unit: Unit, bit: str, value: int) -> None:
        if has_bit(unit, self.status, bit):
            unit.set_bit(self.status, bit, value)

    def _cmd_bit(self, unit: Unit, bit: str) -> int:
        return unit.bit(self.command, bit) if has_bit(unit, self.command, bit) else 0

    def _faulted(self, unit: Unit) -> bool:
        return has_bit(unit, self.status, self.fault_bit) and unit.bit(self.status, self.fault_bit) == 1

    def on_start(self, unit: Unit) -> None:
        self._set_bit(unit, "READY", 1)
        if self.output is not None and unit.has(self.output):
            start_ramp(unit, self.output)

    def on_write(self, unit: Unit, name: str, raw: int) -> None:
        if name == self.command:
            if self._cmd_bit(unit, "FAULT_RESET"):
                self._set_bit(unit, self.fault_bit, 0)
            if self._cmd_bit(unit, "EXTERNAL_FAULT"):
                self._set_bit(unit, self.fault_bit, 1)
            self._update_status(unit)
        elif name == self.frequency and unit.has(self.monitor):
            unit.set_raw(self.monitor, raw)

    def _update_status(self, unit: Unit) -> None:
        running = self._cmd_bit(unit, "RUN") == 1 and not self._faulted(unit)
        self._set_bit(unit, "RUNNING", int(running))
        self._set_bit(unit, "REVERSE", self._cmd_bit(unit, "REVERSE"))
        self._set_bit(unit, "READY", int(not self._faulted(unit)))

    def _running(self, unit: Unit) -> bool:
        return has_bit(unit, self.status, "RUNNING") and unit.bit(self.status, "RUNNING") == 1

    def on_tick(self, unit: Unit, dt: float) -> None:
        if self.output is None or not unit.has(self.output) or not unit.has(self.frequency):
            return
        target = abs(unit.raw(self.frequency)) if self._running(unit) else 0
        ramp(unit, self.output, target, self.ramp_raw_per_s * dt)

    def is_running(self, unit: Unit) -> bool:
        if self._running(unit):
            return True
        return self.output is not None and unit.has(self.output) and unit.raw(self.output) != 0
