"""Cantilever with a rigid actuator, vectorized over rows: paper Eq. (1) with a stiffness profile, and the elastica.

Everything here is per row (numpy arrays of shape (n,)), SI.  Two deflection laws:

* :func:`eq1_deflection` -- paper Eq. (1) (Supplementary Note 2) generalised to a bending stiffness
  that varies along the beam: delta = c_D P + l sin(arctan(c_T P)), with the linear-beam
  integrals c_D = int (L-x)(L+l-x)/EI(x) dx and c_T = int (L+l-x)/EI(x) dx (equal to Eq. (1) for a
  uniform beam);
* :func:`elastica_deflection` -- the dead-load elastica of the same beam (Bisshopp & Drucker,
  Q. Appl. Math. 3 (1945)), tabulated once over (P L^2/EI, l/L) by vectorized shooting and
  interpolated (cross-checked against :func:`acl.physics.beams.elastica` in the tests).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

L_REF = 50e-6          # m: reference length of the stiffness gradient (the paper's beam length)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(24)


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


def eq1_deflection(P, l, c_d, c_t):
    """Load-point deflection delta = c_D P + l sin(arctan(c_T P)) (paper Eq. (1), Suppl. Eq. 2.6)."""
    u = c_t * P
    return c_d * P + l * u / np.sqrt(1.0 + u * u)


# ---- elastica table -------------------------------------------------------------------------

P_MAX = 16.0
_P = np.linspace(0.0, P_MAX, 97)
_LAM = np.linspace(0.0, 2.0, 41)


@lru_cache(maxsize=1)
def elastica_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The table, computed once (about 1 s) and cached on disk next to the units cache."""
    import os

    cache = os.environ.get("ACL_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "acl")
    path = os.path.join(cache, f"elastica-v1-{_P.size}x{_LAM.size}.npy")
    try:
        table = np.load(path)
        if table.shape == (_P.size, _LAM.size) and np.all(np.isfinite(table)):
            return _P, _LAM, table
    except (OSError, ValueError):
        pass
    table = _compute_table()
    try:
        os.makedirs(cache, exist_ok=True)
        tmp = f"{path}.{os.getpid()}.tmp.npy"
        np.save(tmp, table)
        os.replace(tmp, path)
    except OSError:
        pass
    return _P, _LAM, table


def _compute_table() -> np.ndarray:
    """delta/L on the grid (p = P L^2/EI, lam = l/L): shooting on kappa(0) with RK4, Newton, continuation in p.

    theta'' = -p cos(theta), theta(0) = 0, theta'(1) = p lam cos(theta(1)); delta/L = y(1) + lam sin(theta(1))
    (the boundary-value problem of :func:`acl.physics.beams.elastica`, dead load).
    """
    lam = _LAM
    steps = 48
    h = 1.0 / steps
    out = np.zeros((_P.size, lam.size))
    k1 = k2 = None                      # solutions at the two previous loads
    for i, p in enumerate(_P):
        if p == 0.0:
            k1 = np.zeros_like(lam)
            continue
        k0 = p * (1 + lam) if k2 is None else 2 * k1 - k2     # linear guess, then extrapolation in p
        for _ in range(30):
            th, ka, y, ts, ks = _rk4(p, k0, steps, h)
            step = -(ka - p * lam * np.cos(th)) / (ks + p * lam * np.sin(th) * ts)
            k0 = k0 + step
            if np.max(np.abs(step)) < 1e-12 * max(1.0, p):
                break
        th, ka, y, ts, ks = _rk4(p, k0, steps, h)
        out[i] = y + lam * np.sin(th)
        k1, k2 = k0, k1
    return out


def _rk4(p, k0, steps, h):
    """Integrate (theta, kappa, y, d theta/d k0, d kappa/d k0) from s = 0 to 1."""
    th = np.zeros_like(k0)
    ka = k0.copy()
    y = np.zeros_like(k0)
    ts = np.zeros_like(k0)
    ks = np.ones_like(k0)

    def f(th, ka, ts, ks):
        return ka, -p * np.cos(th), np.sin(th), ks, p * np.sin(th) * ts

    for _ in range(steps):
        a = f(th, ka, ts, ks)
        b = f(th + h / 2 * a[0], ka + h / 2 * a[1], ts + h / 2 * a[3], ks + h / 2 * a[4])
        c = f(th + h / 2 * b[0], ka + h / 2 * b[1], ts + h / 2 * b[3], ks + h / 2 * b[4])
        d = f(th + h * c[0], ka + h * c[1], ts + h * c[3], ks + h * c[4])
        th = th + h / 6 * (a[0] + 2 * b[0] + 2 * c[0] + d[0])
        ka = ka + h / 6 * (a[1] + 2 * b[1] + 2 * c[1] + d[1])
        y = y + h / 6 * (a[2] + 2 * b[2] + 2 * c[2] + d[2])
        ts = ts + h / 6 * (a[3] + 2 * b[3] + 2 * c[3] + d[3])
        ks = ks + h / 6 * (a[4] + 2 * b[4] + 2 * c[4] + d[4])
    return th, ka, y, ts, ks


def elastica_deflection(P, L, l, EI):
    """Load-point deflection of the dead-load elastica (interpolated table; P L^2/EI beyond the table is clipped)."""
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
