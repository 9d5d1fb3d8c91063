"""Read programs: the fault-free path of ``read(*accessors)``, ``read_all()`` and ``element.read()``
compiled once
(so a clean read costs little more than its wire time).

For one tuple of keys (the elements a call reads) a program holds the plan's requests as
prepared :class:`~drivemap.runtime.client.transport.bus.Exchange` objects (one request PDU each, reused: the bus
serialises its use), and one straight-line Python function (built from source once per client
class and keys, :func:`compile_reader`) that sends them, checks each reply is a plain success of
the size asked (function code echoed, one word per register asked), takes each cell's raw value
with plain arithmetic (sign, word order), decodes it (the codec's arithmetic inlined for the
integer, float, enum and bool codecs; the codec's ``decode`` otherwise) and builds the snapshot
holding only the fields read, or returns the one value (tuple for an array).

Anything else goes the general way, with the same result as before: a client that knows holes
(adaptive reads) runs the general operation from the start; a reply that is not a plain success
(an exception reply, a short reply) hands every reply received so far to the general operation
(:func:`~drivemap.runtime.client.protocol.sansio.run_replay`), which decodes them, raises, splits or carries on
exactly as if it had sent those requests itself. A plan with pages, bit reads (01h/02h), a
function the map does not list or a decoding the program does not know never gets a program.
Retries, rejected replies, timeouts and quiet times are the bus's, on both paths alike.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from drivemap.runtime.client.protocol.planner import Key, ReadRequest
from drivemap.runtime.client.protocol.sansio import READ_REQUESTS
from drivemap.runtime.client.protocol.tables import SpecTables
from drivemap.runtime.client.transport.exchange import Exchange
from drivemap.runtime.client.values.codec import BoolCodec, Codec, EnumCodec, FloatCodec, IntCodec
from drivemap.runtime.client.values.words import words_to_raw

#: Snapshot table entry per key (see ``ClientCommon._snapshot_table``): decode, field, index in an array.
Entry = tuple["Callable[[int], Any] | None", "str | None", int]
Maker = Callable[..., Callable[..., Any]]


@dataclasses.dataclass(frozen=True)
class Reader:
    """What a read program reads and returns; compiled once per client class."""

    kind: str
    """"snapshot" (read, read_all), "value" (an element's value) or "tuple" (an array's values)."""
    keys: tuple[Key, ...]
    plan: tuple[ReadRequest, ...]
    make_sync: Maker
    make_async: Maker


class _Source:
    """Lines of Python source and the names they use."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.names: dict[str, Any] = {}
        self._ids: dict[int, str] = {}

    def const(self, value: Any, prefix: str = "C") -> str:
        """A name for ``value`` in the namespace (one per object)."""
        name = self._ids.get(id(value))
        if name is None:
            name = self._ids[id(value)] = f"{prefix}{len(self._ids)}"
            self.names[name] = value
        return name

    def add(self, indent: int, text: str) -> None:
        self.lines.append("    " * indent + text)


def eligible(plan: Sequence[ReadRequest], tables: SpecTables) -> bool:
    """Whether a plan can have a program: register reads of listed functions, no pages, each key once."""
    seen: set[Key] = set()
    for req in plan:
        if req.page is not None or req.code not in (0x03, 0x04) or req.code not in tables.read_codes:
            return False
        for key, _ in req.cells:
            if key in seen or key[0] not in tables.decode:
                return False
            seen.add(key)
    return True


def _raw_lines(src: _Source, ind: int, req: ReadRequest, r: int, tables: SpecTables,
               raws: dict[Key, str]) -> None:
    """The raw value of every cell of request ``r`` (what ``Core._decode`` computes), pages noted."""
    for key, offset in req.cells:
        size, signed, low_first, selector, general = tables.decode[key[0]]
        var = f"r{len(raws)}"
        raws[key] = var
        if general is not None:
            src.add(ind, f"{var} = {src.const(words_to_raw, 'F')}({src.const(general, 'S')}, "
                         f"w{r}[{offset}:{offset + size}])")
        elif size == 1:
            src.add(ind, f"{var} = w{r}[{offset}]")
            if signed:
                src.add(ind, f"if {var} & 0x8000: {var} -= 0x10000")
        else:
            first, second = (offset + 1, offset) if low_first else (offset, offset + 1)
            src.add(ind, f"{var} = (w{r}[{first}] << 16) | w{r}[{second}]")
            if signed:
                src.add(ind, f"if {var} & 0x80000000: {var} -= 0x100000000")
        if selector:
            src.add(ind, f"core.pages[{key[0]!r}] = {var}")


def _value_line(src: _Source, ind: int, var: str, codec: Codec[Any], raw: str, factor: str) -> None:
    """``var`` = the decoded value of ``raw`` (the codec's own arithmetic where it is plain)."""
    kind = type(codec)
    if codec.scale_key is not None:
        src.add(ind, f"{var} = {src.const(codec.decode_scaled, 'D')}({raw}, {factor})")
    elif kind is IntCodec and codec._scale == 1 and codec._offset == 0:  # type: ignore[attr-defined]
        src.add(ind, f"{var} = {raw}")
    elif kind is IntCodec:
        src.add(ind, f"{var} = {raw} * {src.const(codec._scale)} + {src.const(codec._offset)}")  # type: ignore[attr-defined]
    elif kind is FloatCodec:
        src.add(ind, f"{var} = round({raw} * {src.const(codec._scale)} + {src.const(codec._offset)}, "  # type: ignore[attr-defined]
                     f"{src.const(codec._digits)})")  # type: ignore[attr-defined]
    elif kind is EnumCodec:
        src.add(ind, f"{var} = {src.const(codec._members, 'M')}.get({raw})")  # type: ignore[attr-defined]
        src.add(ind, f"if {var} is None: {var} = {src.const(codec.enum_type, 'E')}({raw})")  # type: ignore[attr-defined]
    elif kind is BoolCodec:
        src.add(ind, f"{var} = {raw} != 0")
    else:
        src.add(ind, f"{var} = {src.const(codec.decode, 'D')}({raw})")


def _exchange_lines(src: _Source, ind: int, plan: Sequence[ReadRequest], tables: SpecTables, aw: str) -> dict[Key, str]:
    """Send each request (the lock held: ``Bus.transact``), check its reply is a plain success of the
    size asked, take its raw values."""
    raws: dict[Key, str] = {}
    got = ""
    send = "await bus.exchange" if aw else "bus.transact"
    for r, req in enumerate(plan):
        got += f"rep{r}, "
        src.add(ind, f"rep{r} = {send}(EXS[{r}])")
        src.add(ind, f"if rep{r}.function_code != {req.code}: return {aw}FALLBACK(client, ({got}))")
        src.add(ind, f"w{r} = rep{r}.registers")
        src.add(ind, f"if len(w{r}) != {req.count}: return {aw}FALLBACK(client, ({got}))")
        _raw_lines(src, ind, req, r, tables, raws)
    return raws


def _snapshot_lines(src: _Source, ind: int, raws: dict[Key, str], codecs: Mapping[str, Codec[Any]],
                    table: Mapping[Key, Entry], shape: Mapping[str, int], snapshot: type,
                    defaults: Mapping[str, Any]) -> None:
    """The snapshot ``ClientCommon._snapshot`` builds from these raw values (same values, same fields)."""
    values: list[str] = []
    fields: dict[str, str] = {}
    arrays: dict[str, list[str]] = {}
    for n, (key, raw) in enumerate(raws.items()):
        codec = codecs[key[0]]
        factor = raws.get(codec.scale_key, "None") if codec.scale_key is not None else "None"
        _value_line(src, ind, f"v{n}", codec, raw, factor)
        values.append(f"{src.const(key, 'K')}: v{n}")
        entry = table.get(key)
        if entry is None or entry[1] is None:
            continue
        name, index = entry[1], entry[2]
        if index < 0:
            fields[name] = f"v{n}"
        else:
            arrays.setdefault(name, ["None"] * shape[name])[index] = f"v{n}"
    for name, items in arrays.items():
        fields[name] = "(" + ", ".join(items) + ",)"
    src.add(ind, f"snap = NEW({src.const(snapshot, 'T')})")
    src.add(ind, "state = snap.__dict__")
    if defaults:
        src.add(ind, f"state.update({src.const(defaults)})")
    src.add(ind, "state['_values'] = {" + ", ".join(values) + "}")
    for name, expr in fields.items():
        src.add(ind, f"state[{name!r}] = {expr}")
    src.add(ind, "return snap")


def _result_lines(src: _Source, ind: int, kind: str, result: Sequence[Key], raws: dict[Key, str],
                  codecs: Mapping[str, Codec[Any]]) -> None:
    """The value (``kind`` "value") or tuple of values ("tuple") an accessor's read returns."""
    out = []
    for n, key in enumerate(result):
        codec = codecs[key[0]]
        factor = raws.get(codec.scale_key, "None") if codec.scale_key is not None else "None"
        _value_line(src, ind, f"v{n}", codec, raws[key], factor)
        out.append(f"v{n}")
    src.add(ind, f"return {out[0]}" if kind == "value" else "return (" + ", ".join(out) + ",)")


def _function(kind: str, plan: Sequence[ReadRequest], tables: SpecTables, build: Callable[[_Source, int, dict[Key, str]], None],
              asynchronous: bool) -> Maker:
    """``make(EXS, GENERAL, FALLBACK)`` -> the program's function of ``client`` (sync or async)."""
    aw = "await " if asynchronous else ""
    src = _Source()
    src.add(0, "def make(EXS, GENERAL, FALLBACK):")
    src.add(1, f"{'async ' if asynchronous else ''}def program(client):")
    src.add(2, "parts = client._drivemap")
    src.add(2, "core = parts.core")
    src.add(2, f"if core.holes: return {aw}GENERAL(client)")
    src.add(2, "bus = parts.bus")
    if asynchronous:  # what ``async with bus.lock`` does, without its __aenter__/__aexit__ coroutines
        src.add(2, "lock = bus.lock")
        src.add(2, "await lock.acquire()")
        src.add(2, "try:")
    else:
        src.add(2, "with bus.lock:")
    raws = _exchange_lines(src, 3, plan, tables, aw)
    if kind == "snapshot":
        build(src, 3, raws)
    if asynchronous:
        src.add(2, "finally:")
        src.add(3, "lock.release()")
    if kind != "snapshot":
        build(src, 2, raws)
    src.add(1, "return program")
    namespace: dict[str, Any] = {"NEW": object.__new__, **src.names}
    exec(compile("\n".join(src.lines) + "\n", f"<drivemap read program {kind}>", "exec"), namespace)  # noqa: S102
    return namespace["make"]  # type: ignore[no-any-return]


def compile_reader(kind: str, keys: tuple[Key, ...], plan: tuple[ReadRequest, ...], tables: SpecTables,
                   codecs: Mapping[str, Codec[Any]], table: Mapping[Key, Entry], shape: Mapping[str, int],
                   snapshot: type, defaults: Mapping[str, Any] | None, result: Sequence[Key] = ()) -> Reader | None:
    """The program of ``plan`` (``kind``: see :class:`Reader`), or None when it takes the general path."""
    if not plan or not eligible(plan, tables):
        return None
    if kind == "snapshot":
        if defaults is None or any(table.get(key) is None for req in plan for key, _ in req.cells):
            return None  # a snapshot class of its own, or a key without a field: the general path knows

        def build(src: _Source, ind: int, raws: dict[Key, str]) -> None:
            _snapshot_lines(src, ind, raws, codecs, table, shape, snapshot, defaults or {})
    else:
        cells = {key for req in plan for key, _ in req.cells}
        if not result or any(k not in cells for k in result):
            return None

        def build(src: _Source, ind: int, raws: dict[Key, str]) -> None:
            _result_lines(src, ind, kind, result, raws, codecs)
    return Reader(kind, keys, plan, _function(kind, plan, tables, build, False),
                  _function(kind, plan, tables, build, True))


def exchanges(plan: Sequence[ReadRequest], unit: int, timing: Any) -> tuple[Exchange, ...]:
    """The prepared exchanges of a plan, for one client (its unit)."""
    return tuple(Exchange(unit, READ_REQUESTS[req.code](address=req.address, count=req.count, dev_id=unit), timing)
                 for req in plan)


__all__ = ["Reader", "compile_reader", "eligible", "exchanges"]
