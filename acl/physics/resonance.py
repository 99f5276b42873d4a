"""Entrapped-bubble resonance: Rayleigh-Ritz model of a gas spring loaded by pinned interfaces.

The configuration (gas pocket behind a pinned interface, surface tension + gas spring + liquid
inertia) is that of Gelderblom et al., Phys. Fluids 24, 122101 (2012) and of the entrapped
bubbles of Dolev, Kaynak & Sakar, Phys. Fluids 34, 012012 (2022); the paper's Fig. 1e / Table S1.
A capsule traps a gas volume V behind n circular orifices.  Each orifice's liquid/gas interface is
pinned on the orifice rim (radius R) and expanded in the axisymmetric shapes
w_m(r) = (1 - r^2/R^2)^m, m = 1..N (m = 1 is the paraboloid).  Energies (all per shape amplitude):

* surface tension (membrane):   K_s = sigma * integral grad w_i . grad w_j dA
* gas spring (all interfaces):  K_g = kappa p0 / V * v v^T, v_i = integral w_i dA
* added liquid mass, baffled:   M = 2 pi rho * integral_0^inf W_i(k) W_j(k) dk
  (kinetic energy of the potential flow of a baffled aperture, Rayleigh integral written with the
  Hankel transform W of the shape; Lamb, Hydrodynamics, art. 102/302)
* viscous loss of that flow:    C_v = 8 pi mu * integral_0^inf k^2 W_i W_j dk (Lamb art. 329)

With W_m(k) = 2^m m! R^2 J_{m+1}(kR)/(kR)^{m+1} every integral is a Weber-Schafheitlin integral, so
the dimensionless matrices are exact (no quadrature) and scale with R analytically:
M = rho R^3 Mh, C_v = mu R Ch, K_s = sigma Kh, v = R^2 vh.

Coordinates: generalized amplitudes of the shapes, outward (into the liquid) positive.
Response convention (e^{i omega t}): :func:`volume_response` returns the *inward* volume
displacement (bubble compression) per pascal of incident pressure: in phase below resonance,
-90 deg at an undamped natural frequency, -180 deg far above.

Pure numpy; no acl.design import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

# ----------------------------------------------------------------------------------------------
# Dimensionless shape integrals
# ----------------------------------------------------------------------------------------------


def _weber_schafheitlin(mu: float, nu: float, lam: float) -> float:
    """integral_0^inf J_mu(t) J_nu(t) t^-lam dt (Watson, Theory of Bessel Functions, 13.41(2))."""
    lg = math.lgamma
    log = (lg(lam) + lg((mu + nu - lam + 1) / 2) - lam * math.log(2)
           - lg((-mu + nu + lam + 1) / 2) - lg((mu + nu + lam + 1) / 2) - lg((mu - nu + lam + 1) / 2))
    return math.exp(log)


@dataclass(frozen=True)
class ShapeMatrices:
    """Dimensionless Rayleigh-Ritz matrices for N pinned shapes (1 - rho^2)^m, m = 1..N."""

    mass: np.ndarray        # Mh: M = rho R^3 Mh
    stiffness: np.ndarray   # Kh: K_s = sigma Kh
    viscous: np.ndarray     # Ch: C_v = mu R Ch
    volume: np.ndarray      # vh: v = R^2 vh


@lru_cache(maxsize=None)
def shape_matrices(n_modes: int) -> ShapeMatrices:
    """Exact dimensionless M, K_s, C_v, v of the pinned shapes (Lamb, Hydrodynamics §102/§329; Watson §13.41)."""
    if n_modes < 1:
        raise ValueError("n_modes must be >= 1")
    m = np.arange(1, n_modes + 1)
    mass = np.empty((n_modes, n_modes))
    visc = np.empty((n_modes, n_modes))
    stiff = np.empty((n_modes, n_modes))
    for i, a in enumerate(m):
        for j, b in enumerate(m):
            pref = 2.0 ** (a + b) * math.factorial(a) * math.factorial(b)
            mass[i, j] = 2 * math.pi * pref * _weber_schafheitlin(a + 1, b + 1, a + b + 2)
            visc[i, j] = 8 * math.pi * pref * _weber_schafheitlin(a + 1, b + 1, a + b)
            stiff[i, j] = 4 * math.pi * a * b / ((a + b - 1) * (a + b))
    vol = math.pi / (m + 1.0)
    out = ShapeMatrices(mass, stiff, visc, vol)
    for arr in (out.mass, out.stiffness, out.viscous, out.volume):
        arr.setflags(write=False)
    return out


# ----------------------------------------------------------------------------------------------
# One-mode closed form
# ----------------------------------------------------------------------------------------------


def paraboloid_frequency(volume, radius, density, surface_tension, ambient_pressure,
                         polytropic_index):
    """f = sqrt[(kappa p0/V + 8 sigma/(pi R^4)) / (1024 rho/(315 pi^2 R))]/(2 pi): one paraboloid mode (module doc energies)."""
    volume = np.asarray(volume, float)
    radius = np.asarray(radius, float)
    k = polytropic_index * ambient_pressure / volume + 8 * surface_tension / (np.pi * radius**4)
    m = 1024 * density / (315 * np.pi**2 * radius)
    return np.sqrt(k / m) / (2 * np.pi)


# ----------------------------------------------------------------------------------------------
# Batched single-orifice first frequency (Fig. 1e surface)
# ----------------------------------------------------------------------------------------------


@lru_cache(maxsize=None)
def _reduced_single(n_modes: int):
    """Cholesky-reduced tension matrix L^-1 Kh L^-T and gas vector L^-1 vh for Mh = L L^T."""
    s = shape_matrices(n_modes)
    chol = np.linalg.cholesky(s.mass)
    linv = np.linalg.inv(chol)
    a = linv @ s.stiffness @ linv.T
    u = linv @ s.volume
    return (a + a.T) / 2, u


def single_orifice_frequencies(volume, radius, density, surface_tension, ambient_pressure,
                               polytropic_index, n_modes: int = 3, all_modes: bool = False):
    """Natural frequencies (Hz) of single-orifice capsules, K x = w^2 M x, vectorized over V and R (paper Fig. 1e; Lamb §102 added mass).

    Reduced form: w^2 = eig[sigma/(rho R^3) A + kappa p0 R/(rho V) u u^T], A and u fixed
    (Cholesky reduction of the exact shape matrices), solved with one stacked ``eigvalsh``.
    Returns shape ``broadcast(V, R).shape`` (first mode) or ``(..., n_modes)`` if ``all_modes``.
    """
    volume, radius = np.broadcast_arrays(np.asarray(volume, float), np.asarray(radius, float))
    a, u = _reduced_single(n_modes)
    tension = (surface_tension / (density * radius**3))[..., None, None]
    gas = (polytropic_index * ambient_pressure * radius / (density * volume))[..., None, None]
    stack = tension * a + gas * np.outer(u, u)
    w2 = np.linalg.eigvalsh(stack)
    f = np.sqrt(w2) / (2 * np.pi)
    return f if all_modes else f[..., 0]


# ----------------------------------------------------------------------------------------------
# Multi-orifice capsule: modes, damping, response
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BubbleModes:
    """Natural modes of one capsule (arrays, SI).

    ``omega`` (n,) rad/s ascending; ``quality`` (n,); ``orifice_volume`` (n_orifices, n): outward
    volume displacement of each interface per unit mass-normalized modal coordinate.
    """

    omega: np.ndarray
    quality: np.ndarray
    orifice_volume: np.ndarray

    @property
    def frequency(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def share(self) -> np.ndarray:
        """(n_orifices, n): fraction |dV_o| / sum |dV| of each interface in each mode."""
        a = np.abs(self.orifice_volume)
        return a / a.sum(axis=0, keepdims=True)


def capsule_matrices(volume, radii, density, surface_tension, ambient_pressure,
                     polytropic_index, viscosity=0.0, n_modes: int = 3):
    """K, M, C_v and volume matrix B (n_orifices x dof) of one capsule (Rayleigh-Ritz; Lamb §102/§329; gas spring kappa p0/V)."""
    s = shape_matrices(n_modes)
    radii = np.asarray(radii, float)
    n_or = radii.size
    dof = n_or * n_modes
    k = np.zeros((dof, dof))
    m = np.zeros((dof, dof))
    c = np.zeros((dof, dof))
    b = np.zeros((n_or, dof))
    for o, r in enumerate(radii):
        sl = slice(o * n_modes, (o + 1) * n_modes)
        k[sl, sl] = surface_tension * s.stiffness
        m[sl, sl] = density * r**3 * s.mass
        c[sl, sl] = viscosity * r * s.viscous
        b[o, sl] = r**2 * s.volume
    vtot = b.sum(axis=0)
    k += polytropic_index * ambient_pressure / volume * np.outer(vtot, vtot)
    return k, m, c, b


def thermal_polytropic(omega, thermal_radius, heat_capacity_ratio, thermal_diffusivity):
    """Complex effective polytropic index Phi/3 of a gas bubble (Prosperetti, JASA 61, 17 (1977); Prosperetti, Crum & Commander, JASA 83, 502 (1988))."""
    omega = np.asarray(omega, float)
    chi = thermal_diffusivity / (omega * thermal_radius**2)
    z = np.sqrt(1j / chi)
    zcoth = z / np.tanh(z)
    g = heat_capacity_ratio
    return g / (1 - 3 * (g - 1) * 1j * chi * (zcoth - 1))


def symmetric_eigh(k, m):
    """Eigenpairs of K x = w^2 M x, M symmetric positive definite, by Cholesky reduction (Golub & Van Loan, Matrix Computations, 4th ed., 8.7.2): ascending w^2, x^T M x = I.

    The reduction LAPACK's ``sygv`` makes (scipy.linalg.eigh(k, m)), done with numpy.linalg so that
    ``acl analyze`` does not import scipy.linalg (about 0.4 s at start-up).
    """
    li = np.linalg.inv(np.linalg.cholesky(m))
    a = li @ k @ li.T
    w2, y = np.linalg.eigh((a + a.T) / 2)
    return w2, li.T @ y


def radiation_resistance(omega, density, sound_speed):
    """Radiation resistance rho w^2/(4 pi c) of a compact monopole per unit volume velocity squared (Kinsler et al., Fundamentals of Acoustics, simple source; Leighton, The Acoustic Bubble, 3.4)."""
    return density * omega**2 / (4 * np.pi * sound_speed)


def capsule_modes(volume, radii, density, surface_tension, ambient_pressure, polytropic_index,
                  viscosity, sound_speed, thermal_radius, heat_capacity_ratio=1.4,
                  thermal_diffusivity=2.1e-5, quality_override=None,
                  n_modes: int = 3, thermal: bool = True) -> BubbleModes:
    """Natural modes of a capsule, K x = w^2 M x, and their Q (Lamb §329; Leighton ch. 3; Prosperetti 1977).

    Damping per mode, Q = omega_n / (x^T C(omega_n) x) for mass-normalized x, with C the sum of
    (i) viscous loss of the baffled potential flow (Lamb art. 329), (ii) acoustic radiation of the
    capsule as a compact monopole in free field, R_rad = rho omega^2 / (4 pi c) on the total volume
    velocity (Leighton, The Acoustic Bubble, 3.4), (iii) thermal loss of the gas,
    Im(Phi/3) p0 / (V omega) on the total volume (Prosperetti 1977).  ``quality_override`` replaces
    every mode's Q (declared Capsule.quality_factor).  Only axisymmetric (volume-changing) modes are
    modelled; they are the ones a uniform pressure excites.  ``thermal`` False leaves (iii) out
    (:func:`plausible_quality_bound`).
    """
    if np.asarray(radii).size == 0:          # no interface: nothing oscillates
        empty = np.zeros(0)
        return BubbleModes(omega=empty, quality=empty, orifice_volume=np.zeros((0, 0)))
    k, m, c_visc, b = capsule_matrices(volume, radii, density, surface_tension, ambient_pressure,
                                       polytropic_index, viscosity, n_modes)
    w2, x = symmetric_eigh(k, m)
    omega = np.sqrt(w2)
    vol = b @ x                                  # (n_orifices, keep)
    vtot = vol.sum(axis=0)
    c_v = np.einsum("in,ij,jn->n", x, c_visc, x)
    c_rad = radiation_resistance(omega, density, sound_speed) * vtot**2
    phi = thermal_polytropic(omega, thermal_radius, heat_capacity_ratio, thermal_diffusivity)
    c_th = np.abs(phi.imag) * ambient_pressure / (volume * omega) * vtot**2 * float(thermal)
    q = omega / (c_v + c_rad + c_th)
    if quality_override is not None:
        q = np.full_like(omega, float(quality_override))
    for arr in (omega, q, vol):
        arr.setflags(write=False)
    return BubbleModes(omega=omega, quality=q, orifice_volume=vol)


#: How far above the Q of the irrotational viscous and radiation losses alone a capsule mode's Q may plausibly be
#: (:func:`plausible_quality_bound`): 2, the model-form allowance on Lamb's irrotational viscous law.
PLAUSIBLE_Q_FACTOR = 2.0


def plausible_quality_bound(quality_viscous_radiation):
    """Largest plausible Q = 2 Q_vr (Batchelor 1967, 5.14: boundary layers on walls add to the irrotational dissipation), Q_vr the mode's Q with viscous and radiation loss only.

    The irrotational viscous loss of :func:`capsule_modes` is then a lower bound of a pinned interface's
    (its rim and the wall around it add boundary layers); PLAUSIBLE_Q_FACTOR allows for that law's form.
    """
    return PLAUSIBLE_Q_FACTOR * np.asarray(quality_viscous_radiation, float)


def modal_dynamic_stiffness(natural, damping, omega):
    """Dynamic stiffness w_n^2 - w^2 + i w c_n of mass-normalized modes, c_n = w_n/Q_n (Meirovitch, Elements of Vibration Analysis, ch. 7); its inverse is the modal receptance.

    ``natural`` w_n and ``damping`` c_n (rad/s, any batch of modes) broadcast against the drive ``omega`` (rad/s).
    """
    return natural**2 - omega**2 + 1j * omega * damping


def volume_response(modes: BubbleModes, frequency) -> np.ndarray:
    """Inward volume displacement (m^3/Pa) per interface: modal superposition sum_n phi phi^T/(w_n^2 - w^2 + i w w_n/Q_n) (Meirovitch, Elements of Vibration Analysis, ch. 7).

    ``frequency`` (F,) Hz -> complex array (F, n_orifices); uniform incident pressure (capsule
    small against the wavelength).  e^{i omega t}; -90 deg at an undamped natural frequency.
    """
    w = 2 * np.pi * np.atleast_1d(np.asarray(frequency, float))
    phi = modes.orifice_volume                         # (n_or, n)
    force = phi.sum(axis=0)                            # modal force per Pa of compression
    den = modal_dynamic_stiffness(modes.omega[None, :], (modes.omega / modes.quality)[None, :], w[:, None])
    return (force[None, :] / den) @ phi.T
