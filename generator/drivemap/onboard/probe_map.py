"""The map of a SunSpec model chain found by ``drivemap probe --sunspec``.

With the ``drivemap[sunspec]`` extra each model the SunSpec definitions know becomes named points
(the same layout as ``drivemap import sunspec``, with the device's own L); a vendor model, or every
model without the extra, becomes its ID and L registers and its words as raw u16 arrays.
"""

from __future__ import annotations

from drivemap.onboard.importers.mapdoc import MapDoc
from drivemap.onboard.importers.sunspec import (
    SunSpecError,
    add_end,
    add_marker,
    add_model,
    load_model_def,
    models_dir,
)
from drivemap.onboard.probe_sunspec import Chain

__all__ = ["sunspec_registers"]


def sunspec_registers(doc: MapDoc, chain: Chain) -> None:
    add_marker(doc, chain.base)
    named = models_dir() is not None
    if not named:
        doc.review.notes.append("without drivemap[sunspec] the models are raw words: pip install 'drivemap[sunspec]'")
    for model_id, at, length in chain.models:
        definition = load_model_def(model_id) if named else None
        if definition is not None:
            try:
                add_model(doc, definition, length, at, f"model_{model_id}.json, L {length} as read")
                continue
            except SunSpecError as exc:
                doc.review.notes.append(f"model {model_id} as raw words: {exc}")
        elif named:
            doc.review.notes.append(f"model {model_id} is not a SunSpec model the definitions know: raw words")
        _raw_model(doc, model_id, at, length)
    if chain.ended:
        end = chain.models[-1][1] + 2 + chain.models[-1][2] if chain.models else chain.base + 2
        add_end(doc, end)


def _raw_model(doc: MapDoc, model_id: int, at: int, length: int) -> None:
    group = doc.group(f"model_{model_id}", f"SunSpec model {model_id}")
    for name, offset, label in (("id", 0, "Model ID"), ("length", 1, "Model length L")):
        doc.add({"name": doc.name(f"model_{model_id}_{name}"), "table": "holding", "address": at + offset,
                 "type": "u16", "access": "r", "label": label, "group": group, "source": doc.source})
    for start in range(at + 2, at + 2 + length, 256):
        count = min(256, at + 2 + length - start)
        reg = {"name": doc.name(f"model_{model_id}_words_{start - at - 2}"), "table": "holding", "address": start,
               "type": "u16", "access": "r"}
        if count > 1:
            reg["count"] = count
        reg.update(group=group, source=doc.source, notes=f"Words {start - at - 2}.. of model {model_id} (raw).")
        doc.add(reg)
