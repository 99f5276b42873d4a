"""The acoustic and mechanical models vectorised over design points (a leading axis N of independent designs).

Each function is the batched twin of a scalar one elsewhere in :mod:`acl.physics` (same equations,
same floors, same conventions; tests/test_sweep_evaluate*.py compares them point by point), written
so that a sweep evaluates 10^5..10^6 perturbed designs without a Python loop over points:

* :func:`capsule_modes` -- :func:`acl.physics.resonance.capsule_modes` (Rayleigh-Ritz bare modes and Q;
  one-orifice capsules by the closed-form eigenpairs of a rank-one update, others by LAPACK);
* :func:`coupled_modes` -- :func:`acl.physics.coupling.coupled_mode_batch` over the point axis (mutual radiation mass and resistance);
  :func:`lowest_single_interface_mode` its lowest mode for one interface and its wall image (secular equation);
* :func:`two_bubble_forces` -- the force engine of acl.analysis.acoustics for two one-orifice capsules, closed form;
* :func:`coupled_response` -- :func:`acl.physics.coupling.coupled_volumes` from a dense uncoupled response;
* :func:`latch_force`, :func:`latch_switching_force` -- :mod:`acl.physics.latch` (von Mises truss);
* :func:`eq1_force` -- the inverse of paper Eq. (1) (:func:`acl.physics.beams.eq1_force`) with per-point geometry.

Arrays: medium constants are scalars or (N,); geometry carries the point axis first.  Pure numpy, SI.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

# coupling's laws over a leading axis of points
from acl.physics.coupling import contact_distance, coupled_mode_batch, coupled_volumes
from acl.physics.resonance import shape_matrices, thermal_polytropic
from acl.physics.effects import bjerknes_gap_factor
from acl.physics.latch import axial_force
from acl.physics.roots import golden_max


# ----------------------------------------------------------------------------------------------
# Bare capsule modes (resonance.capsule_modes)
# ----------------------------------------------------------------------------------------------


@lru_cache(maxsize=8)
def _fixed_eigh(key):
    a_h, u_h = np.array(key[0]), np.array(key[1])
    lam, vec = np.linalg.eigh(a_h)
    return lam, vec, vec.T @ u_h


def _rank_one_eigh(a_h, u_h, alpha, beta, a):
    """Eigenpairs of alpha A_h + beta u u^T (3 x 3, A_h and u fixed) per point: eigenvalues of the characteristic cubic in closed form (Smith, Commun. ACM 4, 168 (1961)), vectors (Lambda - lambda)^-1 U^T u of the rank-one update (Golub, SIAM Rev. 15, 318 (1973)).

    Rows where a root comes within 1e-7 of a pole of the update (ill-conditioned vectors) are
    solved by LAPACK (``a`` the assembled matrices).
    """
    lam_h, vec_h, ut = _fixed_eigh((tuple(map(tuple, a_h)), tuple(u_h)))
    g = beta / alpha                                                    # B = Lambda + g ut ut^T, A = alpha U B U^T
    d = lam_h
    b00, b11, b22 = d[0] + g * ut[0] ** 2, d[1] + g * ut[1] ** 2, d[2] + g * ut[2] ** 2
    b01, b02, b12 = g * ut[0] * ut[1], g * ut[0] * ut[2], g * ut[1] * ut[2]
    q = (b00 + b11 + b22) / 3
    c00, c11, c22 = b00 - q, b11 - q, b22 - q
    p = np.sqrt((c00**2 + c11**2 + c22**2 + 2 * (b01**2 + b02**2 + b12**2)) / 6)
    det = (c00 * (c11 * c22 - b12 * b12) - b01 * (b01 * c22 - b12 * b02) + b02 * (b01 * b12 - c11 * b02)) / p**3
    phi = np.arccos(np.clip(det / 2, -1.0, 1.0)) / 3
    hi = q + 2 * p * np.cos(phi)
    lo = q + 2 * p * np.cos(phi + 2 * np.pi / 3)
    roots = np.stack([lo, 3 * q - hi - lo, hi], axis=1)                 # (N, 3) ascending
    den = d[None, :, None] - roots[:, None, :]                          # (N, i, k)
    y = ut[None, :, None] / den
    y = y / np.linalg.norm(y, axis=1, keepdims=True)
    vec = vec_h[None] @ y
    w2 = alpha[:, None] * roots
    bad = ~(np.abs(den).min(axis=1) > 1e-7 * (d[-1] - d[0])).all(axis=1) | ~np.isfinite(w2).all(axis=1)
    if bad.any():
        w2[bad], vec[bad] = np.linalg.eigh(a[bad])
    return w2, vec


def _col(x, n):
    """Scalar or (N,) -> (N,) float array."""
    return np.broadcast_to(np.asarray(x, float), (n,))


def capsule_modes(volume, radii, density, surface_tension, ambient_pressure, polytropic_index, viscosity,
                  sound_speed, thermal_radius, heat_capacity_ratio=1.4, thermal_diffusivity=2.1e-5,
                  quality_override=None, n_modes: int = 3):
    """Natural modes K x = w^2 M x of N capsules with P orifices each and their Q (batched resonance.capsule_modes: Lamb §102/§329, Leighton 3.4, Prosperetti 1977).

    ``volume`` (N,), ``radii`` (N, P).  Returns (omega (N, D), quality (N, D), orifice_volume
    (N, P, D)), D = P * n_modes, ascending; outward volume per mass-normalised modal coordinate.
    ``quality_override`` (None, scalar or (N,) with NaN = none) replaces every mode's Q.
    """
    radii = np.asarray(radii, float)
    n, p = radii.shape
    j = n_modes
    d = p * j
    s = shape_matrices(n_modes)
    lh = np.linalg.cholesky(s.mass)
    li = np.linalg.inv(lh)                              # Mh^-1/2 (lower)
    a_h = li @ s.stiffness @ li.T
    a_h = (a_h + a_h.T) / 2
    u_h = li @ s.volume
    rho, sig, p0 = _col(density, n), _col(surface_tension, n), _col(ambient_pressure, n)
    kap, mu, c = _col(polytropic_index, n), _col(viscosity, n), _col(sound_speed, n)
    vol0 = _col(volume, n)
    scale = 1.0 / np.sqrt(rho[:, None] * radii**3)       # (N, P): L^-1 = blockdiag(scale_o Mh^-1/2)
    a = np.zeros((n, d, d))
    for o in range(p):
        sl = slice(o * j, (o + 1) * j)
        a[:, sl, sl] = (sig * scale[:, o] ** 2)[:, None, None] * a_h
    u = (scale * radii**2)[:, :, None] * u_h[None, None, :]          # (N, P, J) = L^-1 b
    u = u.reshape(n, d)
    a += (kap * p0 / vol0)[:, None, None] * u[:, :, None] * u[:, None, :]
    if p == 1 and j == 3:
        w2, y = _rank_one_eigh(a_h, u_h, sig * scale[:, 0] ** 2, kap * p0 / vol0 * (scale[:, 0] * radii[:, 0] ** 2) ** 2, a)
    else:
        w2, y = np.linalg.eigh(a)
    x = (scale[:, :, None, None] * (li.T[None, None] @ y.reshape(n, p, j, d))).reshape(n, d, d)
    omega = np.sqrt(np.maximum(w2, 0.0))
    xo = x.reshape(n, p, j, d)
    vol = radii[:, :, None] ** 2 * (s.volume @ xo)                    # (N, P, D)
    vtot = vol.sum(axis=1)
    c_v = (mu[:, None, None] * radii[:, :, None] * (xo * (s.viscous @ xo)).sum(axis=2)).sum(axis=1)
    c_rad = (rho / (4 * np.pi * c))[:, None] * omega**2 * vtot**2
    phi = thermal_polytropic(omega, _col(thermal_radius, n)[:, None], heat_capacity_ratio,
                             _col(thermal_diffusivity, n)[:, None])
    c_th = np.abs(phi.imag) * (p0 / vol0)[:, None] / omega * vtot**2
    q = omega / (c_v + c_rad + c_th)
    if quality_override is not None:
        qo = _col(quality_override, n)
        q = np.where(np.isnan(qo)[:, None], q, qo[:, None])
    return omega, q, vol


# ----------------------------------------------------------------------------------------------
# Interface coupling (coupling.green_matrix, coupled_modes, coupled_response)
# ----------------------------------------------------------------------------------------------


def coupled_modes(phi, omega, damping, points, radii, body, density, sound_speed, wall_reflection: float = 0.0):
    """Undamped coupled modes per point: :func:`acl.physics.coupling.coupled_mode_batch` (Kinsler et al. ch. 7/8) over the point axis.

    ``phi`` (N, n, M) outward volume of each interface per bare modal coordinate, ``omega`` and
    ``damping`` (N, M) (omega_m/Q_m).  Returns (omega (N, K), volume (N, n, K), quality (N, K)).
    """
    om, vol, quality, _ = coupled_mode_batch(phi, omega, damping, points, radii, body, density, sound_speed,
                                             wall_reflection)
    return om, vol, quality


def lowest_single_interface_mode(phi, omega, damping, point, radius, density, sound_speed, wall_reflection: float = 0.0):
    """Lowest coupled mode of one interface with its wall image: Omega^2 q = w^2 (I + rho g v v^T) q solved as a secular equation (coupling.coupled_modes for n = 1; Golub, SIAM Rev. 15 (1973) rank-one update).

    ``phi`` (N, M) its outward volume per bare modal coordinate, ``omega``/``damping`` (N, M),
    ``point`` (N, 3), ``radius`` (N,).  The lowest root of 1 = w^2 c sum_m v_m^2/(w_m^2 - w^2),
    c = rho R/(4 pi d') the image's mutual mass, lies below w_1^2; Newton from below converges
    monotonically (the secular function is convex there).  Returns (omega (N,), volume (N,), quality (N,)).
    """
    n, m = phi.shape
    rho, c = _col(density, n), _col(sound_speed, n)
    zz = np.abs(2 * point[:, 2])
    d_img = contact_distance(zz, 2 * radius)                         # distance to its own image, floored at 2R
    cc = rho * wall_reflection / (4 * np.pi * d_img)
    om2 = omega**2
    v2 = phi**2
    lo = om2.min(axis=1)
    lam = lo / (1 + cc * v2.sum(axis=1))                              # below the root (Rayleigh bound)
    lam = np.minimum(lam, lo * (1 - 1e-12))
    for _ in range(60):
        den = om2 - lam[:, None]
        g = 1.0 - lam * cc * (v2 / den).sum(axis=1)                  # > 0 below the root, decreasing
        dg = -cc * (v2 / den).sum(axis=1) - lam * cc * (v2 / den**2).sum(axis=1)
        step = -g / dg
        lam = lam + step
        if np.all(np.abs(step) <= 1e-15 * lam):
            break
    q = phi / (om2 - lam[:, None])                                    # eigenvector direction
    norm = (q**2).sum(axis=1) + cc * ((phi * q).sum(axis=1)) ** 2      # q^T (I + c v v^T) q
    q = q / np.sqrt(norm)[:, None]
    w = np.sqrt(lam)
    vol = (phi * q).sum(axis=1)
    k = w / c
    s = wall_reflection * np.sinc(k * d_img / np.pi)
    c_n = (damping * q**2).sum(axis=1) + rho * w**2 / (4 * np.pi * c) * vol**2 * s
    with np.errstate(divide="ignore"):
        quality = np.where(c_n > 0, w / c_n, np.inf)
    return w, vol, quality


def coupled_response(h0, points, radii, body, frequency, density, sound_speed, wall_reflection: float = 0.0):
    """Inward volume U (N, F, n) per pascal per point from the dense uncoupled response ``h0`` (N, F, n, n): :func:`acl.physics.coupling.coupled_volumes` (Kinsler et al.) on its capsule blocks."""
    body = np.asarray(body, int)
    n = body.size
    if n == 0:
        return np.zeros(h0.shape[:-1], complex)
    counts = np.bincount(body)
    p = int(counts.max())
    rank = np.zeros(n, int)                                              # position of each interface in its capsule
    for c in range(counts.size):
        rank[body == c] = np.arange(counts[c])
    blocks = np.zeros(h0.shape[:-2] + (counts.size, p, p), h0.dtype)
    ii, jj = np.nonzero(body[:, None] == body[None, :])                  # entries within a capsule
    blocks[..., body[ii], rank[ii], rank[jj]] = h0[..., ii, jj]
    return coupled_volumes(blocks, body * p + rank, points, radii, frequency, density, sound_speed, wall_reflection)


# ----------------------------------------------------------------------------------------------
# Paper Eq. (1) with per-point geometry
# ----------------------------------------------------------------------------------------------


def eq1_force(delta, L, l, EI, rtol: float = 1e-13):
    """Load P for load-point deflection ``delta``, inverse of paper Eq. (1) (beams.eq1_force, which broadcasts over array geometry)."""
    from acl.physics.beams import eq1_force as _eq1_force

    return _eq1_force(delta, L, l, EI, rtol)


# ----------------------------------------------------------------------------------------------
# Latch (von Mises truss, acl.physics.latch) with per-point geometry
# ----------------------------------------------------------------------------------------------


def effective_beam_force(delta, L, l, EI, e_scale, gradient, weight, iterations: int = 100):
    """Load P (N,) giving load-point deflection ``delta`` (N,) under paper Eq. 1 with declared beam effects: the inverse of acl.physics.effects.effective_beam_deflection per row (bracket doubled from the small-load stiffness, then regula falsi, Illinois; acl.physics.effects.effective_beam_force's root to 1e-13).

    A law that saturates before ``delta`` (the elastica near its reach) gives a wall k0 delta 2^200, as the
    scalar inverse does.
    """
    from acl.physics.effects import effective_beam_deflection
    from acl.physics.roots import illinois

    delta, L, l, EI, e_scale, gradient, weight = np.broadcast_arrays(
        *(np.asarray(v, float) for v in (delta, L, l, EI, e_scale, gradient, weight)))
    sign, target = np.sign(delta), np.abs(delta)

    def defl(p):
        return effective_beam_deflection(p, L, l, EI, e_scale, gradient, weight)

    k0 = 1e-30 / defl(np.full(delta.shape, 1e-30))
    lo, hi = np.zeros(delta.shape), k0 * target
    d_hi, d_prev = defl(hi), np.full(delta.shape, -np.inf)
    wall = np.zeros(delta.shape, bool)
    for _ in range(200):                                 # Eq. (1) and the elastica stiffen: expand the bracket
        short = (d_hi < target) & ~wall
        if not short.any():
            break
        wall |= short & (d_hi <= d_prev * (1.0 + 1e-12))
        short &= ~wall
        lo, d_prev = np.where(short, hi, lo), np.where(short, d_hi, d_prev)
        hi = np.where(short, 2.0 * hi, hi)
        d_hi = np.where(short, defl(hi), d_hi)
    live = (target > 0) & ~wall & (d_hi >= target)
    scale = np.where(target > 0, target, 1.0)
    P = hi
    if live.any():
        def g(p):
            return defl(p) / scale - 1.0
        root, _ = illinois(g, lo, np.where(live, g(lo), -1.0), hi, np.where(live, d_hi / scale - 1.0, 1.0),
                           iterations=iterations, ftol=1e-15)
        P = np.where(live, root, hi)
    P = np.where(wall, k0 * target * 2.0 ** 200, np.where(target > 0, P, 0.0))
    return sign * P, k0


def latch_force(u, theta, L, w, t, E):
    """Holding force (N) at shuttle travel ``u`` with per-point geometry (latch.latch_force: von Mises truss, Bazant & Cedolin; Timoshenko & Gere 2.7)."""
    x = np.asarray(u, float) / L
    c, s = np.cos(theta), np.sin(theta)
    chord = np.hypot(c, s - x)
    phi = np.arctan2(s - x, c)
    n = axial_force(1.0 - chord, np.broadcast_to(w / L, chord.shape))
    per_beam = n * np.sin(phi) + 12.0 * (theta - phi) * c / chord**2
    return 2.0 * per_beam * (E * t * w**3 / 12.0 / L**2)


def latch_switching_force(theta, L, w, t, E, n_grid: int = 257, iterations: int = 60, block: int = 4096):
    """Switching force a -> b (largest holding force between state a and the barrier top) and release force b -> a (largest pull back between state b and the top) per point (latch.latch_landscape, its 2001-point grid extrema refined by golden section).

    Arrays (N,) -> (switching (N,), release (N,) NaN when monostable, bistable (N,)): bistable when
    the force falls through zero (barrier top) and then rises through zero (state b) within
    2.6 L sin(theta).
    """
    theta, L, w, t, E = (np.asarray(v, float) for v in (theta, L, w, t, E))
    n = theta.shape[0]
    if n > block:                       # bounded memory: the landscape grid is (rows, n_grid)
        parts = [latch_switching_force(theta[i:i + block], L[i:i + block], w[i:i + block], t[i:i + block],
                                       E[i:i + block], n_grid, iterations, block) for i in range(0, n, block)]
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))
    rows = np.arange(n)
    reach = 2.6 * L * np.sin(theta)
    grid = np.linspace(0.0, 1.0, n_grid)[None, :] * reach[:, None]                  # (N, G)
    args = (theta[:, None], L[:, None], w[:, None], t[:, None], E[:, None])
    f = latch_force(grid, *args)
    down = (f[:, 1:-1] > 0) & (f[:, 2:] <= 0)
    has_down = down.any(axis=1)
    i0 = np.where(has_down, np.argmax(down, axis=1) + 1, n_grid - 1)
    idx = np.arange(n_grid)[None, :]
    up = (idx[:, :-1] >= i0[:, None]) & (f[:, :-1] < 0) & (f[:, 1:] >= 0)
    bistable = has_down & up.any(axis=1)
    i1 = np.where(bistable, i0 + np.argmax(np.where(idx[:, :-1] >= i0[:, None], up, False), axis=1) - i0, n_grid - 1)
    i0 = np.where(bistable, i0, n_grid - 1)            # monostable: the largest force over the whole reach
    h = reach / (n_grid - 1)
    a1 = (theta, L, w, t, E)

    def refine(values, k, sign):
        lo = np.maximum(grid[rows, k] - h, 0.0)
        hi = np.minimum(grid[rows, k] + h, reach)
        return np.maximum(values[rows, k], golden_max(lambda x: sign * latch_force(x, *a1), lo, hi, iterations)[0])

    masked = np.where(idx <= i0[:, None], f, -np.inf)
    switching = refine(masked, np.argmax(masked, axis=1), 1.0)
    pull = np.where((idx >= i0[:, None]) & (idx <= i1[:, None] + 1), -f, -np.inf)
    release = np.where(bistable, refine(pull, np.argmax(pull, axis=1), -1.0), np.nan)
    return switching, release, bistable


def latch_state_b(theta, L, w, t, E, n_grid: int = 2001, reach: float = 2.6, iterations: int = 200,
                  block: int = 4096):
    """Travel of the latch's second stable state per point, 0 where monostable (latch.latch_landscape: the
    first - -> + crossing of the holding force after the barrier top on its 2001-point grid, refined by
    bisection to 1e-14 L where the scalar code uses Brent; von Mises truss, Bazant & Cedolin)."""
    theta, L, w, t, E = (np.asarray(v, float) for v in (theta, L, w, t, E))
    n = theta.shape[0]
    if n > block:
        return np.concatenate([latch_state_b(theta[i:i + block], L[i:i + block], w[i:i + block], t[i:i + block],
                                             E[i:i + block], n_grid, reach, iterations, block)
                               for i in range(0, n, block)])
    u = np.linspace(0.0, 1.0, n_grid)[None, :] * (reach * L * np.sin(theta))[:, None]
    args = (theta[:, None], L[:, None], w[:, None], t[:, None], E[:, None])
    f = latch_force(u, *args)
    down = (f[:, 1:-1] > 0) & (f[:, 2:] <= 0)
    has_down = down.any(axis=1)
    i0 = np.argmax(down, axis=1) + 1
    idx = np.arange(n_grid - 1)[None, :]
    up = (idx >= i0[:, None]) & (f[:, :-1] < 0) & (f[:, 1:] >= 0)
    bistable = has_down & up.any(axis=1)
    i1 = np.argmax(up, axis=1)
    rows = np.arange(n)
    lo, hi = u[rows, i1], u[rows, np.minimum(i1 + 1, n_grid - 1)]
    one = (theta, L, w, t, E)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = latch_force(mid, *one) < 0
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        if not np.any(hi - lo > 1e-14 * L):
            break
    return np.where(bistable, 0.5 * (lo + hi), 0.0)


# ----------------------------------------------------------------------------------------------
# Two one-orifice capsules under one tone: the whole force model in closed form
# ----------------------------------------------------------------------------------------------


def two_bubble_forces(h, pts, radii, normals, centres, outer, scale, w, pressure, density, sound_speed, viscosity,
                      streaming_constant, wall_reflection: float = 0.0, pair_law=None):
    """Forces (N, 2, 3) on two capsules with one interface each under one tone: coupled volumes, thrust, Bjerknes, jet drag (the acoustics force engine for n = 2, closed form).

    Coupled volumes solve the 2 x 2 system (I - w^2 rho H0 g) U = H0 1 by Cramer's rule (Kinsler et
    al. mutual radiation impedance; Pierce 5.1 wall images); thrust C_s 6 pi mu w eps^2 (Stuart 1966);
    Bjerknes rho w^2 Re(Ua Ub*)/(8 pi d^2) (Crum 1975); drag of each jet on the other capsule
    (Schlichting laminar round jet).  ``h`` (N, 2) uncoupled inward response per Pa, ``pts``,
    ``normals``, ``centres`` (N, 2, 3), ``radii``, ``outer``, ``scale`` (N, 2); ``w`` rad/s and
    ``pressure`` Pa scalars; ``pair_law`` (factor, gap exponent, gap reference), each (N,), of a declared
    bjerknes_scale (:func:`acl.physics.effects.bjerknes_gap_factor`), None for the physics' own law.
    """
    rho = np.asarray(density, float)
    k = w / np.asarray(sound_speed, float)
    pa, pb = pts[:, 0], pts[:, 1]
    ra, rb = radii[:, 0], radii[:, 1]
    sep = pb - pa
    dist = np.sqrt(np.einsum("bk,bk->b", sep, sep))
    d = contact_distance(dist, ra + rb)

    def green(x):
        kx = k * x
        return (np.cos(kx) - 1j * np.sin(kx)) / (4 * np.pi * x)

    def mirror_dist(p, q, floor):
        dz = p[:, 2] + q[:, 2]
        dx = p[:, 0] - q[:, 0]
        dy = p[:, 1] - q[:, 1]
        return contact_distance(np.sqrt(dx * dx + dy * dy + dz * dz), floor)

    g_ab = green(d)
    g_aa = g_bb = 0.0
    if wall_reflection:
        g_ab = g_ab + wall_reflection * green(mirror_dist(pa, pb, ra + rb))
        g_aa = wall_reflection * green(contact_distance(np.abs(2 * pa[:, 2]), 2 * ra))
        g_bb = wall_reflection * green(contact_distance(np.abs(2 * pb[:, 2]), 2 * rb))
    kap = w * w * rho
    ha, hb = h[:, 0], h[:, 1]
    a11, a22 = 1 - kap * ha * g_aa, 1 - kap * hb * g_bb
    a12, a21 = -kap * ha * g_ab, -kap * hb * g_ab
    det = a11 * a22 - a12 * a21
    ua = (ha * a22 - a12 * hb) / det * pressure
    ub = (a11 * hb - a21 * ha) / det * pressure
    eps_a = 2 * np.abs(ua) / (np.pi * ra**2)
    eps_b = 2 * np.abs(ub) / (np.pi * rb**2)
    c0 = streaming_constant * 6 * np.pi * np.asarray(viscosity, float) * w
    thr_a = c0 * eps_a**2 * scale[:, 0]
    thr_b = c0 * eps_b**2 * scale[:, 1]
    na, nb = normals[:, 0], normals[:, 1]
    att = rho * w * w * (ua * np.conj(ub)).real / (8 * np.pi * dist**2)
    if pair_law is not None:
        factor, n, ref = pair_law
        att = att * factor
        if np.any(n):
            att = att * bjerknes_gap_factor(dist, ref, n)
    f_bj = (att / dist)[:, None] * sep                                  # on a, along p_b - p_a
    out = np.empty(pts.shape)
    out[:, 0] = -thr_a[:, None] * na + f_bj
    out[:, 1] = -thr_b[:, None] * nb - f_bj
    for src, dst, thr, nrm in ((0, 1, thr_a, na), (1, 0, thr_b, nb)):
        x = centres[:, dst] - pts[:, src]
        r = np.sqrt(np.einsum("bk,bk->b", x, x))
        cos = np.einsum("bk,bk->b", x, nrm) / r
        drag = thr * np.minimum(1.0, 9 * outer[:, dst] / (4 * r)) * np.clip(cos, 0.0, None) ** 2
        out[:, dst] += drag[:, None] * nrm
    return out
