"""A device's client package built from its :class:`DeviceSpec` in memory, without generated code.

``drivemap build`` writes a package per map (``Client``, ``AsyncClient``, ``SPEC``, the enums, and a
``simulator`` module); :func:`load_package` gives the same objects from a spec alone, which is what
the live verbs and the gateway use for a map that was never built.
"""

from __future__ import annotations

import sys
import types

from drivemap.runtime.client.api.dynamic import client_package
from drivemap.runtime.sim.model import ModelSimulator, simulator_main
from drivemap.runtime.spec import DeviceSpec

__all__ = ["load_package"]


def load_package(spec: DeviceSpec) -> types.ModuleType:
    """The package of ``spec`` as ``drivemap build`` would write it (``Client``, ``AsyncClient``,
    ``SPEC``, enums ..., and a ``simulator`` submodule with its ``Simulator``), built without
    generating or running code; each call builds afresh."""
    name = f"drivemap_inmemory_{spec.name}"
    package = client_package(spec, name)
    package.__path__ = []  # a package, so that ``importlib.import_module(f"{name}.simulator")`` works
    simulator = types.ModuleType(f"{name}.simulator", f"Simulator of {spec.device.title}")
    simulator.Simulator = type("Simulator", (ModelSimulator,), {"SPEC": spec, "__module__": simulator.__name__})  # type: ignore[attr-defined]
    simulator.MODEL = spec.name  # type: ignore[attr-defined]
    simulator.main = simulator_main(simulator.Simulator)  # type: ignore[attr-defined]
    sys.modules[simulator.__name__] = package.simulator = simulator  # type: ignore[attr-defined]
    return package
