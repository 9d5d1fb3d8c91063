"""How map names become Python names (pure rules the compiler and the runtime share).

The python back end writes these names into generated clients; the runtime uses the same rules
when it builds a client class from a spec (:func:`drivemap.runtime.client.api.dynamic.client_package`),
so both give the same classes.
"""

from __future__ import annotations

import keyword
from collections.abc import Sequence

__all__ = ["FIXED_NAMES", "UNKNOWN_MEMBER", "bit_attribute", "camel", "exception_class", "exception_classes"]

#: Names every generated package defines itself. An exception class equal to one of them takes
#: its code as a suffix (kept so that generated names stay what they have been); the checks refuse
#: every other clash with the names the templates import and define.
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


def camel(name: str) -> str:
    """``digital_speed_ram`` -> ``DigitalSpeedRam``."""
    return "".join(part[:1].upper() + part[1:] for part in name.split("_") if part)


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
