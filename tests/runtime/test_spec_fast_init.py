"""The spec classes' fast ``__init__`` (runtime/spec ``_fast_init``) builds the same objects as the
dataclass's own and refuses the same mistakes; generated spec modules construct thousands of them."""

from __future__ import annotations

import dataclasses
import pickle
import re
from typing import Any

import pytest

from drivemap.runtime.spec import BitSpec, RegisterSpec, _fast_init

#: The same fields with the dataclass's generated ``__init__`` (a dataclass subclass gets its own, as model nodes do).
PlainRegisterSpec = dataclasses.dataclass(frozen=True)(type("RegisterSpec", (RegisterSpec,), {}))


CASES: list[tuple[tuple[Any, ...], dict[str, Any]]] = [
    ((), {"name": "speed", "address": 0x100}),
    ((), {"name": "energy", "address": 7, "type": "u32", "word_order": "low_first", "scale": 0.01, "unit": "kWh"}),
    (("text", 12), {"type": "string", "length": 8, "table": "input"}),
    (("flags", 3, "u16", "holding", "rw"), {"bits": (BitSpec("RUN", 0, 1, "run"),), "bits_class": "Flags"}),
]


@pytest.mark.parametrize(("args", "kwargs"), CASES)
def test_same_object_as_the_dataclass_builds(args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
    assert RegisterSpec.__init__ is not PlainRegisterSpec.__init__  # the fast one against the generated one
    fast, plain = RegisterSpec(*args, **kwargs), PlainRegisterSpec(*args, **kwargs)
    assert vars(fast) == vars(plain)
    assert (fast.words, fast.signed) == (plain.words, plain.signed)
    assert repr(fast) == repr(plain)
    assert fast == RegisterSpec(*args, **kwargs) and hash(fast) == hash(RegisterSpec(*args, **kwargs))
    assert pickle.loads(pickle.dumps(fast)) == fast
    assert dataclasses.replace(fast, address=9).address == 9
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.address = 1  # type: ignore[misc]


@pytest.mark.parametrize(("args", "kwargs", "message"), [
    ((), {"address": 1}, r"missing 1 required argument\(s\): 'name'"),
    ((), {}, r"missing 2 required argument\(s\): 'name', 'address'"),
    ((), {"name": "x", "address": 1, "adress": 2}, r"unexpected keyword argument 'adress'"),
    (("x",), {"name": "y", "address": 1}, r"multiple values for argument 'name'"),
    (tuple(range(60)), {}, r"takes \d+ positional arguments but 61 were given"),
])
def test_refuses_what_the_dataclass_refuses(args: tuple[Any, ...], kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(TypeError, match=message):
        RegisterSpec(*args, **kwargs)
    with pytest.raises(TypeError):
        PlainRegisterSpec(*args, **kwargs)


def test_default_factories_are_called_per_instance() -> None:
    @_fast_init
    @dataclasses.dataclass(frozen=True)
    class Holder:
        name: str
        items: list[int] = dataclasses.field(default_factory=list)
        cache: dict[str, int] = dataclasses.field(init=False, default_factory=dict, compare=False)

    a, b = Holder("a"), Holder("b", [1])
    assert a.items == [] and a.items is not Holder("c").items and b.items == [1]
    assert a.cache == {} and a.cache is not b.cache
    assert re.fullmatch(r".*Holder\.__init__", Holder.__init__.__qualname__)


def test_a_slotted_class_keeps_its_own_init() -> None:
    @dataclasses.dataclass(frozen=True, slots=True)
    class Slotted:
        name: str

    init = Slotted.__init__
    assert _fast_init(Slotted).__init__ is init
