"""The client runtime, by layer as pymodbus is: :mod:`.values` (words <-> values), :mod:`.transport`
(buses and exchanges), :mod:`.protocol` (the sans-I/O core, plans, programs) and :mod:`.api` (the
client bases, accessors and descriptors generated clients are made of); each imports only the layers
below it (an import-linter contract).

The package re-exports the client classes of :mod:`.api.sync_client` (the import path generated code uses).
"""

from drivemap.runtime.client.api.sync_client import (
    AsyncBus,
    AsyncClientBase,
    AsyncCommand,
    AsyncReadOnly,
    AsyncReadOnlyArray,
    AsyncReadWrite,
    AsyncReadWriteArray,
    AsyncReadWriteCommand,
    AsyncWriteOnly,
    AsyncWriteOnlyArray,
    Bus,
    ClientBase,
    Command,
    Core,
    DriveError,
    PagePolicy,
    PartialWrite,
    ReadOnly,
    ReadOnlyArray,
    ReadWrite,
    ReadWriteArray,
    ReadWriteCommand,
    SnapshotBase,
    Stats,
    WriteOnly,
    WriteOnlyArray,
    broadcast_refusal,
    broadcast_unit,
)

__all__ = [
    "AsyncBus",
    "AsyncClientBase",
    "AsyncCommand",
    "AsyncReadOnly",
    "AsyncReadOnlyArray",
    "AsyncReadWrite",
    "AsyncReadWriteArray",
    "AsyncReadWriteCommand",
    "AsyncWriteOnly",
    "AsyncWriteOnlyArray",
    "Bus",
    "ClientBase",
    "Command",
    "Core",
    "DriveError",
    "PagePolicy",
    "PartialWrite",
    "ReadOnly",
    "ReadOnlyArray",
    "ReadWrite",
    "ReadWriteArray",
    "ReadWriteCommand",
    "SnapshotBase",
    "Stats",
    "WriteOnly",
    "WriteOnlyArray",
    "broadcast_refusal",
    "broadcast_unit",
]
