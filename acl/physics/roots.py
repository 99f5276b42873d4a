"""Scalar root bracketing without importing scipy.optimize (whose import costs more than the solves).

:func:`brentq` is Brent's method (R. P. Brent, *Algorithms for Minimization without Derivatives*,
Prentice-Hall 1973, ch. 4): inverse quadratic interpolation or secant steps, bisection whenever they
would not shrink the bracket fast enough.  The iteration is the one of ``scipy.optimize.brentq``
(same defaults, same tolerance test ``|x - root| <= xtol + rtol |x|``), so it returns the same
root to the last bit (tests/test_physics_roots.py checks this against scipy).
"""
from __future__ import annotations

import math
from typing import Callable

_EPS = 2.220446049250313e-16


def brentq(f: Callable[[float], float], a: float, b: float, xtol: float = 2e-12,
           rtol: float = 4 * _EPS, maxiter: int = 100) -> float:
    """A root of ``f`` in [a, b] (f(a), f(b) of opposite signs) by Brent's method (Brent 1973, ch. 4).

    Raises ValueError when the signs at the ends agree, a value is not finite, or the tolerances
    are not positive; RuntimeError when ``maxiter`` iterations do not converge.
    """
    if xtol <= 0:
        raise ValueError(f"xtol too small ({xtol:g} <= 0)")
    if rtol < 4 * _EPS:
        raise ValueError(f"rtol too small ({rtol:g} < {4 * _EPS:g})")

    def value(x: float) -> float:
        y = float(f(x))
        if math.isnan(y):
            raise ValueError(f"the function value at x={x} is NaN")
        return y

    xpre, xcur = float(a), float(b)
    fpre, fcur = value(xpre), value(xcur)
    if fpre == 0:
        return xpre
    if fcur == 0:
        return xcur
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise ValueError("f(a) and f(b) must have different signs")
    xblk = fblk = spre = scur = 0.0
    for _ in range(maxiter):
        if fpre != 0 and fcur != 0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:                                   # secant
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:                                              # inverse quadratic interpolation
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):
                spre, scur = scur, stry                        # accept the interpolation
            else:
                spre = scur = sbis                             # bisect
        else:
            spre = scur = sbis
        xpre, fpre = xcur, fcur
        xcur += scur if abs(scur) > delta else (delta if sbis > 0 else -delta)
        fcur = value(xcur)
    raise RuntimeError(f"brentq: no convergence in {maxiter} iterations")
