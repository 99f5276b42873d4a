"""The tie rule for "which is largest" (dominant interface, best-responding capsule, strongest tone).

Symmetric designs (a facing pair, a capsule with two equal orifices) give values that are equal in
exact arithmetic and differ only by rounding, which another BLAS, numpy or CPU can flip.  Values
within a relative ``TIE_RTOL`` of the maximum are a tie, and a tie goes to the first in declaration
order (capsules as declared, then their orifices as declared; tones as listed).  docs/analyze.md.
"""
from __future__ import annotations

import numpy as np

#: Relative tolerance under which two non-negative magnitudes are a tie (rounding is ~1e-15).
TIE_RTOL = 1e-9


def first_max(values, axis: int = -1) -> np.ndarray | int:
    """Index of the first value within TIE_RTOL (relative) of the maximum along ``axis`` (the declaration-order tie rule; not physics, no equation).

    ``values`` non-negative magnitudes (shares, |volume|, responses); NaN counts as smaller than
    any number.  A 1-D input gives an int, else an integer array with ``axis`` removed.
    """
    a = np.asarray(values, float)
    a = np.where(np.isnan(a), -np.inf, a)
    top = np.max(a, axis=axis, keepdims=True)
    with np.errstate(invalid="ignore"):
        near = (a == top) | (a >= top - TIE_RTOL * np.abs(top))
    idx = np.argmax(near, axis=axis)
    return int(idx) if a.ndim == 1 else idx


def first_max_item(mapping, default=("", 0.0)):
    """(key, value) of ``mapping`` (insertion = declaration order) by :func:`first_max`; ``default`` when empty."""
    items = list(mapping.items())
    if not items:
        return default
    k = first_max([float(v) for _, v in items])
    return items[k]
