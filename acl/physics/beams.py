"""Cantilevers carrying a rigid actuator: paper Eq. (1) and a large-deflection elastica.

A flexible beam of length ``L`` and bending stiffness ``EI`` is clamped at one end and carries a
rigid segment of length ``l`` (half the actuator) at the other; the load ``P`` acts at the far end of
the rigid segment, perpendicular to the undeformed axis.  Every quantity is SI.  Functions are
vectorized over the load or the deflection; geometry arguments are scalars.

Two models:

* paper Eq. (1) / Supplementary Note 2: linear beam theory for the flexible part, exact rotation of
  the rigid part.  Closed form; valid while the beam rotation stays moderate.
* the elastica (Euler-Bernoulli, inextensible, exact geometry) for a dead load (fixed direction) or a
  follower load (stays perpendicular to the rigid tip segment), solved as a boundary-value problem
  with ``scipy.integrate.solve_bvp`` and continuation in the load.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

# Relative departure of Eq. (1) from the elastica above which Eq. (1) is flagged as invalid.
EQ1_TOLERANCE = 0.05
# A lower bound of eq1_validity_limit / L at EQ1_TOLERANCE for every rigid length l >= 0: the limit
# grows with l/L from 0.2145 L at l = 0 (tests/test_physics_beams.py checks the bound and the growth
# on a grid of l/L), so a smaller deflection needs no elastica solve to be judged valid.
EQ1_LIMIT_FLOOR = 0.21


# ----------------------------------------------------------------------------------------------
# Paper Eq. (1)
# ----------------------------------------------------------------------------------------------

def eq1_deflection(P, L: float, l: float, EI: float):
    """Load-point deflection of a cantilever with a rigid tip segment, paper Eq. (1) (= Suppl. Eq. 2.7)."""
    P = np.asarray(P, dtype=float)
    c = L * (2 * l + L) / EI
    return L * P / (6 * EI) * (L * (3 * l + 2 * L) + 6 * l * (2 * l + L) / np.sqrt(4 + (c * P) ** 2))


def eq1_slope(P, L: float, l: float, EI: float):
    """Rotation angle of the rigid segment, arctan of the end slope of Suppl. Eq. (2.5)."""
    return np.arctan(L * (2 * l + L) * np.asarray(P, dtype=float) / (2 * EI))


def eq1_compliance(P, L: float, l: float, EI: float):
    """d(delta)/dP of paper Eq. (1), differentiated analytically."""
    P = np.asarray(P, dtype=float)
    c = L * (2 * l + L) / EI
    s = 4 + (c * P) ** 2
    return L / (6 * EI) * (L * (3 * l + 2 * L) + 6 * l * (2 * l + L) * 4 / s**1.5)


def eq1_small_force_stiffness(L: float, l: float, EI: float) -> float:
    """Load-point stiffness of paper Eq. (1) as P -> 0 (its first-order term): 6EI / [L (L(3l + 2L) + 3l(2l + L))]."""
    return 6 * EI / (L * (L * (3 * l + 2 * L) + 3 * l * (2 * l + L)))


def flexible_part_stiffness(L: float, l: float, EI: float) -> float:
    """Stiffness k of Suppl. Eq. (2.5): deflection of the flexible end only (ignores the rigid part's rotation)."""
    return 6 * EI / (L**2 * (3 * l + 2 * L))


def eq1_force(delta, L: float, l: float, EI: float, rtol: float = 1e-13):
    """Load P giving load-point deflection ``delta``: inverse of paper Eq. (1) by safeguarded Newton.

    Eq. (1) is odd, increasing and concave in P >= 0, so Newton started at P0 = k0 * |delta| (k0 the
    small-force stiffness) stays below the root and increases monotonically to it.
    """
    delta = np.asarray(delta, dtype=float)
    target = np.abs(delta)
    P = eq1_small_force_stiffness(L, l, EI) * target
    for _ in range(100):
        step = (target - eq1_deflection(P, L, l, EI)) / eq1_compliance(P, L, l, EI)
        P = P + step
        if np.all(np.abs(step) <= rtol * np.maximum(np.abs(P), 1e-300)):
            break
    return np.sign(delta) * P


def eq1_tangent_stiffness(delta, L: float, l: float, EI: float):
    """dP/d(delta) along paper Eq. (1) at deflection ``delta``."""
    return 1.0 / eq1_compliance(eq1_force(delta, L, l, EI), L, l, EI)


# ----------------------------------------------------------------------------------------------
# Elastica
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ElasticaSolution:
    """Elastica results for an array of loads (SI); ``converged`` per load."""

    load: np.ndarray          # N, perpendicular to the undeformed axis (dead) or to the tip (follower)
    deflection: np.ndarray    # m, load-point displacement perpendicular to the undeformed axis
    shortening: np.ndarray    # m, load-point displacement back along the undeformed axis
    tip_angle: np.ndarray     # rad, rotation of the rigid segment
    converged: np.ndarray     # bool


def _elastica_bvp(p: float, lam: float, mode: str, guess):
    """Nondimensional elastica (s in [0, 1], p = P L^2/EI, lam = l/L), Bisshopp & Drucker, Q. Appl. Math. 3 (1945)."""
    from scipy.integrate import solve_bvp

    def rhs(s, y, par):
        th = y[0]
        dk = -p * np.cos(th) if mode == "dead" else -p * np.cos(th - par[0])
        return np.vstack([y[1], dk, np.cos(th), np.sin(th)])

    def bc(ya, yb, par):
        moment = p * lam * np.cos(par[0]) if mode == "dead" else p * lam
        return np.array([ya[0], ya[2], ya[3], yb[0] - par[0], yb[1] - moment])

    if guess is None:
        s = np.linspace(0.0, 1.0, 21)
        y0 = np.zeros((4, s.size))
        y0[2] = s
        return solve_bvp(rhs, bc, s, y0, p=[0.0], tol=1e-10, max_nodes=20000)
    return solve_bvp(rhs, bc, guess.x, guess.y, p=guess.p, tol=1e-10, max_nodes=20000)


def elastica(P, L: float, l: float, EI: float, mode: str = "dead",
             max_step: float = 0.5) -> ElasticaSolution:
    """Large-deflection cantilever with rigid tip segment under an end load (elastica BVP, Bisshopp & Drucker 1945).

    ``mode`` is ``"dead"`` (load keeps its direction, perpendicular to the undeformed axis) or
    ``"follower"`` (load stays perpendicular to the rotated rigid segment).  Loads are solved in
    increasing magnitude with continuation steps of at most ``max_step`` in P L^2/EI.
    """
    if mode not in ("dead", "follower"):
        raise ValueError(f"mode must be 'dead' or 'follower', not {mode!r}")
    P = np.atleast_1d(np.asarray(P, dtype=float))
    lam = l / L
    scale = L**2 / EI
    mags = np.abs(P) * scale
    order = np.argsort(mags)
    defl = np.full(P.shape, np.nan)
    short = np.full(P.shape, np.nan)
    angle = np.full(P.shape, np.nan)
    ok = np.zeros(P.shape, dtype=bool)
    guess, p_done = None, 0.0
    for idx in order:
        target = mags[idx]
        if target == 0.0:
            defl[idx] = short[idx] = angle[idx] = 0.0
            ok[idx] = True
            continue
        n_sub = max(1, int(np.ceil((target - p_done) / max_step)))
        sol = None
        for p in np.linspace(p_done, target, n_sub + 1)[1:]:
            sol = _elastica_bvp(p, lam, mode, guess)
            if sol.status != 0:
                break
            guess = sol
        if sol is None or sol.status != 0:
            guess = None
            continue
        p_done = target
        th = sol.p[0]
        sign = np.sign(P[idx])
        defl[idx] = sign * L * (sol.y[3, -1] + lam * np.sin(th))
        short[idx] = L * (1.0 + lam - sol.y[2, -1] - lam * np.cos(th))
        angle[idx] = sign * th
        ok[idx] = True
    return ElasticaSolution(P, defl, short, angle, ok)


@lru_cache(maxsize=64)
def _elastica_table(lam: float, mode: str, p_max: float, n: int = 161):
    """Nondimensional deflection delta/L vs p = P L^2/EI on a grid (cached per geometry ratio)."""
    p = np.linspace(0.0, p_max, n)
    sol = elastica(p, 1.0, lam, 1.0, mode=mode, max_step=0.25)
    if not np.all(sol.converged):
        raise RuntimeError("elastica table did not converge")
    return p, sol.deflection


@lru_cache(maxsize=64)
def _elastica_inverse(lam: float, mode: str, p_max: float):
    from scipy.interpolate import PchipInterpolator

    p, d = _elastica_table(lam, mode, p_max)
    inverse = PchipInterpolator(d, p, extrapolate=False)
    return inverse, inverse.derivative()


def elastica_force(delta, L: float, l: float, EI: float, mode: str = "dead", p_max: float = 6.0):
    """Load P for load-point deflection ``delta``: inverse of the elastica (Bisshopp & Drucker 1945), monotone cubic on a cached table.

    Returns NaN where |delta| exceeds the deflection reached at P L^2/EI = ``p_max``.
    """
    inverse, _ = _elastica_inverse(round(l / L, 9), mode, float(p_max))
    delta = np.asarray(delta, dtype=float)
    return np.sign(delta) * inverse(np.abs(delta) / L) * EI / L**2


def elastica_tangent_stiffness(delta, L: float, l: float, EI: float, mode: str = "dead",
                               p_max: float = 6.0):
    """dP/d(delta) along the tabulated elastica (Bisshopp & Drucker 1945), derivative of the monotone cubic inverse."""
    _, slope = _elastica_inverse(round(l / L, 9), mode, float(p_max))
    return slope(np.abs(np.asarray(delta, dtype=float)) / L) * EI / L**3


# ----------------------------------------------------------------------------------------------
# Validity of Eq. (1)
# ----------------------------------------------------------------------------------------------

def eq1_departure(P, L: float, l: float, EI: float):
    """Relative departure of paper Eq. (1) from the dead-load elastica at the same load, (eq1 - elastica)/elastica."""
    el = elastica(P, L, l, EI, mode="dead")
    return (eq1_deflection(P, L, l, EI) - el.deflection) / el.deflection


@lru_cache(maxsize=64)
def _eq1_limit_ratio(lam: float, tolerance: float) -> float:
    from acl.physics.roots import brentq

    solved: list = []      # (p, BVP solution): each new load starts from the nearest solved one

    def deflection(p):
        """delta/L of the dead-load elastica (Bisshopp & Drucker) at p = P L^2/EI, as :func:`elastica`."""
        near = min(solved, key=lambda s: abs(s[0] - p), default=(0.0, None))
        sol, guess = None, near[1]
        for pp in np.linspace(near[0], p, max(1, int(np.ceil(abs(p - near[0]) / 0.5))) + 1)[1:]:
            sol = _elastica_bvp(pp, lam, "dead", guess)
            if sol.status != 0:
                return float(elastica(p, 1.0, lam, 1.0).deflection[0])      # from rest, as elastica does
            guess = sol
        solved.append((p, sol))
        return float(sol.y[3, -1] + lam * np.sin(sol.p[0]))

    def excess(p):
        el = deflection(p)
        return float((eq1_deflection(p, 1.0, lam, 1.0) - el) / el) - tolerance

    hi = 0.25
    while excess(hi) < 0:
        hi *= 1.5
        if hi > 50:
            return float("inf")
    p_star = brentq(excess, 1e-3, hi, xtol=1e-6)
    return deflection(p_star)


def eq1_validity_limit(L: float, l: float, tolerance: float = EQ1_TOLERANCE) -> float:
    """Deflection (m) beyond which paper Eq. (1) departs from the Bisshopp & Drucker elastica by more than ``tolerance``.

    About 0.21 L without rigid segment, 0.33 L at l = L/4, 0.44 L at l = L/2 (docs/physics.md (part B)).
    """
    return L * _eq1_limit_ratio(round(l / L, 9), float(tolerance))


def eq1_is_valid(delta, L: float, l: float, tolerance: float = EQ1_TOLERANCE):
    """True where |delta| is within the range in which paper Eq. (1) matches the elastica (Bisshopp & Drucker 1945) to ``tolerance``."""
    return np.abs(np.asarray(delta, dtype=float)) <= eq1_validity_limit(L, l, tolerance)
