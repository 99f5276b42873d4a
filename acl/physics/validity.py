"""Validity limits of the acoustic and beam models, each with the evidence it rests on, and the model-form
uncertainty a prediction carries beyond a limit (docs/physics.md, part A section 11).

A limit is *soft* (the model still has a meaning past it: acl warns and widens its bands by
:func:`amplitude_model_form`) or *hard* (the model has no meaning: acl refuses).  Pure numpy on SI floats.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT


@dataclass(frozen=True)
class Limit:
    """One validity limit: its value, whether crossing it leaves the model without meaning, and its evidence."""

    name: str
    value: float
    hard: bool
    code: str           # the located warning (soft) or error (hard) acl gives past it
    evidence: str


#: Interface amplitude eps/R, soft: the linear cap stiffness 2 eps/R^2 departs from the exact 2 eps/(R^2 + eps^2) by
#: (eps/R)^2, so the resonance shifts by ~(3/8)(eps/R)^2 (harmonic balance); 0.25 keeps that inside Table S1's 3 %.
AMPLITUDE = Limit(
    "interface amplitude eps/R", LINEAR_AMPLITUDE_LIMIT, False, "W-ACOUSTIC-AMPLITUDE",
    "theory: the cap curvature 2 eps/(R^2 + eps^2) departs from the linear 2 eps/R^2 by (eps/R)^2, which keeps the "
    "resonance within Table S1's validated 3 % up to eps/R = 0.25; measurements: the paper's interface amplitude is "
    "linear in pressure over the whole range it applied (Fig. 2f) and its thrust quadratic in voltage (Fig. 2c), so "
    "past 0.25 acl warns and widens its bands instead of refusing")

#: Interface amplitude eps/R, hard: the Laplace pressure 4 sigma eps/(R^2 + eps^2) of a pinned spherical cap peaks at
#: the hemisphere eps = R; past it no pinned cap balances a larger pressure: the interface leaves the orifice.
AMPLITUDE_MEANING = Limit(
    "interface amplitude eps/R (hemisphere)", 1.0, True, "E-SCHED-NONLINEAR",
    "Young-Laplace: a pinned cap's pressure 4 sigma eps/(R^2 + eps^2) is largest at the hemisphere eps = R; beyond it "
    "the interface bulges out of the orifice and no oscillation about the pinned rest shape exists")

#: Streaming Reynolds number R_s = omega eps^2/nu of the thrust law (Stokes outer flow), soft.
STREAMING_REYNOLDS = Limit(
    "streaming Reynolds number", 1.0, False, "W-ACOUSTIC-STREAMING",
    "theory: the thrust law's Stokes outer flow needs R_s = omega eps^2/nu < 1 (Stuart 1966; Riley 2001); "
    "measurements: the paper's deflection stays quadratic in voltage (Fig. 2c) at drives where acl's R_s exceeds 1, "
    "so the V^2 law is kept and only warned")

#: Distance between two interfaces over the sum of their radii, soft: the pair forces treat each interface as a point
#: monopole, whose next (dipole/finite-size) term is of relative order ((R_a + R_b)/d)^2.
MONOPOLE_DISTANCE = Limit(
    "monopole distance d/(R_a + R_b)", 2.0, False, "W-ACOUSTIC-MONOPOLE",
    "theory: the finite size of the interfaces corrects the point-monopole coupling and Bjerknes force by terms of "
    "relative order ((R_a + R_b)/d)^2, 25 % at d = 2 (R_a + R_b); no measurement of the paper resolves it")

LIMITS = (AMPLITUDE, AMPLITUDE_MEANING, STREAMING_REYNOLDS, MONOPOLE_DISTANCE)


def resonance_shift(eps_over_r, limit: float = LINEAR_AMPLITUDE_LIMIT):
    """Relative resonance shift (3/8)((eps/R)^2 - limit^2), floored at 0, of a pinned cap past the validated amplitude (Duffing harmonic balance of 2 eps/(R^2 + eps^2))."""
    x = np.asarray(eps_over_r, float)
    return 0.375 * np.clip(x * x - limit * limit, 0.0, None)


def amplitude_model_form(eps_over_r, q, limit: float = LINEAR_AMPLITUDE_LIMIT):
    """Relative model-form uncertainty of a force past the amplitude limit: 1 - 1/(1 + (2 Q s)^2), s = :func:`resonance_shift` (|H|^2 of a mode detuned by s)."""
    s = resonance_shift(eps_over_r, limit)
    a = 2.0 * np.asarray(q, float) * s
    return 1.0 - 1.0 / (1.0 + a * a)


def monopole_model_form(distance, radius_sum):
    """Relative model-form uncertainty ((R_a + R_b)/d)^2 of a point-monopole pair force (finite-size correction order)."""
    return (np.asarray(radius_sum, float) / np.asarray(distance, float)) ** 2


def exceeded(limit: Limit, value) -> np.ndarray:
    """True where ``value`` is beyond ``limit``."""
    return np.asarray(value, float) > limit.value
