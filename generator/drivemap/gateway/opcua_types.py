"""OPC UA data types and engineering units of registers (no asyncua import: testable without the extra).

Variant types follow the register: an integer register read in whole units (scale 1, no offset)
keeps its width and sign (u16 -> UInt16, s16 -> Int16, u32 -> UInt32, s32 -> Int32, u64 ->
UInt64, s64 -> Int64); enumerated registers carry their raw value in the same type; bit-field
registers their raw bits unsigned (UInt16 / UInt32 / UInt64 by width); an integer register with a
whole scale other than 1 or an offset is Int64; fractional values are Double; an unscaled f32 is
Float; strings String; coils, discrete inputs and bools Boolean.

``EngineeringUnits`` carry the UNECE Recommendation 20 common code of the unit as OPC UA's
``UnitId`` (Part 8: the code's ASCII characters packed into an integer, first character highest)
with the namespace ``http://www.opcfoundation.org/UA/units/un/cefact``; a unit without a common
code (VAh, varh, %/s ...) has UnitId -1 and its symbol as the display name.
"""

from __future__ import annotations

from drivemap.model.nodes import Register

CEFACT = "http://www.opcfoundation.org/UA/units/un/cefact"

#: The units of the shipped maps (and their usual spellings) -> UNECE Rec. 20 common code.
UNECE: dict[str, str] = {
    "V": "VLT", "mV": "2Z", "kV": "KVT",
    "A": "AMP", "mA": "4K",
    "Hz": "HTZ",
    "W": "WTT", "kW": "KWT",
    "Wh": "WHR", "kWh": "KWH",
    "VA": "D46", "kVA": "KVA",
    "var": "D44", "VAr": "D44", "kvar": "KVR", "kVAr": "KVR",
    "kVAh": "C79", "kvarh": "K3", "kVArh": "K3",
    "Ah": "AMH",
    "r/min": "M46", "rpm": "M46",
    "%": "P1",
    "°C": "CEL", "℃": "CEL", "degC": "CEL",
    "°": "DD", "deg": "DD",
    "s": "SEC", "ms": "C26", "min": "MIN", "h": "HUR",
    "Ω": "OHM",
}

_SIGNED = {"s16": "Int16", "s32": "Int32", "s64": "Int64"}
_UNSIGNED = {"u16": "UInt16", "u32": "UInt32", "u64": "UInt64"}
_BITS_BY_WORDS = {1: "UInt16", 2: "UInt32", 4: "UInt64"}


def unit_id(unit: str | None) -> int:
    """OPC UA's UnitId of a unit: its UNECE common code packed into an integer, or -1."""
    code = UNECE.get(unit or "")
    if code is None:
        return -1
    value = 0
    for c in code:
        value = (value << 8) | ord(c)
    return value


def variant_name(reg: Register) -> str:
    """The name of the ``ua.VariantType`` of a register's value (see the module's rules)."""
    if reg.type == "bool":
        return "Boolean"
    if reg.type == "string":
        return "String"
    if reg.bits:
        words = {"u16": 1, "s16": 1, "u32": 2, "s32": 2, "u64": 4, "s64": 4}.get(reg.type, 4)
        return _BITS_BY_WORDS[words]
    if reg.type == "f32" and reg.scale == 1 and not reg.offset and reg.scale_register is None:
        return "Float"
    whole = reg.scale == 1 and not reg.offset and reg.scale_register is None
    if (reg.enum or reg.is_integer) and whole and reg.type in {**_SIGNED, **_UNSIGNED}:
        return {**_SIGNED, **_UNSIGNED}[reg.type]
    if reg.enum or reg.is_integer:
        return "Int64"
    return "Double"
