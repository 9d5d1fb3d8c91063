"""Is the device that answers the one the map describes? The map's ``identity`` checks, at run time.

A map may name registers and the values that identify its device or family (``identity:`` in the
map, :class:`~drivemap.runtime.spec.IdentitySpec` in the generated spec). :func:`identity_mismatches`
judges raw values already read (no I/O); :func:`check_identity` and :func:`check_identity_async`
read the identity registers through a generated client (sync or async) and raise
:class:`~drivemap.runtime.errors.IdentityMismatch` naming each register with the value the device
holds and the value the map expects. A program calls it once per connection before it writes::

    client = Client.tcp("10.0.0.5", unit=1)
    check_identity(client)          # raises IdentityMismatch if another device answers

Integers are compared with the raw register value (before any scale); texts with the string
register's text (trailing NUL and space stripped). A map without ``identity`` passes (nothing to
check): :func:`has_identity` tells the two apart.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from drivemap.runtime.client.values.codec import StringCodec, unwrap
from drivemap.runtime.errors import IdentityMismatch
from drivemap.runtime.spec import DeviceSpec, IdentitySpec
from drivemap.runtime.types import expected_text, show_value

Key = tuple[str, int]


@dataclass(frozen=True)
class Mismatch:
    """One identity register whose value is not what the map expects."""

    register: str
    address: int
    table: str
    expected: str
    actual: str
    source: str

    def __str__(self) -> str:
        return (f"{self.register} ({self.table} 0x{self.address:04X}) holds {self.actual}; "
                f"the map expects {self.expected} ({self.source})")


def has_identity(spec: DeviceSpec) -> bool:
    return bool(spec.identity)


def identity_keys(spec: DeviceSpec) -> tuple[Key, ...]:
    """The register cells the checks read (element 0 of each register, in map order, once each)."""
    return tuple(dict.fromkeys((check.register, 0) for check in spec.identity))


def _actual(codecs: Mapping[str, Any] | None, name: str, raw: int) -> int | str:
    codec = unwrap(codecs[name]) if codecs is not None and name in codecs else None
    if isinstance(codec, StringCodec):
        return codec.decode(raw)
    return raw


def _matches(check: IdentitySpec, value: int | str) -> bool:
    if check.kind in ("equals", "one_of"):
        return value in check.values
    if not isinstance(value, str):
        return False
    pattern = check.values[0]
    assert isinstance(pattern, str)
    if check.kind == "prefix":
        return value.startswith(pattern)
    return re.fullmatch(pattern, value) is not None


def identity_mismatches(spec: DeviceSpec, raws: Mapping[Key, int],
                        codecs: Mapping[str, Any] | None = None) -> tuple[Mismatch, ...]:
    """The checks of ``spec.identity`` that the raw values ``raws`` fail (``codecs``: the generated
    client's ``CODECS``, which turn a string register's raw value into its text)."""
    out = []
    for check in spec.identity:
        reg = spec.register(check.register)
        value = _actual(codecs, check.register, raws[(check.register, 0)])
        if not _matches(check, value):
            out.append(Mismatch(check.register, reg.address, getattr(reg, "table", "holding"),
                                expected_text(check.kind, check.values), show_value(value), check.source))
    return tuple(out)


def _raise(spec: DeviceSpec, unit: int, found: tuple[Mismatch, ...]) -> None:
    if found:
        lines = "; ".join(str(m) for m in found)
        raise IdentityMismatch(f"unit {unit} is not a {spec.name}: {lines}", found)


def _client(client_or_session: Any) -> Any:
    """A generated client, or the client of anything that holds one (a live session: ``.client``)."""
    return client_or_session if hasattr(client_or_session, "_drivemap") else client_or_session.client


def check_identity(client_or_session: Any, *, raise_on_mismatch: bool = True) -> tuple[Mismatch, ...]:
    """Read the identity registers through a generated sync client (or a live session's) in the
    planned reads and raise :class:`IdentityMismatch` if the device is not the map's
    (``raise_on_mismatch=False``: return the mismatches instead); () when it is, or when the map
    names no identity. Transport errors and exception replies propagate as from any read."""
    client = _client(client_or_session)
    spec: DeviceSpec = client.SPEC
    if not spec.identity:
        return ()
    raws = client._drivemap.read_raw_keys(identity_keys(spec))
    found = identity_mismatches(spec, raws, getattr(client, "CODECS", None))
    if raise_on_mismatch:
        _raise(spec, client.unit, found)
    return found


async def check_identity_async(client_or_session: Any, *, raise_on_mismatch: bool = True) -> tuple[Mismatch, ...]:
    """:func:`check_identity` for a generated async client (or anything holding one as ``.client``)."""
    client = _client(client_or_session)
    spec: DeviceSpec = client.SPEC
    if not spec.identity:
        return ()
    raws = await client._drivemap.read_raw_keys(identity_keys(spec))
    found = identity_mismatches(spec, raws, getattr(client, "CODECS", None))
    if raise_on_mismatch:
        _raise(spec, client.unit, found)
    return found


__all__ = ["Mismatch", "check_identity", "check_identity_async", "expected_text", "has_identity", "show_value", "identity_keys",
           "identity_mismatches"]
