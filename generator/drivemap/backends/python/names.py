"""How map names become generated names (pure rules, shared by the checks and the client view).

The rules live in :mod:`drivemap.runtime.names` (the runtime builds the same classes from a spec).

The checks (:mod:`drivemap.vocab.namecheck`) refuse a map whose generated names collide; the client view
(:mod:`drivemap.backends.views.client`) applies the same rules to write them.
"""

from __future__ import annotations

from drivemap.runtime.names import FIXED_NAMES, UNKNOWN_MEMBER, bit_attribute, exception_class, exception_classes

__all__ = ["FIXED_NAMES", "UNKNOWN_MEMBER", "bit_attribute", "exception_class", "exception_classes"]
