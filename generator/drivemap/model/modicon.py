"""Modicon register numbers (``30001``, ``400001``) <-> table + protocol address.

Many manuals print only the Modicon number: 1-based, with the table as the first digit (0xxxx
coils, 1xxxx discrete inputs, 3xxxx input registers, 4xxxx holding registers). Five-digit numbers
reach address 9998 (``49999``); six-digit numbers (``400001`` .. ``465536``) the whole space.
``30001`` is input register address 0: the off-by-one between the two notations is the most common
transcription error, so the compiler converts and cross-checks, and the docs print both forms.

An integer loses leading zeros, so an integer below 10000 is a five-digit coil number
(``17`` = ``00017``); six-digit coil numbers above ``009999`` must be written as strings. (The
loader refuses an unquoted ``00017``: YAML 1.1 reads it as octal.)
"""

from __future__ import annotations

from typing import Any, Literal

Table = Literal["holding", "input", "coil", "discrete"]
TABLES: tuple[Table, ...] = ("holding", "input", "coil", "discrete")
DIGIT_TABLE: dict[int, Table] = {0: "coil", 1: "discrete", 3: "input", 4: "holding"}
TABLE_DIGIT: dict[str, int] = {table: digit for digit, table in DIGIT_TABLE.items()}
#: Largest address a five-digit number can give (x9999 is address 9998).
FIVE_DIGIT_MAX_ADDRESS = 9998


class ModiconError(ValueError):
    """A Modicon number that names no register (the message says why)."""


def parse(number: int | str) -> tuple[Table, int]:
    """``30001`` -> ``("input", 0)``; ``"400001"`` -> ``("holding", 0)``. Raises :class:`ModiconError`."""
    if isinstance(number, str):
        if not number.isdigit() or len(number) not in (5, 6):
            raise ModiconError(f"Modicon number {number!r} must have 5 or 6 digits")
        digit, rest, six = int(number[0]), int(number[1:]), len(number) == 6
    elif number >= 100000:
        digit, rest, six = number // 100000, number % 100000, True
    else:
        digit, rest, six = number // 10000, number % 10000, False
    shown = number if isinstance(number, str) else str(number)
    table = DIGIT_TABLE.get(digit)
    if table is None:
        raise ModiconError(f"Modicon number {shown}: the first digit {digit} names no table "
                           "(0 coil, 1 discrete input, 3 input register, 4 holding register)")
    limit = 65536 if six else 9999
    if not 1 <= rest <= limit:
        first = f"{digit}{1:05d}" if six else f"{digit}0001"
        raise ModiconError(f"Modicon number {shown} is outside {first}..{digit}{limit:0{5 if six else 4}d} "
                           f"(numbers are 1-based: {first} is {table} address 0)")
    return table, rest - 1


def number(table: str, address: int) -> str:
    """The Modicon number of an address as manuals print it: five digits up to address 9998, else six."""
    digit = TABLE_DIGIT[table]
    if address <= FIVE_DIGIT_MAX_ADDRESS:
        return f"{digit}{address + 1:04d}"
    return f"{digit}{address + 1:05d}"


def locate(reg: dict[str, Any]) -> tuple[Table, int]:
    """(table, address) of a register entry that passed the checks (``register`` or ``table`` + ``address``)."""
    if "register" in reg:
        return parse(reg["register"])
    table: Table = reg.get("table", "holding")
    return table, int(reg["address"])


__all__ = ["DIGIT_TABLE", "FIVE_DIGIT_MAX_ADDRESS", "ModiconError", "TABLES", "TABLE_DIGIT", "Table", "locate",
           "number", "parse"]
