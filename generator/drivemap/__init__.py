"""drivemap: a declarative register-map compiler for Modbus motor drives and inverters.

The package is in layers; each imports only the layers below it (import-linter checks it)::

    cli                      the ``drivemap`` command
    onboard                  draft/import/probe: maps from manuals, definitions users own, live devices
    gateway | live | migrate applications: MQTT/OPC UA gateway; read/write/watch/scan/verify at a drive;
                             older map formats brought to the current one
    build                    a project's outputs (maps -> files), the simulator factory
    compiler                 map path -> checked Model: the front end, then each exporter's validate hook
    backends                 exporters (python, docs, json, homeassistant, esphome, pymodbus-sim, csv),
                             their views and Jinja templates, rendering and the output writer
    frontend                 project, load (YAML with line/column), schema, semantic checks, frames
    model                    the immutable Model (nodes, build) and spec_from_model: Model -> DeviceSpec
    runtime                  what generated and dynamic packages import: spec (DeviceSpec), names,
                             client/ (bus, sans-I/O core, accessors, descriptors, programs, codecs)
                             and sim/ (the simulator, its server, state file, CLI and behaviours)

A map goes ``frontend -> model``; :func:`drivemap.model.spec.spec_from_model` gives the runtime's
:class:`~drivemap.runtime.spec.DeviceSpec`, which the simulator, the live verbs, the gateway and the
exporters use directly (nothing executes rendered text). ``drivemap build`` writes the same spec
printed (``spec.py``), a typed client that declares each register once
(:mod:`drivemap.runtime.client.api.declare`) and a few-line ``simulator.py``;
:mod:`drivemap.runtime.client.api.dynamic` builds the equal client classes from a spec at run time.
See ``docs/architecture.md``.
"""

from drivemap import _compat

__version__ = "0.2.0"

_compat.install()  # the import paths of earlier releases (drivemap._compat.MOVED_MODULES)
