"""The register descriptor every client class declares its registers with (:class:`Reg`).

Its kinds of accessor (read-only, array, command ...) are in :mod:`.declare`; the client bases find a
class's registers by this class (:meth:`~.machinery.ClassMachinery.registers`), so it sits below both.
"""

from __future__ import annotations

from typing import Any, Generic, TypeVar

__all__ = ["Reg"]

T = TypeVar("T")


class Reg(Generic[T]):
    """A register of a client class: makes (once per client) and returns its accessor.

    ``kind`` names the accessor: ``r``, ``w``, ``rw``, ``cmd`` (write-only command), ``rwcmd``,
    ``r[]``, ``w[]``, ``rw[]`` (arrays); broadcast clients use ``w``, ``cmd`` and ``w[]``.
    """

    kind: str = ""
    name: str = ""

    def __init__(self, doc: str | None = None) -> None:
        if doc is not None:
            self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        if type(self).__doc__ is self.__doc__:  # no docstring of its own: point at the client's
            self.__doc__ = f"{name} (see Client.{name})."

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}>"

    def _bind(self, client: Any) -> Any:
        accessor = client._drivemap.ACCESSORS[self.kind](client, client.CODECS[self.name])
        accessor.__doc__ = self.__doc__
        client.__dict__[self.name] = accessor  # later lookups find the accessor, not this descriptor
        return accessor
