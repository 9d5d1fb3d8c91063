"""``@record`` and ``@snapshot`` (runtime/client/records) make the classes ``dataclasses.dataclass`` would,
without its per-class machinery: the same fields, parameters, equality, hashing, frozenness and matching."""

from __future__ import annotations

import dataclasses
import enum
import pickle
from typing import Any, ClassVar

import pytest

from drivemap.runtime.client.api.accessors import SnapshotBase
from drivemap.runtime.client.values.records import record, snapshot


class Mode(enum.IntEnum):
    OFF = 0
    ON = 1


@record
class Bits:
    """Bits of a status word."""

    run: bool
    """bit 0"""
    mode: Mode


@dataclasses.dataclass(frozen=True)
class BitsDC:
    run: bool
    mode: Mode


@snapshot(init=False, repr=False)
class Snap(SnapshotBase):
    speed: float | None = None
    mode: Mode | None = None
    counts: tuple[int | None, ...] | None = None


@dataclasses.dataclass(frozen=True, repr=False, init=False)
class SnapDC(SnapshotBase):
    speed: float | None = None
    mode: Mode | None = None
    counts: tuple[int | None, ...] | None = None


def _fields(cls: Any) -> list[tuple[Any, ...]]:
    return [(f.name, f.type, f.default, f.default_factory, f.init, f.repr, f.hash, f.compare, dict(f.metadata),
             f.kw_only, f._field_type) for f in dataclasses.fields(cls)]  # type: ignore[attr-defined]


@pytest.mark.parametrize(("made", "real"), [(Bits, BitsDC), (Snap, SnapDC)])
def test_same_dataclass_description(made: Any, real: Any) -> None:
    assert _fields(made) == _fields(real)
    assert made.__match_args__ == real.__match_args__
    assert dataclasses.is_dataclass(made)


def test_record_behaves_like_the_frozen_dataclass() -> None:
    a, b = Bits(True, Mode.ON), Bits(run=True, mode=Mode.ON)
    assert a == b and hash(a) == hash(b) and a != Bits(False, Mode.ON) and a != BitsDC(True, Mode.ON)
    assert repr(a) == "Bits(run=True, mode=<Mode.ON: 1>)"
    assert dataclasses.asdict(a) == {"run": True, "mode": Mode.ON}
    assert dataclasses.replace(a, run=False) == Bits(False, Mode.ON)
    assert pickle.loads(pickle.dumps(a)) == a
    match a:
        case Bits(run, mode):
            assert (run, mode) == (True, Mode.ON)
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.run = False  # type: ignore[misc]
    with pytest.raises(TypeError, match="missing 1 required"):
        Bits(True)  # type: ignore[call-arg]


def test_snapshot_behaves_like_the_frozen_dataclass() -> None:
    made, real = Snap(speed=1.5, counts=(1, None)), SnapDC(speed=1.5, counts=(1, None))
    assert made == Snap(speed=1.5, counts=(1, None), _values={("x", 0): 1})  # _values is not compared
    assert made != Snap(speed=2.0) and made != real
    assert hash(made) == hash(Snap(speed=1.5, counts=(1, None)))
    assert repr(made) == repr(real).replace("SnapDC", "Snap") == "Snap(speed=1.5, counts=(1, None))"
    assert dataclasses.replace(made, mode=Mode.OFF).mode is Mode.OFF
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.speed = 2.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        del made.speed
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'"):
        Snap(colour=1)


def test_a_class_the_shortcut_does_not_fit_gets_the_dataclass() -> None:
    @snapshot(init=False, repr=False)
    class Odd(SnapshotBase):
        limit: ClassVar[int] = 3
        speed: float | None = None

    assert [f.name for f in dataclasses.fields(Odd)] == ["_values", "speed"] and Odd.limit == 3
    with pytest.raises(TypeError):
        snapshot(init=True)
