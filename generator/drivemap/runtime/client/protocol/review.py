"""Registers open for review (the map's ``review:``): their reads warn once, their writes are refused.

A register whose ``review:`` names a field that decides its words (:attr:`RegisterSpec.open_for_writes
<drivemap.runtime.spec.RegisterSpec.open_for_writes>`; the client's :attr:`SpecTables.under_review
<drivemap.runtime.client.protocol.tables.SpecTables.under_review>`) is read as the map says, with one
:class:`ReviewWarning` per register and client, and never written: :meth:`Core.check_write
<drivemap.runtime.client.protocol.sansio.Core.check_write>` raises :class:`OpenForReview` naming the fields,
before anything is sent (and, through :func:`refuse_open`, before the values are looked at).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Any

from drivemap.runtime.client.protocol.advice import caller_stacklevel
from drivemap.runtime.client.protocol.planner import Key
from drivemap.runtime.errors import OpenForReview, ReviewWarning
from drivemap.runtime.spec import RegisterSpec

__all__ = ["refuse_open", "sign_checked", "warn_review"]


def warn_review(core: Any, keys: Iterable[Key]) -> None:
    """A :class:`ReviewWarning` for each register of ``keys`` whose map leaves a field that decides
    its value open (once per register and client): the read works, its value may be wrong."""
    review = core.tables.read_review
    warned: set[str] = core.review_warned
    for name, _ in keys:
        fields = review.get(name)
        if fields and name not in warned:
            warned.add(name)
            warnings.warn(ReviewWarning(f"{name}: its map leaves {', '.join(fields)} open for review; the value "
                                        "read may be wrong"), stacklevel=caller_stacklevel())


def refuse_open(core: Any, keys: Iterable[Key]) -> None:
    """:class:`OpenForReview` (through ``core.check_write``) for the first of ``keys`` whose register
    is open for review, before any value is encoded."""
    review = core.tables.under_review
    if review:
        for name, index in keys:
            if name in review:
                core.check_write((name, index))


def sign_checked(spec: RegisterSpec, raw: int) -> int:
    """``raw``, the encoding of an engineering value, unless the map leaves the register's signedness open
    (``review: [signedness]``) and ``raw`` means another value signed than unsigned: then
    :class:`OpenForReview` (a raw write, ``write_raw``, gives its words itself and is not refused)."""
    if spec.review and spec.sign_ambiguous(raw):
        raise OpenForReview(spec.name, ("signedness",), raw)
    return raw
