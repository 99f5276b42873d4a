"""Every number of a resolved design is finite (E305 at the declaration holding one that is not)."""
from __future__ import annotations

import math

from pydantic import BaseModel

from acl.design import model as M


def all_finite(design: M.Design, bag) -> bool:
    """Every number of the resolved design is finite (E305 at the declaration holding one that is not).

    Expressions are checked as they are evaluated; this catches values derived from them (a volume
    from a huge radius), so no NaN or infinity reaches the analyses. An iterative walk over the models.
    """
    # the elements: their derived values (volumes, tips, stiffnesses, orifice centres) are computed
    # by the builders; parameters, observations and program steps hold evaluated expressions only
    parts = [x for x in (design.medium, design.transducer, design.materials, design.capsules, design.beams,
                         design.springs, design.latches, design.anchors, design.effects) if x is not None]
    if finite_walk(list(parts)):
        return True          # the usual case, a tenth of the cost of the walk below (which names each value)
    ok = True
    stack = [(x, None, "design") for x in parts]
    while stack:
        v, span, where = stack.pop()
        if isinstance(v, float):
            if not math.isfinite(v):
                bag.error("E305", f"{where} is not finite ({v}): a value overflowed", span,
                          "check the magnitudes and units of the values it is computed from")
                ok = False
        elif isinstance(v, BaseModel):
            span = getattr(v, "span", None) or span
            name = getattr(v, "name", None)
            for k, x in v.__dict__.items():
                if k != "span" and not isinstance(x, (str, int)):
                    stack.append((x, span, f"{name}.{k}" if isinstance(name, str) else k))
        elif isinstance(v, (tuple, list)):
            stack.extend((x, span, where) for x in v if not isinstance(x, (str, bool)))
        elif isinstance(v, dict):
            stack.extend((x, span, f"{where}.{k}") for k, x in v.items())
    return ok


def finite_walk(stack: list) -> bool:
    """True when every number :func:`all_finite` visits is finite: the same walk, without naming
    where each value is (an f-string per field), exact types first (4.5 ms instead of 43 ms on the
    5,000-line design of benchmarks/check.py). Anything else goes to the general branches."""
    isfinite = math.isfinite
    skip = {str, int, bool, type(None)}         # never holds a number the walk checks
    while stack:
        v = stack.pop()
        t = type(v)
        if t is float:
            if not isfinite(v):
                return False
            continue
        if t is tuple or t is list:
            items = v
        elif isinstance(v, BaseModel):
            items = [x for k, x in v.__dict__.items() if k != "span"]
        else:
            items = None
        if items is not None:
            for x in items:
                tx = type(x)
                if tx is float:
                    if not isfinite(x):
                        return False
                elif tx not in skip:
                    stack.append(x)
        elif isinstance(v, float):
            if not isfinite(v):
                return False
        elif isinstance(v, (tuple, list)):
            stack.extend(x for x in v if not isinstance(x, (str, bool)))
        elif isinstance(v, dict):
            stack.extend(v.values())
    return True
