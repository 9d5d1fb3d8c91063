"""The flat DeviceSpec of releases before 0.2 (removed in drivemap 1.0, :data:`drivemap._compat.REMOVAL`).

A ``spec.py`` printed by an earlier release calls ``DeviceSpec(model=..., title=..., modes=..., ...)``
and code of that time reads ``SPEC.timing``; today's record nests them (``SPEC.device``,
``SPEC.protocol``). :mod:`drivemap.runtime.spec` hands both forms here. The runtime's classes are
passed in, so this module imports nothing of drivemap.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable
from typing import Any

from drivemap._compat import REMOVAL

#: The protocol's methods that earlier releases had on the DeviceSpec itself.
PROTOCOL_METHODS = ("valid_unit", "function", "policy", "comm_policy", "exception")


def moved_attributes(protocol_fields: Iterable[str]) -> dict[str, str]:
    """flat attribute -> the part of the DeviceSpec that holds it now (``device`` or ``protocol``)."""
    return {"model": "device", "title": "device",
            **{f: "protocol" for f in protocol_fields}, **{m: "protocol" for m in PROTOCOL_METHODS}}


def warn_flat_form() -> None:
    warnings.warn("DeviceSpec(model=..., modes=..., ...) is the form of an earlier release; run `drivemap build` "
                  f"to write the current one (the flat form goes in drivemap {REMOVAL})", DeprecationWarning,
                  stacklevel=3)


def warn_flat_attribute(name: str, part: str) -> None:
    warnings.warn(f"DeviceSpec.{name} is now DeviceSpec.{part}.{name}", DeprecationWarning, stacklevel=3)


def split_flat(flat: dict[str, object], product: Callable[[str, str], Any], protocol: Callable[..., Any],
               command: Callable[..., Any], running_state: Callable[..., Any],
               reply_quirk: type) -> tuple[Any, Any]:
    """The device and protocol of a flat DeviceSpec (tuples where now classes are), built with the
    runtime's classes ``product``, ``protocol``, ``command``, ``running_state`` and ``reply_quirk``."""
    given = dict(flat)
    device = product(str(given.pop("model")), str(given.pop("title")))
    configuration, running = given.get("configuration"), given.get("running_state")
    if isinstance(configuration, tuple):
        given["configuration"] = command(*configuration)
    if isinstance(running, tuple):
        given["running_state"] = running_state(*running)
    quirks: Iterable[object] = given.get("reply_quirks", ())  # type: ignore[assignment]
    given["reply_quirks"] = tuple(q if isinstance(q, reply_quirk) else reply_quirk(str(q)) for q in quirks)
    return device, protocol(**given)
