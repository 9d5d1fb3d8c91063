"""View of ``generated/<model>/simulator.py``: the dialect it documents; the class is the runtime's ModelSimulator bound to SPEC."""

from __future__ import annotations

from typing import Any

from drivemap.backends.common import Options
from drivemap.backends.views.common import header, provenance
from drivemap.model.nodes import Model

_CASE_TEXT = {
    "illegal_function": "unsupported function code",
    "illegal_address": "bad address",
    "illegal_quantity": "quantity above the function's maximum",
    "bad_length": "request of the wrong length",
    "out_of_range": "value out of range",
    "read_only": "write to a read-only register",
    "write_only": "read of a write-only register",
    "busy": "write refused while running",
    "bad_frame": "bad CRC/LRC or frame format",
    "timeout": "communication timeout",
}


def _code(code: int | None) -> str:
    return "no reply" if code is None else f"{code:02X}h"


def context(model: Model, options: Options) -> dict[str, Any]:
    p = model.protocol
    dialect = [
        (item.case, _CASE_TEXT.get(item.case, item.case), _code(item.code), item.source, item.reason)
        for item in p.exception_policy
    ]
    recorded = [
        (item.case, _CASE_TEXT.get(item.case, item.case), _code(item.code).replace("no reply", "nothing recorded"))
        for item in p.comm_error_policy
    ]
    broadcast = [f"{fc.code:02X}h" for fc in p.function_codes if fc.broadcast is True and fc.code in (0x06, 0x10)]
    proc = p.timing.processing_ms
    if proc is not None:
        timing = f"{proc[0]:g}-{proc[1]:g} ms processing time"
    elif p.timing.inter_frame_gap_ms is not None:
        timing = f"no reply sooner than {p.timing.inter_frame_gap_ms:g} ms"
    else:
        timing = "no processing time in the map: replies at once"
    eeprom = sum(r.count for r in model.registers if r.storage == "eeprom")
    return {
        "header": header(model, options),
        "provenance": provenance(model),
        "package": options.package,
        "model": model,
        "class_name": "Simulator",
        "functions": ", ".join(f"{fc.code:02X}h" for fc in p.function_codes),
        "dialect": dialect,
        "recorded": recorded,
        "history": p.comm_error_history,
        "broadcast": ", ".join(broadcast) if broadcast and p.broadcast_address is not None else None,
        "broadcast_address": p.broadcast_address,
        "timing": timing,
        "eeprom": eeprom,
        "loopback": p.function(0x08) is not None,
    }
