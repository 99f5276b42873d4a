"""The library of named physical effects the base model lacks (docs/explanation/fit-effects.md has the full table).

Each :class:`Effect` has a stable identifier, few parameters (internal parametrisation nested in the
base model at its ``null`` value), a physical reason and the kind of data that identifies it.  The
formulas themselves live in :mod:`acl.fit.forward` (one function per effect, each citing its source).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional


@dataclass(frozen=True)
class EffectParam:
    name: str                 # internal name (the fitted coordinate)
    unit: str                 # SI unit of the internal coordinate
    lower: float
    upper: float
    null: float               # value at which the effect vanishes (the base model)
    start: float              # first guess (relative to ``scale`` if ``relative``)
    scale: str = "1"          # "1" | "vmax" | "length" | "time" | "deflection": typical magnitude source
    report: Optional[Callable] = None   # internal value -> (name, value, unit) shown to the user


@dataclass(frozen=True)
class Effect:
    id: str
    params: tuple[EffectParam, ...]
    reason: str
    identified_by: str
    requires: tuple[str, ...] = ()       # "time", "frequencies", "frequencies3", "neighbour", "heights", "lengths"
    starts: tuple[tuple[float, ...], ...] = field(default=())   # extra starting points (in scale units)
    search: bool = True     # tried by the default search; False: fitted only when named (`--effects ID`)


def _inv_sqrt(name, unit):
    return lambda v: (name, (1.0 / math.sqrt(v)) if v > 0 else math.inf, unit)


def _inv(name, unit):
    return lambda v: (name, (1.0 / v) if v > 0 else math.inf, unit)


EFFECTS: dict[str, Effect] = {e.id: e for e in [
    Effect("transducer_gain",
           (EffectParam("gain_slope", "", -4.0, 4.0, 0.0, 0.0),),
           "the transducer's pressure per volt is not the declared table: it tilts with frequency "
           "(p -> p exp(s (f - f_ref)/f_ref))",
           "a frequency sweep (three or more drive frequencies) at known voltages",
           requires=("frequencies",), starts=((0.5,), (-0.5,))),
    Effect("transducer_resonance",
           (EffectParam("inv_f_ratio", "", 0.0, 5.0, 0.0, 1.0,
                        report=lambda v: ("transducer resonance f_t/f_ref", (1.0 / v) if v > 0 else math.inf, "")),
            EffectParam("gain_q", "", 0.3, 30.0, math.nan, 2.0, report=lambda v: ("transducer Q", v, ""))),
           "the transducer (or the chamber) has a broad resonance: its pressure per volt rises then falls with "
           "frequency, p -> p |H(f)|/|H(f_ref)|, H = 1/(1 - (f/f_t)^2 + i f/(f_t Q_t)), which a monotone tilt cannot follow",
           "a frequency sweep (four or more drive frequencies) across the transducer's band",
           requires=("frequencies3",), starts=((0.8, 1.5), (1.25, 1.5), (1.0, 4.0))),
    Effect("drive_saturation",
           (EffectParam("inv_vsat2", "1/V^2", 0.0, 100.0, 0.0, 0.25, scale="vmax",
                        report=_inv_sqrt("v_sat", "V")),),
           "the drive (amplifier, transducer) saturates at high voltage: p = p_lin / sqrt(1 + (V/V_s)^2)",
           "voltage ramps to high voltage at two or more frequencies (saturation depends on V, "
           "not on the deflection reached)",
           starts=((1.0,), (0.05,))),
    Effect("large_deflection",
           (EffectParam("elastica_weight", "", 0.0, 1.0, 0.0, 0.5),),
           "the beam deflects beyond the range of linear beam theory (paper Conclusions): the elastica "
           "stiffens; weight 1 is the full elastica, 0 is paper Eq. (1)",
           "deflections beyond about a third of the beam length, at two or more frequencies"),
    Effect("stiffness_scale",
           (EffectParam("e_scale", "", 0.05, 20.0, 1.0, 1.0, report=lambda v: ("E/E_declared", v, "")),),
           "the printed polymer's Young's modulus differs from the declared one (degree of polymerization)",
           "deflections under forces known independently (thrust coefficient not free); with gamma free "
           "it is not identifiable (delta depends on P/EI only)",
           starts=((0.6,), (1.6,))),
    Effect("stiffness_gradient",
           (EffectParam("e_gradient", "", -4.0, 4.0, 0.0, 0.0,
                        report=lambda v: ("E(top)/E(bottom) over 50 um", math.exp(v), "")),),
           "stiffness varies along the beam (uneven polymerization, paper Conclusions): "
           "E(s) = E exp(g (s/50um - 1/2)), s the height above the clamp",
           "beams of several lengths (set:length); with pedestals of several heights to tell it from "
           "substrate_proximity",
           requires=("lengths",), starts=((0.7,), (-0.7,))),
    Effect("offset_drift",
           (EffectParam("offset", "m", -1e-3, 1e-3, 0.0, 0.0, scale="deflection"),
            EffectParam("drift", "m/s", -1.0, 1.0, 0.0, 0.0, scale="deflection/time")),
           "the measurement has an offset and drifts over time (stage, focus, image registration)",
           "a time column, with rows at zero or several voltages spread over the run",
           requires=("time",)),
    Effect("bubble_shrinkage",
           (EffectParam("shrink_rate", "1/s", 0.0, 10.0, 0.0, 0.2, scale="1/time",
                        report=lambda v: ("volume time constant", (1.0 / v) if v > 0 else math.inf, "s")),),
           "the trapped bubble loses gas (V = V0 exp(-r t), r the volume's rate), so its resonance, computed "
           "for V(t) by the resonance model of the analysis (acl.physics.resonance), drifts away from (or "
           "through) the drive frequency",
           "repeated voltage ramps at a fixed frequency spread over time",
           requires=("time",), starts=((1.0,), (0.05,))),
    Effect("neighbour_drag",
           (EffectParam("inv_plateau", "1/m", 0.0, 1e9, 0.0, 0.5, scale="1/deflection",
                        report=_inv("plateau", "m")),),
           "the actuator moves into a neighbour's streaming jet whose drag grows with the displacement "
           "(paper Fig. 5b plateau, 'drag force applied to the moving actuators by the anchored ones'): "
           "P -> P (1 - |delta|/delta_p), on each side of a pair; a lone actuator has no neighbour in the model "
           "(capsules of different units do not interact), so it is not dragged",
           "a pair ramped into the plateau, with an isolated calibration actuator in the same data set to tell it "
           "from drive saturation (the calibration actuator sees the drive but no neighbour)",
           requires=("neighbour",), starts=((1.0,), (0.1,))),
    Effect("substrate_proximity",
           (EffectParam("h_substrate", "m", 0.0, 1e-3, 0.0, 0.4, scale="height"),),
           "acoustic forces are weakened near the substrate (bubble-wall interaction, paper Fig. 2a): "
           "F -> F (1 - exp(-z/h))",
           "actuators at several heights above the substrate (set:pedestal or set:length)",
           requires=("heights",), starts=((0.15,), (1.0,))),
    Effect("bjerknes_scale",
           (EffectParam("factor", "", 0.05, 20.0, 1.0, 1.0, report=lambda v: ("Bjerknes force / predicted", v, "")),),
           "the secondary Bjerknes force between capsules differs from the monopole prediction by a constant factor "
           "(the same declared effect as the analysis, acl.analysis.effects; paper Eq. 3's fitted alpha against the "
           "physics)",
           "pairs (or groups) at several gaps ramped in voltage; with alpha free it is the same freedom",
           requires=("neighbour",), starts=((0.6,), (1.6,)), search=False),
    Effect("bjerknes_shape",
           (EffectParam("gap_exponent", "", -3.0, 3.0, 0.0, 0.0,
                        report=lambda v: ("Bjerknes force x (40 um / d)^n, n", v, "")),),
           "the secondary Bjerknes force falls off with the orifices' distance d other than the monopole d^-2: "
           "x (d_ref/d)^n, d_ref = 40 um (the analysis' bjerknes_scale gap_exponent / gap_ref; paper Eq. 3 and "
           "Fig. S5 need a free scale and shape)",
           "pairs at several gaps ramped in voltage (with bjerknes_scale, or alpha free, for the scale)",
           requires=("neighbour", "coupled"), starts=((0.5,), (-0.5,)), search=False),
]}

GAP_REF = 40e-6     # m: d_ref of bjerknes_shape, where its factor is 1 (written as the analysis' gap_ref)

# fitted coordinates the calibrated design writes under another effect's coefficient of the analysis
ANALYSIS_NAME = {("bjerknes_shape", "gap_exponent"): ("bjerknes_scale", "gap_exponent")}

SEARCHED = tuple(k for k, e in EFFECTS.items() if e.search)   # the default search (`acl fit` without --effects)


def effect(name: str) -> Effect:
    return EFFECTS[name]


def declared_effects(design) -> dict:
    """The effects ``design`` declares (``effect ID { ... }``) as the fit's effects dict (effect id -> {parameter:
    value}, internal coordinates, acl.analysis.effects.coefficients): the base model the fit starts from.  A declared
    ``bjerknes_scale`` with a shape (gap_exponent n at gap_ref) is the fit's bjerknes_scale and bjerknes_shape, the
    factor taken to the fit's reference distance: factor (gap_ref/d)^n = factor (gap_ref/GAP_REF)^n (GAP_REF/d)^n.
    Effects the fit does not model are left out (the analysis notes them)."""
    from acl.analysis.effects import bjerknes_shape, coefficients

    out: dict = {}
    for eff in getattr(design, "effects", ()) or ():
        if eff.name not in EFFECTS:
            continue
        c = coefficients(design, eff.name)
        if eff.name == "bjerknes_scale":
            n, ref = bjerknes_shape(c)
            out["bjerknes_scale"] = {"factor": float(c["factor"]) * ((ref / GAP_REF) ** n if n else 1.0)}
            if n:
                out["bjerknes_shape"] = {"gap_exponent": float(n)}
            continue
        out[eff.name] = {p.name: float(c[p.name]) for p in EFFECTS[eff.name].params if p.name in c}
    return out
