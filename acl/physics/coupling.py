"""Acoustically coupled bubbles: every interface of every capsule hears every other one.

Model (linear, e^{i omega t}).  Each capsule alone is described by its Rayleigh-Ritz modes
(:mod:`acl.physics.resonance`): natural frequencies omega_m, modal damping omega_m/Q_m and the
outward volume phi_om of interface o per mass-normalized modal coordinate.  An interface o whose
inward volume displacement is U_o radiates, in the liquid, the pressure of a monopole of outward
volume -U_o (Leighton, *The Acoustic Bubble*, eq. 3.xx; Pierce, *Acoustics*, 4.3):

    p(r) = omega^2 rho U_o g(r),        g(r) = exp(-i k r) / (4 pi r),   k = omega / c.

So the pressure driving interface i is p_inc + omega^2 rho sum_j g_ij U_j and, with H0 the
uncoupled (block-diagonal, per capsule) inward response per pascal,

    (I - omega^2 rho H0 g) U = H0 1 p_inc                           (coupled response)

In the capsules' modal coordinates q the same coupling is a mutual *mass* rho g_ij between
interfaces (Kinsler et al., *Fundamentals of Acoustics*, mutual radiation impedance of two small
sources, Z_12 = i omega rho exp(-ikd)/(4 pi d) per volume velocity): the undamped modes solve
Omega^2 q = omega^2 (I + rho Phi^T g0 Phi) q with the incompressible g0 = 1/(4 pi d)
(:func:`coupled_modes`), and the real part -sin(kd)/(4 pi d) of g is the mutual radiation
resistance that enters the damping of collective modes.

Terms of g (``green_matrix``):

* interfaces of *different* capsules: the retarded exp(-ikd)/(4 pi d) (kd need not be small);
* interfaces of the *same* capsule (coupled through the gas already, here also through the
  liquid): the incompressible 1/(4 pi d) only, because the capsule's own radiation resistance is
  already in its modal Q (compact monopole on its total volume, :func:`resonance.capsule_modes`);
* the substrate (plane z = 0) as a wall with pressure reflection coefficient R (image sources at the
  mirrored points, Pierce, *Acoustics*, 5.1; R = +1 is a rigid wall): R exp(-ikd')/(4 pi d') for
  every pair i, j' including an interface and its own image (which adds mass rho R/(8 pi z) and,
  at R = 1, doubles the radiation resistance close to the wall).

Both are free-field monopole terms: a capsule is small against the wavelength, so beyond a few
orifice radii its interface radiates as a point source.  Between two orifices on the same flat face
(a baffle) the true mutual mass is up to 2x larger (rho/(2 pi d)); that is not modelled.  This is an
assumption, not an oversight: each capsule's *own* added mass is baffled (:mod:`acl.physics.resonance`),
the mutual terms are free-field; docs/physics.md (Part A section 11, "The baffle assumption, stated")
gives the evidence for keeping them and where the factor is carried as model-form uncertainty.
Distances are smoothly floored at the sum of the two orifice radii (touching interfaces; :func:`contact_distance`).

Pure numpy on SI floats; no acl.design import.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from acl.physics.resonance import BubbleModes, modal_dynamic_stiffness, radiation_resistance


@dataclass(frozen=True)
class BubbleSystem:
    """All interfaces of a design, with each capsule's own modes (arrays, SI).

    ``points`` (n, 3) orifice centres; ``radii`` (n,); ``body`` (n,) capsule index of each interface.
    Padded per-capsule modal data for the vectorised response: ``phi`` (C, P, Mx) outward volume
    per modal coordinate (zero where padded), ``omega`` / ``damping`` (C, Mx) natural frequency and
    omega_m/Q_m (padded modes: omega 1, damping 1, phi 0).  ``slot`` (n,) index of each interface
    in the flattened padded (C*P) layout.
    """

    points: np.ndarray
    radii: np.ndarray
    body: np.ndarray
    phi: np.ndarray
    omega: np.ndarray
    damping: np.ndarray
    slot: np.ndarray

    @property
    def n(self) -> int:
        return int(self.radii.size)


def build_system(modes: Sequence[BubbleModes], points: Sequence, radii: Sequence) -> BubbleSystem:
    """Stack the per-capsule modes (``modes[c]``) and interfaces (``points[c]`` (n_c, 3), ``radii[c]``)."""
    ncap = len(modes)
    p = max([m.orifice_volume.shape[0] for m in modes] + [1])
    mx = max([m.omega.size for m in modes] + [1])
    phi = np.zeros((ncap, p, mx))
    om = np.ones((ncap, mx))
    dmp = np.ones((ncap, mx))
    pts, rad, body, slot = [], [], [], []
    for c, m in enumerate(modes):
        n_or, n_m = m.orifice_volume.shape if m.omega.size else (len(radii[c]), 0)
        if n_m:
            phi[c, :n_or, :n_m] = m.orifice_volume
            om[c, :n_m] = m.omega
            dmp[c, :n_m] = m.omega / m.quality
        pts.append(np.asarray(points[c], float).reshape(-1, 3))
        rad.append(np.asarray(radii[c], float).reshape(-1))
        body += [c] * len(rad[-1])
        slot += [c * p + i for i in range(len(rad[-1]))]
    return BubbleSystem(points=np.concatenate(pts) if pts else np.zeros((0, 3)),
                        radii=np.concatenate(rad) if rad else np.zeros(0),
                        body=np.asarray(body, int), phi=phi, omega=om, damping=dmp,
                        slot=np.asarray(slot, int))


#: Exponent of the smooth contact floor (:func:`contact_distance`): a hard max(d, R_a + R_b) put a kink in every
#: force law at contact (a snap-in "landing" exactly at 20.000 um for Fig. 5c); with 32 the floor changes d by
#: (f/d)^32/32 (under 1e-10 from d = 2 (R_a + R_b) on) and rounds the corner within a few % of contact.  (8 bent
#: the forces of a pair approaching snap-in enough that the fit of tests/test_fit_diagnosis.py's trapped case no
#: longer recovered from its robust start.)
CONTACT_SMOOTHNESS = 32


def contact_distance(distance, floor):
    """Smooth floor (d^n + f^n)^(1/n), n = CONTACT_SMOOTHNESS, of a monopole distance at the touching distance f = R_a + R_b (C-infinity, >= max(d, f))."""
    f = np.asarray(floor, float)
    d = np.asarray(distance, float)
    big, small = np.maximum(d, f), np.minimum(d, f)
    r = small / np.where(big > 0, big, 1.0)                    # in [0, 1]: the power never overflows
    return np.where(f > 0, big * (1.0 + r**CONTACT_SMOOTHNESS) ** (1.0 / CONTACT_SMOOTHNESS), d)


def _distances(points, radii, mirror: bool) -> np.ndarray:
    """|p_i - p_j| (or to the mirror image of p_j in z = 0), smoothly floored at R_i + R_j (:func:`contact_distance`); points (..., n, 3), radii (n,) or (..., n)."""
    q = points.copy()
    if mirror:
        q[..., 2] = -q[..., 2]
    d = np.linalg.norm(points[..., :, None, :] - q[..., None, :, :], axis=-1)
    return contact_distance(d, radii[..., :, None] + radii[..., None, :])


def green_matrix(points, radii, body, wavenumber=None, wall_reflection: float = 0.0) -> np.ndarray:
    """Interface coupling g_ij = exp(-ik d)/(4 pi d) + R exp(-ik d')/(4 pi d') (free-field monopoles + wall images; Pierce, Acoustics 4.3/5.1).

    ``points`` (..., n, 3), ``radii`` (n,) or (..., n).  ``wavenumber`` None gives the static
    (incompressible, k -> 0) real matrix (..., n, n); an array (F,) or (..., F) gives the complex
    (..., F, n, n).  Same-capsule direct terms
    stay incompressible (module doc); the diagonal direct term (self) is zero: each interface's own
    mass is in its capsule's modes.
    """
    points = np.asarray(points, float)
    radii = np.asarray(radii, float)
    body = np.asarray(body)
    n = radii.shape[-1]
    d = _distances(points, radii, False)
    other = body[:, None] != body[None, :]
    direct_mask = ~np.eye(n, dtype=bool)
    di = _distances(points, radii, True) if wall_reflection else None
    if wavenumber is None:
        g = np.where(direct_mask, 1 / (4 * np.pi * d), 0.0)
        if di is not None:
            g = g + wall_reflection / (4 * np.pi * di)
        return g
    k = np.atleast_1d(np.asarray(wavenumber, float))[..., None, None]
    d = d[..., None, :, :]
    phase = np.where(other, np.exp(-1j * k * d), 1.0 + 0j)
    g = np.where(direct_mask, phase / (4 * np.pi * d), 0.0)
    if di is not None:
        di = di[..., None, :, :]
        g = g + wall_reflection * np.exp(-1j * k * di) / (4 * np.pi * di)
    return g


_PATHS: dict = {}


def _einsum(subscripts: str, *operands) -> np.ndarray:
    """``np.einsum(..., optimize=True)`` with the contraction order found once per shape (the search costs more than small contractions)."""
    key = (subscripts,) + tuple(o.shape for o in operands)
    path = _PATHS.get(key)
    if path is None:
        path = _PATHS[key] = np.einsum_path(subscripts, *operands, optimize=True)[0]
        if len(_PATHS) > 256:
            _PATHS.pop(next(iter(_PATHS)))
    return np.einsum(subscripts, *operands, optimize=path)


def uncoupled_response(phi, omega, damping, w, body=None) -> np.ndarray:
    """Inward volume response per pascal H0 (..., F, P, P) = Phi diag(1/(w_m^2 - w^2 + i w w_m/Q_m)) Phi^T over any leading batch axes (Meirovitch ch. 7).

    ``phi`` (..., P, M) outward volume of P interfaces per modal coordinate, ``omega``/``damping`` (..., M),
    drive ``w`` (F,) or (..., F) rad/s.  ``body`` (P,) capsule of each interface: entries between capsules
    are zeroed (each interface's own capsule's modes only).
    """
    w = np.asarray(w, float)
    den = modal_dynamic_stiffness(omega[..., None, :], damping[..., None, :], w[..., None])
    h = _einsum("...im,...fm,...jm->...fij", phi, 1.0 / den, phi)
    if body is not None:
        body = np.asarray(body)
        h = h * (body[:, None] == body[None, :])
    return h


def uncoupled_blocks(system: BubbleSystem, omega) -> np.ndarray:
    """Per-capsule H0 (F, C, P, P) of a system at drives ``omega`` (F,) rad/s (:func:`uncoupled_response`, the capsule as batch axis)."""
    w = np.atleast_1d(np.asarray(omega, float))
    return np.moveaxis(uncoupled_response(system.phi, system.omega, system.damping, w), -3, 0)


#: Complex entries (F x B x N x N) of one chunk of :func:`coupled_response` (16 MB): a design of
#: hundreds of interfaces solves a few frequencies at a time instead of holding 64 dense systems.
CHUNK_ELEMENTS = 2**20


def coupled_response(system: BubbleSystem, frequency, density: float, sound_speed: float,
                     wall_reflection: float = 0.0, points=None, h0=None, chunk: int = 64) -> np.ndarray:
    """Inward volume displacement U (m^3 per Pa incident) of every interface, solving (I - w^2 rho H0 g) U = H0 1 (module doc; Kinsler et al. mutual radiation impedance).

    ``frequency`` (F,) Hz -> complex (F, n) in the order of ``system.points``; uniform incident
    pressure (the design is small against the wavelength).  ``points`` (B, n, 3) evaluates B
    displaced configurations at once -> (B, F, n); ``h0`` reuses :func:`uncoupled_blocks` at these
    frequencies.  Vectorised over frequencies in chunks of ``chunk`` (fewer when
    a chunk would exceed :data:`CHUNK_ELEMENTS`).
    """
    f = np.atleast_1d(np.asarray(frequency, float))
    n = system.n
    batch = points is not None
    pts = np.asarray(points if batch else system.points, float).reshape(-1, n, 3)
    nb = pts.shape[0]
    out = np.zeros((nb, f.size, n), complex)
    if n == 0 or f.size == 0:
        return out if batch else out[0]
    ncap, p, _ = system.phi.shape
    npad = ncap * p
    # padded layout (C*P slots); empty slots have no interface (zero H0 row -> zero response)
    if npad == n:
        pad_pts = pts[:, np.argsort(system.slot)] if np.any(np.diff(system.slot) < 0) else pts
        pad_rad = np.empty(npad)
        pad_rad[system.slot] = system.radii
    else:
        pad_pts = np.zeros((nb, npad, 3))
        pad_pts[:, :] = 1.0 + np.arange(npad)[None, :, None]          # far apart, unused
        pad_pts[:, system.slot] = pts
        pad_rad = np.full(npad, 1e-9)
        pad_rad[system.slot] = system.radii
    pad_body = np.repeat(np.arange(ncap), p)
    eye = np.eye(npad)
    chunk = max(1, min(chunk, CHUNK_ELEMENTS // (nb * npad * npad)))   # bounded memory for large designs
    # green_matrix's frequency-independent parts, once: 1/(4 pi d) off the diagonal, the retarded distance
    # (between capsules only), the wall images' R/(4 pi d')
    d = _distances(pad_pts, pad_rad, False)[:, None]                                # (B, 1, N, N)
    other = (pad_body[:, None] != pad_body[None, :])
    inv = np.where(~np.eye(npad, dtype=bool), 1 / (4 * np.pi * d), 0.0)
    retarded = np.where(other, d, 0.0)
    if wall_reflection:
        di = _distances(pad_pts, pad_rad, True)[:, None]
        inv_image = wall_reflection / (4 * np.pi * di)
    for s in range(0, f.size, chunk):
        w = 2 * np.pi * f[s:s + chunk]
        blk = uncoupled_blocks(system, w) if h0 is None else h0[s:s + chunk]      # (F, C, P, P)
        k = (w / sound_speed)[None, :, None, None]
        g = np.empty((nb, w.size, npad, npad), complex)                           # green_matrix, exp(-ikd) as cos, sin
        kd = k * retarded
        np.multiply(np.cos(kd), inv, out=g.real)
        np.multiply(np.sin(kd), -inv, out=g.imag)
        if wall_reflection:
            kd = k * di
            g.real += np.cos(kd) * inv_image
            g.imag -= np.sin(kd) * inv_image
        del kd
        coef = (w**2 * density)[None, :, None, None]
        if p == 1:
            g *= -coef * blk[None, :, :, 0, 0, None]
            a = g
        else:
            a = -coef * _einsum("fcpq,bfcqn->bfcpn", blk, g.reshape(nb, w.size, ncap, p, npad)).reshape(g.shape)
        a += eye                                                                   # I - w^2 rho H0 g
        rhs = np.broadcast_to(blk.sum(axis=-1).reshape(1, w.size, npad), (nb, w.size, npad))
        u = np.linalg.solve(a, rhs[..., None])[..., 0]
        out[:, s:s + chunk] = u[..., system.slot]
    return out if batch else out[0]


@dataclass(frozen=True)
class CoupledModes:
    """Undamped modes of the coupled system: ``omega`` (K,) rad/s ascending, ``volume`` (n, K)
    outward volume of each interface per mass-normalized coordinate, ``quality`` (K,);
    ``also_quality`` the Q of the same modes for each of :func:`coupled_modes`' ``also_damping``."""

    omega: np.ndarray
    volume: np.ndarray
    quality: np.ndarray
    also_quality: tuple = ()

    @property
    def frequency(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def share(self) -> np.ndarray:
        """(n, K): |dV_o| / sum |dV| of each interface in each mode."""
        a = np.abs(self.volume)
        s = a.sum(axis=0, keepdims=True)
        return np.divide(a, s, out=np.zeros_like(a), where=s > 0)


def _compact(system: BubbleSystem, damping=None):
    """Dense Phi (n, m) over the real modes, their omega and damping (``damping`` (C, Mx) instead of the system's)."""
    ncap, p, mx = system.phi.shape
    keep = np.abs(system.phi).sum(axis=1) > 0                     # (C, Mx) real modes
    cols = np.flatnonzero(keep.reshape(-1))
    big = np.zeros((system.n, ncap * mx))
    for i, (c, sl) in enumerate(zip(system.body, system.slot)):
        big[i, c * mx:(c + 1) * mx] = system.phi[c, sl - c * p]
    dmp = system.damping if damping is None else np.asarray(damping, float)
    return big[:, cols], system.omega.reshape(-1)[cols], dmp.reshape(-1)[cols]


def _diagonal_eigh(omega, mass):
    """Eigenpairs of diag(omega^2) q = w^2 M q by Cholesky reduction (Golub & Van Loan, Matrix Computations, 4th ed., 8.7.2): ascending w, q^T M q = I.

    :func:`resonance.symmetric_eigh` with the product by the diagonal stiffness done elementwise
    (the same numbers; one n^3 matrix product fewer).
    """
    li = np.linalg.inv(np.linalg.cholesky((mass + mass.T) / 2))
    a = (li * omega**2) @ li.T
    w2, y = np.linalg.eigh((a + a.T) / 2)
    return np.sqrt(np.maximum(w2, 0.0)), li.T @ y


def _mutual_resistance(system: BubbleSystem, vol, k, wall_reflection: float, chunk: int = 16) -> np.ndarray:
    """v_n^T S(k_n) v_n for each mode n, S_ij = sin(k d_ij)/(k d_ij) between capsules + R sin(k d'_ij)/(k d'_ij) to the images (Kinsler et al. ch. 7/8, mutual radiation resistance).

    Over the pairs i < j (S is symmetric) and the images' diagonal, for ``chunk`` modes at a time.
    """
    n = system.n
    if k.size == 0 or n == 0:
        return np.zeros(k.size)
    iu, ju = np.triu_indices(n, 1)
    d = _distances(system.points, system.radii, False)[iu, ju]
    other = system.body[iu] != system.body[ju]
    i, j, dist, weight = [iu[other]], [ju[other]], [d[other]], [np.full(int(other.sum()), 2.0)]
    if wall_reflection:
        di = _distances(system.points, system.radii, True)
        diag = np.arange(n)
        i += [iu, diag]
        j += [ju, diag]
        dist += [di[iu, ju], di[diag, diag]]
        weight += [np.full(iu.size, 2.0 * wall_reflection), np.full(n, float(wall_reflection))]
    i, j, dist, weight = (np.concatenate(a) for a in (i, j, dist, weight))
    out = np.empty(k.size)
    vt = np.ascontiguousarray(vol.T)                                               # (K, n)
    for s in range(0, k.size, chunk):
        x = k[s:s + chunk, None] * dist[None, :]                                   # (chunk, pairs)
        if np.all(x > 0):
            sinc, scale = np.sin(x, out=x) / dist, 1.0 / k[s:s + chunk]              # sin(kd)/d, then / k
        else:
            sinc, scale = np.sinc(x / np.pi), 1.0
        sinc *= vt[s:s + chunk, i]
        sinc *= vt[s:s + chunk, j]
        out[s:s + chunk] = (sinc @ weight) * scale
    return out


def coupled_modes(system: BubbleSystem, density: float, sound_speed: float,
                  wall_reflection: float = 0.0, max_omega: float | None = None,
                  also_damping: Sequence = ()) -> CoupledModes:
    """Undamped modes Omega^2 q = w^2 (I + rho Phi^T g0 Phi) q and their Q (mutual radiation mass and resistance; Kinsler et al. ch. 7/8).

    Q_n = w_n / (q_n^T D q_n), q_n mass-normalized, D = diag(w_m/Q_m) of the capsules (viscous,
    thermal, own radiation) + Phi^T (rho w_n^2/(4 pi c)) S Phi with S_ij = sin(k d_ij)/(k d_ij)
    between capsules and R sin(k d'_ij)/(k d'_ij) for the wall images (mutual radiation resistance).
    ``max_omega`` keeps only the modes up to it (the others' Q, n^2 terms each, is not computed).
    ``also_damping``: other (C, Mx) modal dampings of the same system (e.g. without a declared Q);
    their Q come in ``also_quality`` from the same eigensolution and radiation terms.
    """
    phi, om, dmp = _compact(system)
    if om.size == 0:
        z = np.zeros(0)
        return CoupledModes(omega=z, volume=np.zeros((system.n, 0)), quality=z,
                            also_quality=tuple(z for _ in also_damping))
    g0 = green_matrix(system.points, system.radii, system.body, None, wall_reflection)
    mass = np.eye(om.size) + density * phi.T @ g0 @ phi
    omega, q = _diagonal_eigh(om, mass)
    if max_omega is not None:
        kept = int(np.count_nonzero(omega <= max_omega))       # ascending
        omega, q = omega[:kept], q[:, :kept]
    vol = phi @ q
    radiated = radiation_resistance(omega, density, sound_speed) * _mutual_resistance(system, vol, omega / sound_speed,
                                                                                     wall_reflection)
    qualities = []
    for damping in (dmp, *(_compact(system, a)[2] for a in also_damping)):
        c_n = (damping[:, None] * q**2).sum(axis=0) + radiated
        with np.errstate(divide="ignore"):
            qualities.append(np.where(c_n > 0, omega / np.where(c_n > 0, c_n, 1.0), np.inf))
    for arr in (omega, vol, *qualities):
        arr.setflags(write=False)
    return CoupledModes(omega=omega, volume=vol, quality=qualities[0], also_quality=tuple(qualities[1:]))


def prepared_response(system: BubbleSystem, frequency, density: float, sound_speed: float,
                      wall_reflection: float = 0.0, h0=None):
    """:func:`coupled_response` at fixed frequencies for many sets of interface positions: returns ``response(points (B, n, 3)) -> (B, F, n)``.

    The same equations (module doc; Kinsler et al. mutual radiation impedance, Pierce 4.3/5.1 wall
    images); everything that does not depend on the positions (uncoupled blocks, wavenumbers,
    distance floors, masks) is computed once, for solvers that evaluate one design many times.
    """
    f = np.atleast_1d(np.asarray(frequency, float))
    n = system.n
    ncap, p, _ = system.phi.shape
    npad = ncap * p
    w = 2 * np.pi * f
    blk = uncoupled_blocks(system, w) if h0 is None else np.asarray(h0)           # (F, C, P, P)
    pad_rad = np.full(npad, 1e-9)
    pad_rad[system.slot] = system.radii
    pad_body = np.repeat(np.arange(ncap), p)
    floor = pad_rad[:, None] + pad_rad[None, :]
    other = pad_body[:, None] != pad_body[None, :]
    direct = ~np.eye(npad, dtype=bool)
    k = (w / sound_speed)[:, None, None]                                           # (F, 1, 1)
    k_direct = k * other                                                           # retarded between capsules only
    coef = (w**2 * density)[None, :, None, None]
    eye = np.eye(npad)
    rhs = blk.sum(axis=-1).reshape(1, f.size, npad, 1)
    diag = blk[:, :, 0, 0][None, :, :, None] if p == 1 else None                   # (1, F, C, 1)
    identity_order = npad == n and not np.any(np.diff(system.slot) < 0)
    order = np.argsort(system.slot) if npad == n else None
    filler = 1.0 + np.arange(npad)[None, :, None]                                  # unused slots: far apart
    four_pi = 4 * np.pi

    def response(points) -> np.ndarray:
        pts = np.asarray(points, float).reshape(-1, n, 3)
        nb = pts.shape[0]
        if n == 0 or f.size == 0:
            return np.zeros((nb, f.size, n), complex)
        if identity_order:
            pad = pts
        elif npad == n:
            pad = pts[:, order]
        else:
            pad = np.broadcast_to(filler, (nb, npad, 3)).copy()
            pad[:, system.slot] = pts
        diff = pad[:, :, None, :] - pad[:, None, :, :]                             # (B, N, N, 3)
        dxy2 = diff[..., 0] ** 2 + diff[..., 1] ** 2
        d = contact_distance(np.sqrt(dxy2 + diff[..., 2] ** 2), floor)[:, None]    # (B, 1, N, N)
        g = np.exp(-1j * k_direct * d) / (four_pi * d) * direct
        if wall_reflection:
            zs = pad[:, :, None, 2] + pad[:, None, :, 2]
            di = contact_distance(np.sqrt(dxy2 + zs**2), floor)[:, None]
            g = g + wall_reflection * np.exp(-1j * k * di) / (four_pi * di)
        if p == 1:
            hg = diag * g
        else:
            hg = _einsum("fcpq,bfcqn->bfcpn", blk, g.reshape(nb, f.size, ncap, p, npad)).reshape(nb, f.size, npad, npad)
        a = eye - coef * hg
        if npad == 2:              # two interfaces: Cramer's rule (a batched LAPACK call costs more)
            r0, r1 = rhs[..., 0, 0], rhs[..., 1, 0]
            det = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
            u = np.stack([(a[..., 1, 1] * r0 - a[..., 0, 1] * r1) / det,
                          (a[..., 0, 0] * r1 - a[..., 1, 0] * r0) / det], axis=-1)
        else:
            u = np.linalg.solve(a, np.broadcast_to(rhs, (nb, f.size, npad, 1)))[..., 0]
        return u[..., system.slot]

    return response
