"""The one typed path from a compiled :class:`~drivemap.model.nodes.Model` to the runtime's :class:`DeviceSpec`.

:func:`spec_from_model` is what the simulator factory, the live verbs, the gateway, the exporters
and ``drivemap build`` use (:func:`drivemap.runtime.package.load_package` builds a client package
from it); the generated ``spec.py`` is this object printed
(:mod:`drivemap.backends.views.spec`), so a built package and an unbuilt map give equal specs.
Nothing here renders or executes generated text.

The model's nodes that describe what the runtime describes *are* the runtime's classes, extended
by compile-time facts only (the ``Model`` is a ``DeviceSpec``, its ``Register`` a ``RegisterSpec``,
its ``Protocol`` a ``ProtocolSpec``, ...), so the runtime's description of a map is the model
projected onto the runtime's classes (:func:`project`), not a copy field by field.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

from drivemap.model.nodes import Model
from drivemap.runtime.spec import DeviceSpec

__all__ = ["project", "spec_from_model"]

_T = TypeVar("_T")


def _runtime_class(cls: type) -> type:
    """The runtime spec class a model class is (or extends): the first in its MRO from :mod:`drivemap.runtime.spec`."""
    return next(c for c in cls.__mro__ if c.__module__ == DeviceSpec.__module__)


def _projected(value: Any) -> Any:
    """``value`` with every node in it (also in tuples) projected onto its runtime class."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return project(value, _runtime_class(type(value)))
    if isinstance(value, tuple):
        return tuple(_projected(v) for v in value)
    return value


def project(node: object, cls: type[_T]) -> _T:
    """``node`` (a model node, which extends the runtime class ``cls``) as a plain ``cls``: the
    fields the runtime declares, nested nodes projected likewise; the compile-time extras are dropped."""
    return cls(**{f.name: _projected(getattr(node, f.name)) for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                  if f.init})


def spec_from_model(model: Model) -> DeviceSpec:
    """The runtime's description of ``model``: registers, dialect, timing, enums (no YAML, no generated code)."""
    return project(model, DeviceSpec)
