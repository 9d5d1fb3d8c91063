"""``drivemap import ha-solarman``: an ha-solarman inverter profile as a map.

Each item of ``parameters[].items`` becomes a register in its group: ``rule`` gives the type (1/3
unsigned, 2/4 signed, over as many words as ``registers`` lists: the first listed is the low word, so
ascending registers are ``low_first``; 5 a string; 6 raw words; 7 version, 8 date-time, 9 time: u16
words), ``scale`` and ``uom`` the scale and unit, ``lookup`` an enum (``key`` values; ``bit`` keys:
bits), ``configurable`` or a writable ``platform`` (number, select, switch, time, datetime) ``access: rw``
with its min and max. The table comes from the item's, the request range's or the profile's ``code``
(ha-solarman reads 0x03 when none says). What a register cannot carry is listed for review with the
file and line: ``offset``, ``mask``/``divide`` (a field of the word), computed items (rule 0,
``sensors``), registers that are not adjacent, an entity on words another entity already reads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.importers.imported import Occupancy, error_at, fits, leave_open, mark_imported
from drivemap.onboard.importers.mapdoc import MapDoc, snake, upper
from drivemap.onboard.importers.yamlsrc import Node, load_yaml

__all__ = ["import_solarman"]

REPO_PATH = "custom_components/solarman/inverter_definitions/{name}"
_WRITABLE = {"number", "select", "switch", "time", "datetime"}
_TABLES = {3: "holding", 4: "input", 1: "coil", 2: "discrete"}


def import_solarman(doc: MapDoc, path: Path) -> str:
    data = load_yaml(path)
    if not isinstance(data, Node) or not isinstance(data.get("parameters"), list):
        raise error_at(path, 1, "not an ha-solarman profile: no 'parameters' list (profiles have info, "
                                "default, requests and parameters)")
    mark_imported(doc, path, REPO_PATH.format(name=path.name), "ha-solarman", "inverter")
    info: dict[str, Any] = data["info"] if isinstance(data.get("info"), dict) else {}
    doc.vendor = str(info["manufacturer"]) if info.get("manufacturer") else None
    doc.title = " ".join(str(x) for x in (info.get("manufacturer"), info.get("model")) if x) or path.stem
    default: dict[str, Any] = data["default"] if isinstance(data.get("default"), dict) else {}
    requests = [r for r in data.get("requests") or [] if isinstance(r, dict)]
    doc.notes = (f"ha-solarman profile {path.name}. Its items are read through a Solarman logger or Modbus; "
                 f"the table is the profile's function code (0x03 where none is given).")
    taken = Occupancy()
    for group in data["parameters"]:
        if not isinstance(group, Node) or not isinstance(group.get("items"), list):
            raise error_at(path, getattr(group, "line", 1), "a parameters entry without an 'items' list")
        gname = doc.group(str(group.get("group") or "registers"))
        for item in group["items"]:
            if not isinstance(item, Node) or "name" not in item:
                raise error_at(path, getattr(item, "line", getattr(group, "line", 1)), "an item without a name")
            _item(doc, path, item, gname, _code(item, group, requests, default), taken)
    if not doc.registers:
        raise error_at(path, 1, "the profile names no register an item reads")
    return snake(path.stem, "device")


def _code(item: Node, group: Node, requests: list[dict[str, Any]], default: dict[str, Any]) -> int:
    for holder in (item, group):
        if "code" in holder:
            return _read_code(holder["code"])
    regs = item.get("registers") or []
    first = regs[0] if regs and isinstance(regs[0], int) else None
    for req in requests:
        if first is not None and "code" in req and int(req.get("start", 0)) <= first <= int(req.get("end", -1)):
            return _read_code(req["code"])
    return _read_code(default.get("code", 3))


def _read_code(code: Any) -> int:
    if isinstance(code, dict):
        code = code.get("read", 3)
    return int(code)


def _item(doc: MapDoc, path: Path, item: Node, group: str, code: int, taken: Occupancy) -> None:
    where = f"{path.name}:{item.line}"
    label = str(item["name"])
    regs = item.get("registers")
    rule = item.get("rule")
    if rule == 0 or "sensors" in item or not regs:
        doc.review.skipped.append(f"{where}: {label}: computed by ha-solarman from other items (rule 0 or "
                                  "'sensors'), not a register")
        return
    if isinstance(regs, list) and regs and all(isinstance(r, list) for r in regs):
        doc.review.skipped.append(f"{where}: {label}: registers given per device variant ({regs}): which "
                                  "applies depends on the variant ha-solarman detects")
        return
    if not isinstance(regs, list) or not all(isinstance(r, int) for r in regs):
        raise error_at(path, item.line, f"{label}: 'registers' must be a list of register numbers")
    table = _TABLES.get(code)
    if table is None:
        doc.review.skipped.append(f"{where}: {label}: function code {code} is not a read code")
        return
    reg: dict[str, Any] = {"name": doc.name(label), "table": table, "address": min(regs), "label": label,
                           "group": group, "source": where}
    if not _typed(doc, reg, regs, rule, where, label):
        return
    holder = taken.holder(reg)
    if holder is not None:
        doc.review.skipped.append(f"{where}: {label}: reads the words of {holder} (another entity of the same "
                                  f"register: {_what(item)})")
        return
    _facts(doc, reg, item, where)
    _lookup(doc, reg, item, where)
    _writable(doc, reg, item)
    taken.take(reg)
    doc.add(reg)


def _what(item: Node) -> str:
    keys = [k for k in ("mask", "divide", "lookup", "scale", "rule", "platform") if k in item]
    return ", ".join(f"{k} {item[k]!r}" for k in keys if k != "lookup") or "the same words"


def _typed(doc: MapDoc, reg: dict[str, Any], regs: list[int], rule: Any, where: str, label: str) -> bool:
    n = len(regs)
    ascending = regs == list(range(regs[0], regs[0] + n))
    descending = regs == list(range(regs[0], regs[0] - n, -1))
    if not (ascending or descending):
        doc.review.skipped.append(f"{where}: {label}: registers {regs} are not adjacent (drivemap reads one "
                                  "span per register)")
        return False
    if rule in (1, 2, 3, 4):
        types = {1: "u16", 2: "u32", 4: "u64"} if rule in (1, 3) else {1: "s16", 2: "s32", 4: "s64"}
        if n not in types:
            doc.review.skipped.append(f"{where}: {label}: rule {rule} over {n} registers")
            return False
        reg["type"] = types[n]
        if n > 1:
            reg["word_order"] = "low_first" if ascending else "high_first"
    elif rule == 5:
        reg.update(type="string", length=n)
        if descending:
            reg["notes"] = "ha-solarman lists the registers from the last to the first."
            leave_open(doc, reg, "byte_order")
    elif rule in (6, 7, 8, 9):
        reg["type"] = "u16"
        if n > 1:
            reg.update(count=n, stride=1)
        what = {6: "raw words (shown as hex)", 7: "a version (digits of the words)", 8: "a date and time",
                9: "a time of day"}[int(rule)]
        reg["notes"] = f"ha-solarman rule {rule}: {what}" + (", registers listed last first." if descending and n > 1
                                                              else ".")
    else:
        reg["type"] = "u16"
        leave_open(doc, reg, "type")
        reg["notes"] = f"ha-solarman rule {rule!r}: not a type drivemap knows."
    return True


def _facts(doc: MapDoc, reg: dict[str, Any], item: Node, where: str) -> None:
    scale = item.get("scale")
    if isinstance(scale, (int, float)) and not isinstance(scale, bool) and scale > 0 and scale != 1:
        reg["scale"] = float(scale)
    elif scale is not None and scale != 1:
        leave_open(doc, reg, "scale")
        _note(reg, f"ha-solarman scale {scale!r}.")
    if item.get("uom"):
        reg["unit"] = str(item["uom"])
    for key, field in (("offset", "offset"), ("mask", "bits"), ("divide", "scale"), ("magnitude", "scale"),
                       ("multiply", "scale")):
        if key in item:
            _note(reg, f"ha-solarman {key}: {item[key]!r} ({where}).")
            leave_open(doc, reg, field)
    if item.get("signed") is not None and reg["type"].startswith("u"):
        _note(reg, f"ha-solarman signed: {item['signed']!r}.")
        leave_open(doc, reg, "type")


def _note(reg: dict[str, Any], text: str) -> None:
    reg["notes"] = f"{reg['notes']} {text}" if reg.get("notes") else text


def _lookup(doc: MapDoc, reg: dict[str, Any], item: Node, where: str) -> None:
    lookup = item.get("lookup")
    if not isinstance(lookup, list) or not lookup:
        return
    pairs: list[tuple[int, str]] = []
    bits: list[dict[str, Any]] = []
    seen: set[int] = set()
    names: set[str] = set()
    for row in lookup:
        if not isinstance(row, dict) or "value" not in row:
            continue
        if "bit" in row and isinstance(row["bit"], int) and 0 <= row["bit"] <= 15 * _words(reg) + _words(reg) - 1:
            name = upper(str(row["value"]), f"bit_{row['bit']}")
            if name not in names and row["bit"] not in {b["offset"] for b in bits}:
                names.add(name)
                bits.append({"name": name, "offset": row["bit"], "label": str(row["value"])})
            continue
        keys = row.get("key")
        for key in keys if isinstance(keys, list) else [keys]:
            if isinstance(key, int) and not isinstance(key, bool) and key not in seen and key >= 0:
                seen.add(key)
                pairs.append((key, str(row["value"])))
            else:
                _note(reg, f"lookup key {key!r} -> {row['value']!r} left out (not a register value) ({where}).")
                leave_open(doc, reg, "enum")
    if bits and reg["type"] in ("u16", "u32") and "count" not in reg:
        reg["bits"] = sorted(bits, key=lambda b: b["offset"])
    elif pairs and reg["type"] in ("u16", "s16", "u32", "s32") and "scale" not in reg and "count" not in reg:
        reg["enum"] = doc.enum(reg["name"], sorted(pairs))
    elif pairs or bits:
        _note(reg, f"its lookup ({len(pairs) + len(bits)} values) is not kept: the register is scaled, "
                   f"counted or not an integer ({where}).")
        leave_open(doc, reg, "enum")


def _words(reg: dict[str, Any]) -> int:
    return 2 if reg["type"] in ("u32", "s32") else 1


def _writable(doc: MapDoc, reg: dict[str, Any], item: Node) -> None:
    conf = item.get("configurable")
    platform = str(item.get("platform") or "")
    if conf is None and platform not in _WRITABLE and "configurable" not in item:
        return
    if reg["table"] != "holding":
        _note(reg, "ha-solarman marks it writable, but it is not a holding register.")
        return
    reg["access"] = "rw"
    doc.max_quantity.setdefault(16, None)  # ha-solarman writes with 0x10
    if isinstance(conf, dict) and "enum" not in reg and reg["type"] != "string" and "count" not in reg:
        for key in ("min", "max"):
            value = conf.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if fits(reg, value):
                    reg[key] = value
                else:
                    _note(reg, f"ha-solarman {key} {value} does not fit the register's type and scale.")
                    leave_open(doc, reg, key)

