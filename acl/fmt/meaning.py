"""Whether two parsed files mean the same: equal syntax trees once spans are set aside.

Layout is all a formatter may change, so the comparison ignores source positions, the whitespace
inside a requirement's quoted text (`RequireDecl.text`, shown in reports) and the order of
imports (each binds its own name; the formatter sorts them).
"""
from __future__ import annotations

import dataclasses
import re

from acl.diagnostics import Span
from acl.syntax import ast as A

_SPACE = re.compile(r"\s+")


def meaning(module: A.Module):
    """A hashable value equal for two modules exactly when they mean the same."""
    imports = sorted(repr(_norm(s)) for s in module.statements if isinstance(s, A.Import))
    rest = tuple(_norm(s) for s in module.statements if not isinstance(s, A.Import))
    return tuple(imports), rest


_FIELDS: dict[type, tuple[str, ...] | None] = {}   # a dataclass's field names (None: not a dataclass)


def _fields(t: type) -> tuple[str, ...] | None:
    names = _FIELDS.get(t, ())
    if names == ():
        names = tuple(f.name for f in dataclasses.fields(t)) if dataclasses.is_dataclass(t) else None
        _FIELDS[t] = names
    return names


def _norm(x):
    t = type(x)
    if t is Span:
        return None
    if t is tuple or t is list:
        return tuple(_norm(v) for v in x)
    if t in (str, int, float, bool) or x is None:
        return x
    names = _fields(t)
    if names is None or isinstance(x, type):
        return x
    out = [t.__name__]
    for name in names:
        v = getattr(x, name)
        if type(v) is Span:
            continue
        if name == "text" and isinstance(v, str):
            v = _SPACE.sub("", v)
        out.append((name, _norm(v)))
    return tuple(out)
