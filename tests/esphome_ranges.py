"""ESPHome's ``modbus_controller`` range builder, ported line by line for tests and benchmarks.

Port of ``ModbusController::create_register_ranges_()`` and ``SensorItemsComparator`` of ESPHome
2026.6 (esphome/components/modbus_controller/modbus_controller.{h,cpp}) and of the register counts
the platforms' ``to_code`` compute (:func:`ranges`), and of 2026.10's ``RangeBuilder``, which joins by
``reuse_previous_range`` (:func:`ranges_reuse`; 2026.9 replaced register_count/force_new_range by it). Given a device YAML (as loaded), it returns the read ranges the
controller sends every update, and where each entity finds its value. The one liberty: items that
ESPHome orders by pointer are taken in file order here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["Range", "SensorItem", "items_of", "ranges", "ranges_reuse", "update_ranges"]

TYPE_REGISTERS = {"RAW": 1, "U_WORD": 1, "S_WORD": 1, "U_DWORD": 2, "U_DWORD_R": 2, "S_DWORD": 2,
                  "S_DWORD_R": 2, "U_QWORD": 4, "U_QWORD_R": 4, "S_QWORD": 4, "S_QWORD_R": 4, "FP32": 2,
                  "FP32_R": 2}
_TYPE_ORDER = {"custom": 0, "coil": 1, "discrete_input": 2, "holding": 3, "read": 4}  # ModbusRegisterType


@dataclass
class SensorItem:
    name: str
    platform: str
    register_type: str
    start_address: int
    offset: int
    register_count: int
    response_bytes: int
    force_new_range: bool
    skip_updates: int
    seq: int
    word: int = 0          # the word the entity decodes from, as written
    reuse: str | bool = "auto"  # reuse_previous_range (2026.9 and later)
    controller: str = "device"

    def register_size(self) -> int:
        if self.register_type in ("coil", "discrete_input"):
            return 1
        return self.response_bytes if self.response_bytes > 0 else self.register_count * 2


@dataclass
class Range:
    start_address: int
    register_type: str
    register_count: int
    skip_updates: int
    sensors: list[SensorItem] = field(default_factory=list)


def _count(platform: str, cfg: dict[str, Any]) -> tuple[int, int]:
    """(register_count, response_bytes) as each platform's to_code sets them."""
    value_type = cfg.get("value_type", "U_WORD")
    if platform == "text_sensor":
        size = int(cfg.get("response_size", 2))
        return int(cfg.get("register_count", 0)) or (size + 1) // 2, size
    if platform in ("sensor", "select"):
        return int(cfg.get("register_count", 0)) or TYPE_REGISTERS[value_type], 0
    if platform == "number":
        return TYPE_REGISTERS[value_type], 0
    return 1, 0  # binary_sensor, switch on registers


def items_of(doc: dict[str, Any]) -> list[SensorItem]:
    """The polled modbus_controller items of a device YAML, in file order."""
    out: list[SensorItem] = []
    for platform in ("sensor", "binary_sensor", "text_sensor", "number", "select", "switch"):
        for cfg in doc.get(platform) or ():
            if cfg.get("platform") != "modbus_controller":
                continue
            if platform == "switch" and cfg.get("assumed_state"):
                continue
            count, size = _count(platform, cfg)
            offset = int(cfg.get("offset", 0))
            address = int(cfg["address"])
            register_type = cfg.get("register_type", "holding")
            bits = register_type in ("coil", "discrete_input")  # offset in bits there, else in bytes
            out.append(SensorItem(str(cfg.get("name") or cfg.get("id")), platform,
                                  register_type, address, offset, count, size,
                                  bool(cfg.get("force_new_range", False)), int(cfg.get("skip_updates", 0)),
                                  len(out), address + (offset if bits else offset // 2),
                                  cfg.get("reuse_previous_range", "auto"), str(cfg.get("modbus_controller_id"))))
    return out


def _key(item: SensorItem) -> tuple[int, int, int, int, int]:
    return (_TYPE_ORDER[item.register_type], 0 if item.force_new_range else 1, item.start_address, item.offset,
            item.seq)


def ranges(items: list[SensorItem]) -> list[Range]:
    """``create_register_ranges_()``: the ranges, in the order the controller polls them."""
    sensors = sorted(items, key=_key)
    out: list[Range] = []
    r: Range | None = None
    buffer_offset = 0
    prev: SensorItem | None = None
    i = 0
    while i < len(sensors):
        curr = sensors[i]
        if r is None:
            r = Range(curr.start_address, curr.register_type, curr.register_count, curr.skip_updates, [curr])
            buffer_offset = curr.register_size()
        elif not curr.force_new_range and r.register_type == curr.register_type and curr.register_type != "custom":
            assert prev is not None
            if (curr.start_address == r.start_address + r.register_count - prev.register_count
                    and curr.register_count == prev.register_count and curr.register_size() == prev.register_size()):
                curr.start_address = r.start_address
                curr.offset += prev.offset
            elif curr.start_address == r.start_address + r.register_count:
                curr.start_address = r.start_address
                curr.offset += buffer_offset
                buffer_offset += curr.register_size()
                r.register_count += curr.register_count
            sensors.sort(key=_key)  # the C++ erases and reinserts the item whose key changed
            i = sensors.index(curr)
        if curr.start_address == r.start_address and curr.register_type == r.register_type:
            if curr.skip_updates != 0:
                r.skip_updates = min(r.skip_updates, curr.skip_updates) if r.skip_updates else curr.skip_updates
            if curr not in r.sensors:
                r.sensors.append(curr)
            i += 1
        else:
            out.append(r)
            r = None
            buffer_offset = 0
            continue  # the current item is evaluated again, as the first of a new range
        prev = curr
    if r is not None and r.register_count > 0:
        out.append(r)
    return out


_REUSE_ORDER = {"auto": 0, True: 1, False: 2}  # RangeReuse: AUTO, ALWAYS, NEVER


def _bits(item: SensorItem) -> bool:
    return item.register_type in ("coil", "discrete_input")


def _custom(item: SensorItem) -> bool:
    return item.register_size() != item.register_count * 2 and not _bits(item)


class _Builder:
    """2026.10's ``RangeBuilder``: each method is its C++ namesake (offsets bounded by one byte)."""

    def __init__(self) -> None:
        self.out: list[Range] = []
        self.r: Range | None = None
        self.prev: SensorItem | None = None
        self.nbytes, self.custom, self.forced, self.shared = 0, False, False, False
        self.resolved: dict[int, tuple[int, int]] = {}  # seq -> (range start, offset)

    def join(self, curr: SensorItem) -> bool:
        r = self.r
        if r is None or curr.reuse is False or r.register_type != curr.register_type:
            return False
        return self.reuse(curr, r) or self.extend(curr, r) or self.cover(curr, r)

    def reuse(self, curr: SensorItem, r: Range) -> bool:
        prev, end = self.prev, r.start_address + r.register_count
        assert prev is not None
        offset = self.resolved[prev.seq][1] + curr.offset
        if (curr.start_address != end - prev.register_count or prev.start_address + prev.register_count != end
                or curr.register_count != prev.register_count or curr.register_size() != prev.register_size()
                or offset > 255):
            return False
        self.resolved[curr.seq] = (r.start_address, offset)
        return True

    def extend(self, curr: SensorItem, r: Range) -> bool:
        end = r.start_address + r.register_count
        reach = curr.start_address >= end if curr.reuse is True else (
            curr.start_address == end and (_bits(curr) or not self.custom))
        gap = curr.start_address - end
        where = ((curr.start_address - r.start_address) if _bits(curr) else self.nbytes + gap * 2) + curr.offset
        if not reach or r.register_count + gap + curr.register_count > (2000 if _bits(curr) else 125) or where > 255:
            return False
        self.nbytes += (0 if _bits(curr) else gap * 2) + curr.register_size()
        self.custom = self.custom or _custom(curr)
        r.register_count += gap + curr.register_count
        self.resolved[curr.seq] = (r.start_address, where)
        return True

    def cover(self, curr: SensorItem, r: Range) -> bool:
        if (not self.shared or self.forced or curr.start_address < r.start_address
                or curr.start_address + curr.register_count > r.start_address + r.register_count
                or self.custom or _custom(curr)):
            return False
        delta = curr.start_address - r.start_address
        self.resolved[curr.seq] = (r.start_address, (delta if _bits(curr) else delta * 2) + curr.offset)
        return True

    def share(self, curr: SensorItem) -> bool:
        r = self.r
        if r is None or r.register_type != curr.register_type or r.start_address != curr.start_address:
            return False
        self.resolved[curr.seq] = (r.start_address, curr.offset)
        r.register_count = max(r.register_count, curr.register_count)
        self.nbytes = max(self.nbytes, curr.register_size())
        self.custom = self.custom or _custom(curr)
        self.shared, self.forced = True, self.forced or curr.reuse is False
        return True

    def open(self, curr: SensorItem) -> None:
        if self.r is not None:
            self.out.append(self.r)
        self.r = Range(curr.start_address, curr.register_type, curr.register_count, 0, [])
        self.nbytes, self.custom, self.forced, self.shared = (curr.register_size(), _custom(curr),
                                                              curr.reuse is False, False)
        self.resolved[curr.seq] = (curr.start_address, curr.offset)


def ranges_reuse(items: list[SensorItem]) -> list[Range]:
    """2026.10's ``create_polling_commands_()`` for one controller's items: each sensor's ``start_address``
    and ``offset`` become its range's start and its resolved offset (bytes; bits for coils)."""
    sensors = sorted(items, key=lambda i: (_TYPE_ORDER[i.register_type], i.start_address, _REUSE_ORDER[i.reuse],
                                           i.offset, i.seq))
    b = _Builder()
    for curr in sensors:
        if not (b.join(curr) or b.share(curr)):
            b.open(curr)
        assert b.r is not None
        b.r.sensors.append(curr)
        b.prev = curr
    if b.r is not None:
        b.out.append(b.r)
    for item in sensors:
        item.start_address, item.offset = b.resolved[item.seq]
    return b.out


def update_ranges(doc: dict[str, Any], reuse: bool) -> list[Range]:
    """Every range a device YAML makes ESPHome read: before 2026.9 (``reuse`` False) one controller's
    ``create_register_ranges_()``; since then (``reuse_previous_range``) each controller's, one per
    update interval."""
    items = items_of(doc)
    if not reuse:
        return ranges(items)
    by_controller: dict[str, list[SensorItem]] = {}
    for item in items:
        by_controller.setdefault(item.controller, []).append(item)
    return [r for group in by_controller.values() for r in ranges_reuse(group)]
