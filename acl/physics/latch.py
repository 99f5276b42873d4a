"""Bistable latch of paper Fig. 6a: a mirror-symmetric pair of inclined beams carrying a shuttle.

Reduced model: a von Mises truss (Bazant & Cedolin, Stability of Structures, Sec. 2.x) whose two bars
are the inclined beams, with

* axial stretching/compression of each beam, stiffness E A / L, capped in compression by Euler
  buckling of a clamped-clamped column (P_cr = 4 pi^2 E I / L^2) and following the buckled
  elastica beyond it (Timoshenko & Gere, Theory of Elastic Stability, Sec. 2.7: shortening
  2 (1 - E(m)/K(m)) L at load P_cr (2 K(m)/pi)^2);
* bending of each beam whose two clamped ends keep their angle while the chord rotates by
  psi = theta - phi: a rotational spring with energy 6 E I psi^2 / L (slope-deflection, both ends
  rotated by psi relative to the chord).

The shuttle moves by ``u`` along the actuation direction (towards the beams' clamps, u = 0 is the
as-printed state a).  ``latch_force(u)`` is the external force along that direction that holds the
shuttle at ``u`` (positive: the latch pushes back towards state a).  The inclined-beam physics
follows Jiang, Korpas & Raney, Nat. Commun. 10, 128 (2019) (paper ref. 20): switching force grows
with theta, bistability needs enough angle and slenderness.  All SI; vectorized over ``u``.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import functools

import numpy as np

from acl.physics.roots import grid_max
from acl.physics.springs import rect_second_moment


def complete_elliptic(m):
    """Complete elliptic integrals K(m), E(m), 0 <= m < 1, by the arithmetic-geometric mean (Abramowitz & Stegun 17.6.1-17.6.4).

    As scipy.special.ellipk/ellipe to rounding (tests/test_physics_latch.py), without importing
    scipy.special (about 0.35 s of `acl analyze` start-up).
    """
    m = np.asarray(m, dtype=float)
    a, b = np.ones_like(m), np.sqrt(1.0 - m)
    c2sum = 0.5 * m                             # sum 2^(n-1) c_n^2, c_0^2 = m
    scale = 0.5
    for _ in range(40):                         # quadratic convergence: 6-8 rounds for m <= 0.999
        c = (a - b) / 2.0
        a, b = (a + b) / 2.0, np.sqrt(a * b)
        scale *= 2.0
        c2sum = c2sum + scale * c * c
        if np.all(c <= 1e-17 * a):
            break
    K = np.pi / (2.0 * a)
    return K, K * (1.0 - c2sum)


@lru_cache(maxsize=8)
def _buckled_column_table(n: int = 4000):
    """Buckled clamped-clamped elastica: shortening/L and P/P_cr vs modulus m (Timoshenko & Gere Sec. 2.7)."""
    m = np.concatenate([[0.0], np.geomspace(1e-9, 0.97, n)])
    K, Ek = complete_elliptic(m)
    shortening = 2.0 * (1.0 - Ek / K)
    load = (2.0 * K / np.pi) ** 2
    return shortening, load


def axial_force(compression, slenderness):
    """Nondimensional compressive force N L^2/(E I) of one beam vs compression/L: linear E A / L, then buckled elastica (Timoshenko & Gere Sec. 2.7).

    ``slenderness`` w/L a scalar, or an array broadcasting against ``compression`` (one per design point).
    """
    c = np.asarray(compression, dtype=float)
    s = np.asarray(slenderness, dtype=float)
    k_axial = 12.0 / s**2                      # E A L / (E I) for a rectangle of width w: 12 (L/w)^2
    p_cr = 4.0 * np.pi**2
    short, load = _buckled_column_table()
    if s.ndim == 0:
        total = p_cr * load / k_axial + short     # elastic shortening at that load + geometric shortening
        buckled = np.interp(c, total, p_cr * load)
        return np.where(c * k_axial <= p_cr, k_axial * c, buckled)
    k = np.broadcast_to(k_axial, c.shape)
    out = k * c
    buckled = c * k > p_cr
    if buckled.any():
        out[buckled] = _buckled_per_element(c[buckled], p_cr / k[buckled])
    return out


def _buckled_per_element(c, a):
    """N L^2/(E I) on the buckled branch: np.interp(c, a load + short, p_cr load) with a = p_cr/k differing per element."""
    p_cr = 4.0 * np.pi**2
    short, load = _buckled_column_table()
    # a vectorised binary search on the (monotone) table, then the same linear interpolation
    lo = np.zeros(c.shape, int)
    hi = np.full(c.shape, short.size - 1)
    while True:
        mid = (lo + hi) // 2
        if not np.any(hi - lo > 1):
            break
        below = a * load[mid] + short[mid] <= c
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    t0 = a * load[lo] + short[lo]
    t1 = a * load[hi] + short[hi]
    frac = np.clip((c - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)
    buckled = p_cr * (load[lo] + frac * (load[hi] - load[lo]))
    return np.where(c >= a * load[-1] + short[-1], p_cr * load[-1], buckled)


def _axial_energy(compression, slenderness: float):
    """Nondimensional strain energy of one beam's axial member, integral of axial_force (Clapeyron)."""
    c = np.asarray(compression, dtype=float)
    hi = max(float(np.max(c, initial=0.0)), 1e-12)
    grid = np.linspace(0.0, hi, 20001)
    f = axial_force(grid, slenderness)
    # cumulative trapezoid rule (as scipy.integrate.cumulative_trapezoid, without importing scipy.integrate)
    cum = np.concatenate([[0.0], np.cumsum(np.diff(grid) * (f[1:] + f[:-1]) / 2.0)])
    k_axial = 12.0 / slenderness**2
    return np.where(c <= 0.0, 0.5 * k_axial * c**2, np.interp(c, grid, cum))


def _geometry(u, theta):
    u = np.asarray(u, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    chord = np.hypot(c, s - u)
    phi = np.arctan2(s - u, c)
    return chord, phi, c


def _scale(L: float, w: float, t: float, E: float) -> float:
    return E * rect_second_moment(w, t) / L**2   # E I / L^2, N


def latch_force(u, theta: float, L: float, w: float, t: float, E: float):
    """Holding force (N) at shuttle travel ``u``: von Mises truss (Bazant & Cedolin) with Euler-buckling bars (Timoshenko & Gere 2.7) and 6EI psi^2/L bending."""
    chord, phi, c = _geometry(np.asarray(u, dtype=float) / L, theta)
    n = axial_force(1.0 - chord, w / L)
    per_beam = n * np.sin(phi) + 12.0 * (theta - phi) * c / chord**2
    return 2.0 * per_beam * _scale(L, w, t, E)


def latch_energy(u, theta: float, L: float, w: float, t: float, E: float):
    """Strain energy (J) at shuttle travel ``u``: axial (Timoshenko & Gere 2.7) + slope-deflection bending 6 E I psi^2 / L per beam."""
    chord, phi, _ = _geometry(np.asarray(u, dtype=float) / L, theta)
    per_beam = _axial_energy(1.0 - chord, w / L) + 6.0 * (theta - phi) ** 2
    return 2.0 * per_beam * _scale(L, w, t, E) * L


def latch_stiffness(u, theta: float, L: float, w: float, t: float, E: float):
    """Tangent stiffness dF/du (N/m): derivative of the von Mises truss holding force (latch_force), central differences."""
    u = np.asarray(u, dtype=float)
    h = 1e-7 * L
    return (latch_force(u + h, theta, L, w, t, E) - latch_force(u - h, theta, L, w, t, E)) / (2 * h)


def latch_force_and_stiffness(u: float, theta: float, L: float, w: float, t: float, E: float) -> tuple[float, float]:
    """(:func:`latch_force`, :func:`latch_stiffness`) at one travel ``u`` from one vectorised evaluation of the von Mises truss law (same central difference)."""
    h = 1e-7 * L
    f = latch_force(np.array([u, u + h, u - h], dtype=float), theta, L, w, t, E)
    return float(f[0]), float((f[1] - f[2]) / (2 * h))


@dataclass(frozen=True)
class LatchLandscape:
    """Energy landscape along the actuation direction and its critical points (SI)."""

    u: np.ndarray               # m, shuttle displacement from state a
    energy: np.ndarray          # J
    force: np.ndarray           # N, holding force (latch_force)
    bistable: bool
    state_b: float | None       # m, second stable state (None if monostable)
    unstable: float | None      # m, the energy maximum between the states
    barrier: float | None       # J, energy(unstable) - energy(a)
    switching_force: float      # N, max holding force between a and the unstable point (a -> b)
    release_force: float | None  # N, max force pulling back between b and the unstable point (b -> a)


@functools.lru_cache(maxsize=256)
def latch_landscape(theta: float, L: float, w: float, t: float, E: float,
                    n: int = 2001, reach: float = 2.6) -> LatchLandscape:
    """Energy landscape (as paper Fig. 6d), stable states, barrier, switching and release forces of the von Mises truss latch model."""
    u = np.linspace(0.0, reach * L * np.sin(theta), n)
    u.flags.writeable = False   # results are cached and shared
    F = latch_force(u, theta, L, w, t, E)
    U = latch_energy(u, theta, L, w, t, E)
    F.flags.writeable = U.flags.writeable = False
    # Sign changes of the holding force after state a: + -> - is the barrier top, - -> + is state b.
    down = np.nonzero((F[1:-1] > 0) & (F[2:] <= 0))[0] + 1
    if down.size == 0:
        return LatchLandscape(u, U, F, False, None, None, None,
                              _refined_max(lambda x: latch_force(x, theta, L, w, t, E), u, F, 0, u.size), None)
    i0 = down[0]
    up = np.nonzero((F[i0:-1] < 0) & (F[i0 + 1:] >= 0))[0]
    if up.size == 0:
        return LatchLandscape(u, U, F, False, None, None, None,
                              _refined_max(lambda x: latch_force(x, theta, L, w, t, E), u, F, 0, u.size), None)
    i1 = i0 + up[0]
    from acl.physics.roots import brentq

    def f(x):
        return float(latch_force(x, theta, L, w, t, E))

    u_top = brentq(f, u[i0], u[i0 + 1], xtol=1e-14 * L)
    u_b = brentq(f, u[i1], u[i1 + 1], xtol=1e-14 * L)
    barrier = float(latch_energy(u_top, theta, L, w, t, E))
    switching = _refined_max(lambda x: latch_force(x, theta, L, w, t, E), u, F, 0, i0 + 1)
    release = _refined_max(lambda x: -latch_force(x, theta, L, w, t, E), u, -F, i0, i1 + 1)
    return LatchLandscape(u, U, F, True, u_b, u_top, barrier, switching, release)


def _refined_max(fn, u: np.ndarray, values: np.ndarray, lo: int, hi: int, iterations: int = 60) -> float:
    """Largest ``fn`` on u[lo:hi]: the grid maximum refined by golden section (acl.physics.roots.grid_max).

    The extreme often sits at the buckling kink, between grid points: the grid alone underestimates
    the switching force (up to 5e-4 relative) and the release force (2e-3), so the margin it gives
    would be optimistic.  Never below the grid value.
    """
    return float(grid_max(lambda x: float(fn(x)), u, values, lo, hi, iterations)[0])
