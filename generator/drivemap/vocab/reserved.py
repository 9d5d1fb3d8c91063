"""The names and files generated outputs already use: data the python (and docs) back end owns.

A map name equal to one of these would shadow or overwrite something the generated package or the
docs page defines; :mod:`.namecheck` refuses it. The sets are data, not computed at validation time:
``tests/vocab/test_generated_names.py`` renders a probe map through the built-in exporters, reads the output
back (``tests/reserved_probe.py``) and fails when these sets differ from what the templates really
produce. After a template or runtime change, ``python tests/reserved_probe.py > generator/drivemap/vocab/reserved.py``
writes this file anew.

* ``module``: every name bound at module level of a generated ``client.py`` / ``__init__.py``
  (imports, classes, constants) besides the map's own classes;
* ``annotation``: builtins named in annotations inside the generated classes;
* ``client``: every attribute of a generated client besides its registers;
* ``outputs``: per built-in exporter, the files of one model (``{model}`` for its id) and the files
  written once for all models;
* ``headings``: the anchors of the fixed headings of a model's docs page.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RESERVED", "Reserved", "reserved"]


@dataclass(frozen=True)
class Reserved:
    module: frozenset[str]
    annotation: frozenset[str]
    client: frozenset[str]
    outputs: tuple[tuple[str, frozenset[str], frozenset[str]], ...]
    """(exporter, files of one model with ``{model}`` for its id, files written once for all models)"""
    headings: frozenset[str]


RESERVED = Reserved(
    module=frozenset({
        'AccessError', 'Any', 'AsyncBroadcastClient', 'AsyncBus', 'AsyncClient', 'AsyncClientBase',
        'AsyncCommand', 'AsyncReadOnly', 'AsyncReadOnlyArray', 'AsyncReadWrite', 'AsyncReadWriteArray',
        'AsyncReadWriteCommand', 'AsyncWriteOnly', 'AsyncWriteOnlyArray', 'BoolCodec', 'BroadcastArrayReg',
        'BroadcastClient', 'BroadcastCommandReg', 'BroadcastRead', 'BroadcastReg', 'Bus', 'CODECS', 'Client',
        'ClientBase', 'Codec', 'Codecs', 'Command', 'CommandReg', 'Core', 'DEFAULT_BAUDRATE',
        'DEFAULT_BROADCAST_GAP_MS', 'DEFAULT_RESPONSE_TIMEOUT_S', 'DEFAULT_RETRIES', 'DeviceException',
        'DriveEnum', 'DriveError', 'DriveTimeout', 'EXCEPTIONS', 'EnumCodec', 'Exchange', 'Field',
        'FieldsCodec', 'FlagCodec', 'FloatCodec', 'IdentityMismatch', 'IeeeCodec', 'IndexOutOfRange',
        'InexactValue', 'IntCodec', 'InvalidArgument', 'InvalidValue', 'Mapping', 'MisalignedRequest',
        'NotAllowedValue', 'NotBroadcastable', 'OpenForReview', 'OptionalCodec', 'PagePolicy', 'PartialWrite',
        'RawCodec', 'ReadOnly', 'ReadOnlyArray', 'ReadOnlyArrayReg', 'ReadOnlyReg', 'ReadOnlyRegister',
        'ReadWrite', 'ReadWriteArray', 'ReadWriteArrayReg', 'ReadWriteCommand', 'ReadWriteCommandReg',
        'ReadWriteReg', 'Reg', 'ReviewWarning', 'RunningWriteWarning', 'SPEC', 'STEP_TOLERANCE',
        'ScaleUnavailable', 'ScaledCodec', 'Snapshot', 'SnapshotBase', 'Stats', 'StringCodec', 'TYPE_BOUNDS',
        'TransportError', 'UnknownRegister', 'UnsupportedFunction', 'ValueOutOfRange', 'WriteOnly',
        'WriteOnlyArray', 'WriteOnlyArrayReg', 'WriteOnlyReg', 'WriteOnlyRegister', 'WrongPage',
        '_BroadcastRegisters', '_Registers', '__all__', 'allowed_text', 'annotations', 'broadcast_refusal',
        'broadcast_unit', 'check_raw', 'check_values', 'codec_for', 'codecs_for', 'display_text', 'enum',
        'exact_raw', 'join_words', 'kind_of', 'number_text', 'raw_bounds', 'raw_to_words', 'record',
        'register_text', 'reply_mismatch', 'shortest_f32_text', 'sleep_until', 'snapshot', 'split_words',
        'unwrap', 'words_to_raw',
    }),
    annotation=frozenset({
        'bool', 'float', 'int', 'str', 'tuple',
    }),
    client=frozenset({
        'CODECS', 'EXCEPTIONS', 'SNAPSHOT', 'SPEC', '_drivemap', '_is_protocol', 'accessor',
        'apply_configuration', 'broadcast', 'bus', 'close', 'connect', 'holes', 'loopback', 'page_policy',
        'pending_configuration', 'pending_power_cycle', 'plan', 'read', 'read_all', 'read_by_name',
        'read_modify_write', 'read_registers', 'registers', 'rtu_over_tcp', 'serial', 'stats', 'tcp', 'unit',
        'write_by_name', 'write_many',
    }),
    outputs=(
        ('csv', frozenset({
            '{model}.csv',
        }), frozenset({
        })),
        ('docs', frozenset({
            '{model}.md',
        }), frozenset({
            'index.md',
        })),
        ('esphome', frozenset({
            '{model}.esphome.yaml',
        }), frozenset({
        })),
        ('homeassistant', frozenset({
            '{model}.homeassistant.yaml',
        }), frozenset({
        })),
        ('json', frozenset({
            '{model}.json',
        }), frozenset({
        })),
        ('pymodbus-sim', frozenset({
            '{model}.pymodbus-sim.json',
        }), frozenset({
        })),
        ('python', frozenset({
            '{model}/__init__.py', '{model}/client.py', '{model}/simulator.py', '{model}/spec.py',
        }), frozenset({
            '__init__.py', 'py.typed',
        })),
    ),
    headings=frozenset({
        'alignment', 'bit-fields', 'checksum', 'communication-error-codes', 'configuration-command',
        'connection', 'contents', 'device-and-manual', 'enums', 'examples', 'exception-codes',
        'function-codes', 'how-to-use-it', 'identity', 'known-issues-in-this-manual', 'protocol', 'registers',
        'reply-quirks', 'reserved-and-unlisted-addresses', 'running-state', 'timing',
        'what-the-device-answers',
    }),
)


def reserved() -> Reserved:
    """The reserved names and files (:data:`RESERVED`)."""
    return RESERVED
