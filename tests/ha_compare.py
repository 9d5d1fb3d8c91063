"""Compare what a real Home Assistant shows with what ``drivemap read`` reads, entity by entity.

For the ``modbus`` export: every modbus entity is located by the export's own address/input type (and
``virtual_count`` slaves by their element address), every template entity by the modbus sensor its
template reads; the value HA shows must equal drivemap's within the precision the export gives HA.
For MQTT discovery: every discovered entity by its unique id (``drivemap_<gateway>_<device>_<object>``).
Each function returns (compared, mismatches, not compared with the reason).
"""

from __future__ import annotations

import json
import re
from typing import Any

WORDS = {"int16": 1, "uint16": 1, "int32": 2, "uint32": 2, "float32": 2, "int64": 4, "uint64": 4, "float64": 4}
_SOURCE = re.compile(r"states\('sensor\.([a-z0-9_]+)'\)")
_OPTS = re.compile(r"\{% set opts = (\[.*?\]) %\}")

Result = tuple[list[str], list[str], list[str]]


def read_index(doc: dict[str, Any]) -> dict[tuple[str, int], dict[str, Any]]:
    """``drivemap read --all --json`` -> {(table, address): entry}."""
    return {(e["table"], int(e["address"])): e for e in doc["registers"]}


def _number_matches(shown: str, value: Any, precision: int) -> bool:
    try:
        got = float(shown)
    except (TypeError, ValueError):
        return False
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return abs(got - float(value)) <= 0.5 * 10 ** -precision + 1e-9 * max(1.0, abs(float(value)))


def modbus_sensors(hub: dict[str, Any]) -> dict[str, tuple[str, int, dict[str, Any]]]:
    """unique id -> (table, address, entity config) for every modbus sensor and its virtual slaves."""
    out: dict[str, tuple[str, int, dict[str, Any]]] = {}
    for ent in hub.get("sensors", []):
        table = "input" if ent.get("input_type") == "input" else "holding"
        words = int(ent.get("count", 1)) if ent["data_type"] == "string" else WORDS[ent["data_type"]]
        out[ent["unique_id"]] = (table, int(ent["address"]), ent)
        for slave in range(1, int(ent.get("virtual_count", 0)) + 1):
            out[f"{ent['unique_id']}_{slave}"] = (table, int(ent["address"]) + slave * words, ent)
    return out


def _precision(ent: dict[str, Any]) -> int:
    if "precision" in ent:
        return int(ent["precision"])
    return 2 if ent["data_type"].startswith("float") else 0


def compare_modbus(export: dict[str, Any], ha: dict[str, dict[str, Any]], reads: dict[tuple[str, int], Any],
                   model: str) -> Result:
    hub = export["modbus"][0]
    sensors = modbus_sensors(hub)
    by_uid = {e["unique_id"]: (eid, e) for eid, e in ha.items() if e["unique_id"]}
    compared: list[str] = []
    bad: list[str] = []
    skipped: list[str] = []
    for uid, (table, address, ent) in sensors.items():
        if uid not in by_uid:
            bad.append(f"{uid}: no such entity in Home Assistant")
            continue
        eid, state = by_uid[uid]
        entry = reads.get((table, address))
        if entry is None:
            bad.append(f"{eid}: drivemap read nothing at {table} {address:#06x}")
            continue
        value, shown = entry["value"], state["state"]
        if ent["data_type"] == "string":
            ok = shown == str(value)
        elif isinstance(value, dict) or isinstance(value, list) or isinstance(value, str) or isinstance(value, bool):
            ok = shown == str(entry["raw"])  # enums, bit fields and flags: HA's sensor holds the raw number
        else:
            ok = _number_matches(shown, value, _precision(ent))
        (compared if ok else bad).append(f"{eid}: HA {shown!r} drivemap {value!r} (raw {entry['raw']})")
    for uid in (e["unique_id"] for e in hub.get("switches", [])):
        skipped.append(f"{uid}: a command switch (write-only, HA keeps an assumed state)")
    for kind in export.get("template", []):
        for domain, entities in kind.items():
            for ent in entities:
                _compare_template(domain, ent, by_uid, sensors, reads, (compared, bad, skipped))
    return compared, bad, skipped


def _expected_template(domain: str, ent: dict[str, Any], entry: dict[str, Any]) -> str | None:
    value = entry["value"]
    last = ent["name"].split()[-2 if ent["name"].endswith(" label") else -1]
    if domain == "binary_sensor":
        if isinstance(value, list):
            return "on" if last in value else "off"
        if isinstance(value, dict) and last.lower() in value:
            return "on" if value[last.lower()] else "off"
        return None
    if domain == "select":
        found = _OPTS.search(ent["state"])
        if not found:
            return None
        return next((label for v, label in json.loads(found.group(1)) if v == value), "unknown")
    if isinstance(value, dict) and last.lower() in value:  # one field of a bit-field register
        for part in str(entry["meaning"]).split("; "):
            if part.startswith(last.lower() + " "):
                text = part[len(last) + 1:]  # a value the map does not list: HA shows its number
                return text[8:] if text.startswith("UNKNOWN_") else text
        return None
    return None if entry["meaning"] is None else str(entry["meaning"])


def _compare_template(domain: str, ent: dict[str, Any], by_uid: dict[str, tuple[str, dict[str, Any]]],
                      sensors: dict[str, tuple[str, int, dict[str, Any]]], reads: dict[tuple[str, int], Any],
                      out: tuple[list[str], list[str], list[str]]) -> None:
    compared, bad, skipped = out
    uid = ent["unique_id"]
    source = _SOURCE.search(str(ent.get("state", "")))
    if uid not in by_uid:
        bad.append(f"{uid}: no such template entity in Home Assistant")
        return
    eid, state = by_uid[uid]
    if source is None or source.group(1) not in sensors:
        skipped.append(f"{eid}: reads no exported sensor")
        return
    table, address, _ent = sensors[source.group(1)]
    entry = reads.get((table, address))
    expected = None if entry is None else _expected_template(domain, ent, entry)
    if expected is None:
        skipped.append(f"{eid}: drivemap's read gives no text to compare")
        return
    ok = state["state"] == expected
    (compared if ok else bad).append(f"{eid}: HA {state['state']!r} drivemap {expected!r}")


def _mqtt_target(suffix: str, names: list[str]) -> tuple[str, int | None, str | None] | None:
    """An MQTT object id (after ``drivemap_<gw>_<dev>_``) -> (register, element, bit or "reading")."""
    for name in sorted(names, key=len, reverse=True):
        if suffix != name and not suffix.startswith(name + "_"):
            continue
        rest = suffix[len(name) + 1:].split("_", 1) if suffix != name else []
        index = int(rest.pop(0)) if rest and rest[0].isdigit() else None
        return name, index, ("_".join(rest) if rest else None)
    return None


def _mqtt_expected(component: str, payload: dict[str, Any], value: Any, part: str | None) -> str | None:
    if part not in (None, "reading"):
        if isinstance(value, list):
            value = any(flag.lower() == part for flag in value)
        elif isinstance(value, dict):
            value = value.get(part, next((v for k, v in value.items() if k.lower() == part), None))
        else:
            return None
    if component in ("binary_sensor", "switch"):
        return "on" if value else "off"
    if value is None:
        return "unknown"
    if isinstance(value, str):
        options = payload.get("options")
        return value if options is None or value in options else "unknown"
    if component == "number" and not payload["min"] <= value <= payload["max"]:
        return "unknown"
    return repr(value)


def compare_mqtt(configs: list[dict[str, Any]], ha: dict[str, dict[str, Any]], reads: dict[str, dict[str, Any]],
                 node: str) -> Result:
    """``configs``: the discovery payloads of one device; ``reads``: its ``drivemap read`` by element name."""
    by_uid = {e["unique_id"]: (eid, e) for eid, e in ha.items() if e["unique_id"]}
    names = sorted({n.split("[")[0] for n in reads})
    compared: list[str] = []
    bad: list[str] = []
    skipped: list[str] = []
    for payload in configs:
        uid, component = payload["unique_id"], payload["component"]
        if uid not in by_uid:
            bad.append(f"{uid}: discovered but no such entity in Home Assistant")
            continue
        eid, state = by_uid[uid]
        if component == "button" or "state_topic" not in payload:
            skipped.append(f"{eid}: a {component} without a state")
            continue
        target = _mqtt_target(uid[len(node) + 1:], names)
        key = None if target is None else target[0] if target[1] is None else f"{target[0]}[{target[1]}]"
        if key is None or key not in reads:
            bad.append(f"{eid}: drivemap read no register for {uid}")
            continue
        assert target is not None
        expected = _mqtt_expected(component, payload, reads[key]["value"], target[2])
        shown = state["state"]
        if expected is None:
            skipped.append(f"{eid}: no value to compare")
            continue
        ok = shown == expected or (expected not in ("on", "off", "unknown") and _number_matches(
            shown, float(expected) if _is_number(expected) else None, 6))
        (compared if ok else bad).append(f"{eid}: HA {shown!r} drivemap {expected!r}")
    return compared, bad, skipped


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
