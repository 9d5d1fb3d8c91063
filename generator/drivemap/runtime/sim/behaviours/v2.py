"""V2 series inverter: 0101H run/reverse bits -> 0120H status, 0102H frequency -> 0123H monitor.

The V2 document has no output-frequency register, so the frequency-command monitor (0123H) is
what follows the frequency command. Parameters (P_0..P_255) are refused with 55H while RUNNING.
"""

from __future__ import annotations

from drivemap.runtime.sim.behaviours import register
from drivemap.runtime.sim.behaviours._inverter import BitCommandInverter


@register("v2")
class V2(BitCommandInverter):
    command = "run_command"
    frequency = "frequency_command"
    status = "status"
    monitor = "frequency_command_monitor"
    output = None
    fault_bit = "FAULT"
