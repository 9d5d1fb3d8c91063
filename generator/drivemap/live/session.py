"""A connected client of one model on one link, and the reads the live verbs share.

The reads go through the generated client's runtime (:mod:`drivemap.runtime.client.api.sync_client`): the same
planner, codecs, page handling, timing and retries as a program using the client. Raw words for
addresses the map does not name (reserved ranges, probes) go through :meth:`Bus.exchange`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from typing import Any

from drivemap.device.connection import Link, open_bus, resolve_link, run
from drivemap.device.errors import EXIT_IDENTITY, EXIT_INPUT, LiveError
from drivemap.device.target import Target
from drivemap.model.nodes import Register
from drivemap.runtime.client.api.identity import Mismatch, identity_keys, identity_mismatches
from drivemap.runtime.client.protocol.planner import Key, ReadRequest, read_function
from drivemap.runtime.client.protocol.sansio import READ_REQUESTS, Core
from drivemap.runtime.client.protocol.sansio import run as run_program
from drivemap.runtime.client.transport.bus import Bus, Exchange
from drivemap.runtime.errors import DriveError
from drivemap.runtime.spec import READ_CODES


class Session:
    """``with Session(target, link) as s:`` -- a connected client (``s.client``) and its bus.

    ``identity``: what to do, once per connection, with the map's identity checks
    (:func:`check_identity`): ``"refuse"`` (a device that does not match is an error before
    anything is sent to it), ``"warn"`` (one line on stderr; ``s.identity`` keeps the mismatches) or
    ``"off"``."""

    def __init__(self, target: Target, link: Link, *, switch_pages: bool = False, identity: str = "warn") -> None:
        self.target = target
        self.link = link
        self.page_policy = "switch" if switch_pages else "raise"
        self.identity_mode = identity
        self.identity: tuple[Mismatch, ...] = ()
        self.bus: Bus | None = None
        self.client: Any = None

    def __enter__(self) -> Session:
        check_unit(self.target, self.link.unit)
        self.bus = open_bus(self.link)
        self.client = self.target.client_class(self.bus, self.link.unit, page_policy=self.page_policy)
        if self.identity_mode != "off":
            try:
                self.identity = check_identity(self)
            except BaseException:
                self.bus.close()
                raise
            if self.identity and self.identity_mode == "refuse":
                self.bus.close()
                raise LiveError(EXIT_IDENTITY, identity_message(self) + "; nothing was written "
                                "(--no-identity-check writes anyway)")
            if self.identity:
                print(f"warning: {identity_message(self)}", file=sys.stderr)
        return self

    def __exit__(self, *exc: object) -> None:
        if self.bus is not None:
            self.bus.close()

    @property
    def core(self) -> Core:
        core: Core = self.client._drivemap.core
        return core

    def call(self, what: str, func: Any, *args: Any) -> Any:
        """``func(*args)``; a failure becomes one actionable line (:func:`connection.explain`)."""
        assert self.bus is not None
        return run(self.bus, self.link, self.target, what, func, *args)

    # -- reads
    def read_keys(self, keys: Sequence[Key]) -> dict[Key, int]:
        """Raw values of ``keys`` in the fewest requests the map allows (the client's planner), with
        the scale-factor registers of scaled ones read in the same pass (``fmt.decode`` needs them)."""
        factors = {self.target.codecs[name].scale_key for name, _ in keys} - {None} - set(keys)
        return self.client._drivemap.read_raw_keys(tuple(keys) + tuple(sorted(factors)))  # type: ignore[no-any-return]

    def read_request(self, request: ReadRequest) -> dict[Key, int]:
        """Raw values of one planned request, exactly as planned."""
        keys = [key for key, _ in request.cells]
        assert self.bus is not None
        return run_program(self.bus, self.core.read_raw(keys, (request,), checked=True))

    def read_words(self, address: int, count: int, table: str = "holding") -> list[int]:
        """``count`` words (bits) at ``address`` of ``table`` with its read function (no register
        needed there: probes of what the map calls reserved or unreadable go out as asked)."""
        assert self.bus is not None
        code = read_function(self.core.spec, table) or READ_CODES[table]
        return read_words(self.bus, self.core, address, count, code)


def check_identity(session: Session) -> tuple[Mismatch, ...]:
    """The map's identity checks against the connected device (one read; () when all match or the
    map names none). Callable by any holder of a live session or generated client: gateways too."""
    spec = session.target.spec
    if not spec.identity:
        return ()
    raws = session.call("reading the identity registers", session.client._drivemap.read_raw_keys, identity_keys(spec))
    return identity_mismatches(spec, raws, session.target.codecs)


def identity_message(session: Session) -> str:
    return (f"unit {session.link.unit} is not a {session.target.model.name}: "
            + "; ".join(str(m) for m in session.identity))


def check_unit(target: Target, unit: int) -> None:
    """A unit id the map does not allow is a command-line error (before opening anything)."""
    spec = target.spec
    if not spec.protocol.valid_unit(unit):
        fixed = f" (or fixed port units {', '.join(map(str, spec.protocol.fixed_units))})" if spec.protocol.fixed_units else ""
        raise LiveError(EXIT_INPUT, f"--unit {unit}: outside {target.model.name}'s unit ids "
                                    f"{spec.protocol.unit_min}..{spec.protocol.unit_max}{fixed}")


def read_words(bus: Bus, core: Core, address: int, count: int, code: int | None = None) -> list[int]:
    code = code if code is not None else read_function(core.spec) or 0x03
    cls = READ_REQUESTS[code]
    reply = core.raise_for(bus.exchange(Exchange(core.unit, cls(address=address, count=count), core.spec.protocol.timing)), code)
    if code <= 0x02:
        return [1 if b else 0 for b in reply.bits[:count]]
    return list(reply.registers)


def session_for(args: argparse.Namespace, target: Target, identity: str = "warn") -> Session:
    """The verb's session; ``identity``: the verb's answer to a device that does not match its map
    (``--no-identity-check`` turns the check off)."""
    mode = "off" if getattr(args, "no_identity_check", False) else identity
    return Session(target, resolve_link(args, target), switch_pages=getattr(args, "switch_pages", False), identity=mode)


def keys_of(cells: Iterable[tuple[Register, int]]) -> list[Key]:
    return [(reg.name, index) for reg, index in cells]


def describe_keys(target: Target, keys: Sequence[Key], limit: int = 4) -> str:
    names = [target.model.register(n).element_name(i) for n, i in keys]
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit else "")


__all__ = ["DriveError", "Session", "check_identity", "describe_keys", "keys_of", "read_words", "session_for"]
