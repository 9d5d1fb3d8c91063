"""Tests only: a map's generated package as ``drivemap build`` would write it, rendered and run in memory.

The tools themselves never run rendered text (they use ``drivemap.model.spec.spec_from_model`` and
``drivemap.runtime.client.api.dynamic.client_package``); the tests use this to exercise the generated
code of the synthetic maps in ``tests/maps`` without writing a package to disk. The modules are
registered under ``drivemap_rendered_<model>``, a name no build writes.
"""

from __future__ import annotations

import sys
import types

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.python import PythonExporter
from drivemap.model.nodes import Model
from drivemap.runtime.spec import DeviceSpec

__all__ = ["load_package", "load_spec"]

_ORDER = ("spec", "client", "simulator")


def _package_name(model: Model) -> str:
    return f"drivemap_rendered_{model.name}"


def load_package(model: Model, options: Options | None = None) -> types.ModuleType:
    """The generated package of ``model`` (``Client``, ``AsyncClient``, ``SPEC``, enums ...), in memory.

    Each call compiles afresh (a changed map gives a new package); the modules are registered in
    ``sys.modules`` under ``drivemap_rendered_<model>`` so that pickling, logging and relative
    imports work as in a built package.
    """
    files = PythonExporter().render(model, options or Options())
    name = _package_name(model)
    for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
        del sys.modules[key]
    package = types.ModuleType(name, f"drivemap map {model.path} in memory")
    package.__path__ = []
    package.__package__ = name
    sys.modules[name] = package
    for module in _ORDER:
        _run(f"{name}.{module}", files[f"{model.name}/{module}.py"], model, package)
    _run(name, files[f"{model.name}/__init__.py"], model, package, module=package)
    return package


def _run(name: str, text: str, model: Model, package: types.ModuleType,
         module: types.ModuleType | None = None) -> types.ModuleType:
    mod = module or types.ModuleType(name)
    mod.__package__ = package.__name__
    mod.__file__ = f"<{name} from {model.path}>"
    sys.modules[name] = mod
    exec(compile(text, mod.__file__, "exec"), mod.__dict__)
    if module is None:
        setattr(package, name.rpartition(".")[2], mod)
    return mod


def load_spec(model: Model, options: Options | None = None) -> DeviceSpec:
    """The model's ``SPEC`` (the generated ``spec.py``, run in memory)."""
    spec = load_package(model, options).SPEC
    assert isinstance(spec, DeviceSpec)
    return spec
