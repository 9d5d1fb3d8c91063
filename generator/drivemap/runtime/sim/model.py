"""The simulator of one model: what every generated ``simulator.py`` used to spell out, written once.

A generated ``simulator.py`` declares ``class Simulator(ModelSimulator): SPEC = SPEC`` and
``main = simulator_main(Simulator)``; the constructor binds the spec and the behaviour registered for
the model (entry point ``drivemap.behaviours``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import ClassVar, Protocol

from drivemap.runtime.sim import cli as simcli
from drivemap.runtime.sim.behaviours import Behaviour, behaviour_for
from drivemap.runtime.sim.simulator import Simulator, SimValue
from drivemap.runtime.spec import DeviceSpec

__all__ = ["ModelSimulator", "SimulatorMain", "default_unit", "simulator_main"]


class ModelSimulator(Simulator):
    """A model's simulator: ``SPEC``'s register store and dialect, with the model's behaviour.

    ``units`` are the unit ids it answers (several drives on one bus; by default the first valid
    one, ``DEFAULT_UNIT``); ``state_file`` keeps EEPROM-class registers across restarts;
    ``realistic_timing`` delays replies like the device; ``refuse_advised_while_running`` (off by
    default) also refuses, while running, writes the manual only advises against
    (``running_advice``; the device is not known to refuse them); ``reply_quirks`` answers in
    non-standard reply forms the map lists (none by default); ``behaviour`` replaces the one
    registered for the model (entry point ``drivemap.behaviours``); ``presets`` are (cell name,
    engineering value) pairs the memory holds at power-up (every unit).
    Presets later: ``set(name, value, unit=None)`` / ``set_raw``; one-shot exceptions: ``inject_exception(code)``.
    """

    SPEC: ClassVar[DeviceSpec]

    def __init__(
        self,
        units: Sequence[int] | None = None,
        *,
        state_file: str | os.PathLike[str] | None = None,
        realistic_timing: bool = False,
        behaviour: Behaviour | None = None,
        refuse_advised_while_running: bool = False,
        reply_quirks: Sequence[str] = (),
        presets: Sequence[tuple[str, SimValue]] = (),
    ) -> None:
        spec = self.SPEC
        super().__init__(
            spec,
            units if units is not None else (default_unit(spec),),
            behaviour=behaviour if behaviour is not None else behaviour_for(spec.name),
            state_file=state_file,
            realistic_timing=realistic_timing,
            refuse_advised_while_running=refuse_advised_while_running,
            reply_quirks=reply_quirks,
            presets=presets,
        )


def default_unit(spec: DeviceSpec) -> int:
    """Unit 1 where the map allows it, else its lowest unit id."""
    return 1 if spec.protocol.unit_min <= 1 <= spec.protocol.unit_max else spec.protocol.unit_min


class SimulatorMain(Protocol):
    def __call__(self, argv: Sequence[str] | None = None) -> int: ...


def simulator_main(simulator: type[ModelSimulator]) -> SimulatorMain:
    """The ``main(argv)`` of a generated ``simulator.py``: serve it (same options as ``drivemap simulate``)."""

    def main(argv: Sequence[str] | None = None) -> int:
        """Serve this simulator (same options as ``drivemap simulate``) until Ctrl-C."""
        return simcli.main(simulator.SPEC.name, simulator, argv)

    return main
