"""ESPHome's ``modbus_controller`` range batching, steered to drivemap's read plan.

ESPHome sorts a controller's items by (register type, ``force_new_range`` first, address, offset)
and grows a range while the next item starts where the range ends; an item at the same word as
the one before (a bit of a register, the label of an enum) shares its read. Its ranges know no
device limit and no holes. So, for drivemap's plan of the exported elements:

* a hole inside a planned request (a readable reserved word, a register not exported) gets an
  internal filler sensor whose ``register_count`` spans it;
* a request that starts right where the previous one ends must not be merged into it: its items
  are given ``force_new_range``. When the request's first word holds a single item that can carry
  ``register_count`` (sensor, text_sensor, select) and no later item is a select (which takes no
  ``offset``), every item of the request is written as
  (request start, byte offset) and that item spans the whole request: one read, as planned.
  Otherwise (a number, a binary_sensor or several entities there: ESPHome would order them by
  pointer) only the first word's items are forced, which costs one extra read (reported);
* each table is its own address space (ESPHome's register_type): ranges never join two tables;
* every item of a request gets the request's ``skip_updates`` (its fastest element's interval):
  ESPHome polls a range as one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from drivemap.backends.yamltext import Hex
from drivemap.runtime.client.protocol.planner import ReadRequest

#: ESPHome's ModbusRegisterType order (coil, discrete_input, holding, read): its ranges run per type.
TABLE_ORDER = {"coil": 1, "discrete": 2, "holding": 3, "input": 4}

__all__ = ["COUNTABLE", "Item", "Layout", "align"]

#: platforms whose items take ``register_count``
COUNTABLE = frozenset({"sensor", "text_sensor", "select"})
BIT_TABLES = frozenset({"coil", "discrete"})
#: platforms whose items take no ``offset`` (ESPHome's select schema)
NO_OFFSET = frozenset({"select"})


@dataclass
class Item:
    """One ESPHome entity of the modbus_controller (its YAML in ``config``)."""

    platform: str
    config: dict[str, Any]
    address: int          # the register word it reads (or writes)
    words: int
    polled: bool = True
    filler: bool = False
    table: str = "holding"


@dataclass
class Layout:
    requests: list[ReadRequest] = field(default_factory=list)
    esphome_requests: int = 0
    notes: list[str] = field(default_factory=list)
    #: skip counts that got a controller of their own (ESPHome 2026.9 and later)
    skips: set[int] = field(default_factory=set)


def align(items: list[Item], plan: tuple[ReadRequest, ...], skips: dict[tuple[str, int], int],
          make_filler: Any, reuse: bool = False) -> Layout:
    """Set address/offset/register_count/force_new_range/skip_updates so ESPHome reads ``plan``.

    ``skips``: (table, word address) -> skip_updates of the element there; ``make_filler(table,
    address, words)`` returns a filler :class:`Item` (appended to ``items``). ``reuse``: the
    ranges of ESPHome 2026.9 and later (:func:`align_reuse`)."""
    if reuse:
        return align_reuse(items, plan, skips)
    layout = Layout(list(plan))
    requests = sorted(plan, key=lambda r: (TABLE_ORDER.get(r.table, 9), r.address))
    previous_end: tuple[str, int] | None = None
    for req in requests:
        inside = [i for i in items if i.polled and i.table == req.table and req.address <= i.address < req.address + req.count]
        for start, words in _holes(req, inside):
            filler = make_filler(req.table, start, words)
            items.append(filler)
            inside.append(filler)
        skip = min((skips[(i.table, i.address)] for i in inside if (i.table, i.address) in skips), default=0)
        for item in inside:
            if skip:
                item.config["skip_updates"] = skip
        contiguous = previous_end == (req.table, req.address)
        previous_end = (req.table, req.address + req.count)
        layout.esphome_requests += 1
        if not contiguous:
            continue
        first = [i for i in inside if i.address == req.address]
        later = [i for i in inside if i.address != req.address]
        if len(first) == 1 and first[0].platform in COUNTABLE and not any(i.platform in NO_OFFSET for i in later):
            for item in inside:
                item.config["address"] = Hex(req.address)
                if item.address != req.address:
                    # bytes into the reply; bits for coils and discrete inputs
                    item.config["offset"] = (1 if req.table in BIT_TABLES else 2) * (item.address - req.address)
                item.config["force_new_range"] = True
            first[0].config["register_count"] = req.count
        else:
            for item in first:
                item.config["force_new_range"] = True
            if req.count > first[0].words:
                layout.esphome_requests += 1
                layout.notes.append(
                    f"ESPHome reads 0x{req.address:04X}..0x{req.address + req.count - 1:04X} in two requests "
                    "(drivemap: one): no single entity on its first word can span it (register_count), so only "
                    "that word starts the new range")
    return layout


def _holes(req: ReadRequest, inside: list[Item]) -> list[tuple[int, int]]:
    covered: set[int] = set()
    for item in inside:
        covered.update(range(item.address, item.address + item.words))
    holes: list[tuple[int, int]] = []
    for word in range(req.address, req.address + req.count):
        if word in covered:
            continue
        if holes and holes[-1][0] + holes[-1][1] == word:
            holes[-1] = (holes[-1][0], holes[-1][1] + 1)
        else:
            holes.append((word, 1))
    return holes



def align_reuse(items: list[Item], plan: tuple[ReadRequest, ...], skips: dict[tuple[str, int], int]) -> Layout:
    """ESPHome 2026.9 and later: ranges are steered by ``reuse_previous_range`` alone (``register_count``,
    ``force_new_range`` and ``skip_updates`` were removed or do nothing). Each planned request is one
    range: its first item does not join an adjacent request before it (``reuse_previous_range: false``),
    an item after a hole inside the request joins across it (``true``: the hole is read, no filler).
    A slower interval gets its own controller (``Item.config['modbus_controller_id']`` is set to
    ``device_<n>x``: n update intervals), as ESPHome advises in place of skip_updates; ``Layout.skips``
    lists them."""
    layout = Layout(list(plan))
    requests = sorted(plan, key=lambda r: (TABLE_ORDER.get(r.table, 9), r.address))
    previous_end: dict[int, tuple[str, int]] = {}
    for req in requests:
        inside = sorted((i for i in items if i.polled and i.table == req.table
                         and req.address <= i.address < req.address + req.count), key=lambda i: i.address)
        skip = min((skips[(i.table, i.address)] for i in inside if (i.table, i.address) in skips), default=0)
        if skip:
            layout.skips.add(skip)
            for item in inside:
                item.config["modbus_controller_id"] = f"device_{skip + 1}x"
        layout.esphome_requests += 1
        if previous_end.get(skip) == (req.table, req.address):
            for item in inside:
                if item.address == req.address:
                    item.config["reuse_previous_range"] = False
        previous_end[skip] = (req.table, req.address + req.count)
        end = req.address
        for item in inside:
            if item.address > end:
                item.config["reuse_previous_range"] = True  # across the hole [end, item.address)
            end = max(end, item.address + item.words)
    return layout
