"""How map names become generated names (pure rules, shared by the checks and the client view).

The checks (:mod:`drivemap.backends.python.namecheck`) refuse a map whose generated names collide; the client view
(:mod:`drivemap.backends.views.client`) applies the same rules to write them.
"""

from __future__ import annotations

import keyword
from collections.abc import Sequence

from drivemap.model.nodes import camel

__all__ = ["FIXED_NAMES", "UNKNOWN_MEMBER", "bit_attribute", "exception_class", "exception_classes"]

#: Names every generated package defines itself. An exception class equal to one of them takes
#: its code as a suffix (kept so that generated names stay what they have been); the checks refuse
#: every other clash with the names the templates import and define (:mod:`drivemap.backends.python.reserved`).
FIXED_NAMES = frozenset({
    "Client", "AsyncClient", "BroadcastClient", "AsyncBroadcastClient", "Snapshot", "Bus", "AsyncBus", "SPEC",
    "EXCEPTIONS", "CODECS", "DriveError", "DeviceException", "DriveTimeout", "ValueOutOfRange", "ReadOnlyRegister",
    "WriteOnlyRegister", "WrongPage", "NotBroadcastable", "BroadcastRead", "InvalidValue", "UnknownRegister",
    "UnsupportedFunction", "TransportError", "AccessError", "Stats", "PagePolicy", "DriveEnum", "PartialWrite",
    "ScaleUnavailable", "IndexOutOfRange", "InvalidArgument",
})

#: Prefix of the pseudo-members a generated enum makes for values the map does not name
#: (``MotorState(99)`` reads as ``UNKNOWN_99``); map members may not look like them.
UNKNOWN_MEMBER = "UNKNOWN_"


def bit_attribute(name: str) -> str:
    """The dataclass attribute of an UPPER_CASE bit name: lower case, keywords get a trailing underscore."""
    low = name.lower()
    return low + "_" if keyword.iskeyword(low) or keyword.issoftkeyword(low) else low


def exception_class(name: str) -> str:
    """``illegal_function`` -> ``IllegalFunctionError``."""
    cls = camel(name)
    if not cls[:1].isalpha():
        cls = "Code" + cls
    return cls if cls.endswith("Error") else cls + "Error"


def exception_classes(exceptions: Sequence[tuple[str, int]]) -> list[str]:
    """The class of each (name, code): :func:`exception_class`, with the code as a suffix when that
    class is taken by an earlier exception or by the package (``A03Error``). The result can still
    repeat a name (``a`` code 3 after ``a_03``); the checks refuse such a map."""
    used: set[str] = set()
    out = []
    for name, code in exceptions:
        cls = exception_class(name)
        if cls in used or cls in FIXED_NAMES:
            cls = f"{cls[:-5]}{code:02X}Error"
        used.add(cls)
        out.append(cls)
    return out
