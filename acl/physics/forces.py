"""Acoustic forces on capsules: streaming thrust, secondary Bjerknes force, drag in a neighbour's jet.

Sign conventions
----------------
* Thrust: the streaming jet leaves the orifice along its outward normal n and the capsule is pushed
  the other way, F = -|F| n (paper Fig. 1d jet; facing identical capsules are pushed apart, paper
  text around Eq. 2).
* Pair forces: a scalar is *attraction-positive* (paper Eq. 3 convention); vectors are in the
  design frame.
* Volume amplitudes are complex (e^{i omega t}); only products V1 conj(V2) and |V|^2 enter, so the
  overall sign convention of the volume response cancels.

Pure numpy on SI floats.
"""
from __future__ import annotations

import numpy as np

from acl.physics.effects import bjerknes_gap_factor, drag_load
from acl.physics.ties import TIE_RTOL, first_max


def interface_centre_amplitude(volume_amplitude, radius):
    """Centre displacement eps = 2 |dV| / (pi R^2) of a paraboloidal pinned interface (cap volume pi R^2 eps / 2)."""
    return 2 * np.abs(volume_amplitude) / (np.pi * np.asarray(radius, float) ** 2)


def boundary_layer(omega, density, viscosity):
    """Stokes layer thickness delta = sqrt(2 nu / omega) (Landau & Lifshitz, Fluid Mechanics, section 24)."""
    return np.sqrt(2 * np.asarray(viscosity, float) / (np.asarray(density, float) * np.asarray(omega, float)))


def streaming_reynolds(eps, omega, density, viscosity):
    """Streaming Reynolds number R_s = U^2/(omega nu) = omega eps^2/nu = 2 (eps/delta)^2 of an interface oscillating at amplitude eps (Riley, Annu. Rev. Fluid Mech. 33, 43 (2001))."""
    return np.asarray(omega, float) * np.asarray(eps, float) ** 2 * np.asarray(density, float) / np.asarray(viscosity, float)


def thrust_magnitude(volume_amplitude, radius, omega, viscosity, streaming_constant):
    """Streaming thrust |F| = C_s 6 pi mu omega eps^2 of one orifice: slip velocity u_s ~ omega eps^2/R driving a Stokes outer flow (Stuart, J. Fluid Mech. 24, 673 (1966); Riley 2001), Stokes traction 6 pi mu R u_s.

    ``eps`` = 2|dV|/(pi R^2) is the interface centre amplitude; valid for streaming Reynolds number
    R_s = omega eps^2/nu below ~1 (:func:`streaming_reynolds`).  One constant C_s (a calibration:
    :func:`streaming_constant_from_critical_distance`).  Quadratic in eps, so thrust = gamma V^2
    (paper Eq. 3).
    """
    area = np.pi * np.asarray(radius, float) ** 2               # eps^2 = 4 |dV|^2 / (pi R^2)^2
    return (streaming_constant * 6 * np.pi * np.asarray(viscosity, float) * np.asarray(omega, float) * 4
            * np.abs(volume_amplitude) ** 2 / area**2)


def law_critical_distance(radius, omega, density, viscosity, streaming_constant):
    """d_c = R^2 / (delta sqrt(192 C_s)) of two identical facing interfaces in phase (free-field Bjerknes rho w^2 |dV|^2/(8 pi d^2) = 2 x thrust of :func:`thrust_magnitude`)."""
    delta = boundary_layer(omega, density, viscosity)
    return np.asarray(radius, float) ** 2 / (delta * np.sqrt(192 * np.asarray(streaming_constant, float)))


def streaming_constant_from_critical_distance(d_c, radius, omega, density, viscosity):
    """C_s = R^4 / (192 delta^2 d_c^2): the inverse of :func:`law_critical_distance` (a calibration on one measured d_c)."""
    delta = boundary_layer(omega, density, viscosity)
    return np.asarray(radius, float) ** 4 / (192 * delta**2 * np.asarray(d_c, float) ** 2)


def bjerknes_attraction(omega, volume_a, volume_b, distance, density):
    """Secondary Bjerknes force of one tone: :func:`bjerknes_from_rates` of the rate product w^2 Re(Va conj Vb) (attraction positive)."""
    omega = np.asarray(omega, float)
    prod = np.real(np.asarray(volume_a) * np.conj(np.asarray(volume_b)))
    return bjerknes_from_rates(omega**2 * prod, distance, density)


def bjerknes_from_rates(rate_product, distance, density):
    """Attraction-positive secondary Bjerknes force rho P / (8 pi d^2), P = sum over tones of w^2 Re(Va conj Vb) = 2 <dVa/dt dVb/dt> (Crum, J. Acoust. Soc. Am. 57, 1363 (1975); Leighton, The Acoustic Bubble, ch. 4).

    Tones at different frequencies add in power (their cross terms average to zero), so ``rate_product``
    is the sum of each tone's.  ``density`` may be an array (e.g. rho times a pair's factor).
    Assumption: free-field monopoles, although each capsule's own added mass is baffled
    (acl.physics.resonance); two orifices on one large rigid wall would feel up to 2x (half-space
    source).  The factor is absorbed by the streaming constant's calibration on d_c and carried as
    model-form uncertainty (docs/physics.md, Part A section 11, "The baffle assumption, stated").
    """
    return np.asarray(density, float) / (8 * np.pi) * rate_product / np.asarray(distance, float) ** 2


def bjerknes_vectors(omega, volume_a, position_a, volume_b, position_b, density):
    """Bjerknes force vectors (on a, on b) between two point volume sources: :func:`bjerknes_attraction` along the line of centres, equal and opposite."""
    pa = np.asarray(position_a, float)
    pb = np.asarray(position_b, float)
    sep = pb - pa
    d = np.linalg.norm(sep, axis=-1)
    unit = sep / d[..., None]
    f = bjerknes_attraction(omega, volume_a, volume_b, d, density)
    on_a = f[..., None] * unit
    return on_a, -on_a


def pair_law_force(alpha, gamma, distance, voltage):
    """Reduced pair law F = (alpha/d^2 - 2 gamma) V^2, attraction positive (paper Eq. 3, sign corrected: docs)."""
    d = np.asarray(distance, float)
    return (alpha / d**2 - 2 * gamma) * np.asarray(voltage, float) ** 2


def critical_distance(alpha, gamma):
    """d_c = sqrt(alpha / (2 gamma)), where the reduced pair law changes sign (paper Eq. 3)."""
    return np.sqrt(np.asarray(alpha, float) / (2 * np.asarray(gamma, float)))


def jet_drag(momentum_flux, distance, cos_angle, target_radius, fraction=None):
    """Drag of a neighbour's jet: J min(1, 9a/(4x)) max(cos, 0)^2 (laminar round jet u = 3J/(8 pi rho nu x), Schlichting, Boundary-Layer Theory, laminar round jet; Stokes drag 6 pi mu a u).

    ``momentum_flux`` J (N) of the jet, ``distance`` x from the orifice to the target's centre,
    ``cos_angle`` between the jet axis and that line, ``target_radius`` a.  The factor is capped
    at 1 (a body cannot take more than the jet's momentum flux); the cos^2 weight is a crude cone.
    ``fraction`` replaces min(1, 9a/(4x)) by a constant: 1 is paper Eq. (3)'s assumption F_d = F_AS
    at every distance (:data:`PAPER_DRAG_FRACTION`), the other end of this law's model-form range.
    """
    x = np.asarray(distance, float)
    c = np.clip(np.asarray(cos_angle, float), 0.0, None)
    frac = (np.minimum(1.0, 9 * np.asarray(target_radius, float) / (4 * x)) if fraction is None
            else np.full_like(x, float(fraction)))
    return np.asarray(momentum_flux, float) * frac * c**2


#: Paper Eq. (3)'s neighbour drag: F_d = F_AS, one thrust at every distance (text before Eq. 3), the
#: upper end of :func:`jet_drag`'s fraction (a body cannot take more than the jet's momentum flux).
PAPER_DRAG_FRACTION = 1.0


# ----------------------------------------------------------------------------------------------
# The force model of many capsules at many configurations (leading batch axis B)
# ----------------------------------------------------------------------------------------------


def pressure_terms(unit, w2, pressure, scale):
    """(thrust constant (..., T, n), Bjerknes weight (..., T)) of tone pressures (..., T) Pa: :func:`thrust_magnitude` per unit volume amplitude ``unit`` (T, n) x p^2 x each orifice's thrust scale (..., n), and the rate weight w^2 p^2 of :func:`bjerknes_from_rates` (volumes linear in p)."""
    pressure = np.asarray(pressure, float)
    return unit * pressure[..., :, None] ** 2 * np.asarray(scale, float)[..., None, :], w2 * pressure**2


def force_constants(omega, radii, body, n_capsules: int, viscosity: float, density: float, streaming_constant: float,
                    pressure, scale, pair, gap_shape=(0.0, 1.0)) -> dict:
    """The position-independent factors of :func:`capsule_forces`: :func:`thrust_magnitude` per unit volume, :func:`pressure_terms`, :func:`bjerknes_from_rates` per unit rate and distance (other-capsule pairs, times ``pair`` (C, C)), the jet-drag mask (:func:`jet_drag`); ``gap_shape`` (n, d_ref) of :func:`acl.physics.effects.bjerknes_gap_factor`."""
    w = np.asarray(omega, float)
    body = np.asarray(body, int)
    other = body[:, None] != body[None, :]
    unit = thrust_magnitude(1.0, radii, w[:, None], viscosity, streaming_constant)
    thrust, w2p2 = pressure_terms(unit, w**2, pressure, np.asarray(scale, float)[body])
    return {
        "thrust": thrust,             # (T, n) N per |dV/p|^2
        "thrust_unit": unit,          # (T, n) per unit volume amplitude, before pressure and thrust scale
        "other": other,
        "w2p2": w2p2,
        "w2": w**2,
        "bjerknes": bjerknes_from_rates(1.0, 1.0, density * other * np.asarray(pair, float)[body][:, body]),
        "drag_mask": body[:, None] != np.arange(n_capsules)[None, :],
        "gap_exponent": float(gap_shape[0]),   # a declared bjerknes_scale shape (d_ref/d)^n; 0: the d^-2 law
        "gap_ref": float(gap_shape[1]),
    }


def interface_distances(points, other) -> np.ndarray:
    """|p_j - p_i| (B, n, n) of the interface pairs of different capsules (``other`` (n, n)), 1 elsewhere (:func:`bjerknes_pair_sum`'s distances)."""
    sep = points[:, None, :, :] - points[:, :, None, :]                   # (B, i, j, 3)
    # two interfaces in contact (d = 0, a solver's contact configuration) pull with no direction: no force, not NaN
    return np.where(other, np.maximum(np.sqrt((sep * sep).sum(axis=-1)), 1e-12), 1.0)


def bjerknes_pair_sum(points, response, w2p2, coefficient, other, gap_exponent: float = 0.0, gap_ref: float = 1.0,
                      distance=None):
    """Secondary Bjerknes force (B, n, 3) on every interface from every other capsule's, and the attraction (B, n, n): :func:`bjerknes_from_rates` of each pair along p_j - p_i, tones in power.

    ``points`` (B, n, 3), ``response`` (B, T, n) volumes per pascal, ``w2p2`` (T,) or (B, T) rate weights,
    ``coefficient`` (n, n) :func:`bjerknes_from_rates` at unit rate and distance (0 within a capsule),
    ``other`` (n, n) the pairs of different capsules; ``gap_exponent``, ``gap_ref``: a declared shape
    (:func:`acl.physics.effects.bjerknes_gap_factor`; exponent 0 is the monopole law); ``distance`` the
    :func:`interface_distances` of these points when the caller keeps them.
    """
    if not np.any(other):     # one capsule: no pair of different capsules, no Bjerknes force (its coefficient is 0)
        n = points.shape[-2]
        return np.zeros(points.shape), np.zeros(points.shape[:-1] + (n,))
    d = interface_distances(points, other) if distance is None else distance
    w2p2 = np.asarray(w2p2, float)
    prod = np.einsum("t,bti,btj->bij" if w2p2.ndim == 1 else "bt,bti,btj->bij", w2p2, response,
                     np.conj(response)).real
    att = coefficient * prod / d**2
    if np.any(gap_exponent):          # a float, or per configuration (B, 1, 1)
        att = att * bjerknes_gap_factor(d, gap_ref, gap_exponent)
    c = att / d
    return c @ points - c.sum(axis=-1)[..., None] * points, att          # sum_j c_ij (p_j - p_i)


def jet_lines(points, normals, centres, mask) -> tuple:
    """(distance (B, n, C), 1 where ``mask`` is False; cosine to the jet's normal (B, n, C)) from every interface to every capsule centre (:func:`jet_drag_on_capsules`' geometry)."""
    x = centres[:, None, :, :] - points[:, :, None, :]                    # (B, n, C, 3)
    dist = np.sqrt((x * x).sum(axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):   # positions a runaway solver step made non-finite:
        cos = (x * normals[None, :, None, :]).sum(axis=-1) / dist         # NaN forces, which the solver rejects
    return np.where(mask, dist, 1.0), cos


def jet_drag_on_capsules(thrust, points, normals, centres, outer, mask, fraction=None, lines=None):
    """Drag (B, C, 3) of every interface's jet on the other capsules: :func:`jet_drag` of each jet (momentum flux = its thrust (B, n)) on each capsule centre (B, C, 3) along the jet's normal (n, 3); ``fraction`` as :func:`jet_drag`'s.

    ``lines``: the :func:`jet_lines` of these positions when the caller keeps them.
    """
    dist, cos = jet_lines(points, normals, centres, mask) if lines is None else lines
    drag = jet_drag(thrust[:, :, None], dist, cos, outer[None, None, :], fraction) * mask
    return drag.transpose(0, 2, 1) @ normals


def capsule_forces(centres, body, offsets, normals, onehot, outer, response, consts: dict, points=None, distance=None,
                   lines=None):
    """Total acoustic force (B, C, 3) on each capsule at centres (B, C, 3): streaming thrust (:func:`thrust_magnitude`) + :func:`bjerknes_pair_sum` + :func:`jet_drag_on_capsules`.

    Interfaces (n): ``body`` (n,) capsule index, ``offsets`` (n, 3) from the capsule centre, ``normals``
    (n, 3) outward, ``onehot`` (n, C); ``outer`` (C,) the radius a jet drags; ``response`` (B, T, n) the
    coupled volumes per pascal at these centres; ``consts`` :func:`force_constants` (or rows of them);
    ``points`` the interface centres (B, n, 3) when the caller already has them, ``distance`` their
    :func:`interface_distances` and ``lines`` their :func:`jet_lines`; ``consts["jet_drag_fraction"]``
    (optional) a constant drag fraction (:func:`jet_drag`).
    Returns (total, points (B, n, 3), thrust per interface (B, n), attraction (B, n, n)).
    """
    pts = centres[:, body, :] + offsets if points is None else points     # (B, n, 3) orifice centres
    thr = ((response.real**2 + response.imag**2) * consts["thrust"]).sum(axis=1)     # (B, n), tones added
    bj, att = bjerknes_pair_sum(pts, response, consts["w2p2"], consts["bjerknes"], consts["other"],
                                consts.get("gap_exponent", 0.0), consts.get("gap_ref", 1.0), distance)
    total = onehot.T @ (bj - thr[:, :, None] * normals)                 # (B, C, 3); thrust against the jet (module doc)
    if np.any(consts["drag_mask"]):      # a jet that reaches another capsule (none with one capsule)
        total = total + jet_drag_on_capsules(thr, pts, normals, centres, outer, consts["drag_mask"],
                                             consts.get("jet_drag_fraction"), lines)
    return total, pts, thr, att


def neighbour_drag(total, centres, rest, near, inv_plateau):
    """Forces (B, C, 3) with a neighbour's jet drag weakening as the capsule moves in: :func:`acl.physics.effects.drag_load` of each displacement from rest (capsules with ``near`` (C,) True only)."""
    delta = np.linalg.norm(centres - rest[None], axis=-1) * np.asarray(near, float)
    return drag_load(total, delta[..., None], inv_plateau)


def interface_pairs(points, body, n_capsules: int) -> tuple:
    """The interface pairs (i of a, j of b) of every capsule pair a < b at ``points`` (n, 3): (i, j, pair row, p_j - p_i, |p_j - p_i|, one interface per capsule) (:func:`capsule_pair_forces`' geometry; not physics, no equation).

    A caller that evaluates many drives at one configuration computes it once and passes it as ``pairs``.
    """
    body = np.asarray(body, int)
    oi, oj = np.nonzero(body[:, None] < body[None, :])
    sep = points[oj] - points[oi]
    a, b = body[oi], body[oj]
    k = a * n_capsules - a * (a + 1) // 2 + (b - a - 1)
    single = body.size == n_capsules and np.array_equal(body, np.arange(n_capsules))
    return oi, oj, k, sep, np.linalg.norm(sep, axis=-1), single


def capsule_pair_forces(points, attraction, body, n_capsules: int, pairs=None):
    """Bjerknes vector (P, 3) on capsule a of every capsule pair a < b (``np.triu_indices`` order): the sum over interface pairs (i of a, j of b) of :func:`bjerknes_pair_sum`'s attraction along p_j - p_i.

    ``pairs``: the :func:`interface_pairs` of these points when the caller keeps them.
    """
    pa, pb = np.triu_indices(n_capsules, 1)
    fa = np.zeros((pa.size, 3))
    oi, oj, k, sep, norm, single = interface_pairs(points, body, n_capsules) if pairs is None else pairs
    if oi.size:
        contrib = (attraction[oi, oj] / norm)[:, None] * sep
        if single:                    # one interface per capsule: row k is pair k (the sum of one term, + 0.0)
            return np.add(contrib, 0.0, out=fa)
        for axis in range(3):
            fa[:, axis] = np.bincount(k, weights=contrib[:, axis], minlength=pa.size)
    return fa


def dominant_pair_phase(volumes, points, body, n_capsules: int, distance, pairs=None):
    """(phase difference (P,) rad, distance (P,) m) of every capsule pair a < b between their dominant interfaces at the strongest tone of ``volumes`` (T, n); ties: the first declared interface, the first tone (acl.physics.ties); ``distance`` (P,) where a capsule has no interface.

    ``pairs``: the :func:`interface_pairs` of these points when the caller keeps them.
    """
    pa, pb = np.triu_indices(n_capsules, 1)
    body = np.asarray(body, int)
    if pairs is not None and pairs[5] and volumes.shape[0]:     # one interface per capsule: it is the dominant one
        if volumes.shape[0] == 1:
            t = np.zeros(pa.size, np.intp)
        else:
            mag = np.abs(volumes)
            t = first_max(mag[:, pa] * mag[:, pb], axis=0)
        return np.angle(volumes[t, pa] * np.conj(volumes[t, pb])), np.array(pairs[4], float)
    dphi = np.zeros(pa.size)
    gap = np.array(distance, float)
    counts = np.bincount(body, minlength=n_capsules) if body.size else np.zeros(n_capsules, int)
    has = counts > 0
    if volumes.shape[0] and body.size:
        mag = np.abs(volumes)                                         # (T, n)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[has]   # interfaces are grouped by capsule
        peak = np.full((volumes.shape[0], n_capsules), -np.inf)
        peak[:, has] = np.maximum.reduceat(mag, starts, axis=1)
        first = np.zeros((volumes.shape[0], n_capsules), int)
        at_peak = np.where(mag >= peak[:, body] * (1 - TIE_RTOL), np.arange(body.size)[None, :], body.size)
        first[:, has] = np.minimum.reduceat(at_peak, starts, axis=1)
        ok = has[pa] & has[pb]
        t = first_max(peak[:, pa[ok]] * peak[:, pb[ok]], axis=0)
        ja, jb = first[t, pa[ok]], first[t, pb[ok]]
        dphi[ok] = np.angle(volumes[t, ja] * np.conj(volumes[t, jb]))
        gap[ok] = np.linalg.norm(points[jb] - points[ja], axis=-1)
    return dphi, gap
