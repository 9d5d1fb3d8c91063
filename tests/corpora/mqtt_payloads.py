"""Hostile MQTT command payloads: every one must be refused, answered on the result topic, and leave
the gateway polling and publishing (tests/gateway/test_gateway_hostile.py sends each to every command topic of
the example devices). None of them is a value any register of those devices takes."""

from __future__ import annotations

#: (label, payload bytes)
PAYLOADS: list[tuple[str, bytes]] = [
    ("1,000 '['", b"[" * 1000),
    ("1,000 '{'", b'{"a":' * 1000),
    ("100,000 nested lists", b"[" * 100_000 + b"]" * 100_000),
    ("1 MiB of digits", b"9" * (1 << 20)),
    ("64 KiB of spaces", b" " * 65536),
    ("binary", bytes(range(256))),
    ("NUL", b"\x00"),
    ("non-UTF-8", b"\xff\xfe\xfd"),
    ("lone surrogate (CESU)", b"\xed\xa0\x80"),
    ("empty", b""),
    ("whitespace", b"   "),
    ("NaN", b"NaN"),
    ("Infinity", b"Infinity"),
    ("-Infinity", b"-Infinity"),
    ("1e400", b"1e400"),
    ("-1e400", b"-1e400"),
    ("huge integer", b"9" * 5000),
    ("2**64", str(2**64).encode()),
    ("-2**63 - 1", str(-(2**63) - 1).encode()),
    ("object", b'{"value": 1}'),
    ("bits out of range", b'{"X0": 2, "X1": -1}'),
    ("unknown bit", b'{"NOPE": true}'),
    ("list", b"[1, 2, 3]"),
    ("nested list", b"[[1]]"),
    ("null in a list", b"[null]"),
    ("string of a number", b'"12"'),
    ("bool for a number", b"true"),
    ("a word that is no bool", b"maybe"),
    ("Arabic-Indic digit", "\u0661".encode()),
    ("full-width digits", "\uff11\uff12".encode()),
    ("underscored number", b"1_000"),
    ("hex float", b"0x1p3"),
    ("JSON with trailing garbage", b"12 13"),
    ("unterminated string", b'"abc'),
    ("escape bomb", b'"' + b"\\u0000" * 1000 + b'"'),
    ("script", b"<script>alert(1)</script>"),
    ("format string", b"%s%s%s%n"),
    ("jinja", b"{{ 7*7 }}"),
    ("enum name that is not one", b"SIDEWAYS_RUNNING"),
    ("UNKNOWN pseudo-member", b"UNKNOWN_0"),
    ("press in a list", b'["PRESS"]'),
    ("a number that underflows a float (0 as one)", b"1e-400"),
    ("more digits than a float holds (100.0 as one)", b"99.999999999999999999"),
    ("a key named twice", b'{"X0": true, "X0": false}'),
]

#: Index parts of ``.../REGISTER/INDEX/set`` topics that are not array indexes.
INDEXES: list[str] = ["\u0661", "-1", "99999999", "0x1", " 1", "1.0", "", "\uff10"]
