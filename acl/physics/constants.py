"""Physical constants and documented defaults of the acoustic models (SI units).

A design normally declares its medium and transducer; these values are used only when the
design leaves them out (the analysis says so in its result).  Every number names its source.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MediumConstants:
    """Liquid and gas properties used by the bubble models (same fields as acl.design Medium)."""

    density: float = 998.2               # kg/m^3, water 20 C (CRC Handbook)
    viscosity: float = 1.002e-3          # Pa s, water 20 C (CRC Handbook)
    sound_speed: float = 1482.0          # m/s, water 20 C (CRC Handbook)
    surface_tension: float = 0.0728      # N/m, water/air 20 C (CRC Handbook); PBS within 1 %
    ambient_pressure: float = 101325.0   # Pa, standard atmosphere
    # Polytropic index of the trapped air.  1.0 (isothermal): the thermal diffusion length of air
    # at 100 kHz, sqrt(2 D / omega) ~ 7 um, is as large as the cavity's volume-to-wall ratio
    # (~7 um) and the polymer walls are a heat reservoir, so the gas stays near wall temperature;
    # Prosperetti (J. Acoust. Soc. Am. 61, 17 (1977)) gives Re(Phi)/3 ~ 1.1 at this Peclet number.
    # See docs/physics.md (part A) for the check against Table S1 with 1.4.
    polytropic_index: float = 1.0
    gas_thermal_diffusivity: float = 2.1e-5   # m^2/s, air 20 C
    gas_heat_capacity_ratio: float = 1.4      # air; used by the thermal damping model only

    def as_tuple(self) -> tuple[float, ...]:
        return (self.density, self.viscosity, self.sound_speed, self.surface_tension,
                self.ambient_pressure, self.polytropic_index, self.gas_thermal_diffusivity,
                self.gas_heat_capacity_ratio)


WATER_20C = MediumConstants()

#: Flat transducer gain used when a design declares no transducer (Pa per V peak).  The paper does
#: not print its Fig. S1 / Fig. 2e values.  100 Pa/V keeps Design 1's interface centre amplitude
#: (about 2 nm/Pa at resonance in this model) below R/2 at the ~20 V the paper drives with (Table S2
#: via Eq. 3), i.e. inside the linear regime of Fig. 2f.  Order of magnitude only; NOT fitted to
#: gamma (the gain that would reproduce gamma = 0.027 nN/V^2 is reported in the docs).
DEFAULT_GAIN_PA_PER_V = 100.0

#: Calibration point of the streaming law (paper text at Fig. 4): two facing identical Design-1
#: capsules (orifice radius 10 um) driven at 125 kHz (Fig. 4e caption) change from attraction to
#: repulsion at the measured critical distance d_c = 50 um.
STREAMING_CALIBRATION = {"radius_m": 10e-6, "frequency_hz": 125e3, "critical_distance_m": 50e-6}


def _streaming_constant() -> float:
    from math import pi

    r, f, dc = (STREAMING_CALIBRATION[k] for k in ("radius_m", "frequency_hz", "critical_distance_m"))
    delta2 = 2 * WATER_20C.viscosity / (WATER_20C.density * 2 * pi * f)
    return r**4 / (192 * delta2 * dc**2)     # acl.physics.forces.streaming_constant_from_critical_distance


#: Dimensionless streaming constant C_s of the thrust law F = C_s 6 pi mu omega eps^2 (Stokes-regime
#: steady streaming of an oscillating interface: Stuart, J. Fluid Mech. 24, 673 (1966); Riley,
#: Annu. Rev. Fluid Mech. 33, 43 (2001); acl.physics.forces.thrust_magnitude).  A CALIBRATION, not a
#: prediction: the one constant is set so that the law's d_c = R^2 / (delta sqrt(192 C_s)) equals the
#: measured 50 um at R = 10 um, 125 kHz in water at 20 C (STREAMING_CALIBRATION; about 8.1e-3).  Every
#: other d_c (other radii, frequencies, media, unequal pairs, coupled responses) is predicted.
STREAMING_CONSTANT = _streaming_constant()

#: Pressure reflection coefficient of the substrate (plane z = 0) for the image sources of the
#: coupled bubble model (acl.physics.coupling).  +1 is a rigid wall.  The near field of the bubbles
#: (distances << wavelength ~ 12 mm) is incompressible, where any wall much stiffer than water is
#: rigid; a glass slide (impedance ~13 MRayl vs 1.5 MRayl) reflects 0.8 in the far field.
SUBSTRATE_REFLECTION = 1.0

#: Linear-regime limit of an interface: centre amplitude eps over orifice radius R.  The exact
#: curvature of a pinned spherical cap, 2 eps/(R^2 + eps^2), departs from the linear 2 eps/R^2 by
#: (eps/R)^2 (Young-Laplace), so the surface-tension stiffness, and with it the resonance (which
#: surface tension dominates at R ~ 10 um), shifts by about (eps/R)^2 / 2.  The limit keeps that shift
#: within the model's validated frequency accuracy, the 3 % of Table S1: (eps/R)^2 / 2 <= 0.03, i.e.
#: eps/R <= 0.245, rounded to 0.25 (cap volume error (eps/R)^2/3 = 2 %).  Beyond it the resonance, the
#: phase and the V^2 force laws (paper Eq. 3) no longer hold; the paper's measured deflections are
#: quadratic in V (Fig. 2c), i.e. its bubbles were linear.
LINEAR_AMPLITUDE_LIMIT = 0.25

#: Number of axisymmetric membrane shapes per interface in the Rayleigh-Ritz model: the first
#: frequency at 3 shapes is within 0.001 % of 8 shapes over the Fig. 1e range
#: (tests/test_physics_resonance.py checks 0.2 %).
DEFAULT_MEMBRANE_MODES = 3

#: The measured / first-principles ratio of the pair (secondary Bjerknes) force, one row per measured pair of the
#: paper (its source, the ratio): the paper's Eq. (3) alpha 174.5 nN um^2/V^2 fitted on Fig. 4e over acl's
#: first-principles alpha of examples/fig4_facing_pair.acl at the two ends of that figure's gaps, and the paper's
#: Fig. 5b beta 745.6 (Supplementary Note 3) over acl's of examples/fig5a_gripper.acl (stdlib
#: calibrations.gripper_pair_factor).  stdlib/calibrations.acl lists the same rows; tests/test_pair_scale_spread.py
#: recomputes each ratio from acl's analysis (within 1 %) and keeps the stdlib's rows and figures equal to these.
PAIR_SCALE_ROWS = (
    ("Fig. 4e pair, 20 um", 3.25),        # paper Eq. (3) alpha / acl's first-principles alpha at a 20 um gap
    ("Fig. 4e pair, 80 um", 1.86),        # the same at 80 um
    ("Fig. 5b gripper", 14.985),          # paper beta (Supplementary Note 3) / acl's first-principles beta
)


def _log_normal_of_rows() -> tuple[float, float]:
    """(mean, sd with n - 1) of the natural logs of PAIR_SCALE_ROWS: the log-normal fitted to the ratios."""
    from statistics import fmean, stdev

    logs = [math.log(r) for _, r in PAIR_SCALE_ROWS]
    return fmean(logs), stdev(logs)


#: The log-normal fitted to PAIR_SCALE_ROWS (log mean and log sd with n - 1): a DESCRIPTION of the measured ratios, the
#: range acl lint calls plausible for a declared bjerknes_scale (acl.physics.effect_table); median exp(mean) = 4.49,
#: every measured pair attracted harder than first principles.
PAIR_SCALE_LOG_MEAN, PAIR_SCALE_LOG_SD = _log_normal_of_rows()

#: The median of that log-normal (stdlib calibrations.first_principles_pair_scale_median, rounded there).
FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN = math.exp(PAIR_SCALE_LOG_MEAN)

#: The spread `acl compile`'s bands and `acl sweep`'s yield interval draw for a pair no bjerknes_scale calibrates is the
#: PREDICTIVE distribution of the next pair's log ratio, not the fitted log-normal: with the log sd estimated from 3
#: rows, ln s = mean + sd sqrt(1 + 1/n) T, T Student t with n - 1 = 2 degrees of freedom (the prediction interval of a
#: normal sample, e.g. Hahn & Meeker, Statistical Intervals, 1991, sec. 4.5).  Its 95 % range, 0.021-961x, is 26x wider
#: at the top than the known-sd log-normal's 0.54-37x, which would be an optimistic margin.  It is truncated to
#: PAIR_SCALE_BOUNDS, the ratios at which acl's coupled-bubble force is no model at all (1000x on a force, 30x on each
#: volume amplitude: bjerknes_scale.factor's hard range, acl.physics.effect_table): 95 % range 0.051-180x.
PAIR_SCALE_DOF = len(PAIR_SCALE_ROWS) - 1
PAIR_SCALE_PREDICTIVE_LOG_SCALE = PAIR_SCALE_LOG_SD * math.sqrt(1.0 + 1.0 / len(PAIR_SCALE_ROWS))
PAIR_SCALE_BOUNDS = (1e-3, 1e3)
PAIR_SCALE_DISTRIBUTION = (f"predictive log-Student-t ({PAIR_SCALE_DOF} dof) of {len(PAIR_SCALE_ROWS)} measured ratios, "
                           f"truncated to {PAIR_SCALE_BOUNDS[0]:g}-{PAIR_SCALE_BOUNDS[1]:g}x")


def student_t_cdf(t: float, dof: int) -> float:
    """Student t CDF: closed forms for 1 and 2 degrees of freedom (Johnson, Kotz & Balakrishnan vol. 2, ch. 28), scipy beyond."""
    if dof == 1:
        return 0.5 + math.atan(t) / math.pi
    if dof == 2:
        return 0.5 + t / (2.0 * math.sqrt(2.0 + t * t))
    from scipy.stats import t as student

    return float(student.cdf(t, dof))


def student_t_quantile(p: float, dof: int) -> float:
    """Inverse of :func:`student_t_cdf` (closed forms for 1 and 2 dof: Hill, Comm. ACM 13, 617 (1970)), scipy beyond."""
    if dof == 1:
        return math.tan(math.pi * (p - 0.5))
    if dof == 2:
        return (2.0 * p - 1.0) / math.sqrt(2.0 * p * (1.0 - p))
    from scipy.stats import t as student

    return float(student.ppf(p, dof))


def _predictive_cdf_of_scale(s: float) -> float:
    return student_t_cdf((math.log(s) - PAIR_SCALE_LOG_MEAN) / PAIR_SCALE_PREDICTIVE_LOG_SCALE, PAIR_SCALE_DOF)


def pair_scale_from_uniform(u):
    """The first-principles pair scale(s) at uniform probability(ies) ``u`` in (0, 1): the truncated predictive
    log-Student-t above (inverse CDF), so ``u`` uniform draws it and ``u`` = p gives its p quantile."""
    import numpy as np

    lo, hi = (_predictive_cdf_of_scale(b) for b in PAIR_SCALE_BOUNDS)
    q = lo + np.asarray(u, float) * (hi - lo)
    t = np.vectorize(lambda x: student_t_quantile(float(x), PAIR_SCALE_DOF), otypes=[float])(q)
    return np.exp(PAIR_SCALE_LOG_MEAN + PAIR_SCALE_PREDICTIVE_LOG_SCALE * t)


def pair_scale_cdf(s: float) -> float:
    """P(scale <= ``s``) under the first-principles pair-scale spread (:func:`pair_scale_from_uniform`'s inverse)."""
    lo, hi = (_predictive_cdf_of_scale(b) for b in PAIR_SCALE_BOUNDS)
    if s <= PAIR_SCALE_BOUNDS[0]:
        return 0.0
    if s >= PAIR_SCALE_BOUNDS[1]:
        return 1.0
    return (_predictive_cdf_of_scale(s) - lo) / (hi - lo)


def pair_scale_quantile(p: float) -> float:
    """The ``p`` quantile of the first-principles pair-scale spread (:func:`pair_scale_from_uniform`)."""
    return float(pair_scale_from_uniform(p))


def pair_ratio_fit_quantile(p: float) -> float:
    """The ``p`` quantile of the log-normal fitted to PAIR_SCALE_ROWS (PAIR_SCALE_LOG_MEAN, PAIR_SCALE_LOG_SD): the
    measured ratios' own range (acl lint's plausible bjerknes_scale), not the spread a prediction carries."""
    from statistics import NormalDist

    return math.exp(PAIR_SCALE_LOG_MEAN + PAIR_SCALE_LOG_SD * NormalDist().inv_cdf(p))
