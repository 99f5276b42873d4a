"""The one table of declared effects (``effect ID { coefficient = quantity, ... }``), read by every stage.

Pure Python (no numpy), so the design stage and `acl check` load it without the numerics: the design stage
takes names, units, sign domains and admissible ranges from it (acl.design.core), the analysis the nulls,
aliases and where each effect acts (acl.analysis.effects), sweep where its batched evaluation applies each
effect and which leave the forces at rest or the latch law unchanged (acl.sweep.columns), fit and synth the
aliases and examples.  The formulas are in
:mod:`acl.physics.effects`; the fit's search library (acl.fit.effects: bounds, starts, the data that identify
an effect) covers the effects the fit can search, each named here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

from acl.physics.constants import pair_ratio_fit_quantile


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
    sweep: str = ""                       # where the batched sweep applies it (acl.sweep.acoustic_state); "": point by point

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
#: bjerknes_scale.factor's plausible top: the 97.5 % quantile of the log-normal fitted to the measured pair ratios
#: (acl.physics.constants.pair_ratio_fit_quantile; a lint range, not the predictive spread compile draws),
#: rounded up: the paper's Fig. 5b pair alone is 15x first principles, so a 10x top warned on its calibration.
_PAIR_SCALE_PLAUSIBLE_HI = float(math.ceil(pair_ratio_fit_quantile(0.975)))
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
        "drive pressure (acoustics)", example="gain_slope:0.5",
        sweep="PointAcoustics.pressure_factor"),
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
        "drive pressure vs frequency (acoustics)",
        sweep="PointAcoustics.pressure_factor"),
    EffectSpec("drive_saturation", (
        Coefficient("inv_vsat2", "1/V^2", 0.0, "nonneg", EffectRange(
            0.0, 1e6, 0.0, 100.0,
            "1/V_s^2 with V_s >= 1 mV (as v_sat); plausible: the fit's range (<= 100 V^-2, V_s >= 0.1 V)")),
        Coefficient("v_sat", "V", math.nan, "positive", EffectRange(
            1e-3, 1e5, 0.1, 1e4,
            "the voltage where the drive saturates: below 1 mV no drive is linear at all (the table would be wrong, "
            "not saturated); above 100 kV, 10x any transducer's maximum (E502), there is no saturation; plausible: "
            "the fit's range (>= 0.1 V) up to the 10 kV transducer limit"), alias_of="inv_vsat2", to_internal=_inv2)),
        "drive pressure (acoustics; forces no longer scale as V^2)", example="v_sat:8V",
        sweep="PointAcoustics.pressure; snap-in in V^2 sat(V)^2 (PairMechanics.snap_in)"),
    EffectSpec("large_deflection", (
        Coefficient("elastica_weight", "", 0.0, "unit", EffectRange(
            0.0, 1.0, 0.0, 1.0, "it blends paper Eq. (1) (0) with the elastica (1)")),),
        "beam force law (mechanics)", rest_neutral=True, latch_neutral=True, example="elastica_weight:1", beam_law=True,
        sweep="PointAcoustics.beam_law (physics.batch.effective_beam_force)"),
    EffectSpec("stiffness_scale", (
        Coefficient("e_scale", "", 1.0, "positive", _E_SCALE),
        Coefficient("factor", "", math.nan, "positive", EffectRange(1e-3, 1e3, 0.05, 20.0, "E/E_declared (as e_scale)"),
                    alias_of="e_scale", to_internal=float)),
        "Young's modulus of beams and latches (mechanics)", rest_neutral=True, example="e_scale:0.7", beam_law=True,
        sweep="PointAcoustics.e_scale (beams and latches)"),
    EffectSpec("stiffness_gradient", (
        Coefficient("e_gradient", "", 0.0, None, EffectRange(
            -GRADIENT_BOUND, GRADIENT_BOUND, -4.0, 4.0,
            "E(s) = E exp(g (s/50um - 1/2)): beyond g = +-27.6 the modulus of the clamp end of the 50 um reference is "
            "off by more than 6 decades, the span of polymer networks (each beam is checked over its own length too); "
            "plausible: the fit's range (-4 .. 4)")),),
        "beam force law (mechanics)", rest_neutral=True, latch_neutral=True, example="e_gradient:0.7", beam_law=True,
        sweep="PointAcoustics.beam_law (physics.batch.effective_beam_force)"),
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
        rest_neutral=True, latch_neutral=True, example="plateau:5um",
        sweep="PointAcoustics.neighbour_drag"),
    EffectSpec("substrate_proximity", (
        Coefficient("h_substrate", "m", 0.0, "nonneg", EffectRange(
            0.0, 1.0, 0.0, 1e-3,
            "the decay length of the wall's weakening: beyond 1 m (any print volume) every force vanishes; plausible: "
            "the fit's range (<= 1 mm, about bubble sizes)")),),
        "thrust, jet drag and Bjerknes forces vs height (acoustics)", example="h_substrate:20um",
        sweep="PointAcoustics.substrate"),
    EffectSpec("bjerknes_scale", (
        Coefficient("factor", "", 1.0, "nonneg", EffectRange(
            0.0, 1e3, 0.1, _PAIR_SCALE_PLAUSIBLE_HI,
            "the secondary Bjerknes force relative to the coupled-bubble model (paper Eq. 3's alpha): a model wrong by "
            "1000x on a force (30x on each volume amplitude) is no model; plausible: 0.1x up to the 97.5 % quantile "
            f"({_PAIR_SCALE_PLAUSIBLE_HI:g}x) of the measured / first-principles ratios of the paper's pairs "
            "(1.86 .. 15, acl.physics.constants.PAIR_SCALE_ROWS)")),
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
        "of the pair law on measured pairs (paper Eq. 3, Fig. S5; stdlib calibrations), not first principles",
        sweep="PointAcoustics.pair_law"),
]}
