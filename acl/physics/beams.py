"""Cantilevers carrying a rigid actuator: paper Eq. (1) and a large-deflection elastica.

A flexible beam of length ``L`` and bending stiffness ``EI`` is clamped at one end and carries a
rigid segment of length ``l`` (half the actuator) at the other; the load ``P`` acts at the far end of
the rigid segment, perpendicular to the undeformed axis.  Every quantity is SI.  Functions are
vectorized over the load or the deflection (the ``*_profile`` forms and the elastica also over the
geometry: leading axes are any batch).

Two models, each written once:

* paper Eq. (1) / Supplementary Note 2: linear beam theory for the flexible part, exact rotation of
  the rigid part.  Closed form in the two linear-beam integrals c_D, c_T
  (:func:`eq1_profile_deflection`), which also hold for a bending stiffness graded along the beam
  (:func:`stiffness_integrals`); valid while the beam rotation stays moderate.
* the elastica (Euler-Bernoulli, inextensible, exact geometry) for a dead load (fixed direction) or a
  follower load (stays perpendicular to the rigid tip segment): :func:`elastica_tip`, batched
  shooting with Newton and continuation in the load.  :func:`elastica` (per load, SI),
  :func:`elastica_force` (its inverse on a table) and :func:`elastica_deflection` (a table over the
  load and l/L, the fit's) are written on it.
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
L_REF = 50e-6          # m: reference length of the stiffness gradient (the paper's beam length)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(24)


# ----------------------------------------------------------------------------------------------
# Paper Eq. (1)
# ----------------------------------------------------------------------------------------------

def stiffness_integrals(L, l, EI, gradient=0.0):
    """(c_D, c_T) of a cantilever with EI(x) = EI exp(g (x/L_REF - 1/2)) (Suppl. Note 2 integrals, Gauss-Legendre)."""
    L = np.asarray(L, float)[..., None]
    l = np.asarray(l, float)[..., None]
    x = 0.5 * L * (_GL_X + 1.0)
    w = 0.5 * L * _GL_W
    g = np.asarray(gradient, float)[..., None] if np.ndim(gradient) else gradient
    inv = np.exp(-g * (x / L_REF - 0.5)) / np.asarray(EI, float)[..., None]
    c_d = np.sum(w * (L - x) * (L + l - x) * inv, axis=-1)
    c_t = np.sum(w * (L + l - x) * inv, axis=-1)
    return c_d, c_t


def eq1_profile_deflection(P, l, c_d, c_t):
    """Load-point deflection delta = c_D P + l sin(arctan(c_T P)) (paper Eq. (1), Suppl. Eq. 2.6).

    c_D = int (L-x)(L+l-x)/EI(x) dx and c_T = int (L+l-x)/EI(x) dx are the linear-beam integrals
    (:func:`stiffness_integrals`; for a uniform beam c_D = L^2 (2L + 3l)/(6 EI), c_T = L (L + 2l)/(2 EI)).
    """
    u = c_t * P
    return c_d * P + l * u / np.sqrt(1.0 + u * u)


def eq1_deflection(P, L: float, l: float, EI: float):
    """Load-point deflection of a uniform cantilever with a rigid tip segment, paper Eq. (1) (= Suppl. Eq. 2.7)."""
    return eq1_profile_deflection(np.asarray(P, dtype=float), l, L * L * (2 * L + 3 * l) / (6 * EI),
                                  L * (L + 2 * l) / (2 * EI))


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

# RK4 steps along the beam: 7e-11 relative from scipy's solve_bvp at tol 1e-10 up to P L^2/EI = 6
ELASTICA_STEPS = 96


@dataclass(frozen=True)
class ElasticaSolution:
    """Elastica results for an array of loads (SI); ``converged`` per load."""

    load: np.ndarray          # N, perpendicular to the undeformed axis (dead) or to the tip (follower)
    deflection: np.ndarray    # m, load-point displacement perpendicular to the undeformed axis
    shortening: np.ndarray    # m, load-point displacement back along the undeformed axis
    tip_angle: np.ndarray     # rad, rotation of the rigid segment
    converged: np.ndarray     # bool


def _shoot(p, lam, follower: bool, k0, phi, steps: int):
    """RK4 from the clamp (s = 0) to the tip (s = 1) of theta'' = -p cos(theta - c phi), c = 1 for a follower load.

    Integrates (theta, kappa, x, y) and the sensitivities of (theta, kappa) to kappa(0) and (follower) to phi.
    """
    h = 1.0 / steps
    shape = np.broadcast(p, lam, k0, phi).shape if follower else np.broadcast(p, lam, k0).shape
    state = np.zeros((8 if follower else 6,) + shape)       # one array: four numpy calls per RK4 stage fewer
    state[1] += k0
    state[5] = 1.0

    def f(st, out):
        th, ka = st[0], st[1]
        a = th - phi if follower else th
        ps = p * np.sin(a)
        out[0] = ka
        out[1] = -p * np.cos(a)
        out[2] = np.cos(th)
        out[3] = np.sin(th)
        out[4] = st[5]
        out[5] = ps * st[4]
        if follower:
            out[6] = st[7]
            out[7] = ps * (st[6] - 1.0)
        return out

    a, b, c, d = (np.empty_like(state) for _ in range(4))
    for _ in range(steps):
        f(state, a)
        f(state + 0.5 * h * a, b)
        f(state + 0.5 * h * b, c)
        f(state + h * c, d)
        state = state + h / 6 * (a + 2 * b + 2 * c + d)
    return state


def _newton(p, lam, follower: bool, k0, phi, steps: int, iterations: int = 30):
    """Shooting on (kappa(0), phi): theta(1) = phi and the tip moment kappa(1) = p lam cos((1 - c) phi)."""
    for _ in range(iterations):
        st = _shoot(p, lam, follower, k0, phi, steps)
        c = 1.0 if follower else 0.0
        r1 = st[0] - phi
        r2 = st[1] - p * lam * np.cos((1 - c) * phi)
        j11, j21 = st[4], st[5]
        j12 = (st[6] if follower else 0.0) - 1.0
        j22 = (st[7] if follower else 0.0) + p * lam * (1 - c) * np.sin((1 - c) * phi)
        det = j11 * j22 - j12 * j21
        det = np.where(det == 0.0, 1e-300, det)
        dk = -(r1 * j22 - j12 * r2) / det
        dphi = -(j11 * r2 - j21 * r1) / det
        k0, phi = k0 + dk, phi + dphi
        if not np.any(np.abs(dk) + np.abs(dphi) > 1e-12 * np.maximum(1.0, p)):     # NaN: given up
            break
    st = _shoot(p, lam, follower, k0, phi, steps)
    ok = np.isfinite(st[0]) & (np.abs(st[0] - phi) <= 1e-9 * np.maximum(1.0, p)) \
        & (np.abs(st[1] - p * lam * np.cos((0.0 if follower else 1.0) * phi)) <= 1e-9 * np.maximum(1.0, p))
    return k0, phi, st, ok


def elastica_tip(p, lam, mode: str = "dead", max_step: float = 0.5, steps: int = ELASTICA_STEPS, start=None):
    """Tip of the nondimensional elastica with a rigid end segment (Bisshopp & Drucker, Q. Appl. Math. 3 (1945)), batched.

    theta'' = -p cos(theta) (dead load) or -p cos(theta - theta(1)) (follower), theta(0) = 0 and the tip
    moment p lam cos(theta(1)) (dead) or p lam (follower), s in [0, 1], p = P L^2/EI >= 0, lam = l/L, any
    broadcastable shapes.  Solved by shooting on the clamp curvature (RK4, Newton) with continuation in p,
    steps of at most ``max_step``, each started by linear extrapolation from the two loads before.
    ``start``, one or two solved (p, state) pairs (the last at the load to continue from), replaces the
    continuation from p = 0.  Returns (delta/L, shortening/L, tip angle, converged, (p, state)); unconverged
    entries are NaN.
    """
    if mode not in ("dead", "follower"):
        raise ValueError(f"mode must be 'dead' or 'follower', not {mode!r}")
    follower = mode == "follower"
    p = np.asarray(p, dtype=float)
    lam = np.asarray(lam, dtype=float)
    shape = np.broadcast(p, lam).shape
    history = [(0.0, (np.zeros(shape), np.zeros(shape)))] if start is None else list(start)[-2:]
    p0 = np.asarray(history[-1][0], float)
    n = max(1, int(np.ceil(np.max(np.abs(p - p0), initial=0.0) / max_step)))
    for j in range(1, n + 1):
        pj = p0 + (p - p0) * (j / n)
        if start is None and j == 1:                        # the linear beam
            guess = (pj * (1 + lam), pj * (0.5 + lam))
        elif len(history) == 1:
            guess = history[-1][1]
        else:                                               # linear extrapolation in the load
            (pa, sa), (pb, sb) = history[-2:]
            span = np.asarray(pb - pa, float)
            w = np.where(span != 0.0, (pj - pb) / np.where(span != 0.0, span, 1.0), 0.0)
            guess = (sb[0] + w * (sb[0] - sa[0]), sb[1] + w * (sb[1] - sa[1]))
        k, phi, st, ok = _newton(pj, lam, follower, guess[0], guess[1], steps)
        history = [history[-1], (pj, (k, phi))]
    th = st[0]
    delta = np.where(ok, st[3] + lam * np.sin(th), np.nan)
    short = np.where(ok, 1.0 + lam - st[2] - lam * np.cos(th), np.nan)
    return delta, short, np.where(ok, th, np.nan), ok, history[-1]


def elastica(P, L: float, l: float, EI: float, mode: str = "dead",
             max_step: float = 0.5) -> ElasticaSolution:
    """Large-deflection cantilever with rigid tip segment under an end load (elastica, Bisshopp & Drucker 1945).

    ``mode`` is ``"dead"`` (load keeps its direction, perpendicular to the undeformed axis) or
    ``"follower"`` (load stays perpendicular to the rotated rigid segment): :func:`elastica_tip` in SI,
    continuation steps of at most ``max_step`` in P L^2/EI.
    """
    P = np.atleast_1d(np.asarray(P, dtype=float))
    delta, short, angle, ok, _ = elastica_tip(np.abs(P) * L**2 / EI, l / L, mode, max_step)
    sign = np.sign(P)
    return ElasticaSolution(P, sign * L * delta, L * short, sign * angle, ok)


@lru_cache(maxsize=64)
def _elastica_table(lam: float, mode: str, p_max: float, n: int = 161):
    """Nondimensional deflection delta/L vs p = P L^2/EI on a grid (cached per geometry ratio)."""
    p = np.linspace(0.0, p_max, n)
    delta, _, _, ok, _ = elastica_tip(p, lam, mode, max_step=0.5)
    if not np.all(ok):
        raise RuntimeError("elastica table did not converge")
    return p, delta


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


# The fit's table over (P L^2/EI, l/L), interpolated bilinearly: 48 RK4 steps are enough for its 2e-3
# interpolation error (1.5e-9 from solve_bvp at P L^2/EI <= 6) and keep its one-off cost near 1 s.
P_MAX = 16.0
_P = np.linspace(0.0, P_MAX, 97)
_LAM = np.linspace(0.0, 2.0, 41)


@lru_cache(maxsize=1)
def elastica_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """delta/L of the dead-load elastica (Bisshopp & Drucker 1945) on the (P L^2/EI, l/L) grid, computed once, cached on disk."""
    import os

    cache = os.environ.get("ACL_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "acl")
    path = os.path.join(cache, f"elastica-v2-{_P.size}x{_LAM.size}.npy")
    try:
        table = np.load(path)
        if table.shape == (_P.size, _LAM.size) and np.all(np.isfinite(table)):
            return _P, _LAM, table
    except (OSError, ValueError):
        pass
    table = np.zeros((_P.size, _LAM.size))
    solved = None                                           # the rows before: the continuation in the load
    for i, p in enumerate(_P[1:], 1):
        table[i], _, _, ok, state = elastica_tip(p, _LAM, "dead", max_step=1.0, steps=48, start=solved)
        if not np.all(ok):
            raise RuntimeError("elastica table did not converge")
        solved = [state] if solved is None else [solved[-1], state]
    try:
        os.makedirs(cache, exist_ok=True)
        tmp = f"{path}.{os.getpid()}.tmp.npy"
        np.save(tmp, table)
        os.replace(tmp, path)
    except OSError:
        pass
    return _P, _LAM, table


def elastica_deflection(P, L, l, EI):
    """Load-point deflection of the dead-load elastica (Bisshopp & Drucker 1945), bilinear in the table of :func:`elastica_table`.

    Any batch shape; P L^2/EI beyond the table is clipped.
    """
    p_grid, lam_grid, table = elastica_table()
    P = np.asarray(P, float)
    sign = np.sign(P)
    p = np.clip(np.abs(P) * L * L / EI, 0.0, p_grid[-1])
    lam = np.clip(np.asarray(l, float) / L, lam_grid[0], lam_grid[-1])
    fp = p / (p_grid[1] - p_grid[0])
    ip = np.clip(fp.astype(int), 0, p_grid.size - 2)
    wp = fp - ip
    fl = (lam - lam_grid[0]) / (lam_grid[1] - lam_grid[0])
    il = np.clip(fl.astype(int), 0, lam_grid.size - 2)
    wl = fl - il
    d = ((1 - wp) * (1 - wl) * table[ip, il] + wp * (1 - wl) * table[ip + 1, il]
         + (1 - wp) * wl * table[ip, il + 1] + wp * wl * table[ip + 1, il + 1])
    return sign * d * L


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

    solved: list = []      # (p, shooting state): each new load starts from the two nearest solved ones

    def deflection(p):
        """delta/L of the dead-load elastica (Bisshopp & Drucker) at p = P L^2/EI, as :func:`elastica`."""
        near = sorted(solved, key=lambda s: abs(float(s[0][0]) - p))[:2][::-1]      # the nearest last
        delta, _, _, ok, state = elastica_tip(np.array([p]), lam, start=near or None)
        if not ok[0] and near:
            delta, _, _, ok, state = elastica_tip(np.array([p]), lam)                  # from rest, as elastica does
        if ok[0]:
            solved.append(state)
        return float(delta[0])

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

    About 0.21 L without rigid segment, 0.33 L at l = L/4, 0.44 L at l = L/2 (docs/explanation/structures.md).
    """
    return L * _eq1_limit_ratio(round(l / L, 9), float(tolerance))


def eq1_is_valid(delta, L: float, l: float, tolerance: float = EQ1_TOLERANCE):
    """True where |delta| is within the range in which paper Eq. (1) matches the elastica (Bisshopp & Drucker 1945) to ``tolerance``."""
    return np.abs(np.asarray(delta, dtype=float)) <= eq1_validity_limit(L, l, tolerance)
