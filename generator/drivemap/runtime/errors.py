"""Every error a drivemap client raises: one hierarchy under :class:`DriveError`.

Errors about the caller's input (:class:`InvalidValue`, :class:`ValueOutOfRange`,
:class:`InvalidArgument`, :class:`IndexOutOfRange`, :class:`ReadOnlyRegister`,
:class:`WriteOnlyRegister`, :class:`NotBroadcastable`, :class:`BroadcastRead`, :class:`WrongPage`,
:class:`UnknownRegister`, :class:`NotAllowedValue`, :class:`MisalignedRequest`) are raised *before* any byte is sent. :class:`DeviceException` carries an exception reply of the device; generated
packages subclass it once per exception code of their map.
"""

from __future__ import annotations

from typing import ClassVar


class DriveError(Exception):
    """Base class of every error raised by a drivemap client."""


class InvalidValue(DriveError, TypeError):
    """The value has the wrong type for the register (e.g. ``str`` for a number, ``int`` for an enum)."""


class ValueOutOfRange(DriveError, ValueError):
    """The value lies outside the register's documented range or its raw type."""


class NotAllowedValue(ValueOutOfRange):
    """A value outside the register's value set (``values:`` in the map); ``allowed`` lists the set."""

    def __init__(self, message: str, allowed: tuple[object, ...] = ()) -> None:
        super().__init__(message)
        self.allowed = allowed


class MisalignedRequest(DriveError, ValueError):
    """A request that breaks an alignment rule of the map (``protocol.alignment``): a start address or
    quantity the device refuses, or part of a multi-word value."""


class InexactValue(ValueOutOfRange):
    """The value lies between two steps of the register's resolution (its scale, offset or scale
    factor): it is refused, never rounded. ``nearest`` holds the representable values either side
    (within the register's range), ``rounded`` the nearer one (half away from zero) or None, and
    ``rounded_raw`` its raw value: what an explicit rounding (``drivemap write --round``) sends."""

    def __init__(self, message: str, nearest: tuple[float, ...] = (), rounded: float | None = None,
                 rounded_raw: int | None = None) -> None:
        super().__init__(message)
        self.nearest = nearest
        self.rounded = rounded
        self.rounded_raw = rounded_raw


class InvalidArgument(DriveError, ValueError):
    """An argument that is none of the values the call accepts (e.g. ``page_policy``, a serial setting)."""


class IndexOutOfRange(DriveError, IndexError):
    """An array element index outside ``0 .. count - 1`` (negative indexes included)."""


class AccessError(DriveError):
    """The register cannot be accessed this way."""


class ReadOnlyRegister(AccessError):
    """A write to a register the map marks read-only."""


class WriteOnlyRegister(AccessError):
    """A read of a register the map marks write-only."""


class OpenForReview(AccessError):
    """A write to a register whose map leaves a field that decides the written words open (its
    ``review:`` list names it): nothing is sent. ``register`` is its name, ``fields`` the open fields."""

    def __init__(self, register: str, fields: tuple[str, ...], raw: int | None = None) -> None:
        self.register = register
        self.fields = fields
        what = (f"raw value {raw} reads differently signed and unsigned, and its map leaves signedness open"
                if raw is not None else f"its map leaves {', '.join(fields)} open")
        super().__init__(f"{register} is not written: {what} for review (review: [{', '.join(fields)}]); state "
                         f"{'them' if len(fields) > 1 else 'it'} in the map and remove the review item first")


class ReviewWarning(UserWarning):
    """A register whose map leaves a field that decides its value open (``review:``) was read: the
    value may be wrong. Given once per register and client."""


class NotBroadcastable(AccessError):
    """A broadcast write to a register whose function code the map does not allow for broadcast."""


class BroadcastRead(AccessError):
    """A read on a broadcast client (a broadcast is never answered)."""


class WrongPage(AccessError):
    """A paged register was read while its page selector shows another page (``page_policy="raise"``)."""


class IdentityMismatch(DriveError):
    """The device that answers is not the one the map describes: an identity register (the map's
    ``identity``) holds another value. Raised before anything is written."""

    def __init__(self, message: str, mismatches: tuple[object, ...] = ()) -> None:
        super().__init__(message)
        self.mismatches = mismatches


class UnknownRegister(DriveError, KeyError):
    """``read_by_name`` / ``write_by_name`` with a name the map does not define."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "unknown register"


class UnsupportedFunction(DriveError):
    """The operation needs a function code the map does not list."""


class TransportError(DriveError):
    """The transport failed (not connected, connection lost, malformed reply)."""


class DriveTimeout(TransportError, TimeoutError):
    """No valid reply after the last retry."""


class ScaleUnavailable(DriveError):
    """A register scaled by a scale-factor register (``scale_register``) cannot be given a value: its
    factor reads as one of its not-available values, is not a plausible power of ten, or was not read.

    The client never scales by a remembered or missing factor; it raises this instead.
    """


class PartialWrite(DriveError):
    """A write that needed several requests stopped part-way: what was and was not written.

    Element names (``"digital_speed[3]"``), in the order written:

    * ``written``: confirmed by the device's reply (or sent, for a broadcast);
    * ``maybe_written``: in the request that got no valid reply (timeout, transport error): the
      device may or may not have applied it;
    * ``not_written``: refused by the device (exception reply) or never sent, because the write
      stops at the first failing request.

    ``error`` (also ``__cause__``) is the error of the failing request.
    """

    def __init__(self, error: DriveError, *, written: tuple[str, ...], maybe_written: tuple[str, ...],
                 not_written: tuple[str, ...]) -> None:
        self.error = error
        self.written = written
        self.maybe_written = maybe_written
        self.not_written = not_written
        parts = [f"written: {', '.join(written) or '-'}"]
        if maybe_written:
            parts.append(f"unconfirmed: {', '.join(maybe_written)}")
        parts.append(f"not written: {', '.join(not_written) or '-'}")
        super().__init__(f"write incomplete ({'; '.join(parts)}): {error}")


class DeviceException(DriveError):
    """An exception reply of the device: ``code`` with the map's ``name`` and ``meaning``.

    Generated packages define one subclass per exception code of the map (class attributes
    ``CODE``, ``NAME``, ``MEANING``); codes the map does not list raise this class itself.
    """

    CODE: ClassVar[int | None] = None
    NAME: ClassVar[str] = "unknown"
    MEANING: ClassVar[str] = "exception code not listed in the map"

    def __init__(self, code: int, function_code: int, *, name: str | None = None, meaning: str | None = None) -> None:
        self.code = code
        self.function_code = function_code
        self.name = name if name is not None else self.NAME
        self.meaning = meaning if meaning is not None else self.MEANING
        super().__init__(f"device answered exception 0x{code:02X} ({self.name}) to function 0x{function_code:02X}: {self.meaning}")


class RunningWriteWarning(UserWarning):
    """A register the manual advises against writing while the drive runs was written while it reported
    running (the map's ``running_advice``). A Python warning, not an error: the manual only advises, the
    device is not known to refuse. ``warnings.simplefilter("error", RunningWriteWarning)`` makes it an
    error (raised before the write is sent), ``"ignore"`` silences it."""


__all__ = [
    "AccessError",
    "BroadcastRead",
    "DeviceException",
    "DriveError",
    "DriveTimeout",
    "IdentityMismatch",
    "IndexOutOfRange",
    "InexactValue",
    "InvalidArgument",
    "InvalidValue",
    "MisalignedRequest",
    "NotAllowedValue",
    "NotBroadcastable",
    "OpenForReview",
    "PartialWrite",
    "ReadOnlyRegister",
    "ReviewWarning",
    "RunningWriteWarning",
    "ScaleUnavailable",
    "TransportError",
    "UnknownRegister",
    "UnsupportedFunction",
    "ValueOutOfRange",
    "WriteOnlyRegister",
    "WrongPage",
]
