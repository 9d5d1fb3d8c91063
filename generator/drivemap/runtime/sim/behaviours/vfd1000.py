"""VFD1000: 1000H control command -> 1001H inverter state; 3000H follows the frequency setting.

Simulator choices (the manual does not give them): the maximum frequency P0.04 is taken as
50.00 Hz and 3000H/3001H are in 0.01 Hz, so 2000H = 100.00 % gives 3001H = 5000; 3000H ramps
toward 3001H at 100 Hz/s while running. 0004H (printed "Forward jogging", probably reverse jog)
runs forward, as printed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivemap.runtime.sim.behaviours import Behaviour, register
from drivemap.runtime.sim.behaviours._inverter import ramp, start_ramp

if TYPE_CHECKING:
    from drivemap.runtime.sim.view import UnitView as Unit

FORWARD_RUNNING, REVERSE_RUNNING, STANDBY, FAULT = 1, 2, 3, 4
_RUN_FORWARD = {0x0001, 0x0003, 0x0004}
_RUN_REVERSE = {0x0002}
_STOP = {0x0005, 0x0008}
_FREE_STOP = 0x0006
_FAULT_RESET = 0x0007
MAX_FREQUENCY_RAW = 5000


@register("vfd1000")
class Vfd1000(Behaviour):
    #: Simulator choice: 100 Hz per second in 0.01 Hz units.
    ramp_raw_per_s = 10000.0

    def on_start(self, unit: Unit) -> None:
        if unit.has("inverter_state") and "inverter_state" in unit.unset:
            unit.set_raw("inverter_state", STANDBY)
        self._follow_setting(unit)
        if unit.has("operating_frequency"):
            start_ramp(unit, "operating_frequency")

    def _fault(self, unit: Unit) -> bool:
        return unit.has("fault_code") and unit.raw("fault_code") != 0

    def _follow_setting(self, unit: Unit) -> None:
        if unit.has("communication_setting") and unit.has("set_frequency"):
            percent = abs(unit.raw("communication_setting")) / 10000.0
            unit.set_raw("set_frequency", int(round(percent * MAX_FREQUENCY_RAW)))

    def on_write(self, unit: Unit, name: str, raw: int) -> None:
        if name == "communication_setting":
            self._follow_setting(unit)
        if name != "control_command" or not unit.has("inverter_state"):
            return
        if raw == _FAULT_RESET:
            if unit.has("fault_code"):
                unit.set_raw("fault_code", 0)
            unit.set_raw("inverter_state", STANDBY)
            return
        if self._fault(unit):
            return
        if raw in _RUN_FORWARD:
            unit.set_raw("inverter_state", FORWARD_RUNNING)
        elif raw in _RUN_REVERSE:
            unit.set_raw("inverter_state", REVERSE_RUNNING)
        elif raw in _STOP:
            unit.set_raw("inverter_state", STANDBY)
        elif raw == _FREE_STOP:
            unit.set_raw("inverter_state", STANDBY)
            if unit.has("operating_frequency"):
                ramp(unit, "operating_frequency", 0, float("inf"))

    def on_tick(self, unit: Unit, dt: float) -> None:
        if not unit.has("inverter_state"):
            return
        if self._fault(unit):
            unit.set_raw("inverter_state", FAULT)
        if not unit.has("operating_frequency") or not unit.has("set_frequency"):
            return
        running = unit.raw("inverter_state") in (FORWARD_RUNNING, REVERSE_RUNNING)
        target = unit.raw("set_frequency") if running else 0
        step = self.ramp_raw_per_s * dt
        if unit.raw("inverter_state") == FAULT:
            step = float("inf")  # the output is cut at once
        ramp(unit, "operating_frequency", target, step)

    def is_running(self, unit: Unit) -> bool:
        if unit.has("inverter_state") and unit.raw("inverter_state") in (FORWARD_RUNNING, REVERSE_RUNNING):
            return True
        return unit.has("operating_frequency") and unit.raw("operating_frequency") != 0
