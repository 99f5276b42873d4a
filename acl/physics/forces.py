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
    eps = interface_centre_amplitude(volume_amplitude, radius)
    return (streaming_constant * 6 * np.pi * np.asarray(viscosity, float) * np.asarray(omega, float) * eps**2)


def law_critical_distance(radius, omega, density, viscosity, streaming_constant):
    """d_c = R^2 / (delta sqrt(192 C_s)) of two identical facing interfaces in phase (free-field Bjerknes rho w^2 |dV|^2/(8 pi d^2) = 2 x thrust of :func:`thrust_magnitude`)."""
    delta = boundary_layer(omega, density, viscosity)
    return np.asarray(radius, float) ** 2 / (delta * np.sqrt(192 * np.asarray(streaming_constant, float)))


def streaming_constant_from_critical_distance(d_c, radius, omega, density, viscosity):
    """C_s = R^4 / (192 delta^2 d_c^2): the inverse of :func:`law_critical_distance` (a calibration on one measured d_c)."""
    delta = boundary_layer(omega, density, viscosity)
    return np.asarray(radius, float) ** 4 / (192 * delta**2 * np.asarray(d_c, float) ** 2)


def bjerknes_attraction(omega, volume_a, volume_b, distance, density):
    """Attraction-positive secondary Bjerknes force rho w^2 Re(Va conj Vb) / (8 pi d^2) = -rho <dVa/dt dVb/dt>/(4 pi d^2) (Crum, J. Acoust. Soc. Am. 57, 1363 (1975); Leighton, The Acoustic Bubble, ch. 4)."""
    omega = np.asarray(omega, float)
    prod = np.real(np.asarray(volume_a) * np.conj(np.asarray(volume_b)))
    return density * omega**2 * prod / (8 * np.pi * np.asarray(distance, float) ** 2)


def bjerknes_vectors(omega, volume_a, position_a, volume_b, position_b, density):
    """Bjerknes force vectors (on a, on b) between two point volume sources (Crum, JASA 57, 1363 (1975)); equal and opposite."""
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


def jet_drag(momentum_flux, distance, cos_angle, target_radius):
    """Drag of a neighbour's jet: J min(1, 9a/(4x)) max(cos, 0)^2 (laminar round jet u = 3J/(8 pi rho nu x), Schlichting, Boundary-Layer Theory, laminar round jet; Stokes drag 6 pi mu a u).

    ``momentum_flux`` J (N) of the jet, ``distance`` x from the orifice to the target's centre,
    ``cos_angle`` between the jet axis and that line, ``target_radius`` a.  The factor is capped
    at 1 (a body cannot take more than the jet's momentum flux); the cos^2 weight is a crude cone.
    """
    x = np.asarray(distance, float)
    c = np.clip(np.asarray(cos_angle, float), 0.0, None)
    frac = np.minimum(1.0, 9 * np.asarray(target_radius, float) / (4 * x))
    return np.asarray(momentum_flux, float) * frac * c**2
