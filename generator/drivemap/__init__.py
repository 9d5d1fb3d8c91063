"""drivemap: a declarative register-map compiler for Modbus motor drives.

Pipeline (one module per stage): :mod:`load` (YAML with line/column) -> :mod:`schema`
(JSON Schema) -> :mod:`checks` (semantic checks) -> :mod:`model` (immutable model) ->
:mod:`render` (Jinja templates) -> files. :mod:`runtime` is what generated code imports.
"""

__version__ = "0.2.0"
