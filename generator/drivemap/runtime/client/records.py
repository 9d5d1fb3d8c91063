"""``@record``: the frozen dataclasses of generated bit-field registers, built in linear time.

``dataclasses.dataclass(frozen=True)`` compiles six methods (``__init__``, ``__repr__``,
``__eq__``, ``__hash__``, ``__setattr__``, ``__delattr__``) for every class with ``exec``: about
1 ms per class, so a map with thousands of bit-field registers spends seconds importing its
client. :func:`record` makes the same frozen dataclass (``dataclasses.fields``, ``replace``,
``asdict``, ``match`` all work) from methods shared by every record class: ``__init__`` takes the
fields by position or keyword, all required; ``repr``, equality (same class only), hashing and
the refusal to assign (:class:`dataclasses.FrozenInstanceError`) are what the dataclass would
have. Type checkers see a dataclass (:func:`typing.dataclass_transform`). Only
``__dataclass_params__`` tells the difference (the methods are not the dataclass's own).
"""

from __future__ import annotations

import dataclasses
import reprlib
from typing import Any, TypeVar, dataclass_transform

__all__ = ["record"]

C = TypeVar("C", bound=type)


def _names(self: Any) -> tuple[str, ...]:
    return type(self).__record_fields__  # type: ignore[no-any-return]


def _init(self: Any, *args: Any, **kwargs: Any) -> None:
    names = _names(self)
    cls = type(self).__qualname__
    if len(args) > len(names):
        raise TypeError(f"{cls}.__init__() takes {len(names) + 1} positional arguments but {len(args) + 1} were given")
    state = self.__dict__
    for name, value in zip(names, args, strict=False):  # fewer arguments than fields: checked below
        state[name] = value
    for name, value in kwargs.items():
        if name not in type(self).__record_field_set__:
            raise TypeError(f"{cls}.__init__() got an unexpected keyword argument {name!r}")
        if name in state:
            raise TypeError(f"{cls}.__init__() got multiple values for argument {name!r}")
        state[name] = value
    missing = [n for n in names if n not in state]
    if missing:
        raise TypeError(f"{cls}.__init__() missing {len(missing)} required argument(s): "
                        + ", ".join(repr(n) for n in missing))


@reprlib.recursive_repr()
def _repr(self: Any) -> str:
    return f"{type(self).__qualname__}(" + ", ".join(f"{n}={getattr(self, n)!r}" for n in _names(self)) + ")"


def _astuple(self: Any) -> tuple[Any, ...]:
    return tuple(getattr(self, n) for n in _names(self))


def _eq(self: Any, other: object) -> Any:
    if other.__class__ is self.__class__:
        return _astuple(self) == _astuple(other)
    return NotImplemented


def _hash(self: Any) -> int:
    return hash(_astuple(self))


def _setattr(self: Any, name: str, value: Any) -> None:
    raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")


def _delattr(self: Any, name: str) -> None:
    raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")


_METHODS: dict[str, Any] = {"__init__": _init, "__repr__": _repr, "__eq__": _eq, "__hash__": _hash,
                           "__setattr__": _setattr, "__delattr__": _delattr}


@dataclass_transform(frozen_default=True)
def record(cls: C) -> C:
    """Make ``cls`` a frozen dataclass whose fields are all required (see the module docstring)."""
    dc: Any = dataclasses.dataclass(init=False, repr=False, eq=False)(cls)
    names = tuple(f.name for f in dataclasses.fields(dc))
    dc.__record_fields__ = names
    dc.__record_field_set__ = frozenset(names)
    for name, method in _METHODS.items():
        setattr(dc, name, method)
    return cls
