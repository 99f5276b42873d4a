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


def _norm(x):
    if isinstance(x, Span):
        return None
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        out = [type(x).__name__]
        for f in dataclasses.fields(x):
            v = getattr(x, f.name)
            if isinstance(v, Span):
                continue
            if f.name == "text" and isinstance(v, str):
                v = _SPACE.sub("", v)
            out.append((f.name, _norm(v)))
        return tuple(out)
    if isinstance(x, (tuple, list)):
        return tuple(_norm(v) for v in x)
    return x
