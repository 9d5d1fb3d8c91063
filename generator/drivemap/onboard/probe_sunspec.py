"""``drivemap probe --sunspec``: find the "SunS" marker and walk the SunSpec model chain.

The marker is looked for at 40000, 50000 and 0 (holding registers, the SunSpec base addresses);
from base+2 each model is its ID and its length L, the next one L+2 words further, until the end
model (ID 0xFFFF). Only reads are sent, each at most ``max_quantity`` words.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from drivemap.onboard.importers.sunspec import END_ID, MARKER
from drivemap.onboard.probe import Prober

__all__ = ["BASES", "Chain", "walk"]

BASES = (40000, 50000, 0)
_MAX_MODELS = 256


@dataclass
class Chain:
    """What the walk found: the base, (model id, address of its ID, L) in order, every word read."""

    base: int
    models: list[tuple[int, int, int]] = field(default_factory=list)
    values: dict[int, int] = field(default_factory=dict)
    ended: bool = False
    problem: str = ""


def walk(prober: Prober, bases: tuple[int, ...] = BASES) -> Chain | None:
    """The chain from the first base where "SunS" reads, or None when no base has it."""
    for base in bases:
        marker = prober.read("holding", base, 2)
        if marker is not None and tuple(marker) == MARKER:
            chain = Chain(base, values={base: marker[0], base + 1: marker[1]})
            _follow(prober, chain)
            return chain
    return None


def _follow(prober: Prober, chain: Chain) -> None:
    address = chain.base + 2
    for _ in range(_MAX_MODELS):
        header = prober.read("holding", address, 2)
        if header is None:
            chain.problem = f"the model header at {address} does not read"
            return
        model_id, length = header
        chain.values.update({address: model_id, address + 1: length})
        if model_id == END_ID:
            chain.ended = True
            return
        if address + 2 + length > 0x10000:
            chain.problem = f"model {model_id} at {address} claims L {length}, past the end of the table"
            return
        chain.models.append((model_id, address, length))
        _read_body(prober, chain, address + 2, length)
        address += 2 + length
    chain.problem = f"more than {_MAX_MODELS} models: stopped"


def _read_body(prober: Prober, chain: Chain, start: int, length: int) -> None:
    into: dict[int, int] = {}
    prober.sweep("holding", start, start + length - 1, into)
    chain.values.update(into)
    if len(into) < length:
        chain.problem = f"{length - len(into)} words of the model at {start - 2} do not read"
