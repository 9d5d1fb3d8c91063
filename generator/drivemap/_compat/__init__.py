"""Everything drivemap still answers for code written against an earlier release, in one place, each
with the release that removes it.

* **Import paths** that moved (:data:`MOVED_MODULES`): ``import drivemap.runtime.codec`` still gives the
  module's objects (the very same ones as the new path), with a :class:`DeprecationWarning` naming the
  new path. A finder on :data:`sys.meta_path` (installed when ``drivemap`` is imported) answers them:
  no module file is kept for an old path.
* **The flat DeviceSpec form** a ``spec.py`` of an earlier release prints
  (``DeviceSpec(model=..., modes=..., ...)``) and the flat attributes (``SPEC.timing``):
  :mod:`drivemap._compat.flat`, which :mod:`drivemap.runtime.spec` calls.

This package imports nothing of drivemap itself (the new modules are imported by name, on demand).
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
import types
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    from importlib.abc import Loader

#: The release that removes what this package keeps.
REMOVAL = "1.0"

#: old module -> the module that holds its objects now.
MOVED_MODULES: dict[str, str] = {
    "drivemap.runtime.bus": "drivemap.runtime.client.transport.bus",
    "drivemap.runtime.codec": "drivemap.runtime.client.values.codec",
    "drivemap.runtime.records": "drivemap.runtime.client.values.records",
    "drivemap.runtime.simulator": "drivemap.runtime.sim.simulator",
    "drivemap.runtime.simcli": "drivemap.runtime.sim.cli",
    # the client runtime by layer (values, transport, protocol, API): its modules moved one folder down
    "drivemap.runtime.client.accessors": "drivemap.runtime.client.api.accessors",
    "drivemap.runtime.client.advice": "drivemap.runtime.client.protocol.advice",
    "drivemap.runtime.client.async_client": "drivemap.runtime.client.api.async_client",
    "drivemap.runtime.client.base": "drivemap.runtime.client.api.base",
    "drivemap.runtime.client.bus": "drivemap.runtime.client.transport.bus",
    "drivemap.runtime.client.busbase": "drivemap.runtime.client.transport.busbase",
    "drivemap.runtime.client.codec": "drivemap.runtime.client.values.codec",
    "drivemap.runtime.client.declare": "drivemap.runtime.client.api.declare",
    "drivemap.runtime.client.descriptor": "drivemap.runtime.client.api.descriptor",
    "drivemap.runtime.client.display": "drivemap.runtime.client.values.display",
    "drivemap.runtime.client.dynamic": "drivemap.runtime.client.api.dynamic",
    "drivemap.runtime.client.enums": "drivemap.runtime.client.values.enums",
    "drivemap.runtime.client.exchange": "drivemap.runtime.client.transport.exchange",
    "drivemap.runtime.client.identity": "drivemap.runtime.client.api.identity",
    "drivemap.runtime.client.planner": "drivemap.runtime.client.protocol.planner",
    "drivemap.runtime.client.programs": "drivemap.runtime.client.protocol.programs",
    "drivemap.runtime.client.quirks": "drivemap.runtime.client.transport.quirks",
    "drivemap.runtime.client.rawio": "drivemap.runtime.client.protocol.rawio",
    "drivemap.runtime.client.records": "drivemap.runtime.client.values.records",
    "drivemap.runtime.client.review": "drivemap.runtime.client.protocol.review",
    "drivemap.runtime.client.runner": "drivemap.runtime.client.protocol.runner",
    "drivemap.runtime.client.sansio": "drivemap.runtime.client.protocol.sansio",
    "drivemap.runtime.client.serialrx": "drivemap.runtime.client.transport.serialrx",
    "drivemap.runtime.client.staleguard": "drivemap.runtime.client.transport.staleguard",
    "drivemap.runtime.client.steps": "drivemap.runtime.client.values.steps",
    "drivemap.runtime.client.sync_client": "drivemap.runtime.client.api.sync_client",
    "drivemap.runtime.client.tables": "drivemap.runtime.client.protocol.tables",
    "drivemap.runtime.client.wire": "drivemap.runtime.client.protocol.wire",
    "drivemap.runtime.client.words": "drivemap.runtime.client.values.words",
    "drivemap.runtime.client.writes": "drivemap.runtime.client.protocol.writes",
}


class _Moved(types.ModuleType):
    """An old module path: every attribute is the new module's."""

    def __init__(self, name: str, target: types.ModuleType) -> None:
        super().__init__(name, target.__doc__)
        self.__target = target
        self.__all__ = list(getattr(target, "__all__", [n for n in vars(target) if not n.startswith("_")]))

    def __getattr__(self, name: str) -> object:
        return getattr(self.__target, name)

    def __dir__(self) -> list[str]:
        return sorted(set(self.__all__) | set(super().__dir__()))


class _Finder:
    """A meta path finder and loader (the protocols of :mod:`importlib`, without importing its ABCs at startup)."""

    def find_spec(self, fullname: str, path: Sequence[str] | None, target: types.ModuleType | None = None,
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED_MODULES:
            return None
        return importlib.machinery.ModuleSpec(fullname, cast("Loader", self))

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        new = MOVED_MODULES[spec.name]
        warnings.warn(f"{spec.name} is now {new}; the old path goes in drivemap {REMOVAL}",
                      DeprecationWarning, stacklevel=2)
        return _Moved(spec.name, importlib.import_module(new))

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run: the module's objects are the new module's."""


def install() -> None:
    """Answer the old import paths (once per interpreter)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())


__all__ = ["MOVED_MODULES", "REMOVAL", "install"]
