"""``drivemap import modbus-local-gateway``: a modbus_local_gateway device config as a map.

The four sections are the tables: ``read_write_word`` holding (rw), ``read_only_word`` input,
``read_write_boolean`` coils (rw), ``read_only_boolean`` discrete inputs. Each entity becomes a
register: ``size`` words (1, 2 or 4), ``float``/``signed``/``string`` the type, ``swap: word`` the word
order (the gateway reads most significant word first unless it says so), ``multiplier`` the scale,
``unit_of_measurement`` the unit, ``map``/``options``/``switch`` an enum, ``number`` min and max.
Entities that read a field of one word (``bits``/``shift_bits``) become the bit fields of one register.
What a register cannot carry is listed for review with the file and line: ``offset`` (its order with the
multiplier is the gateway's code), ``flags`` (bit masks or bit numbers: the config does not say which),
an entity on words another entity already reads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.onboard.importers.imported import Occupancy, error_at, fits, leave_open, mark_imported
from drivemap.onboard.importers.mapdoc import MapDoc, snake, upper
from drivemap.onboard.importers.yamlsrc import Node, load_yaml

__all__ = ["import_mlg"]

REPO_PATH = "custom_components/modbus_local_gateway/device_configs/{name}"
SECTIONS = {"read_write_word": ("holding", "rw"), "read_only_word": ("input", "r"),
            "read_write_boolean": ("coil", "rw"), "read_only_boolean": ("discrete", "r")}
_KINDS = (("sdm", "meter"), ("growatt", "inverter"), ("atv", "drive"), ("waveshare", "io"), ("me31", "io"),
          ("relay", "io"))


def import_mlg(doc: MapDoc, path: Path) -> str:
    data = load_yaml(path)
    if not isinstance(data, Node) or not any(k in data for k in SECTIONS):
        raise error_at(path, 1, "not a modbus_local_gateway device config: none of "
                                f"{', '.join(SECTIONS)}")
    device = data["device"] if isinstance(data.get("device"), dict) else {}
    vendor, model = str(device.get("manufacturer") or ""), str(device.get("model") or "")
    text = f"{vendor} {model} {path.stem}".lower()
    kind = next((k for word, k in _KINDS if word in text), "other")
    mark_imported(doc, path, REPO_PATH.format(name=path.name), "modbus-local-gateway", kind)
    doc.vendor = vendor or None
    doc.title = f"{vendor} {model}".strip() or path.stem
    doc.notes = f"modbus_local_gateway device config {path.name}."
    if isinstance(device.get("max_register_read"), int):
        doc.notes += f" The gateway reads at most {device['max_register_read']} registers per request."
    taken = Occupancy()
    fields: dict[tuple[str, int], dict[str, Any]] = {}
    for section, (table, access) in SECTIONS.items():
        entities = data.get(section)
        if entities is None:
            continue
        if not isinstance(entities, Node):
            raise error_at(path, 1, f"{section}: a mapping of entities is expected")
        group = doc.group(section, section.replace("_", " "))
        for key, entity in entities.items():
            if not isinstance(entity, Node) or not isinstance(entity.get("address"), int):
                line = entity.line if isinstance(entity, Node) else entities.line
                raise error_at(path, line, f"{section}.{key}: an entity needs an integer 'address'")
            _entity(doc, path, key, entity, table, access, group, taken, fields)
    if not doc.registers:
        raise error_at(path, 1, "the config names no entity")
    return snake(path.stem, "device")


def _entity(doc: MapDoc, path: Path, key: str, entity: Node, table: str, access: str, group: str,
            taken: Occupancy, fields: dict[tuple[str, int], dict[str, Any]]) -> None:
    where = f"{path.name}:{entity.line}"
    label = str(entity.get("name") or key)
    if table in ("holding", "input") and "bits" in entity:
        _field(doc, where, key, label, entity, table, access, group, taken, fields)
        return
    reg: dict[str, Any] = {"name": doc.name(key), "table": table, "address": entity["address"], "label": label,
                           "group": group, "source": where}
    if not _typed(doc, reg, entity, where):
        return
    holder = taken.holder(reg)
    if holder is not None:
        doc.review.skipped.append(f"{where}: {key}: reads the words of {holder} (another entity of the same "
                                  "register)")
        return
    reg["access"] = access
    if table in ("holding", "input"):
        _facts(doc, reg, entity, where)
    if access == "rw":
        doc.max_quantity.setdefault(16 if table == "holding" else 15, None)
    taken.take(reg)
    doc.add(reg)


def _typed(doc: MapDoc, reg: dict[str, Any], entity: Node, where: str) -> bool:
    if reg["table"] in ("coil", "discrete"):
        reg["type"] = "bool"
        return True
    size = entity.get("size", 1)
    if entity.get("string"):
        reg.update(type="string", length=int(size))
        return True
    types = {1: "16", 2: "32", 4: "64"}
    if size not in types:
        doc.review.skipped.append(f"{where}: size {size!r} (1, 2 or 4 words)")
        return False
    if entity.get("float"):
        if size == 1:
            doc.review.skipped.append(f"{where}: a 16-bit float (drivemap has f32 and f64)")
            return False
        reg["type"] = "f" + types[size]
    else:
        reg["type"] = ("s" if entity.get("signed") else "u") + types[size]
    swap = entity.get("swap")
    if size > 1:
        reg["word_order"] = "low_first" if swap in ("word", "word_byte") else "high_first"
    if swap in ("byte", "word_byte"):
        reg["byte_order"] = "low_first"
    return True


def _facts(doc: MapDoc, reg: dict[str, Any], entity: Node, where: str) -> None:
    mult = entity.get("multiplier")
    if isinstance(mult, (int, float)) and not isinstance(mult, bool) and mult > 0 and mult != 1:
        reg["scale"] = float(mult)
    elif mult is not None and mult != 1:
        _note(reg, f"multiplier {mult!r} ({where}).")
        leave_open(doc, reg, "scale")
    if entity.get("unit_of_measurement"):
        reg["unit"] = str(entity["unit_of_measurement"])
    if "offset" in entity:
        _note(reg, f"offset {entity['offset']!r} ({where}).")
        leave_open(doc, reg, "offset")
    if "flags" in entity:
        flags = entity["flags"]
        _note(reg, "flags: " + (", ".join(f"{k}: {v}" for k, v in flags.items()) if isinstance(flags, dict)
                                else str(flags)) + f" ({where}).")
        leave_open(doc, reg, "bits")
    labels = entity.get("map") or entity.get("options") or _switch(entity)
    if isinstance(labels, dict) and reg["type"] in ("u16", "s16", "u32", "s32") and "scale" not in reg:
        pairs = [(k, str(v)) for k, v in labels.items() if isinstance(k, int) and not isinstance(k, bool) and k >= 0]
        if pairs:
            reg["enum"] = doc.enum(reg["name"], sorted(pairs))
        if len(pairs) < len(labels):
            leave_open(doc, reg, "enum")
    elif labels:
        _note(reg, f"value labels {labels!r} not kept: the register is scaled or not an integer ({where}).")
        leave_open(doc, reg, "enum")
    number = entity.get("number")
    if isinstance(number, dict) and "enum" not in reg and reg["type"] != "string":
        for key in ("min", "max"):
            value = number.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if fits(reg, value):
                    reg[key] = value
                else:
                    _note(reg, f"number {key} {value} does not fit the register's type and scale.")
                    leave_open(doc, reg, key)


def _switch(entity: Node) -> dict[int, str] | None:
    switch = entity.get("switch")
    if isinstance(switch, dict) and all(isinstance(v, int) and not isinstance(v, bool) for v in switch.values()):
        return {int(v): str(k) for k, v in switch.items()}
    return None


def _field(doc: MapDoc, where: str, key: str, label: str, entity: Node, table: str, access: str, group: str,
           taken: Occupancy, fields: dict[tuple[str, int], dict[str, Any]]) -> None:
    width, shift = entity.get("bits"), entity.get("shift_bits", 0)
    if not (isinstance(width, int) and isinstance(shift, int) and 1 <= width and 0 <= shift and shift + width <= 16):
        doc.review.skipped.append(f"{where}: {key}: bits {width!r} at shift {shift!r} is not a field of one word")
        return
    reg = fields.get((table, entity["address"]))
    if reg is None:
        reg = {"name": doc.name(f"word_{entity['address']}"), "table": table, "address": entity["address"],
               "label": f"word {entity['address']} (bit fields)", "group": group, "type": "u16",
               "access": access, "source": where, "bits": []}
        holder = taken.holder(reg)
        if holder is not None:
            doc.review.skipped.append(f"{where}: {key}: a bit field of a word {holder} reads whole")
            return
        fields[(table, entity["address"])] = reg
        taken.take(reg)
        doc.add(reg)
    used = {o for b in reg["bits"] for o in range(b["offset"], b["offset"] + b.get("width", 1))}
    if used & set(range(shift, shift + width)):
        doc.review.skipped.append(f"{where}: {key}: bits {shift}..{shift + width - 1} overlap another field")
        return
    bit: dict[str, Any] = {"name": upper(key, "FIELD"), "offset": shift, "label": label}
    if bit["name"] in {b["name"] for b in reg["bits"]}:
        bit["name"] = f"{bit['name']}_{shift}"
    if width > 1:
        bit["width"] = width
    if entity.get("map") or entity.get("options"):
        bit["notes"] = f"value labels: {entity.get('map') or entity.get('options')!r}"
    reg["bits"].append(bit)
    if access == "rw":
        doc.max_quantity.setdefault(16, None)


def _note(reg: dict[str, Any], text: str) -> None:
    reg["notes"] = f"{reg['notes']} {text}" if reg.get("notes") else text
