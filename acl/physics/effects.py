"""Formulas of the effect library (docs/fit.md), shared by the fit's forward model and the analysis.

Pure numpy, SI.  :mod:`acl.fit.forward` applies them row-wise to measured data;
:mod:`acl.analysis.acoustics` and :mod:`acl.analysis.mechanics` apply them to a design that declares
``effect ID { ... }``.  One implementation of each formula, its source in its docstring.
"""
from __future__ import annotations

import numpy as np

from acl.physics import cantilever as CB


def gain_tilt(f, f_ref, slope):
    """Pressure gain factor exp(s (f - f_ref)/f_ref), held beyond 2 f_ref: smooth tilt of the transducer transfer function (paper Fig. S1)."""
    # A tilt is a smooth deviation across the transducer's band, narrower than an octave (85 .. 150 kHz in Fig. S1):
    # beyond f = 2 f_ref it is held (like the table, flat outside it), so exp never overflows at the analysis'
    # out-of-band frequencies (a 20 .. 400 kHz selectivity sweep, coupled modes in MHz); f >= 0 keeps the
    # relative offset >= -1 already.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        x = np.minimum(np.asarray(f, float) / f_ref - 1.0, 1.0)
    return np.exp(slope * x)


def saturation(vtot, inv_vsat2):
    """Pressure factor 1/sqrt(1 + (V/V_s)^2) of a saturating drive (soft limiter; paper Fig. 2e is its linear part)."""
    return 1.0 / np.sqrt(1.0 + inv_vsat2 * vtot * vtot)


def transducer_resonance(f, f_ref, inv_ratio, q):
    """Pressure gain |H(f)|/|H(f_ref)| of a second-order transducer resonance H = 1/(1 - (f/f_t)^2 + i f/(f_t Q_t)), u = f_ref/f_t (u = 0: flat; Kinsler et al., Fundamentals of Acoustics, driven oscillator)."""
    def h2(x):
        a = inv_ratio * x / f_ref
        return 1.0 / ((1.0 - a * a) ** 2 + (a / q) ** 2)
    return np.sqrt(h2(f) / h2(f_ref))


def mode_response_ratio(f, fn0, q0, fn, q):
    """|H(f; f_n, Q)|^2 / |H(f; f_n0, Q0)|^2 of the first bubble mode (one-mode term of acl.physics.resonance.volume_response)."""
    def h2(fr, qq):
        return 1.0 / ((fr * fr - f * f) ** 2 + (f * fr / qq) ** 2)
    return h2(fn, q) / h2(fn0, q0)


def shrunk_frequency(fn0, volume, radius, density, surface_tension, ambient_pressure, polytropic_index, rate, t):
    """First natural frequency after the gas volume shrank to V0 exp(-r t): f_n0 f(V(t))/f(V0) with f the Rayleigh-Ritz resonance of acl.physics.resonance (paper Fig. 1e model)."""
    from acl.physics.resonance import single_orifice_frequencies

    ok = volume > 0
    v0 = np.where(ok, volume, 1.0)
    r = np.where(ok, radius, 1.0)
    args = (density, surface_tension, ambient_pressure, polytropic_index)
    f0 = single_orifice_frequencies(v0, r, *args)
    ft = single_orifice_frequencies(v0 * np.exp(-rate * t), r, *args)
    return np.where(ok, fn0 * ft / f0, fn0)


def volume_frequency_table(volume, radius, density, surface_tension, ambient_pressure, polytropic_index, n=241, span=8.0):
    """(ln x, ln f(x V0)/f(V0)) on x in [e^-span, e^span]: the first natural frequency of a single-orifice capsule vs its
    gas volume (acl.physics.resonance.single_orifice_frequencies, paper Fig. 1e model), for fast interpolation."""
    from acl.physics.resonance import single_orifice_frequencies

    lx = np.linspace(-span, span, n)
    f = single_orifice_frequencies(volume * np.exp(lx), radius, density, surface_tension, ambient_pressure,
                                   polytropic_index)
    f0 = single_orifice_frequencies(volume, radius, density, surface_tension, ambient_pressure, polytropic_index)
    return lx, np.log(f / f0)


def capsule_volume_frequency_table(volume, radii, target_hz, density, surface_tension, ambient_pressure, polytropic_index,
                                   n=241, span=8.0):
    """(ln x, ln f_k(x V0)/f_k(V0)) of the undamped mode k of a multi-orifice capsule nearest ``target_hz`` at V0, vs the
    gas volume (Rayleigh-Ritz K x = w^2 M x, acl.physics.resonance.capsule_matrices; k kept by its rank), for shrinkage."""
    from scipy.linalg import eigh

    from acl.physics.resonance import capsule_matrices

    def freqs(v):
        k, m, _, _ = capsule_matrices(v, radii, density, surface_tension, ambient_pressure, polytropic_index)
        return np.sqrt(np.abs(eigh(k, m, eigvals_only=True))) / (2 * np.pi)

    mode = int(np.argmin(np.abs(np.log(freqs(volume) / target_hz))))
    lx = np.linspace(-span, span, n)
    f = np.empty(n)
    for i, x in enumerate(lx):
        f[i] = freqs(volume * np.exp(x))[mode]
    f0 = np.interp(0.0, lx, f)
    return lx, np.log(f / f0)


def elastica_blend(d_eq1, d_elastica, weight):
    """(1 - w) paper Eq. (1) + w dead-load elastica (Bisshopp & Drucker 1945): w = 1 is the large-deflection beam."""
    return (1.0 - weight) * d_eq1 + weight * d_elastica


def drag_load(load, delta, inv_plateau):
    """P (1 - delta/delta_p), floored at 0: drag of a neighbour's jet growing with penetration (paper Fig. 5b plateau; phenomenological)."""
    return load * np.clip(1.0 - inv_plateau * delta, 0.0, None)


def bjerknes_gap_factor(d, d_ref, n):
    """Factor (d_ref/d)^n on the secondary Bjerknes force at centre distance d: with n = 0 the monopole d^-2 law (Crum 1975); a measured pair's shape (paper Eq. 3, Fig. S5; calibration)."""
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        return (d_ref / np.asarray(d, float)) ** n


def substrate_factor(z, h):
    """Force factor 1 - exp(-z/h) near a rigid wall (image-source weakening, Leighton, The Acoustic Bubble, ch. 4; phenomenological)."""
    with np.errstate(divide="ignore", over="ignore"):
        return np.where(h > 0, 1.0 - np.exp(-z / np.maximum(h, 1e-300)), 1.0)


def effective_beam_deflection(P, L, l, EI, e_scale=1.0, gradient=0.0, weight=0.0):
    """Load-point deflection of a cantilever with E scaled, E graded along it and the elastica blended (paper Eq. (1), Suppl. Note 2; Bisshopp & Drucker 1945)."""
    ei = EI * e_scale
    c_d, c_t = CB.stiffness_integrals(L, l, ei, gradient)
    d = CB.eq1_deflection(P, l, c_d, c_t)
    if weight:
        d = elastica_blend(d, CB.elastica_deflection(P, L, l, ei), weight)
    return d


def effective_beam_force(delta, L, l, EI, e_scale=1.0, gradient=0.0, weight=0.0):
    """(load P, tangent dP/d delta) giving load-point deflection ``delta``: inverse of :func:`effective_beam_deflection` (Brent, secant tangent)."""
    delta = float(delta)
    if delta <= 0.0:
        d1 = float(effective_beam_deflection(1e-30, L, l, EI, e_scale, gradient, weight))
        return 0.0, 1e-30 / d1
    def defl(p):
        return float(effective_beam_deflection(p, L, l, EI, e_scale, gradient, weight))
    k0 = 1e-30 / defl(1e-30)                       # small-load stiffness
    lo, hi = 0.0, k0 * delta
    d_hi, d_prev = defl(hi), None
    for _ in range(200):                           # Eq. (1) and the elastica stiffen: expand the bracket
        if d_hi >= delta:
            break
        if d_prev is not None and d_hi <= d_prev * (1.0 + 1e-12):
            # the law saturated (the elastica near its reach): delta is beyond it; a wall as stiff as 200 doublings
            # would give, found without the 200 evaluations (a soft beam made every solve take seconds)
            P = k0 * delta * 2.0 ** 200
            return P, P / delta
        lo, hi, d_prev = hi, 2.0 * hi, d_hi
        d_hi = defl(hi)
    if d_hi >= delta:
        from scipy.optimize import brentq           # ~10 evaluations where bisection to 1e-13 took ~45

        P = float(brentq(lambda p: defl(p) - delta, lo, hi, xtol=1e-300, rtol=1e-13))
    else:
        P = hi
    if not P > 0.0:
        return P, k0
    for rel in (1e-6, 1e-4, 1e-2):                 # a saturated law (the full elastica near its reach) is flat in
        h = rel * P                                # double precision at a small step: widen it, never divide by 0
        dd = defl(P + h) - defl(P - h)
        if dd > 0.0:
            return P, 2 * h / dd
    return P, max(P / delta, k0)                   # still flat: the secant from the origin (finite, stiff)


# ------------------------------------------------------------------------------------------------
# The one table of declared effects (``effect ID { coefficient = quantity, ... }``).  Every package reads
# it: the design stage (names, units, domains, ranges: acl.design.core), the analysis (nulls, aliases,
# where each acts: acl.analysis.effects), sweep (which effects leave the rest forces or the latch law as
# they are), fit and synth (aliases, examples).  The fit's own library (acl.fit.effects: search bounds,
# starts, the data that identify each effect) covers the effects the fit can search, each named here.
# ------------------------------------------------------------------------------------------------

import math  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from typing import Callable, Optional  # noqa: E402


@dataclass(frozen=True)
class EffectRange:
    """The admissible range of one effect coefficient (SI): outside [lo, hi] it is no physical value (E401);
    outside [plausible_lo, plausible_hi] it is finite and analysable but not plausible (W402).  ``why`` says why."""
    lo: float
    hi: float
    plausible_lo: float
    plausible_hi: float
    why: str


@dataclass(frozen=True)
class Coefficient:
    """One coefficient of an effect: SI unit ('' a plain number), value at which the effect vanishes, sign domain
    ("positive", "nonneg", "unit" 0..1, None any), admissible range; an alias names the internal coefficient it
    sets and the conversion."""
    name: str
    unit: str
    null: float = math.nan
    domain: Optional[str] = None
    range: Optional[EffectRange] = None
    alias_of: Optional[str] = None
    to_internal: Optional[Callable] = None


@dataclass(frozen=True)
class EffectSpec:
    """A declared effect: its coefficients, where it acts, and how the stages treat it."""
    name: str
    coefficients: tuple
    acts_on: str                          # where the analysis applies it (its note)
    static_note: str = ""                 # non-empty: it does not change static predictions, and why
    rest_neutral: bool = False            # leaves the acoustic forces at rest unchanged
    latch_neutral: bool = False           # leaves the latch law unchanged
    beam_law: bool = False                # changes the beams' force law (acl.analysis.mechanics)
    example: str = ""                     # a planted value for `acl synth --effect` (its help)

    def internal(self) -> tuple:
        return tuple(c for c in self.coefficients if c.alias_of is None)


def _inv2(v):
    return 1.0 / (v * v) if v > 0 else 0.0


def _inv(v):
    return 1.0 / v if v > 0 else 0.0


# Bounds shared by several coefficients (each justified where it is used below).
GAIN_BOUND = 1e3          # a transducer pressure factor beyond 1e3 (60 dB) either way is not the declared transducer
TILT_BOUND = math.log(GAIN_BOUND)   # |gain_slope|: the tilt is held beyond 2 f_ref (gain_tilt)
MODULUS_DECADES = 6.0     # a polymer network's modulus spans at most ~6 decades (a gel's kPa to a glass's GPa)
GRADIENT_BOUND = 2.0 * MODULUS_DECADES * math.log(10)   # |e_gradient|: the modulus at the 50 um reference's clamp end
GRADIENT_REFERENCE = 50e-6   # m: stiffness_gradient's length scale (acl.physics.cantilever.L_REF)
F_REF_RANGE = (1e3, 1e8)  # Hz: the drive frequencies of micro-bubble actuators (Minnaert resonances of 1 mm .. 0.1 um)

_F_REF = EffectRange(*F_REF_RANGE, *F_REF_RANGE,
                     "a frequency of the drive: micro-bubble actuators resonate between kHz (mm bubbles) and 100 MHz")
_E_SCALE = EffectRange(
    1e-3, 1e3, 0.05, 20.0,
    "E/E_declared: a printed polymer's modulus moves by about two decades with its degree of cure; three "
    "decades either way is another material (declare it); plausible: the fit's range (0.05 .. 20)")

EFFECT_TABLE: dict[str, EffectSpec] = {e.name: e for e in [
    EffectSpec("transducer_gain", (
        Coefficient("gain_slope", "", 0.0, None, EffectRange(
            -TILT_BOUND, TILT_BOUND, -4.0, 4.0,
            "the tilt exp(s (f - f_ref)/f_ref), held beyond 2 f_ref, stays within 1/1000 .. 1000 of the table; "
            "plausible: the fit's range (acl/fit/effects.py, -4 .. 4)")),
        Coefficient("f_ref", "Hz", math.nan, "positive", _F_REF),
        Coefficient("gain", "", 1.0, "positive", EffectRange(
            1.0 / GAIN_BOUND, GAIN_BOUND, 0.1, 10.0,
            "a scale on the declared table's pressure per volt: beyond 1000x (60 dB) either way the table is not the "
            "transducer's (declare its own table); forces scale with its square. Plausible: within 20 dB of the table"))),
        "drive pressure (acoustics)", example="gain_slope:0.5"),
    EffectSpec("transducer_resonance", (
        Coefficient("inv_f_ratio", "", 0.0, "nonneg", EffectRange(
            0.0, 100.0, 0.0, 5.0,
            "f_ref/f_t: a transducer resonance more than 100x below f_ref leaves the band on its 1/f^2 tail (no "
            "resonance left to model); plausible: the fit's range (0 .. 5)")),
        Coefficient("gain_q", "", 1.0, "positive", EffectRange(
            1e-3, 1e4, 0.3, 30.0,
            "the transducer's quality factor: no piezoceramic reaches 1e4 (hard PZT ~2000 unloaded, far less in water); "
            "below 1e-3 the response is the damping alone; plausible: the fit's range (0.3 .. 30, a water-loaded "
            "transducer)")),
        Coefficient("f_ref", "Hz", math.nan, "positive", EffectRange(
            *F_REF_RANGE, *F_REF_RANGE, "a frequency of the drive (as transducer_gain's f_ref)"))),
        "drive pressure vs frequency (acoustics)"),
    EffectSpec("drive_saturation", (
        Coefficient("inv_vsat2", "1/V^2", 0.0, "nonneg", EffectRange(
            0.0, 1e6, 0.0, 100.0,
            "1/V_s^2 with V_s >= 1 mV (as v_sat); plausible: the fit's range (<= 100 V^-2, V_s >= 0.1 V)")),
        Coefficient("v_sat", "V", math.nan, "positive", EffectRange(
            1e-3, 1e5, 0.1, 1e4,
            "the voltage where the drive saturates: below 1 mV no drive is linear at all (the table would be wrong, "
            "not saturated); above 100 kV, 10x any transducer's maximum (E502), there is no saturation; plausible: "
            "the fit's range (>= 0.1 V) up to the 10 kV transducer limit"), alias_of="inv_vsat2", to_internal=_inv2)),
        "drive pressure (acoustics; forces no longer scale as V^2)", example="v_sat:8V"),
    EffectSpec("large_deflection", (
        Coefficient("elastica_weight", "", 0.0, "unit", EffectRange(
            0.0, 1.0, 0.0, 1.0, "it blends paper Eq. (1) (0) with the elastica (1)")),),
        "beam force law (mechanics)", rest_neutral=True, latch_neutral=True, example="elastica_weight:1", beam_law=True),
    EffectSpec("stiffness_scale", (
        Coefficient("e_scale", "", 1.0, "positive", _E_SCALE),
        Coefficient("factor", "", math.nan, "positive", EffectRange(1e-3, 1e3, 0.05, 20.0, "E/E_declared (as e_scale)"),
                    alias_of="e_scale", to_internal=float)),
        "Young's modulus of beams and latches (mechanics)", rest_neutral=True, example="e_scale:0.7", beam_law=True),
    EffectSpec("stiffness_gradient", (
        Coefficient("e_gradient", "", 0.0, None, EffectRange(
            -GRADIENT_BOUND, GRADIENT_BOUND, -4.0, 4.0,
            "E(s) = E exp(g (s/50um - 1/2)): beyond g = +-27.6 the modulus of the clamp end of the 50 um reference is "
            "off by more than 6 decades, the span of polymer networks (each beam is checked over its own length too); "
            "plausible: the fit's range (-4 .. 4)")),),
        "beam force law (mechanics)", rest_neutral=True, latch_neutral=True, example="e_gradient:0.7", beam_law=True),
    EffectSpec("offset_drift", (
        Coefficient("offset", "m", 0.0, None, EffectRange(
            -1.0, 1.0, -1e-3, 1e-3,
            "an offset of the observation beyond 1 m is outside any print volume (E414); plausible: a field of view "
            "(1 mm)")),
        Coefficient("drift", "m/s", 0.0, None, EffectRange(
            -1.0, 1.0, -1e-5, 1e-5,
            "an observation drifting 1 m/s leaves any microscope field of view (< 1 mm) within 1 ms: no measurement; "
            "plausible: stage and focus drift are nm/s .. 100 nm/s, 10 um/s crosses a 50 um device in 5 s"))),
        "the observation (a measurement artefact)",
        static_note="a measurement artefact (offset and drift of the observation), not a property of the device",
        rest_neutral=True, latch_neutral=True, example="offset:0.5um,drift:10nm/s"),
    EffectSpec("bubble_shrinkage", (
        Coefficient("shrink_rate", "1/s", 0.0, "nonneg", EffectRange(
            0.0, 100.0, 0.0, 1.0,
            "the gas volume's rate: a free 10 um air bubble dissolves in about 1 s (Epstein & Plesset 1950), a trapped "
            "one slower; at 100/s the bubble is gone within a ramp's first step; plausible: <= 1/s")),),
        "the resonance over time",
        static_note="time-dependent (the bubble loses gas after filling); the analysis is at t = 0",
        rest_neutral=True, latch_neutral=True, example="shrink_rate:0.01Hz"),
    EffectSpec("neighbour_drag", (
        Coefficient("inv_plateau", "1/m", 0.0, "nonneg", EffectRange(
            0.0, 1e9, 0.0, 5e6, "1/plateau with plateau >= 1 nm (as plateau; the fit's range 0 .. 1e9 /m)")),
        Coefficient("plateau", "m", math.nan, "positive", EffectRange(
            1e-9, 1.0, 0.2e-6, 1e-3,
            "the displacement where the drag stops the actuator: below 1 nm it is blocked (declare an anchor), beyond "
            "1 m it is outside any print volume; plausible: the printable resolution (0.2 um) to a field of view "
            "(1 mm)"), alias_of="inv_plateau", to_internal=_inv)),
        "force on each capsule with a neighbour (named with it in a gap observe) vs its displacement (acoustics)",
        rest_neutral=True, latch_neutral=True, example="plateau:5um"),
    EffectSpec("substrate_proximity", (
        Coefficient("h_substrate", "m", 0.0, "nonneg", EffectRange(
            0.0, 1.0, 0.0, 1e-3,
            "the decay length of the wall's weakening: beyond 1 m (any print volume) every force vanishes; plausible: "
            "the fit's range (<= 1 mm, about bubble sizes)")),),
        "thrust, jet drag and Bjerknes forces vs height (acoustics)", example="h_substrate:20um"),
    EffectSpec("bjerknes_scale", (
        Coefficient("factor", "", 1.0, "nonneg", EffectRange(
            0.0, 1e3, 0.1, 10.0,
            "the secondary Bjerknes force relative to the coupled-bubble model (paper Eq. 3's alpha): a model wrong by "
            "1000x on a force (30x on each volume amplitude) is no model; plausible: within 10x")),
        Coefficient("gap_exponent", "", 0.0, None, EffectRange(
            -6.0, 6.0, -2.0, 2.0,
            "the shape (gap_ref/d)^n on the monopole d^-2 law: beyond |n| = 6 the force falls off faster than a "
            "quadrupole's or grows with distance, no pair of bubbles; plausible: within a dipole's correction "
            "(|n| <= 2)")),
        Coefficient("gap_ref", "m", math.nan, "positive", EffectRange(
            1e-9, 1.0, 1e-6, 1e-3,
            "the distance where the shape is 1: between a nm and any print volume; plausible: bubble sizes "
            "(1 um .. 1 mm)"))),
        "secondary Bjerknes force between capsules, x factor (gap_ref/d)^gap_exponent (acoustics): a calibration "
        "of the pair law on measured pairs (paper Eq. 3, Fig. S5; stdlib calibrations), not first principles"),
]}
