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


#: Complex entries (F x B x N x N) of one chunk of :func:`coupled_volumes` (16 MB): a design of
#: hundreds of interfaces solves a few frequencies at a time instead of holding 64 dense systems.
CHUNK_ELEMENTS = 2**20


#: :func:`coupled_volumes` evaluates the Green function once per distinct pair geometry (d, d', same capsule or not)
#: when these are at most this share of the pairs (an array of identical capsules on a pitch: 5,647 distinct of
#: 77,421 pairs in benchmarks/check.py's 5,000-line design), and gathers the matrix from them; else pair by pair.
DISTINCT_PAIRS = 0.5
#: ... and when it evaluates the Green function at this many frequencies at least (:func:`mutual_resistance`: half as
#: many modes): finding the distinct pairs costs about as much as 15 frequencies pair by pair (45-75 ms for 77,421
#: pairs), which a solver evaluating one configuration at a few tones would pay on every call.
TABLE_MIN_EVALUATIONS = 16


def _batched(x, batch: tuple, tail: int) -> np.ndarray:
    """``x`` (..., *tail dims) as (1, ...) when it has no batch, else broadcast to ``batch`` and flattened to (B, ...)."""
    x = np.asarray(x)
    if x.ndim == tail:                                   # no batch axes: a view, as reshape((1,) + shape) gives
        return x[None]
    core = x.shape[x.ndim - tail:] if tail else ()
    if int(np.prod(x.shape[:x.ndim - tail], dtype=int)) == 1:
        return x.reshape((1,) + core)
    return np.broadcast_to(x, batch + core).reshape((-1,) + core)


@dataclass(frozen=True)
class _PadLayout:
    """The index arrays of :func:`coupled_volumes`' padded layout (C*P slots), which depend on the layout only:
    the upper triangle's pairs (i <= j) and their flat places, which pairs join different capsules."""

    npad: int
    iu: np.ndarray           # (m,) first slot of each pair of the upper triangle (diagonal included)
    ju: np.ndarray           # (m,) second slot
    upper: np.ndarray        # (m,) flat index i * N + j
    lower: np.ndarray        # (m,) flat index j * N + i
    offdiag: np.ndarray      # (m,) bool: i != j
    other: np.ndarray        # (m,) bool: different capsules
    other_at: np.ndarray     # (k,) indices of the True entries of ``other``
    filled: bool             # every slot holds an interface, in order (slot == arange(N)): no padding


_LAYOUTS: dict = {}


def _pad_layout(ncap: int, p: int, slot: np.ndarray) -> _PadLayout:
    """:class:`_PadLayout` of ``ncap`` capsules of ``p`` slots with interfaces at ``slot``, built once per layout (read-only)."""
    key = (ncap, p, slot.tobytes())
    lay = _LAYOUTS.get(key)
    if lay is None:
        npad = ncap * p
        body = np.repeat(np.arange(ncap), p)
        iu, ju = np.triu_indices(npad)
        other = body[iu] != body[ju]
        lay = _PadLayout(npad, iu, ju, iu * npad + ju, ju * npad + iu, iu != ju, other, np.flatnonzero(other),
                         bool(slot.size == npad and np.array_equal(slot, np.arange(npad))))
        for a in (lay.iu, lay.ju, lay.upper, lay.lower, lay.offdiag, lay.other, lay.other_at):
            a.setflags(write=False)
        if len(_LAYOUTS) >= 64:
            _LAYOUTS.pop(next(iter(_LAYOUTS)))
        _LAYOUTS[key] = lay
    return lay


def _pair_distances(points, radii, iu, ju, mirror: bool) -> np.ndarray:
    """:func:`_distances` of the pairs (iu, ju) only: |p_i - p_j| (..., m), and with ``mirror`` also to p_j's image in z = 0, stacked (2, ..., m); smoothly floored at R_i + R_j (:func:`contact_distance`).

    The same numbers as :func:`_distances` (its norm sums the squares x, y, z in that order)."""
    xyz = np.moveaxis(points, -1, 0)                       # (3, ..., n)
    a, b = xyz[..., iu], xyz[..., ju]
    sq = a - b
    sq *= sq
    plane = sq[0] + sq[1]
    d = np.sqrt(plane + sq[2])
    floor = radii[..., iu] + radii[..., ju]
    if mirror:                                             # p_i - (x_j, y_j, -z_j)
        z = a[2] + b[2]
        d = np.stack([d, np.sqrt(plane + z * z)])
    return contact_distance(d, floor)


def _green_terms(k, terms, wall_reflection: float, other_at=None) -> np.ndarray:
    """green_matrix's exp(-ikd)/(4 pi d) + R exp(-ikd')/(4 pi d') (Pierce, Acoustics 4.3/5.1) from its frequency-independent parts: ``k`` (B, F, 1), ``terms`` [retarded d, 1/(4 pi d), d', R/(4 pi d')] (each (B, 1, m)) -> (B, F, m).

    ``other_at``: the columns whose retarded distance may be non-zero (pairs of different capsules); elsewhere it is
    0, whose phase is exactly 1 (cos 0 = 1, and -sin 0 times the positive 1/(4 pi d) is -0.0): no cosine or sine.
    """
    shape = np.broadcast_shapes(k.shape, terms[1].shape)
    out = np.empty(shape, complex)
    if other_at is None or other_at.size == terms[1].shape[-1]:
        kd = k * terms[0]
        np.multiply(np.cos(kd), terms[1], out=out.real)
        np.multiply(np.sin(kd), -terms[1], out=out.imag)
    else:
        out.real[...] = terms[1]
        out.imag[...] = -0.0
        if other_at.size:
            kd = k * terms[0][..., other_at]
            inv = terms[1][..., other_at]
            out.real[..., other_at] = np.cos(kd) * inv
            out.imag[..., other_at] = np.sin(kd) * -inv
    if wall_reflection:
        kd = k * terms[2]
        out.real += np.cos(kd) * terms[3]
        out.imag -= np.sin(kd) * terms[3]
    return out


def coupled_volumes(blocks, slot, points, radii, frequency, density, sound_speed, wall_reflection: float = 0.0,
                    chunk: int = 64) -> np.ndarray:
    """Inward volume U (..., F, n) per pascal incident solving (I - w^2 rho H0 g) U = H0 1 over leading batch axes (module doc; Kinsler et al. mutual radiation impedance, Pierce 4.3/5.1 wall images).

    ``blocks`` (..., F, C, P, P) each capsule's uncoupled inward response per pascal (:func:`uncoupled_response`),
    ``slot`` (n,) each interface's index in the flattened C*P layout, ``points`` (..., n, 3), ``radii`` (n,) or
    (..., n), ``frequency`` (F,) or (..., F) Hz, ``density`` / ``sound_speed`` scalars or (...).  The batch axes
    (design points, displaced configurations) broadcast.  Uniform incident pressure (the design is small against
    the wavelength).  Frequencies are solved ``chunk`` at a time (fewer when a chunk would exceed
    :data:`CHUNK_ELEMENTS`).
    """
    blocks = np.asarray(blocks)
    slot = np.asarray(slot, int)
    points, radii, f = (np.asarray(a, float) for a in (points, radii, frequency))
    f = np.atleast_1d(f)
    n, nf = slot.size, f.shape[-1]
    ncap, p = blocks.shape[-3], blocks.shape[-1]
    batch = np.broadcast_shapes(blocks.shape[:-4], points.shape[:-2], radii.shape[:-1], f.shape[:-1],
                                np.shape(density), np.shape(sound_speed))
    nb = int(np.prod(batch, dtype=int))
    if n == 0 or nf == 0:
        return np.zeros(batch + (nf, n), complex)
    lay = _pad_layout(ncap, p, slot)
    npad = lay.npad
    out = np.empty((nb, nf, n), complex)
    blk = _batched(blocks, batch, 4)                                                # (Bh, F, C, P, P)
    pts, rad, f = _batched(points, batch, 2), _batched(radii, batch, 1), _batched(f, batch, 1)
    rho, c = _batched(density, batch, 0), _batched(sound_speed, batch, 0)
    if lay.filled:
        pad_pts, pad_rad = pts, rad
    else:   # the padded layout; an empty slot has no interface (zero H0 row -> zero response), far from the others
        pad_pts = np.broadcast_to(1.0 + np.arange(npad)[None, :, None], (pts.shape[0], npad, 3)).copy()
        pad_pts[:, slot] = pts
        pad_rad = np.full((rad.shape[0], npad), 1e-9)
        pad_rad[:, slot] = rad
    chunk = max(1, min(chunk, CHUNK_ELEMENTS // (nb * npad * npad)))   # bounded memory for large designs
    # green_matrix's frequency-independent parts on the upper triangle (g is symmetric: d_ij = d_ji and d'_ij = d'_ji
    # exactly), once: 1/(4 pi d) off the diagonal, the retarded distance (between capsules only), the wall images'
    # R/(4 pi d')
    iu, ju, upper, lower = lay.iu, lay.ju, lay.upper, lay.lower
    dd = _pair_distances(pad_pts, pad_rad, iu, ju, bool(wall_reflection))           # (Bd, m) or (2, Bd, m)
    d = (dd[0] if wall_reflection else dd)[:, None]                                 # (Bd, 1, m)
    tri = [np.where(lay.other, d, 0.0), np.where(lay.offdiag, 1 / (4 * np.pi * d), 0.0)]
    if wall_reflection:
        di = dd[1][:, None]
        tri += [di, wall_reflection / (4 * np.pi * di)]
    # one configuration (Bd = 1): the pairs share few distinct (d, d') in an array of capsules; the Green function of
    # each distinct pair once, then gathered into the full matrix (the same operations on the same numbers as
    # computing every pair: bit for bit the same g)
    table = None
    if tri[0].shape[0] == 1 and upper.size > 64 and nf >= TABLE_MIN_EVALUATIONS:
        cols, index = np.unique(np.stack([t[0, 0] for t in tri]), axis=1, return_inverse=True)
        if cols.shape[1] <= DISTINCT_PAIRS * upper.size:
            table = [np.ascontiguousarray(x)[None, None] for x in cols]
            full = np.empty(npad * npad, np.intp)
            full[upper] = index.reshape(-1)
            full[lower] = index.reshape(-1)
    for s in range(0, nf, chunk):
        w = 2 * np.pi * f[:, s:s + chunk]                                           # (Bf, Fc)
        h = blk[:, s:s + chunk]
        fc = h.shape[1]
        k = (w / c[:, None])[..., None]
        g = np.empty((nb, fc, npad * npad), complex)
        if table is not None:
            t = _green_terms(k, table, wall_reflection)
            if t.shape[0] == nb:
                np.take(t, full, axis=-1, out=g)
            else:
                g[...] = np.take(t, full, axis=-1)
        else:
            gu = _green_terms(k, tri, wall_reflection, lay.other_at)
            g[..., upper] = gu
            g[..., lower] = gu
            del gu
        g = g.reshape(nb, fc, npad, npad)
        coef = (w**2 * rho[:, None])[..., None, None]
        if p == 1:
            g *= -coef * h[:, :, :, 0, 0, None]
            a = g
        else:           # each capsule's block row of H0 g (a batched matrix product; h broadcasts over the batch)
            a = -coef * np.matmul(h, g.reshape(nb, fc, ncap, p, npad)).reshape(g.shape)
        a.reshape(nb * fc, npad * npad)[:, ::npad + 1] += 1.0                       # I - w^2 rho H0 g (contiguous)
        rhs = np.broadcast_to(h.sum(axis=-1).reshape(h.shape[0], fc, npad), (nb, fc, npad))
        if npad == 2:              # two interfaces: Cramer's rule (a batched LAPACK call costs more)
            det = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
            u = np.stack([(a[..., 1, 1] * rhs[..., 0] - a[..., 0, 1] * rhs[..., 1]) / det,
                          (a[..., 0, 0] * rhs[..., 1] - a[..., 1, 0] * rhs[..., 0]) / det], axis=-1)
        else:
            u = np.linalg.solve(a, rhs[..., None])[..., 0]
        out[:, s:s + fc] = u if lay.filled else u[..., slot]
    return out.reshape(batch + (nf, n))


def coupled_response(system: BubbleSystem, frequency, density: float, sound_speed: float,
                     wall_reflection: float = 0.0, points=None, h0=None, chunk: int = 64) -> np.ndarray:
    """Inward volume displacement U (m^3 per Pa incident) of every interface of a system: :func:`coupled_volumes` (Kinsler et al. mutual radiation impedance) with its own blocks.

    ``frequency`` (F,) Hz -> complex (F, n) in the order of ``system.points``.  ``points`` (B, n, 3)
    evaluates B displaced configurations at once -> (B, F, n); ``h0`` reuses :func:`uncoupled_blocks` at these
    frequencies.
    """
    f = np.atleast_1d(np.asarray(frequency, float))
    n = system.n
    batch = points is not None
    pts = np.asarray(points, float).reshape(-1, n, 3) if batch else system.points
    if n == 0 or f.size == 0:
        out = np.zeros((pts.shape[0] if batch else 1, f.size, n), complex)
        return out if batch else out[0]
    blocks = uncoupled_blocks(system, 2 * np.pi * f) if h0 is None else np.asarray(h0)
    return coupled_volumes(blocks, system.slot, pts, system.radii, f, density, sound_speed, wall_reflection, chunk)


def volume_shares(volume) -> np.ndarray:
    """(n, K): |dV_o| / sum |dV| of each interface in each mode (columns of ``volume``)."""
    a = np.abs(volume)
    s = a.sum(axis=0, keepdims=True)
    return np.divide(a, s, out=np.zeros_like(a), where=s > 0)


class _ModeViews:
    """Frequencies (Hz) and interface shares of modes given by ``omega`` (K,) rad/s and ``volume`` (n, K)."""

    @property
    def frequency(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def share(self) -> np.ndarray:
        """(n, K): |dV_o| / sum |dV| of each interface in each mode."""
        return volume_shares(self.volume)


@dataclass(frozen=True)
class CoupledModes(_ModeViews):
    """Undamped modes of the coupled system: ``omega`` (K,) rad/s ascending, ``volume`` (n, K)
    outward volume of each interface per mass-normalized coordinate, ``quality`` (K,);
    ``also_quality`` the Q of the same modes for each of :func:`coupled_modes`' ``also_damping``."""

    omega: np.ndarray
    volume: np.ndarray
    quality: np.ndarray
    also_quality: tuple = ()


@dataclass(frozen=True)
class ModeShapes(_ModeViews):
    """The undamped coupled modes of a system without their Q (:func:`mode_shapes`): ``omega`` (K,) rad/s
    ascending, ``coordinates`` (M, K) over the system's real bare modes, mass-normalized, ``volume`` (n, K)."""

    omega: np.ndarray
    coordinates: np.ndarray
    volume: np.ndarray


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
    """Eigenpairs of diag(omega^2) q = w^2 M q by Cholesky reduction over leading batch axes (Golub & Van Loan, Matrix Computations, 4th ed., 8.7.2): ascending w, q^T M q = I.

    :func:`resonance.symmetric_eigh` with the product by the diagonal stiffness done elementwise
    (the same numbers; one n^3 matrix product fewer).
    """
    li = np.linalg.inv(np.linalg.cholesky((mass + np.swapaxes(mass, -1, -2)) / 2))
    lt = np.swapaxes(li, -1, -2)
    a = (li * omega[..., None, :] ** 2) @ lt
    w2, y = np.linalg.eigh((a + np.swapaxes(a, -1, -2)) / 2)
    return np.sqrt(np.maximum(w2, 0.0)), lt @ y


#: Entries (B x modes x pairs) of one chunk of :func:`mutual_resistance`'s pair sums (16 MB of float64).
PAIR_CHUNK_ELEMENTS = 2**21


def mutual_resistance(volume, points, radii, body, wavenumber, wall_reflection: float = 0.0) -> np.ndarray:
    """v_n^T S(k_n) v_n (..., K) of each mode n over leading batch axes, S_ij = sin(k d_ij)/(k d_ij) between capsules + R sin(k d'_ij)/(k d'_ij) to the wall images (Kinsler et al. ch. 7/8, mutual radiation resistance).

    ``volume`` (..., n, K) outward volume of each interface per modal coordinate, ``points`` (..., n, 3), ``radii``
    (n,) or (..., n), ``body`` (n,), ``wavenumber`` (..., K).  Summed over the pairs i < j (S is symmetric) and the
    images' diagonal, a few modes at a time (:data:`PAIR_CHUNK_ELEMENTS`).
    """
    volume, points, radii, k = (np.asarray(a, float) for a in (volume, points, radii, wavenumber))
    body = np.asarray(body)
    n, nk = volume.shape[-2], volume.shape[-1]
    batch = np.broadcast_shapes(volume.shape[:-2], points.shape[:-2], radii.shape[:-1], k.shape[:-1])
    nb = int(np.prod(batch, dtype=int))
    if nk == 0 or n == 0:
        return np.zeros(batch + (nk,))
    iu, ju = np.triu_indices(n, 1)
    d = _distances(points, radii, False)[..., iu, ju]
    other = body[iu] != body[ju]
    i, j, dist, weight = [iu[other]], [ju[other]], [d[..., other]], [np.full(int(other.sum()), 2.0)]
    if wall_reflection:
        di = _distances(points, radii, True)
        diag = np.arange(n)
        i += [iu, diag]
        j += [ju, diag]
        dist += [di[..., iu, ju], di[..., diag, diag]]
        weight += [np.full(iu.size, 2.0 * wall_reflection), np.full(n, float(wall_reflection))]
    i, j, weight = (np.concatenate(a) for a in (i, j, weight))
    dist = np.concatenate(dist, axis=-1)
    # one configuration: sin(kd)/d once per distinct distance (an array of capsules repeats them; DISTINCT_PAIRS),
    # gathered to the pairs: the same operations on the same numbers as pair by pair
    uniq = index = None
    if dist.size == dist.shape[-1] and dist.size > 64 and nk >= TABLE_MIN_EVALUATIONS // 2:
        uniq, index = np.unique(dist.reshape(-1), return_inverse=True)
        if uniq.size > DISTINCT_PAIRS * dist.size:
            uniq = index = None
    dist = np.broadcast_to(dist, batch + dist.shape[-1:]).reshape(nb, 1, -1)        # (B, 1, pairs)
    vt = np.ascontiguousarray(np.swapaxes(np.broadcast_to(volume, batch + (n, nk)), -1, -2)).reshape(nb, nk, n)
    k = np.broadcast_to(k, batch + (nk,)).reshape(nb, nk)
    out = np.empty((nb, nk))
    chunk = max(1, PAIR_CHUNK_ELEMENTS // (nb * max(i.size, 1)))
    for s in range(0, nk, chunk):
        ks = k[:, s:s + chunk]
        d = dist if uniq is None else uniq[None, None]
        x = ks[..., None] * d                                                      # (B, chunk, pairs or distinct)
        if np.all(x > 0):
            sinc, scale = np.sin(x, out=x) / d, 1.0 / ks                           # sin(kd)/d, then / k
        else:
            sinc, scale = np.sinc(x / np.pi), 1.0
        if uniq is not None:
            sinc = np.take(sinc, index.reshape(-1), axis=-1)
        sinc *= np.take(vt[:, s:s + chunk], i, axis=-1)                            # (a gather: faster than [..., i])
        sinc *= np.take(vt[:, s:s + chunk], j, axis=-1)
        out[:, s:s + chunk] = (sinc @ weight) * scale
    return out.reshape(batch + (nk,))


#: Bare modes from which the coupled modes are found from the scaled standard problem (:func:`_scaled_eigh`: a design of
#: hundreds of capsules, 1,179 bare modes, 2.0x faster than :func:`_diagonal_eigh`, whose Cholesky reduction costs as
#: much as the eigensolution); smaller systems (every example) keep :func:`_diagonal_eigh`, bit for bit.
SCALED_EIGH_MIN_MODES = 256


def _scaled_eigh(omega, mass):
    """Eigenpairs of diag(omega^2) q = w^2 M q over leading batch axes, ascending w, q^T M q = I, from the standard problem (D^-1/2 M D^-1/2) z = w^-2 z, D = diag(omega^2), q = w D^-1/2 z (Golub & Van Loan, Matrix Computations, 4th ed., 8.7.2)."""
    s = 1.0 / omega
    b = mass * s[..., :, None] * s[..., None, :]
    mu, z = np.linalg.eigh((b + np.swapaxes(b, -1, -2)) / 2)
    mu, z = mu[..., ::-1], z[..., ::-1]                  # the largest w^-2 first: ascending w
    w = 1.0 / np.sqrt(np.maximum(mu, np.finfo(float).tiny))
    return w, s[..., :, None] * z * w[..., None, :]


def coupled_mode_shapes(phi, omega, points, radii, body, density, wall_reflection: float = 0.0,
                        max_omega: float | None = None) -> tuple:
    """Undamped modes Omega^2 q = w^2 (I + rho Phi^T g0 Phi) q over leading batch axes (mutual radiation mass; Kinsler et al. ch. 7/8).

    ``phi`` (..., n, M) outward volume of each interface per bare modal coordinate, ``omega`` (..., M),
    ``points`` (..., n, 3), ``radii`` (n,) or (..., n), ``body`` (n,), ``density`` scalar or (...).
    ``max_omega`` keeps the modes up to it (the most any batch row keeps).  Returns (omega (..., K) ascending,
    coordinates q (..., M, K) mass-normalized, volume (..., n, K)); :func:`mode_quality` gives their Q.
    """
    phi, omega, density = (np.asarray(a, float) for a in (phi, omega, density))
    g0 = green_matrix(points, radii, body, None, wall_reflection)
    mass = np.eye(omega.shape[-1]) + density[..., None, None] * (np.swapaxes(phi, -1, -2) @ g0 @ phi)
    om, q = (_scaled_eigh if omega.shape[-1] >= SCALED_EIGH_MIN_MODES else _diagonal_eigh)(omega, mass)
    if max_omega is not None:
        kept = int(np.max(np.count_nonzero(om <= max_omega, axis=-1), initial=0))       # ascending
        om, q = om[..., :kept], q[..., :kept]
    return om, q, phi @ q


def mode_quality(omega, q, volume, dampings: Sequence, points, radii, body, density, sound_speed,
                 wall_reflection: float = 0.0) -> list:
    """Q_n = w_n / (q_n^T D q_n) of coupled modes over leading batch axes, D = diag(damping) + Phi^T (rho w_n^2/(4 pi c)) S Phi (mutual radiation resistance, :func:`mutual_resistance`; Kinsler et al. ch. 7/8).

    ``omega`` (..., K), ``q`` (..., M, K) and ``volume`` (..., n, K) from :func:`coupled_mode_shapes` (any subset of
    their modes: each mode's Q depends on that mode only); ``dampings`` a list of (..., M) bare modal dampings
    omega_m/Q_m.  Returns one (..., K) Q per damping.
    """
    density, sound_speed = np.asarray(density, float), np.asarray(sound_speed, float)
    radiated = radiation_resistance(omega, density[..., None], sound_speed[..., None]) * \
        mutual_resistance(volume, points, radii, body, omega / sound_speed[..., None], wall_reflection)
    qualities = []
    for dmp in dampings:
        c_n = (np.asarray(dmp, float)[..., :, None] * q**2).sum(axis=-2) + radiated
        with np.errstate(divide="ignore"):
            qualities.append(np.where(c_n > 0, omega / np.where(c_n > 0, c_n, 1.0), np.inf))
    return qualities


def coupled_mode_batch(phi, omega, damping, points, radii, body, density, sound_speed, wall_reflection: float = 0.0,
                       max_omega: float | None = None, also_damping: Sequence = ()) -> tuple:
    """Undamped modes Omega^2 q = w^2 (I + rho Phi^T g0 Phi) q and their Q over leading batch axes (mutual radiation mass and resistance; Kinsler et al. ch. 7/8).

    ``phi`` (..., n, M) outward volume of each interface per bare modal coordinate, ``omega`` / ``damping``
    (..., M) (damping omega_m/Q_m), ``points`` (..., n, 3), ``radii`` (n,) or (..., n), ``body`` (n,) capsule of
    each interface; ``density`` / ``sound_speed`` scalars or (...).  Q_n = w_n / (q_n^T D q_n), q_n
    mass-normalized, D = diag(damping) + Phi^T (rho w_n^2/(4 pi c)) S Phi (:func:`mutual_resistance`).
    ``max_omega`` keeps the modes up to it (the most any batch row keeps; the others' Q is not computed).
    ``also_damping``: other (..., M) modal dampings; their Q from the same eigensolution and radiation terms.
    Returns (omega (..., K) ascending, volume (..., n, K), quality (..., K), tuple of the other qualities):
    :func:`coupled_mode_shapes` then :func:`mode_quality`.
    """
    om, q, vol = coupled_mode_shapes(phi, omega, points, radii, body, density, wall_reflection, max_omega)
    qualities = mode_quality(om, q, vol, [damping, *also_damping], points, radii, body, density, sound_speed,
                             wall_reflection)
    return om, vol, qualities[0], tuple(qualities[1:])


def mode_shapes(system: BubbleSystem, density: float, wall_reflection: float = 0.0,
                max_omega: float | None = None) -> ModeShapes:
    """Undamped coupled modes of a system without their Q: :func:`coupled_mode_shapes` at batch size 1 over its real modes (mutual radiation mass; Kinsler et al. ch. 7/8)."""
    phi, om, _ = _compact(system)
    if om.size == 0:
        return ModeShapes(omega=np.zeros(0), coordinates=np.zeros((0, 0)), volume=np.zeros((system.n, 0)))
    omega, q, vol = coupled_mode_shapes(phi, om, system.points, system.radii, system.body, density, wall_reflection,
                                        max_omega)
    for arr in (omega, q, vol):
        arr.setflags(write=False)
    return ModeShapes(omega=omega, coordinates=q, volume=vol)


def coupled_modes(system: BubbleSystem, density: float, sound_speed: float,
                  wall_reflection: float = 0.0, max_omega: float | None = None,
                  also_damping: Sequence = (), shapes: ModeShapes | None = None, which=None) -> CoupledModes:
    """Coupled modes of a system and their Q: :func:`mode_shapes` then :func:`mode_quality` (Kinsler et al. ch. 7/8).

    ``max_omega`` keeps only the modes up to it (the others' Q, n^2 terms each, is not computed).
    ``also_damping``: other (C, Mx) modal dampings of the same system (e.g. without a declared Q);
    their Q come in ``also_quality``.  ``shapes``: :func:`mode_shapes` of this system (the same density, wall and
    ``max_omega``) if already computed; ``which``: indices of the modes to return (only their Q is computed: each
    mode's Q depends on that mode alone).
    """
    if shapes is None:
        shapes = mode_shapes(system, density, wall_reflection, max_omega)
    omega, q, vol = shapes.omega, shapes.coordinates, shapes.volume
    if which is not None:
        which = np.asarray(which, int)
        omega, q, vol = omega[which], q[:, which], vol[:, which]
    if omega.size == 0:
        z = np.zeros(0)
        return CoupledModes(omega=z, volume=np.zeros((system.n, 0)), quality=z,
                            also_quality=tuple(z for _ in also_damping))
    _, _, dmp = _compact(system)
    quality, *also = mode_quality(omega, q, vol, [dmp] + [_compact(system, a)[2] for a in also_damping],
                                  system.points, system.radii, system.body, density, sound_speed, wall_reflection)
    for arr in (quality, *also):
        arr.setflags(write=False)
    return CoupledModes(omega=omega, volume=vol, quality=quality, also_quality=tuple(also))


def prepared_response(system: BubbleSystem, frequency, density: float, sound_speed: float,
                      wall_reflection: float = 0.0, h0=None):
    """:func:`coupled_response` at fixed frequencies for many sets of interface positions: returns ``response(points (B, n, 3)) -> (B, F, n)``.

    :func:`coupled_volumes` with the uncoupled blocks computed once, for solvers that evaluate one design many times.
    """
    f = np.atleast_1d(np.asarray(frequency, float))
    n = system.n
    blocks = uncoupled_blocks(system, 2 * np.pi * f) if h0 is None else np.asarray(h0)      # (F, C, P, P)

    def response(points) -> np.ndarray:
        pts = np.asarray(points, float).reshape(-1, n, 3)
        if n == 0 or f.size == 0:
            return np.zeros((pts.shape[0], f.size, n), complex)
        return coupled_volumes(blocks, system.slot, pts, system.radii, f, density, sound_speed, wall_reflection)

    return response
