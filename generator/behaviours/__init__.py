"""Device behaviour for simulators: what a drive does when a control program talks to it.

The simulator core (:mod:`generator.runtime.simulator`) answers every request in the device's
dialect; a :class:`Behaviour` makes the device *react*: a run command moves the motor, an alarm
reset clears the alarm. Each model may have its own module here, ``generator/behaviours/<model>.py``,
defining a :class:`Behaviour` subclass and registering it::

    from . import Behaviour, register

    @register("mymodel")
    class MyModel(Behaviour):
        def on_write(self, unit, name, raw): ...

Adding a module is all a new model needs: :func:`behaviour_for` imports
``generator.behaviours.<model>`` on demand, and models without a module get the plain
:class:`Behaviour` (a register store with the dialect, nothing moves). Hooks run with the
simulator's lock held; they change the unit through :class:`~generator.runtime.simulator.Unit`.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from ..runtime.simulator import Unit

__all__ = ["Behaviour", "behaviour_class", "behaviour_for", "register", "registered"]

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


def behaviour_class(model: str) -> type[Behaviour]:
    """The behaviour class of ``model``: its own module's, or the plain stub."""
    if model not in _REGISTRY and re.fullmatch(r"[a-z][a-z0-9_]*", model):
        try:
            importlib.import_module(f"{__name__}.{model}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{model}":
                raise
    return _REGISTRY.get(model, Behaviour)


def behaviour_for(model: str) -> Behaviour:
    """A fresh behaviour instance for one simulator of ``model``."""
    return behaviour_class(model)()
