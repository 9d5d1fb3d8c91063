"""Device behaviour for simulators: what a drive does when a control program talks to it.

The simulator core (:mod:`drivemap.runtime.sim.simulator`) answers every request in the device's
dialect; a :class:`Behaviour` makes the device *react*: a run command moves the motor, an alarm
reset clears the alarm. Models without a behaviour get the plain :class:`Behaviour` (a register
store with the dialect, nothing moves). Hooks run with the simulator's lock held; they change the
unit through :class:`~drivemap.runtime.sim.simulator.Unit`.

A behaviour is found, for model id ``mymodel``, in this order:

1. a class registered with :func:`register` by a module that was imported, such as the modules a
   project lists in its ``behaviours`` setting (``[tool.drivemap] behaviours = ["plant.sim"]``,
   imported by ``drivemap simulate`` with the project root on ``sys.path``)::

       from drivemap.runtime.sim.behaviours import Behaviour, register

       @register("mymodel")
       class MyModel(Behaviour):
           def on_write(self, unit, name, raw): ...

2. an entry point named ``mymodel`` in the group ``drivemap.behaviours`` of any installed
   distribution (``mymodel = "plant.sim:MyModel"``). drivemap's own seed models (ev, vfd1000,
   v2, edx) are registered this way by drivemap's own distribution.
"""

from __future__ import annotations

import importlib
import importlib.metadata
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from drivemap.runtime.sim.view import UnitView as Unit

__all__ = ["Behaviour", "behaviour_class", "behaviour_for", "load_modules", "register", "registered"]

_REGISTRY: dict[str, type[Behaviour]] = {}
_B = TypeVar("_B", bound="type[Behaviour]")


class Behaviour:
    """The plain stub: every hook does nothing and the device never runs."""

    model: str | None = None

    def on_start(self, unit: Unit) -> None:
        """Power-up: called once per unit after defaults (and saved EEPROM values) are loaded."""

    def on_write(self, unit: Unit, name: str, raw: int) -> None:
        """A Modbus write stored ``raw`` in cell ``name`` (after the dialect accepted it)."""

    def on_read(self, unit: Unit, names: Sequence[str]) -> None:
        """A Modbus read is about to return the cells ``names``: refresh them if needed."""

    def on_request(self, unit: Unit) -> None:
        """A well-formed request reached ``unit`` (addressed to it, or a broadcast), before it is served
        (also when it is then refused): e.g. a communication watchdog restarts."""

    def on_tick(self, unit: Unit, dt: float) -> None:
        """``dt`` seconds of device time passed."""

    def is_running(self, unit: Unit) -> bool:
        """True while writes to ``refuse_while_running`` registers must be refused (busy)."""
        return False


def register(model: str) -> Callable[[_B], _B]:
    """Class decorator: the behaviour of ``model``."""

    def deco(cls: _B) -> _B:
        cls.model = model
        _REGISTRY[model] = cls
        return cls

    return deco


def registered() -> dict[str, type[Behaviour]]:
    """Every behaviour registered so far (model -> class)."""
    return dict(_REGISTRY)


def load_modules(modules: Sequence[str]) -> None:
    """Import the modules a project names in ``behaviours`` (they register their classes)."""
    for name in modules:
        importlib.import_module(name)


def _entry_point(model: str) -> type[Behaviour] | None:
    for entry in importlib.metadata.entry_points(group="drivemap.behaviours", name=model):
        obj = entry.load()
        if isinstance(obj, type) and issubclass(obj, Behaviour):
            return obj
        raise TypeError(f"entry point drivemap.behaviours:{model} ({entry.value}) is not a Behaviour subclass")
    return None


def behaviour_class(model: str) -> type[Behaviour]:
    """The behaviour class of ``model``: registered, else an entry point, else the plain stub."""
    if model in _REGISTRY:
        return _REGISTRY[model]
    found = _entry_point(model)
    return found if found is not None else Behaviour


def behaviour_for(model: str) -> Behaviour:
    """A fresh behaviour instance for one simulator of ``model``."""
    return behaviour_class(model)()
