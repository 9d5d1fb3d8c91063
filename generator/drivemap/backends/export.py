"""``drivemap export MODEL --format json``: the normalized model (a stable contract)."""

from __future__ import annotations

import dataclasses
from typing import Any

from drivemap.frontend.frames import export_form
from drivemap.model.nodes import FunctionCode, Model, Register


def _register_entries(model: Model, reg: Register) -> list[dict[str, Any]]:
    """Each element of ``reg`` (numbers are the model's: ints when whole)."""
    enum = None
    if reg.enum:
        enum = {v.name: v.value for v in model.enum(reg.enum).members}
    bits = [{"name": b.name, "offset": b.offset, "width": b.width} for b in reg.bits] or None
    out = []
    for i in range(reg.count):
        out.append(
            {
                "name": reg.element_name(i),
                "address": reg.element_address(i),
                "param": reg.element_param(i),
                "access": reg.access,
                "type": reg.type,
                "scale": reg.scale,
                "offset": reg.offset,
                "unit": reg.unit,
                "min": reg.min,
                "max": reg.max,
                "default": reg.default_at(i),
                "reflect": None if reg.reflect == "unknown" else reg.reflect,
                "storage": None if reg.storage == "unknown" else reg.storage,
                "broadcast": _broadcast(model, reg),
                "enum": enum,
                "bits": bits,
                "page": {"selector": reg.page.selector, "value": reg.page.value} if reg.page else None,
                "table": reg.table,
                "length": reg.words,
                "word_order": reg.word_order,
                "byte_order": reg.byte_order,
                "encoding": reg.encoding if reg.type == "string" else None,
                "scale_register": reg.scale_register,
                "not_available": list(reg.not_available) or None,
                # present only where the map states what its source leaves open
                **({"review": list(reg.review)} if reg.review else {}),
            }
        )
    return out


def _broadcast(model: Model, reg: Register) -> bool | None:
    """Whether a register may be written by broadcast: the model's answer, but unknown (None) where it
    derives ``false`` though the map leaves a function that writes it open (``broadcast: null``)."""
    if reg.broadcast or not reg.writable or reg.scale_register:
        return reg.broadcast
    single, multiple = (0x05, 0x0F) if reg.table == "coil" else (0x06, 0x10)
    deciding = [fc.broadcast for fc in model.protocol.function_codes
                if fc.code == multiple or (fc.code == single and reg.words == 1)]
    return None if any(b is None for b in deciding) else reg.broadcast


#: Fields of model nodes that are no part of the contract: where a node stands in its map, the cache's key.
_NOT_CONTRACT = frozenset({"src", "cache_key"})


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value) if f.name not in _NOT_CONTRACT}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, bytes):
        return value.hex().upper()
    return value


def _function(fc: FunctionCode) -> dict[str, Any]:
    """A function code in the contract's key order (the map's order, not the class's)."""
    return {"code": fc.code, "name": fc.name, "max_quantity": fc.max_quantity, "broadcast": fc.broadcast,
            "request_bytes": _plain(fc.request_bytes), "response_bytes": _plain(fc.response_bytes),
            "source": fc.source, "notes": fc.notes, "broadcast_reason": fc.broadcast_reason}


#: The contract's protocol keys, in its order: what the map says (the runtime's ``serial`` and
#: ``fixed_units``, derived from the ports, are not part of it).
PROTOCOL_KEYS = ("modes", "unit_min", "unit_max", "unit_source", "broadcast_address", "ports", "function_codes",
                 "exceptions", "comm_errors", "exception_policy", "comm_error_policy", "comm_error_history", "timing",
                 "max_frame_bytes", "configuration", "checksum", "source", "notes", "running_state", "reply_quirks",
                 "max_gap", "alignment")


def _protocol(model: Model) -> dict[str, Any]:
    p = model.protocol
    return {key: [_function(fc) for fc in p.function_codes] if key == "function_codes" else _plain(getattr(p, key))
            for key in PROTOCOL_KEYS}


def _device_extras(model: Model) -> dict[str, Any]:
    dev = model.device
    out: dict[str, Any] = {}
    if dev.evidence is not None:
        out["evidence"] = dev.evidence
    if dev.origin is not None:
        out["origin"] = _plain(dev.origin)
    if dev.kind is not None:
        out["kind"] = dev.kind
    return out


def export(model: Model) -> dict[str, Any]:
    """The export contract of one compiled model."""
    return {
        "model": model.device.model,
        "title": model.device.title,
        # the evidence level, origin and kind: present only where the map states them
        **_device_extras(model),
        "protocol": _protocol(model),
        "registers": [entry for reg in model.registers for entry in _register_entries(model, reg)],
        "reserved": [
            {
                "start": r.start,
                "end": r.end,
                "readable": r.readable,
                "writable": r.writable,
                "page": {"selector": r.page.selector, "value": r.page.value} if r.page else None,
                "table": r.table,
                "kind": r.kind,
                "source": r.source,
            }
            for r in model.reserved
        ],
        "known_issues": [_plain(issue) for issue in model.known_issues],
        "identity": [{"register": c.register, "kind": c.kind, "values": list(c.values), "source": c.source}
                     for c in model.identity],
        "examples": [
            {
                "name": ex.name,
                "source": ex.source,
                "mode": ex.mode,
                "request": export_form(ex.request, ex.mode),
                "response": export_form(ex.response, ex.mode),
                "status": ex.status,
                "erratum": ex.erratum,
                "corrected_request": export_form(ex.corrected_request, ex.mode),
                "corrected_response": export_form(ex.corrected_response, ex.mode),
            }
            for ex in model.examples
        ],
    }
