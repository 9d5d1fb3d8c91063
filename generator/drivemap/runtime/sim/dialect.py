"""The Modbus standard's answers a simulator falls back on where the map names none: the exception
code per error case, the largest quantity per function code, the table each read code reads."""

from __future__ import annotations

__all__ = ["CASES", "FALLBACK", "READ_TABLES", "STANDARD_CODES", "STANDARD_MAX_QUANTITY"]

#: The standard exception code of each error case.
STANDARD_CODES: dict[str, int] = {
    "illegal_function": 0x01,
    "illegal_address": 0x02,
    "illegal_quantity": 0x03,
    "out_of_range": 0x03,
    "read_only": 0x02,
    "write_only": 0x02,
    "busy": 0x06,
    "bad_length": 0x03,
}
CASES = tuple(STANDARD_CODES)
FALLBACK = {
    "write_only": "illegal_address",
    "read_only": "illegal_address",
    "bad_length": "illegal_quantity",
    "busy": "out_of_range",
}
#: Largest quantity a standard Modbus PDU can carry, per function code (when the map gives none).
STANDARD_MAX_QUANTITY = {0x01: 2000, 0x02: 2000, 0x03: 125, 0x04: 125, 0x06: 1, 0x0F: 1968, 0x10: 123}
#: The table each read function code reads.
READ_TABLES = {0x01: "coil", 0x02: "discrete", 0x03: "holding", 0x04: "input"}
