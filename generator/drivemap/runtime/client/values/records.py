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
from collections.abc import Callable
from operator import attrgetter
from typing import Any, TypeVar, dataclass_transform

__all__ = ["record", "snapshot"]

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


@dataclasses.dataclass(init=False, repr=False, eq=False)
class _Prototype:
    field: int


#: What ``dataclasses.dataclass(init=False, repr=False, eq=False)`` gives every record class: its
#: parameters, and the marker of a field (taken from a real dataclass, not from private names).
_PARAMS = _Prototype.__dataclass_params__  # type: ignore[attr-defined]
_FIELD = dataclasses.fields(_Prototype)[0]._field_type  # type: ignore[attr-defined]


class _LazyFields:
    """``__dataclass_fields__`` of a record or snapshot class, made when first read (by
    ``dataclasses.fields``, ``replace``, ``asdict``, ``is_dataclass``): making a ``Field`` per
    annotation costs about 2 µs, which thousands of classes paid at import though few are ever
    asked. The dict it makes replaces it on the class, so it is made once."""

    def __init__(self, owner: type, notes: dict[str, Any], default: Any) -> None:
        self.owner, self.notes, self.default = owner, notes, default

    def __get__(self, obj: object, objtype: type | None = None) -> dict[str, dataclasses.Field[Any]]:
        owner = self.owner
        made: dict[str, dataclasses.Field[Any]] = dict(getattr(owner.__bases__[0], "__dataclass_fields__", {}))
        for name, note in self.notes.items():
            f: Any = dataclasses.field() if self.default is dataclasses.MISSING else dataclasses.field(default=self.default)
            f.name, f.type, f.kw_only = name, note, False
            f._field_type = _FIELD
            made[name] = f
        setattr(owner, "__dataclass_fields__", made)  # noqa: B010 - replaces this descriptor
        return made


def _plain(cls: type) -> dict[str, Any] | None:
    """The annotations of a class whose fields :func:`record` can list itself (no base class but
    ``object``, no ``ClassVar``/``InitVar``, no defaults), else None (the dataclass does it)."""
    notes = cls.__dict__.get("__annotations__", {})
    if cls.__bases__ != (object,) or any("__dataclass_fields__" in vars(b) for b in cls.__mro__[1:]):
        return None
    for name, note in notes.items():
        text = note if isinstance(note, str) else getattr(note, "__name__", repr(note))
        if "ClassVar" in text or "InitVar" in text or name in cls.__dict__:
            return None
    return dict(notes)


@dataclass_transform(frozen_default=True)
def record(cls: C) -> C:
    """Make ``cls`` a frozen dataclass whose fields are all required (see the module docstring).

    What ``dataclasses.dataclass(init=False, repr=False, eq=False)`` records about the class
    (``__dataclass_fields__``, ``__dataclass_params__``, ``__match_args__``) is set directly: the
    dataclass machinery costs about 0.4 ms per class (each annotation is parsed for ``ClassVar``),
    most of the import time of a client with thousands of bit-field registers."""
    notes = _plain(cls)
    dc: Any = cls
    if notes is None:
        dc = dataclasses.dataclass(init=False, repr=False, eq=False)(cls)
        names = tuple(f.name for f in dataclasses.fields(dc))
    else:
        names = tuple(notes)
        dc.__dataclass_fields__ = _LazyFields(dc, notes, dataclasses.MISSING)
        dc.__dataclass_params__ = _PARAMS
        setattr(dc, "__match_args__", names)  # noqa: B010 - a dunder mypy will not see assigned
    dc.__record_fields__ = names
    dc.__record_field_set__ = frozenset(names)
    for name, method in _METHODS.items():
        setattr(dc, name, method)
    return cls


# ---------------------------------------------------------------- snapshot classes


def _snapshot_eq(self: Any, other: Any) -> Any:
    if other.__class__ is self.__class__:
        values = self.__snapshot_values__
        return values(self) == values(other)
    return NotImplemented


def _snapshot_hash(self: Any) -> int:
    return hash(self.__snapshot_values__(self))


def _snapshot_setattr(self: Any, name: str, value: Any) -> None:
    raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")


def _snapshot_delattr(self: Any, name: str) -> None:
    raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")


_SNAPSHOT_METHODS: dict[str, Any] = {"__eq__": _snapshot_eq, "__hash__": _snapshot_hash,
                                     "__setattr__": _snapshot_setattr, "__delattr__": _snapshot_delattr}


@dataclasses.dataclass(frozen=True, init=False, repr=False)
class _SnapshotPrototype:
    field: int | None = None


_SNAPSHOT_PARAMS = _SnapshotPrototype.__dataclass_params__  # type: ignore[attr-defined]


@dataclass_transform(frozen_default=True)
def snapshot(*, init: bool = False, repr: bool = False, frozen: bool = True) -> Callable[[C], C]:  # noqa: A002
    """``@snapshot(init=False, repr=False)``: the generated ``Snapshot`` class as
    ``dataclasses.dataclass(frozen=True, repr=False, init=False)`` makes it (its fields, all
    defaulting to None, after its base's; equality and hashing over the compared fields; frozen),
    built without the dataclass machinery, whose cost for a snapshot of thousands of registers was
    most of the import time of their client (each annotation parsed, ``__eq__`` compiled). A class
    the shortcut does not fit (a field without the default None, a ``ClassVar``) gets the dataclass."""
    if init or repr or not frozen:
        raise TypeError("snapshot() makes frozen classes with the base's __init__ and __repr__")

    def make(cls: C) -> C:
        notes = cls.__dict__.get("__annotations__", {})
        base = [b for b in cls.__mro__[1:] if "__dataclass_fields__" in vars(b)]
        own = cls.__dict__
        if (len(cls.__bases__) != 1 or not base or base[0] is not cls.__bases__[0]
                or any(own.get(n, 0) is not None for n in notes)
                or any("ClassVar" in str(t) or "InitVar" in str(t) for t in notes.values())):
            made: Any = dataclasses.dataclass(frozen=True, repr=False, init=False)(cls)
            return made  # type: ignore[no-any-return]
        inherited = base[0].__dataclass_fields__  # type: ignore[attr-defined]
        compared = tuple(f.name for f in inherited.values() if f._field_type is _FIELD and f.compare) + tuple(notes)
        dc: Any = cls
        dc.__dataclass_fields__ = _LazyFields(dc, dict(notes), None)
        dc.__dataclass_params__ = _SNAPSHOT_PARAMS
        values = attrgetter(*compared) if len(compared) > 1 else (lambda obj: tuple(getattr(obj, n) for n in compared))
        dc.__snapshot_values__ = staticmethod(values)
        if "__match_args__" not in own:
            setattr(dc, "__match_args__", tuple(n for n, f in inherited.items() if f.init) + tuple(notes))  # noqa: B010
        for name, method in _SNAPSHOT_METHODS.items():
            setattr(dc, name, method)
        return cls

    return make
