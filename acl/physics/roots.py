"""Root finding and extremum searches, once for the package (issue 23: one numerics module).

Scalar root bracketing without importing scipy.optimize (whose import costs more than the solves),
and the batched searches every stage shares (leading axes: design points, rows, waypoints):
:func:`golden_max` / :func:`grid_max` (golden section, Kiefer 1953), :func:`first_sign_change`
(a root's bracket on a grid), :func:`illinois` / :func:`illinois_step` / :func:`illinois_ascending`
(regula falsi, Illinois variant, Dowell & Jarratt 1971).

:func:`brentq` is Brent's method (R. P. Brent, *Algorithms for Minimization without Derivatives*,
Prentice-Hall 1973, ch. 4): inverse quadratic interpolation or secant steps, bisection whenever they
would not shrink the bracket fast enough.  The iteration is the one of ``scipy.optimize.brentq``
(same defaults, same tolerance test ``|x - root| <= xtol + rtol |x|``), so it returns the same
root to the last bit (tests/test_physics_roots.py checks this against scipy).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

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


# ----------------------------------------------------------------------------------------------
# Batched extremum searches and bracketing (every element of the leading axes solved at once)
# ----------------------------------------------------------------------------------------------

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0      # 1/phi: the golden-section shrink factor (Kiefer 1953)


def golden_max(fn, lo, hi, iterations: int = 60, rtol: float = 0.0, state=None):
    """Largest value of a unimodal ``fn`` on [lo, hi] per element by golden section (Kiefer, Proc. AMS 4, 502 (1953)).

    ``lo``, ``hi``: scalars (then ``fn`` gets Python floats) or arrays of any shape (``fn`` gets arrays
    of that shape, every element at once; a kink is allowed).  Stops after ``iterations`` steps or, with
    ``rtol`` > 0, once every bracket is narrower than ``rtol`` x max(hi, 1) (converged elements are frozen).
    With ``state`` (an array of the elements' shape, e.g. a warm start), ``fn(x, state) -> (value,
    state at x)`` and the state of the point a new one is probed from is handed on.
    Returns ``(value, x)`` of the best point evaluated (the larger of the last two interior points:
    golden section always keeps the best one; ties: the left point), plus that point's state when
    ``state`` is given.
    """
    scalar = np.ndim(lo) == 0 and np.ndim(hi) == 0 and state is None
    if scalar:
        return _golden_max_scalar(fn, float(lo), float(hi), iterations, rtol)
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    lo, hi = np.broadcast_arrays(lo, hi)
    g = GOLDEN
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    if state is None:
        f1, f2 = fn(x1), fn(x2)
        s1 = s2 = None
    else:
        f1, s1 = fn(x1, state)
        f2, s2 = fn(x2, state)
    f1, f2 = np.asarray(f1, float), np.asarray(f2, float)
    for _ in range(iterations):
        active = hi - lo > rtol * np.maximum(hi, 1.0) if rtol > 0 else None
        if active is not None and not np.any(active):
            break
        left = f1 >= f2
        if active is not None:
            left_move = left & active
            right_move = ~left & active
        else:
            left_move, right_move = left, ~left
        hi = np.where(left_move, x2, hi)
        lo = np.where(right_move, x1, lo)
        nx = np.where(left, hi - g * (hi - lo), lo + g * (hi - lo))
        if state is None:
            nf = np.asarray(fn(nx), float)
        else:
            nf, ns = fn(nx, np.where(left, s1, s2))
            nf = np.asarray(nf, float)
            s1, s2 = np.where(left_move, ns, np.where(right_move, s2, s1)), np.where(left_move, s1,
                                                                                     np.where(right_move, ns, s2))
        x1, x2, f1, f2 = (np.where(left_move, nx, np.where(right_move, x2, x1)),
                          np.where(left_move, x1, np.where(right_move, nx, x2)),
                          np.where(left_move, nf, np.where(right_move, f2, f1)),
                          np.where(left_move, f1, np.where(right_move, nf, f2)))
    take1 = f1 >= f2
    best = np.where(take1, f1, f2)
    x = np.where(take1, x1, x2)
    if state is None:
        return best, x
    return best, x, np.where(take1, s1, s2)


def _golden_max_scalar(fn, a: float, b: float, iterations: int, rtol: float):
    """:func:`golden_max` of one bracket with Python floats (no array overhead per step)."""
    g = GOLDEN
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = float(fn(c)), float(fn(d))
    for _ in range(iterations):
        if rtol > 0 and b - a <= rtol * max(b, 1.0):
            break
        if fc >= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = float(fn(c))
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = float(fn(d))
    return (fc, c) if fc >= fd else (fd, d)


def grid_max(fn, grid, values, lo=None, hi=None, iterations: int = 60, rtol: float = 0.0):
    """Largest ``fn`` over a sampled grid: the grid maximum refined by golden section (Kiefer 1953) between its neighbours.

    ``grid``, ``values``: (..., G) ascending abscissae and ``fn`` there; ``lo``/``hi`` (...,) integer
    limits of the search, grid indices ``lo <= k < hi`` (default the whole grid).  Never below the grid
    maximum (a peak between grid points is found; one at a kink too).  Ties: the first grid point.
    Returns ``(value, x)``, each of the leading shape (floats for a 1-d grid).
    """
    grid = np.asarray(grid, float)
    values = np.asarray(values, float)
    idx = np.arange(grid.shape[-1])
    lo_i = 0 if lo is None else np.asarray(lo)[..., None]
    hi_i = grid.shape[-1] if hi is None else np.asarray(hi)[..., None]
    masked = np.where((idx >= lo_i) & (idx < hi_i), values, -np.inf)
    k = np.argmax(masked, axis=-1)
    vk = np.take_along_axis(masked, k[..., None], -1)[..., 0]
    xk = np.take_along_axis(grid, k[..., None], -1)[..., 0]
    a = np.take_along_axis(grid, np.maximum(k - 1, 0)[..., None], -1)[..., 0]
    b = np.take_along_axis(grid, np.minimum(k + 1, grid.shape[-1] - 1)[..., None], -1)[..., 0]
    if grid.ndim == 1:
        a, b, vk, xk = float(a), float(b), float(vk), float(xk)
    best, x = golden_max(fn, a, b, iterations, rtol)
    if grid.ndim == 1:
        return (vk, xk) if vk >= best else (best, x)
    keep = vk >= best
    return np.where(keep, vk, best), np.where(keep, xk, x)


def first_sign_change(values, axis: int = -1):
    """(found, k) per row: the first cell k with values[k] and values[k + 1] of strictly opposite signs or values[k + 1] == 0 (a bracket of a root for :func:`illinois`)."""
    v = np.moveaxis(np.asarray(values, float), axis, -1)
    a, b = v[..., :-1], v[..., 1:]
    cross = ((a < 0) & (b >= 0)) | ((a > 0) & (b <= 0))
    found = cross.any(axis=-1)
    return found, np.where(found, np.argmax(cross, axis=-1), v.shape[-1] - 2)


def illinois_step(g, a, fa, b, fb):
    """One step of regula falsi, Illinois variant (Dowell & Jarratt, BIT 11, 168 (1971)), inside [a, b] per element: (c, g(c), whether g(c) and fb differ in sign); the caller keeps (b, fb) as the new far end on a flip, else halves fa."""
    den = fb - fa
    nz = den != 0
    mid = 0.5 * (a + b)
    c = np.where(nz, b - fb * (b - a) / np.where(nz, den, 1.0), mid)
    c = np.where((c >= np.minimum(a, b)) & (c <= np.maximum(a, b)), c, mid)
    fc = g(c)
    return c, fc, np.sign(fc) != np.sign(fb)


def illinois(g, a, fa, b, fb, iterations: int = 60, ftol: float = 0.0, xtol=0.0):
    """Root per element of ``g`` in the brackets [a, b] (fa, fb of opposite signs) by regula falsi, Illinois variant (Dowell & Jarratt 1971).

    Stops after ``iterations`` steps or when every |g| <= ``ftol`` or every bracket is narrower than
    ``xtol``; always inside the bracket.  Returns (root estimate, g there).
    """
    a, fa, b, fb = (np.asarray(v, float) for v in (a, fa, b, fb))
    fb_out = fb
    for _ in range(iterations):
        c, fc, flip = illinois_step(g, a, fa, b, fb)
        a, fa = np.where(flip, b, a), np.where(flip, fb, 0.5 * fa)
        b, fb = c, fc
        fb_out = fc
        if np.all((np.abs(fc) <= ftol) | (np.abs(b - a) <= xtol)):
            break
    return b, fb_out


def illinois_ascending(fun, lo, hi, f_lo, f_hi, iters, ftol, xrel, state=None):
    """Root per point of f rising through 0 on (lo, hi), f(lo) < 0 <= f(hi): regula falsi, Illinois variant (Dowell & Jarratt, BIT 11, 168 (1971)).

    ``fun(s, state_hi) -> (f(s), state)`` may carry a warm-start state (kept at the ``hi`` end) or return
    ``(f, None)``.  Stops after ``iters`` steps or when every point has |f| <= ftol or a bracket narrower
    than ``xrel`` x hi.  Returns (s, f(s), state at s) of the last evaluation.
    """
    side = np.zeros(np.shape(lo))
    s, fs, st = hi, np.full(np.shape(lo), np.nan), state
    for _ in range(iters):
        s = np.where(f_hi != f_lo, hi - f_hi * (hi - lo) / np.where(f_hi != f_lo, f_hi - f_lo, 1.0), 0.5 * (lo + hi))
        s = np.where((s > lo) & (s < hi), s, 0.5 * (lo + hi))
        fs, st = fun(s, state)
        below = fs < 0
        lo, f_lo = np.where(below, s, lo), np.where(below, fs, f_lo)
        hi, f_hi = np.where(below, hi, s), np.where(below, f_hi, fs)
        if st is not None:
            state = np.where(below, state, st)
        # Illinois: halve the stale end's value when the same end is kept twice
        f_hi = np.where(below & (side == 1), f_hi / 2, f_hi)
        f_lo = np.where(~below & (side == -1), f_lo / 2, f_lo)
        side = np.where(below, 1, -1)
        if not np.any((np.abs(fs) > ftol) & (hi - lo > xrel * np.maximum(hi, 1e-300))):
            break
    return s, fs, st
