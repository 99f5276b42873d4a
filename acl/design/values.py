"""Values produced by evaluating acl expressions (before they become model fields)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from acl.diagnostics import Span
from acl.units import Quantity


@dataclass(frozen=True)
class VecVal:
    items: tuple[Quantity, ...]


@dataclass(frozen=True)
class DirVal:
    vector: tuple[float, float, float]


@dataclass(frozen=True)
class DeclVal:
    """A reference to a declaration (material, medium, capsule...)."""

    kind: str
    name: str           # qualified name as the user wrote it
    node: object        # syntax Block
    env: object         # Module environment the declaration lives in


@dataclass(frozen=True)
class CallVal:
    name: str
    args: tuple
    kwargs: tuple[tuple[str, object], ...]
    span: Span

    def kw(self, key: str, default=None):
        for k, v in self.kwargs:
            if k == key:
                return v
        return default


@dataclass(frozen=True)
class ListVal:
    items: tuple


@dataclass(frozen=True)
class StrVal:
    value: str


@dataclass(frozen=True)
class IdentVal:
    """A bare identifier that names nothing (used for enum-like values: `state = b`)."""

    name: str


def unit_vector(v) -> tuple[float, float, float] | None:
    x, y, z = v
    n = math.sqrt(x * x + y * y + z * z)
    if n == 0 or not math.isfinite(n):
        return None
    return (x / n, y / n, z / n)


@dataclass(frozen=True)
class RangeVal:
    lower: Quantity
    upper: Quantity
