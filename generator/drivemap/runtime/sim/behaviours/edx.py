"""EDX inverter: 00E6H run/reverse bits -> 00EFH status, 00E7H frequency -> 00F2H, 00F3H ramps.

The output frequency (00F3H, raw, assumed to share the 0.01 Hz of 00E7H) ramps toward the
frequency command at 100 Hz/s while running and back to 0 when stopped (a simulator choice:
the manual gives no acceleration).
"""

from __future__ import annotations

from drivemap.runtime.sim.behaviours import register
from drivemap.runtime.sim.behaviours._inverter import BitCommandInverter


@register("edx")
class Edx(BitCommandInverter):
    command = "operation_signal"
    frequency = "frequency_command"
    status = "status"
    monitor = "frequency_command_monitor"
    output = "output_frequency"
    fault_bit = "ABNORMAL"
