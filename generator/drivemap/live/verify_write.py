"""``verify --write-safe``: write/read-back round trips of RAM registers, each restored afterwards.

Only registers the map says are read-write and stored in RAM (plus EEPROM ones with
``--eeprom``); never command registers, page selectors, bit fields or volatile (operation)
registers. Test values are the map's min and max (or another enum member, or the next raw
step; for a register with a value set, another value of the set), encoded with the client's codec, so
the client's own checks apply. The original raw
value is written back and read again; a register that cannot be restored is reported loudly.
"""

from __future__ import annotations

from collections.abc import Callable

from drivemap.live.session import Session
from drivemap.live.verify_checks import Cell, Finding, Results, failure_text
from drivemap.model.nodes import Register
from drivemap.runtime.errors import DeviceException, DriveError, DriveTimeout


def candidates(session: Session, cells: list[Cell], eeprom: bool, results: Results) -> list[Cell]:
    """The cells --write-safe writes; every other writable cell is listed in ``results.skipped`` with why."""
    model = session.target.model
    selectors = {r.page.selector for r in model.registers if r.page is not None}
    config = model.protocol.configuration.register if model.protocol.configuration else None
    out: list[Cell] = []
    for reg, i in cells:
        why = skip_reason(reg, eeprom, selectors, config, (reg.name, i) in results.alone)
        if why is None:
            out.append((reg, i))
        elif reg.writable:
            results.skipped.append(f"{reg.element_name(i)}: not written by --write-safe: {why}")
    return out


def skip_reason(reg: Register, eeprom: bool, selectors: set[str], config: str | None, read: bool) -> str | None:
    """Why --write-safe does not write ``reg`` (None: it does)."""
    if reg.access != "rw":
        return "write-only (cannot be read back)"
    if reg.command_value is not None:
        return "a command register (writing it acts)"
    if reg.name in selectors:
        return "a page selector (writing it changes what other registers read)"
    if reg.name == config:
        return "the Configuration command"
    if reg.bits:
        return "a bit field (its bits may act)"
    if reg.storage == "eeprom" and not eeprom:
        return "stored in EEPROM (limited write cycles; --eeprom writes it too)"
    if reg.storage not in ("ram", "eeprom"):
        return f"storage {reg.storage} (only RAM registers, and EEPROM ones with --eeprom, are written)"
    if not read:
        return "its value was not read (nothing to restore)"
    return None


def test_raws(session: Session, reg: Register, original: int) -> list[tuple[str, int]]:
    """(description, raw) values to try: the map's min and max, else another enum value or raw step."""
    codec = session.target.codecs[reg.name]
    out: list[tuple[str, int]] = []
    if reg.enum is not None:
        others = [v for v in session.target.model.enum(reg.enum).members if v.value != original]
        if others:
            out.append((f"{others[0].name}", others[0].value))
        return out
    if reg.values:  # only values of the set: never a raw step the map does not allow
        for item in reg.value_set:
            try:
                raw = codec.encode(int(item.value) if reg.is_integer and not isinstance(item.value, str) else item.value)
            except DriveError:
                continue
            if raw != original:
                return [(f"the value {item.text()}", raw)]
        return out
    for what, value in (("min", reg.min), ("max", reg.max)):
        if value is not None:
            try:
                raw = codec.encode(int(value) if reg.is_integer and float(value).is_integer() else value)
            except DriveError:
                continue
            if raw != original:
                out.append((f"the map's {what} {value:g}{' ' + reg.unit if reg.unit else ''}", raw))
    if not out:
        lo, hi = reg.raw_bounds()
        step = original + 1 if original < hi else original - 1
        out.append((f"raw {step}", max(lo, step)))
    return out


def check_writes(session: Session, cells: list[Cell], results: Results, tick: Callable[[], None]) -> None:
    for reg, index in cells:
        key = (reg.name, index)
        original = results.alone[key]
        for what, raw in test_raws(session, reg, original):
            round_trip(session, reg, index, what, raw, results)
        restore(session, reg, index, original, results)
        results.count("write-safe")
        tick()


def round_trip(session: Session, reg: Register, index: int, what: str, raw: int, results: Results) -> None:
    key = (reg.name, index)
    name = reg.element_name(index)
    address = reg.element_address(index)
    try:
        session.client._drivemap.write_raw_items([(key, raw)])
    except (DeviceException, DriveTimeout) as exc:
        results.add(Finding("write-safe", "disagree", name, address, reg.line, f"accepts {what} (raw {raw})",
                            f"refuses it: {failure_text(session, exc)}",
                            "a narrower range, another scale, or not writable in this state?"))
        return
    try:
        back = session.read_keys([key])[key]
    except (DeviceException, DriveTimeout) as exc:
        back = None
        results.add(Finding("write-safe", "disagree", name, address, reg.line, "reads back what was written",
                            f"read after write: {failure_text(session, exc)}"))
    if back is not None and back != raw:
        note = reg.reflect == "configuration"
        results.add(Finding("write-safe", "note" if note else "disagree", name, address, reg.line,
                            f"reads back {what} (raw {raw})", f"reads back raw {back}",
                            "reflect: configuration (takes effect after Configuration)" if note else
                            "another address, scale or storage for this firmware?"))


def restore(session: Session, reg: Register, index: int, original: int, results: Results) -> None:
    key = (reg.name, index)
    name = reg.element_name(index)
    try:
        session.client._drivemap.write_raw_items([(key, original)])
        back = session.read_keys([key])[key]
    except (DeviceException, DriveTimeout) as exc:
        back, problem = None, failure_text(session, exc)
    else:
        problem = "" if back == original else f"reads raw {back}"
    if problem:
        results.add(Finding("restore", "disagree", name, reg.element_address(index), reg.line,
                            f"restored to raw {original}", f"NOT RESTORED: {problem}",
                            f"set it back by hand: drivemap write {session.target.model.name} {name}=..."))
