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


_END = object()          # closes a node or a sequence in the flat encoding


def _norm(x) -> tuple:
    """``x`` as a flat tuple (pre-order, each node and sequence closed by ``")"``): equal exactly when the
    trees are, spans aside.  Flat and built without recursion, so a sum of 1,000 terms (1,000 BinOps deep)
    neither overflows the stack here nor in the comparison of two encodings."""
    out: list = []
    stack = [x]
    while stack:
        x = stack.pop()
        if x is _END:
            out.append(")")
            continue
        t = type(x)
        if t is Span:
            out.append(None)
            continue
        if t is tuple or t is list:
            out.append("(")
            stack.append(_END)
            stack.extend(reversed(x))
            continue
        if t in (str, int, float, bool) or x is None:
            out.append((t.__name__, x) if t is not str else x)
            continue
        names = _fields(t)
        if names is None or isinstance(x, type):
            out.append(x)
            continue
        out.append(t.__name__)
        stack.append(_END)
        items = []
        for name in names:
            v = getattr(x, name)
            if type(v) is Span:
                continue
            if name == "text" and isinstance(v, str):
                v = _SPACE.sub("", v)
            items.append(v)
            items.append(_Name(name))
        stack.extend(items)              # popped last field first, each name before its value
    return tuple(out)


class _Name(str):
    """A field's name in the encoding (kept apart from a string value)."""


