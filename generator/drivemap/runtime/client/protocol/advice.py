"""The manual's advice for writes while the drive runs (map key ``running_advice``).

Some manuals only *advise* against a write while the motor runs (ev 001 §4.6 NOTE: change operation
data through the RAM addresses while the motor runs); they do not say the device refuses it. The
client therefore never refuses such a write: before sending it, it reads the register the map names
in ``protocol.running_state`` and, when that reports running, issues a :class:`RunningWriteWarning`
(Python :mod:`warnings`, attributed to the caller's line), then writes. A warnings filter decides
what happens: shown once per call site (Python's default), ``"error"`` raises it before anything
is written, ``"ignore"`` silences it. The check costs one read request per such write; a broadcast
client cannot read and does not check.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Sequence

from drivemap.runtime.errors import RunningWriteWarning
from drivemap.runtime.spec import DeviceSpec, RegisterSpec

#: the client runtime's folder (``runtime/client/``, all its layers): frames inside it are not the caller's
_RUNTIME_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep


def caller_stacklevel() -> int:
    """The ``stacklevel`` of the first frame outside ``drivemap.runtime.client`` (the user's call), seen from
    the function that calls :func:`warnings.warn` (this function's caller)."""
    frame = sys._getframe(1)
    level = 1
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_RUNTIME_DIR):
        frame = frame.f_back
        level += 1
    return level


def warn_if_running(spec: DeviceSpec, written: Sequence[tuple[RegisterSpec, str]], state_raw: int) -> None:
    """Warn when ``state_raw`` (the value of ``spec.protocol.running_state``'s register) means running.

    ``written``: (register, element name) of every element about to be written that carries advice.
    """
    if spec.protocol.running_state is None or state_raw not in spec.protocol.running_state.values:
        return
    names = ", ".join(name for _, name in written)
    advice = "; ".join(dict.fromkeys(reg.running_advice or "" for reg, _ in written))
    warnings.warn(
        f"{spec.name}: writing {names} while the drive reports running "
        f"({spec.protocol.running_state.register} = {state_raw}); the manual advises: {advice}",
        RunningWriteWarning,
        stacklevel=caller_stacklevel(),
    )


__all__ = ["RunningWriteWarning", "caller_stacklevel", "warn_if_running"]
