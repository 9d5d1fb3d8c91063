"""``drivemap import sunspec``: SunSpec model definitions (pysunspec2's JSON models) laid out as a map.

The models sit one after another from ``base`` the way a SunSpec device lays them out: the "SunS"
marker (two words) at ``base``, then each model as its ID and L registers and L words of points,
then the end model (ID 0xFFFF, L 0). Each point becomes a register with its SunSpec type, unit,
scale factor (a ``sunssf`` point -> ``scale_register``; a fixed exponent -> ``scale``), the SunSpec
"not implemented" value as ``not_available`` (not for ID and L), enums (``enum16``/``enum32``) and
bit fields (``bitfield16``/``bitfield32``); ``access: rw`` where the model says RW.

A model's length depends on the device only through its repeating groups: such a model needs its L
(``160:48``, or the L a probe read), since drivemap does not guess how many repeats a device has.
"""

from __future__ import annotations

import importlib.util
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivemap.onboard.importers.mapdoc import MapDoc, snake, upper

__all__ = ["SunSpecError", "add_end", "add_marker", "add_model", "add_models", "load_model_def", "models_dir"]

#: SunSpec point type -> (drivemap type, "not implemented" raw value or None).
TYPES: dict[str, tuple[str, int | None]] = {
    "uint16": ("u16", 0xFFFF), "int16": ("s16", -0x8000), "count": ("u16", None), "acc16": ("u16", 0),
    "enum16": ("u16", 0xFFFF), "bitfield16": ("u16", 0xFFFF), "sunssf": ("s16", -0x8000), "pad": ("u16", 0x8000),
    "uint32": ("u32", 0xFFFFFFFF), "int32": ("s32", -0x80000000), "acc32": ("u32", 0), "enum32": ("u32", 0xFFFFFFFF),
    "bitfield32": ("u32", 0xFFFFFFFF), "ipaddr": ("u32", 0), "float32": ("f32", 0x7FC00000),
    "uint64": ("u64", 0xFFFFFFFFFFFFFFFF), "int64": ("s64", -0x8000000000000000), "acc64": ("u64", 0),
    "eui48": ("u64", None), "string": ("string", None), "ipv6addr": ("string", None),
}
MARKER = (0x5375, 0x6E53)  # "SunS"
#: SunSpec unit spellings -> the usual symbols (the others are kept as the model writes them)
UNITS = {"Pct": "%", "C": "°C", "F": "°F", "Secs": "s", "AH": "Ah", "ohms": "Ω"}
END_ID = 0xFFFF


class SunSpecError(ValueError):
    """A model that cannot be laid out (message for a located error)."""


def models_dir() -> Path | None:
    """pysunspec2's bundled JSON models (None without the ``drivemap[sunspec]`` extra)."""
    spec = importlib.util.find_spec("sunspec2")
    if spec is None or spec.origin is None:
        return None
    folder = Path(os.path.dirname(spec.origin)) / "models" / "json"
    return folder if folder.is_dir() else None


def load_model_def(model_id: int) -> dict[str, Any] | None:
    folder = models_dir()
    if folder is None:
        raise SunSpecError("SunSpec model numbers need the SunSpec models: pip install 'drivemap[sunspec]' "
                           "(or give a model's JSON file)")
    path = folder / f"model_{model_id}.json"
    if not path.is_file():
        return None
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data


def _fixed_size(group: dict[str, Any]) -> int:
    return sum(int(p.get("size", 1)) for p in group.get("points", []))


def _group_size(group: dict[str, Any]) -> int:
    if any(g.get("groups") for g in group.get("groups", [])):
        raise SunSpecError(f"group {group.get('name')!r} nests repeating groups (not supported)")
    return _fixed_size(group) + sum(_fixed_size(g) for g in group.get("groups", []))


@dataclass
class _Place:
    doc: MapDoc
    group: str
    source: str
    sf_names: dict[str, str]
    pending: list[tuple[dict[str, Any], str]]
    limit: int = 0x10000

    def resolve(self) -> None:
        """Scale-factor points usually follow the points they scale: resolved once the model is laid out."""
        for reg, sf in self.pending:
            target = self.sf_names.get(sf)
            if target is None:
                self.doc.review.miss(reg["name"], f"scale factor {sf} (not a point of the model)")
            else:
                reg["scale_register"] = target


def add_models(doc: MapDoc, defs: list[tuple[dict[str, Any], int | None, str]], base: int) -> int:
    """Lay out ``defs`` ((model JSON, L or None, where it came from)) from ``base``; the end address."""
    if not 0 <= base <= 0xFFFD:
        raise SunSpecError(f"--base {base}: the address of 'SunS' is 0..65533")
    add_marker(doc, base)
    address = base + 2
    for model, length, where in defs:
        address = add_model(doc, model, length, address, where)
    add_end(doc, address)
    return address + 2


def add_marker(doc: MapDoc, base: int) -> None:
    grp = doc.group("sunspec", "SunSpec marker and end model")
    marker = _reg(doc, "sunspec_id", base, "u32", grp, "SunSpec marker 'SunS' (0x53756E53)", doc.source)
    doc.add({**marker, "word_order": "high_first"})


def add_end(doc: MapDoc, address: int) -> None:
    grp = doc.group("sunspec", "SunSpec marker and end model")
    for name, offset, label in (("end_model_id", 0, "End model ID (0xFFFF)"), ("end_model_length", 1, "End model L (0)")):
        doc.add(_reg(doc, name, address + offset, "u16", grp, label, doc.source))


def add_model(doc: MapDoc, model: dict[str, Any], length: int | None, address: int, where: str) -> int:
    top = model.get("group")
    if not isinstance(top, dict) or not isinstance(model.get("id"), int):
        raise SunSpecError(f"{where}: not a SunSpec model definition (no 'id' and 'group')")
    fixed = _fixed_size(top) - 2
    repeats = top.get("groups", [])
    if repeats and length is None:
        raise SunSpecError(f"model {model['id']} has a repeating group: give its length L as "
                           f"{model['id']}:L (the device's L register)")
    length = fixed if length is None else length
    if address + 2 + length > 0x10000:
        raise SunSpecError(f"model {model['id']} does not fit below 0x10000 at {address}")
    place = _Place(doc, doc.group(snake(top.get("name", f"model_{model['id']}")), top.get("label") or top["name"]),
                   f"SunSpec model {model['id']} ({where})", {}, [], address + 2 + length)
    at = _points(place, top, address, prefix="", count=1, stride=0)
    for sub in repeats:
        size = _group_size(sub)
        count = (address + 2 + length - at) // size if size else 0
        if count >= 1:
            _points(place, sub, at, prefix=snake(sub.get("name", "group")) + "_", count=count, stride=size)
            at += count * size
    place.resolve()
    if at < address + 2 + length:
        doc.review.notes.append(f"model {model['id']}: L {length} leaves {address + 2 + length - at} words "
                                f"that its definition does not describe (from {at})")
    return address + 2 + length


def _points(place: _Place, group: dict[str, Any], at: int, *, prefix: str, count: int, stride: int) -> int:
    for point in group.get("points", []):
        size = int(point.get("size", 1))
        if at + (count - 1) * stride + size > place.limit:  # the last element's end
            place.doc.review.skipped.append(f"{place.source}: point {point.get('name')} lies past the model's "
                                            f"length L")
        elif point.get("type") != "pad":
            _point(place, point, at, prefix, count, stride)
        at += size
    return at


def _point(place: _Place, point: dict[str, Any], at: int, prefix: str, count: int, stride: int) -> None:
    doc = place.doc
    kind = str(point.get("type"))
    if kind not in TYPES:
        doc.review.skipped.append(f"{place.source}: point {point.get('name')} of type {kind!r}")
        return
    base_name = {"ID": "model_id", "L": "model_length"}.get(point["name"], point["name"])
    wanted = f"{place.group}_{snake(base_name)}" if point["name"] in ("ID", "L") else prefix + snake(base_name)
    name = doc.name(wanted if wanted not in doc._names else f"{place.group}_{wanted}")
    place.sf_names.setdefault(point["name"], name)
    dtype, missing = TYPES[kind]
    reg = _reg(doc, name, at, dtype, place.group, point.get("label"), place.source)
    if dtype == "string":
        reg["length"] = int(point.get("size", 1))
    elif dtype not in ("u16", "s16"):
        reg["word_order"] = "high_first"  # SunSpec: big-endian, most significant register first
    if count > 1:
        reg.update(count=count, stride=stride)
    if point.get("access") == "RW":
        reg["access"] = "rw"
    if missing is not None and point["name"] not in ("ID", "L"):
        reg["not_available"] = [missing]
    if point.get("units"):
        reg["unit"] = UNITS.get(str(point["units"]), str(point["units"]))
    _scale(place, reg, point)
    _symbols(place, reg, point, kind)
    if point.get("desc"):
        reg["notes"] = str(point["desc"])
    doc.add(reg)


def _reg(doc: MapDoc, name: str, address: int, dtype: str, group: str, label: str | None,
         source: str) -> dict[str, Any]:
    reg: dict[str, Any] = {"name": name, "table": "holding", "address": address, "type": dtype, "access": "r"}
    if label:
        reg["label"] = label
    reg.update(group=group, source=source)
    return reg


def _scale(place: _Place, reg: dict[str, Any], point: dict[str, Any]) -> None:
    sf = point.get("sf")
    if isinstance(sf, int) and sf != 0:
        reg["scale"] = float(10.0 ** sf)
    elif isinstance(sf, str):
        place.pending.append((reg, sf))


def _symbols(place: _Place, reg: dict[str, Any], point: dict[str, Any], kind: str) -> None:
    symbols = point.get("symbols") or []
    if not symbols:
        return
    if kind.startswith("enum"):
        pairs = [(int(s["value"]), str(s.get("label") or s["name"])) for s in symbols]
        reg["enum"] = place.doc.enum(f"{place.group}_{reg['name']}", pairs)
    elif kind.startswith("bitfield"):
        seen: set[str] = set()
        bits = []
        for s in sorted(symbols, key=lambda s: int(s["value"])):
            bit_name = upper(str(s["name"]), f"bit_{s['value']}")
            if bit_name in seen or int(s["value"]) > (15 if kind == "bitfield16" else 31):
                continue
            seen.add(bit_name)
            bits.append({"name": bit_name, "offset": int(s["value"]), "label": str(s.get("label") or s["name"])})
        reg["bits"] = bits
