"""drivemap: a declarative register-map compiler for Modbus motor drives.

Layers, top to bottom (each imports only those below it; ``lint-imports`` checks it):
:mod:`~drivemap.cli` -> :mod:`~drivemap.gateway`, :mod:`~drivemap.live` (applications) ->
:mod:`~drivemap.build` -> :mod:`~drivemap.compiler` (the pipeline) -> :mod:`~drivemap.backends`
(exporters, views, templates, output) -> :mod:`~drivemap.frontend` (load, schema, checks) ->
:mod:`~drivemap.model` (the immutable model) -> :mod:`~drivemap.runtime` (what generated code
imports: ``runtime.client`` and ``runtime.sim``). See ``docs/architecture.md``.
"""

__version__ = "0.2.0"
