"""The protocol section, examples and known issues of drivemap's JSON export, in the map's form.

The export writes the protocol as the model holds it (``unit_min``/``unit_max``/``unit_source``, the
exception policies as lists, ``processing_ms`` as a pair, the LRC example's bytes as hex digits, every
default filled in); :func:`protocol` gives it the map's shape and drops the nulls the schema lets a
map leave out. An example's ``meaning`` is what its frames state (unit, operation, address, quantity,
exception code); an example the export cannot give back whole (an erratum: its corrected frames; an
illegible one: its note; a function no map operation names) is left out and listed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivemap.frontend import frames
from drivemap.frontend.schema import schema
from drivemap.onboard.importers.jsonsrc import field, objects
from drivemap.onboard.importers.mapdoc import Review
from drivemap.onboard.importers.yamlsrc import located

__all__ = ["example", "known_issue", "protocol"]

_OPERATIONS = {1: "read", 2: "read", 3: "read", 4: "read", 5: "write", 6: "write", 15: "write_multiple",
               16: "write_multiple", 8: "loopback"}
_ADDRESSED = (1, 2, 3, 4, 5, 6, 15, 16)
_UNIT_KEYS = ("unit_min", "unit_max", "unit_source")


def protocol(path: Path, p: Any) -> dict[str, Any]:
    """The map's ``protocol`` section from the export's."""
    out: dict[str, Any] = {"modes": field(path, p, "modes", "list", "protocol"),
                           "unit_ids": {"min": field(path, p, "unit_min", "int", "protocol"),
                                        "max": field(path, p, "unit_max", "int", "protocol"),
                                        "source": field(path, p, "unit_source", "str", "protocol")}}
    for key, value in p.items():
        if key in _UNIT_KEYS or key == "modes":
            continue
        if key in ("exception_policy", "comm_error_policy"):
            value = _policies(path, p, key)
        elif key == "max_gap" and value == 0:
            continue
        out[key] = value
    timing = field(path, p, "timing", "object", "protocol")
    processing = field(path, timing, "processing_ms", "list", "protocol.timing", default=None, nullable=True)
    if processing is not None:
        if len(processing) != 2:
            raise located(path, timing, "protocol.timing: processing_ms must be [min, max]")
        out["timing"] = {**timing, "processing_ms": {"min": processing[0], "max": processing[1]}}
    for i, item in enumerate(objects(path, p, "exceptions", "protocol")):
        if item.get("documented") == (item.get("source") != "map choice"):
            out["exceptions"][i] = {k: v for k, v in item.items() if k != "documented"}
    checksum = field(path, p, "checksum", "object", "protocol", default=None, nullable=True)
    lrc = field(path, checksum, "lrc_example", "object", "protocol.checksum", default=None, nullable=True) \
        if checksum is not None else None
    if checksum is not None and lrc is not None:
        data = field(path, lrc, "data", "str", "protocol.checksum.lrc_example")
        out["checksum"] = {**checksum, "lrc_example": {**lrc, "data": " ".join(data[i:i + 2] for i in range(0, len(data), 2))}}
    fitted: dict[str, Any] = fit(out, schema()["properties"]["protocol"])
    return fitted


def _policies(path: Path, p: Any, key: str) -> dict[str, Any]:
    """The export's list of {case, code, source, reason} as the map's mapping case -> {code, source, reason}."""
    out: dict[str, Any] = {}
    for item in objects(path, p, key, "protocol"):
        case = field(path, item, "case", "str", f"protocol.{key}")
        out[case] = {k: v for k, v in item.items() if k != "case"}
    return out


def fit(value: Any, node: dict[str, Any]) -> Any:
    """``value`` without the nulls its schema ``node`` lets a map leave out (keys that are not required)."""
    node = _resolve(node, value)
    if isinstance(value, dict):
        props = node.get("properties", {})
        patterns = list(node.get("patternProperties", {}).values())
        required = set(node.get("required", ()))
        out = {}
        for key, item in value.items():
            if item is None and key not in required:
                continue
            child = props.get(key) or (patterns[0] if patterns else None)
            out[key] = fit(item, child) if child else item
        return out
    if isinstance(value, list) and isinstance(node.get("items"), dict):
        return [fit(item, node["items"]) for item in value]
    return value


def _resolve(node: dict[str, Any], value: Any) -> dict[str, Any]:
    """The schema node that describes ``value`` ($ref followed; of a oneOf, the alternative of its type)."""
    while True:
        if "$ref" in node:
            node = schema()["$defs"][node["$ref"].rsplit("/", 1)[1]]
        elif "oneOf" in node:
            want = "object" if isinstance(value, dict) else "array" if isinstance(value, list) else None
            node = next((alt for alt in node["oneOf"] if alt.get("type") == want or
                         ("$ref" in alt and want == "object")), {})
        else:
            return node


def example(path: Path, item: Any, where: str, proto: dict[str, Any], review: Review) -> dict[str, Any] | None:
    """The map's example from the export's (None: left out and listed for review). An erratum example
    comes back with its printed frames, its corrected ones and the reason; its meaning is what the
    frames on the line (the corrected ones) state."""
    name = field(path, item, "name", "str", where)
    mode = field(path, item, "mode", "str", where)
    status = field(path, item, "status", "str", where)
    reason = field(path, item, "erratum", "str", where, default=None, nullable=True)
    if status not in ("verified", "erratum") or (status == "erratum") != (reason is not None):
        review.skipped.append(f"example {name} ({status}): the export does not carry what makes it {status}; "
                              "add it from the map")
        return None
    out: dict[str, Any] = {"name": name, "source": field(path, item, "source", "str", where), "mode": mode}
    parsed: dict[str, frames.Frame | None] = {}
    corrected: dict[str, str] = {}
    for part in ("request", "response", "corrected_request", "corrected_response"):
        text = _frame_text(path, item, part, where, mode, parsed)
        if part.startswith("corrected_"):
            if text is not None:
                corrected[part.removeprefix("corrected_")] = text
        else:
            out[part] = text
    if reason is not None and not corrected:
        review.skipped.append(f"example {name} (erratum): the export carries no corrected frame; add it from the map")
        return None
    wire = {part: parsed.get(f"corrected_{part}") or parsed[part] for part in ("request", "response")}
    meaning = _meaning(wire["request"], wire["response"], proto)
    if meaning is None:
        review.skipped.append(f"example {name}: a function no map operation names (read, write, write_multiple, "
                              "loopback)")
        return None
    out["meaning"] = meaning
    if reason is not None:
        out["erratum"] = {**corrected, "reason": reason}
    return out


def _frame_text(path: Path, item: Any, part: str, where: str, mode: str,
                parsed: dict[str, frames.Frame | None]) -> str | None:
    """One frame of an example in the map's form (rtu: hex bytes with spaces), parsed into ``parsed``."""
    default: dict[str, Any] = {"default": None} if part.startswith("corrected_") else {}
    text: str | None = field(path, item, part, "str", where, nullable=True, **default)
    if text is not None and mode == "rtu":
        text = " ".join(text[i:i + 2] for i in range(0, len(text), 2))
    try:
        parsed[part] = None if text is None else frames.parse(text, mode)
    except frames.FrameSyntaxError as exc:
        raise located(path, item, f"{where}: {part}: {exc}") from None
    return text


def _meaning(request: frames.Frame | None, response: frames.Frame | None, proto: dict[str, Any]) -> dict[str, Any] | None:
    """What the frames state: unit, operation, address and quantity (request), exception code (response)."""
    first = request or response
    if first is None or len(first.body) < 2:
        return None
    fc = first.body[1] & 0x7F
    if fc not in _OPERATIONS:
        return None
    meaning: dict[str, Any] = {"unit": first.body[0], "operation": _OPERATIONS[fc]}
    if request is not None and fc in _ADDRESSED and len(request.body) >= 4:
        meaning["address"] = int.from_bytes(request.body[2:4], "big")
        if fc in (1, 2, 3, 4, 15, 16) and len(request.body) >= 6:
            quantity = int.from_bytes(request.body[4:6], "big")
            if 1 <= quantity <= 2000:
                meaning["quantity"] = quantity
    if response is not None and response.body[1] & 0x80 and len(response.body) > 2:
        meaning["exception"] = response.body[2]
    if request is not None and response is None and request.body[0] == proto.get("broadcast_address"):
        meaning["broadcast"] = True
    return meaning


def known_issue(path: Path, item: Any, where: str, names: set[str], review: Review) -> dict[str, Any]:
    out: dict[str, Any] = {key: field(path, item, key, "str", where) for key in ("title", "source", "printed")}
    corrected = field(path, item, "corrected", "str", where, default=None, nullable=True)
    if corrected is not None:
        out["corrected"] = corrected
    out.update({key: field(path, item, key, "str", where) for key in ("chosen", "reason")})
    affects = field(path, item, "affects", "list", where, default=[])
    kept = [ref for ref in affects if isinstance(ref, str) and ref.split("[")[0] in names]
    if len(kept) != len(affects):
        gone = ", ".join(str(ref) for ref in affects if ref not in kept)
        review.notes.append(f"known issue {out['title']!r}: affects {gone}, which the import left out")
    if kept:
        out["affects"] = kept
    return out
