"""The design stage's shared core: the failure signal, declaration kinds, key schemas, wording.

Everything else in :mod:`acl.design` builds on this module and it imports none of them: the stage
runs one way, core -> :mod:`~acl.design.evaluate` (expressions, parameters, blocks) ->
:mod:`~acl.design.builders` (one model per declaration) -> :mod:`~acl.design.programs` ->
:mod:`~acl.design.assemble` (the Design) -> :mod:`~acl.design.resolve` (the public ``load``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from acl.design.values import CallVal, DeclVal, DirVal, IdentVal, ListVal, RangeVal, StrVal, VecVal
from acl.units import Quantity, describe, parse_unit_static, si_unit


# One polytropic default for every medium: the physics constant (isothermal, 1.0; justified in
# docs/physics.md part A section 1 and acl.physics.constants.MediumConstants).
from acl.physics.constants import WATER_20C as _WATER  # noqa: E402

_POLYTROPIC_DEFAULT = _WATER.polytropic_index


class Fail(Exception):
    """Evaluation of one expression failed; the diagnostic is already recorded."""


DECL_KINDS = ("medium", "material", "transducer", "generator", "amplifier", "capsule", "beam", "spring", "truss", "latch",
              "anchor", "effect")

# Effects of the model library (docs/fit.md); `effect NAME { coefficient = quantity, ... }`.
EFFECTS = ("transducer_gain", "transducer_resonance", "drive_saturation", "large_deflection", "stiffness_scale", "stiffness_gradient",
           "offset_drift", "bubble_shrinkage", "neighbour_drag", "substrate_proximity", "bjerknes_scale")

D = parse_unit_static
LENGTH, FREQ, VOLT, TIME = D("m"), D("Hz"), D("V"), D("s")
_ONE = D("")

# The unit of each known effect coefficient (acl/fit/effects.py's SI units, plus the user-facing
# aliases v_sat, plateau and factor, and transducer_gain's f_ref and gain): another dimension is E301
# (`v_sat = 8 um` is not a saturation voltage).  Coefficients not listed are left to the analysis' note.
EFFECT_UNITS = {
    "transducer_gain": {"gain_slope": ("", _ONE), "f_ref": ("Hz", FREQ), "gain": ("", _ONE)},
    "transducer_resonance": {"inv_f_ratio": ("", _ONE), "gain_q": ("", _ONE), "f_ref": ("Hz", FREQ)},
    "drive_saturation": {"inv_vsat2": ("1/V^2", tuple(-2 * x for x in VOLT)), "v_sat": ("V", VOLT)},
    "large_deflection": {"elastica_weight": ("", _ONE)},
    "stiffness_scale": {"e_scale": ("", _ONE), "factor": ("", _ONE)},
    "stiffness_gradient": {"e_gradient": ("", _ONE)},
    "offset_drift": {"offset": ("m", LENGTH), "drift": ("m/s", D("m/s"))},
    "bubble_shrinkage": {"shrink_rate": ("1/s", FREQ)},
    "neighbour_drag": {"inv_plateau": ("1/m", tuple(-x for x in LENGTH)), "plateau": ("m", LENGTH)},
    "substrate_proximity": {"h_substrate": ("m", LENGTH)},
    "bjerknes_scale": {"factor": ("", _ONE), "gap_exponent": ("", _ONE), "gap_ref": ("m", LENGTH)},
}

# The physical range of effect coefficients (E401 outside it): "positive" (> 0), "nonneg" (>= 0), "unit" (0 .. 1).
# A pressure scale, a modulus scale, a frequency, a saturation voltage, a plateau length, a quality factor are
# positive; a rate, an inverse square voltage, a height, a Bjerknes factor may be 0 (the effect vanishes);
# the elastica weight blends two force laws.  Not listed (gain_slope, e_gradient, offset, drift): any sign.
EFFECT_DOMAIN = {
    ("transducer_gain", "gain"): "positive", ("transducer_gain", "f_ref"): "positive",
    ("transducer_resonance", "inv_f_ratio"): "nonneg", ("transducer_resonance", "gain_q"): "positive",
    ("transducer_resonance", "f_ref"): "positive",
    ("drive_saturation", "inv_vsat2"): "nonneg", ("drive_saturation", "v_sat"): "positive",
    ("large_deflection", "elastica_weight"): "unit",
    ("stiffness_scale", "e_scale"): "positive", ("stiffness_scale", "factor"): "positive",
    ("bubble_shrinkage", "shrink_rate"): "nonneg",
    ("neighbour_drag", "inv_plateau"): "nonneg", ("neighbour_drag", "plateau"): "positive",
    ("substrate_proximity", "h_substrate"): "nonneg",
    ("bjerknes_scale", "factor"): "nonneg", ("bjerknes_scale", "gap_ref"): "positive",
}



@dataclass(frozen=True)
class EffectRange:
    """The admissible range of one effect coefficient (SI): outside [lo, hi] it is no physical value (E401);
    outside [plausible_lo, plausible_hi] it is finite and analysable but not plausible (W402).  ``why`` says why."""
    lo: float
    hi: float
    plausible_lo: float
    plausible_hi: float
    why: str


# Bounds shared by several coefficients (each justified where it is used below).
GAIN_BOUND = 1e3          # a transducer pressure factor beyond 1e3 (60 dB) either way is not the declared transducer
TILT_BOUND = math.log(GAIN_BOUND)   # |gain_slope|: the tilt is held beyond 2 f_ref (acl.physics.effects.gain_tilt)
MODULUS_DECADES = 6.0     # a polymer network's modulus spans at most ~6 decades (a gel's kPa to a glass's GPa)
GRADIENT_BOUND = 2.0 * MODULUS_DECADES * math.log(10)   # |e_gradient|: the modulus at the 50 um reference's clamp end
GRADIENT_REFERENCE = 50e-6   # m: stiffness_gradient's length scale (acl.physics.cantilever.L_REF)
F_REF_RANGE = (1e3, 1e8)  # Hz: the drive frequencies of micro-bubble actuators (Minnaert resonances of 1 mm .. 0.1 um)

# The admissible range of every known effect coefficient (checked by acl.design.assemble._effect; the fit's
# bounds in acl/fit/effects.py lie inside every hard range, so a calibrated design written by `acl fit`
# is accepted; tests/test_effect_ranges.py).  A coefficient at its null value always lies inside.
EFFECT_RANGES = {
    ("transducer_gain", "gain"): EffectRange(
        1.0 / GAIN_BOUND, GAIN_BOUND, 0.1, 10.0,
        "a scale on the declared table's pressure per volt: beyond 1000x (60 dB) either way the table is not the "
        "transducer's (declare its own table); forces scale with its square. Plausible: within 20 dB of the table"),
    ("transducer_gain", "gain_slope"): EffectRange(
        -TILT_BOUND, TILT_BOUND, -4.0, 4.0,
        "the tilt exp(s (f - f_ref)/f_ref), held beyond 2 f_ref, stays within 1/1000 .. 1000 of the table; "
        "plausible: the fit's range (acl/fit/effects.py, -4 .. 4)"),
    ("transducer_gain", "f_ref"): EffectRange(
        *F_REF_RANGE, *F_REF_RANGE,
        "a frequency of the drive: micro-bubble actuators resonate between kHz (mm bubbles) and 100 MHz"),
    ("transducer_resonance", "inv_f_ratio"): EffectRange(
        0.0, 100.0, 0.0, 5.0,
        "f_ref/f_t: a transducer resonance more than 100x below f_ref leaves the band on its 1/f^2 tail (no resonance "
        "left to model); plausible: the fit's range (0 .. 5)"),
    ("transducer_resonance", "gain_q"): EffectRange(
        1e-3, 1e4, 0.3, 30.0,
        "the transducer's quality factor: no piezoceramic reaches 1e4 (hard PZT ~2000 unloaded, far less in water); "
        "below 1e-3 the response is the damping alone; plausible: the fit's range (0.3 .. 30, a water-loaded transducer)"),
    ("transducer_resonance", "f_ref"): EffectRange(
        *F_REF_RANGE, *F_REF_RANGE, "a frequency of the drive (as transducer_gain's f_ref)"),
    ("drive_saturation", "v_sat"): EffectRange(
        1e-3, 1e5, 0.1, 1e4,
        "the voltage where the drive saturates: below 1 mV no drive is linear at all (the table would be wrong, not "
        "saturated); above 100 kV, 10x any transducer's maximum (E502), there is no saturation; plausible: the "
        "fit's range (>= 0.1 V) up to the 10 kV transducer limit"),
    ("drive_saturation", "inv_vsat2"): EffectRange(
        0.0, 1e6, 0.0, 100.0, "1/V_s^2 with V_s >= 1 mV (as v_sat); plausible: the fit's range (<= 100 V^-2, V_s >= 0.1 V)"),
    ("large_deflection", "elastica_weight"): EffectRange(
        0.0, 1.0, 0.0, 1.0, "it blends paper Eq. (1) (0) with the elastica (1)"),
    ("stiffness_scale", "e_scale"): EffectRange(
        1e-3, 1e3, 0.05, 20.0,
        "E/E_declared: a printed polymer's modulus moves by about two decades with its degree of cure; three "
        "decades either way is another material (declare it); plausible: the fit's range (0.05 .. 20)"),
    ("stiffness_scale", "factor"): EffectRange(1e-3, 1e3, 0.05, 20.0, "E/E_declared (as e_scale)"),
    ("stiffness_gradient", "e_gradient"): EffectRange(
        -GRADIENT_BOUND, GRADIENT_BOUND, -4.0, 4.0,
        "E(s) = E exp(g (s/50um - 1/2)): beyond g = +-27.6 the modulus of the clamp end of the 50 um reference is "
        "off by more than 6 decades, the span of polymer networks (each beam is checked over its own length too); "
        "plausible: the fit's range (-4 .. 4)"),
    ("offset_drift", "offset"): EffectRange(
        -1.0, 1.0, -1e-3, 1e-3,
        "an offset of the observation beyond 1 m is outside any print volume (E414); plausible: a field of view (1 mm)"),
    ("offset_drift", "drift"): EffectRange(
        -1.0, 1.0, -1e-5, 1e-5,
        "an observation drifting 1 m/s leaves any microscope field of view (< 1 mm) within 1 ms: no measurement; "
        "plausible: stage and focus drift are nm/s .. 100 nm/s, 10 um/s crosses a 50 um device in 5 s"),
    ("bubble_shrinkage", "shrink_rate"): EffectRange(
        0.0, 100.0, 0.0, 1.0,
        "the gas volume's rate: a free 10 um air bubble dissolves in about 1 s (Epstein & Plesset 1950), a trapped "
        "one slower; at 100/s the bubble is gone within a ramp's first step; plausible: <= 1/s"),
    ("neighbour_drag", "plateau"): EffectRange(
        1e-9, 1.0, 0.2e-6, 1e-3,
        "the displacement where the drag stops the actuator: below 1 nm it is blocked (declare an anchor), beyond "
        "1 m it is outside any print volume; plausible: the printable resolution (0.2 um) to a field of view (1 mm)"),
    ("neighbour_drag", "inv_plateau"): EffectRange(
        0.0, 1e9, 0.0, 5e6, "1/plateau with plateau >= 1 nm (as plateau; the fit's range 0 .. 1e9 /m)"),
    ("substrate_proximity", "h_substrate"): EffectRange(
        0.0, 1.0, 0.0, 1e-3,
        "the decay length of the wall's weakening: beyond 1 m (any print volume) every force vanishes; plausible: "
        "the fit's range (<= 1 mm, about bubble sizes)"),
    ("bjerknes_scale", "factor"): EffectRange(
        0.0, 1e3, 0.1, 10.0,
        "the secondary Bjerknes force relative to the coupled-bubble model (paper Eq. 3's alpha): a model wrong by "
        "1000x on a force (30x on each volume amplitude) is no model; plausible: within 10x"),
    ("bjerknes_scale", "gap_exponent"): EffectRange(
        -6.0, 6.0, -2.0, 2.0,
        "the shape (gap_ref/d)^n on the monopole d^-2 law: beyond |n| = 6 the force falls off faster than a "
        "quadrupole's or grows with distance, no pair of bubbles; plausible: within a dipole's correction (|n| <= 2)"),
    ("bjerknes_scale", "gap_ref"): EffectRange(
        1e-9, 1.0, 1e-6, 1e-3,
        "the distance where the shape is 1: between a nm and any print volume; plausible: bubble sizes (1 um .. 1 mm)"),
}


# The physical range of declared properties that were only sign-checked (E412 outside it, at the value): absurd
# magnitudes (a medium of 1e300 kg/m^3, a surface tension of 1e-300 N/m) made the bubble eigenproblem fail
# (LinAlgError) or the analyses overflow.  (schema, key) -> (lo, hi, why), SI.  A capsule's `thrust` is not
# listed: compile's error band evaluates the design at 1 sigma of a declared `gamma +- s`, and an absurd s must
# stay E-SCHED-UNCERTAINTY there (tests/test_hostile_more.py), not a draw that fails to load.
PROPERTY_RANGES = {
    ("medium", "density"): (1e-3, 3e4, "from a rarefied gas (1e-3 kg/m^3) to beyond mercury (13.5e3) and osmium (22.6e3)"),
    ("medium", "viscosity"): (1e-6, 1e3, "from below any gas (hydrogen 8.8 uPa*s) to a polymer melt (1 kPa*s)"),
    ("medium", "sound_speed"): (50.0, 2e4, "from a heavy gas (SF6 136 m/s) to beyond diamond (18 km/s)"),
    ("medium", "surface_tension"): (1e-4, 3.0, "from liquid helium (0.37 mN/m) to molten metals (about 2 N/m)"),
    ("medium", "pressure"): (1e2, 1e8, "from near vacuum (100 Pa) to the deepest ocean floor (about 110 MPa)"),
    ("medium", "thermal_diffusivity"): (1e-7, 1e-2, "a gas's: air 2.1e-5 m^2/s, helium 1.9e-4; 1e-2 only near vacuum"),
    ("material", "youngs"): (1e3, 1.2e12, "from the softest printable gel (1 kPa) to diamond (1.2 TPa), the stiffest solid"),
    ("material", "density"): (1.0, 3e4, "from an aerogel (about 1 kg/m^3) to beyond osmium (22.6e3)"),
    ("capsule", "q"): (0.1, 1e4, "a bubble mode's quality factor: below 0.1 there is no resonance left, above 1e4 no "
                                 "liquid-loaded bubble (radiation and viscous damping alone bound Q to tens)"),
    ("latch", "length"): (1e-7, 1e-2, "a printed flexure: from a voxel (about 100 nm) to 10 mm, beyond any "
                                      "two-photon print field"),
    ("latch", "width"): (1e-7, 1e-2, "a printed flexure: from a voxel (about 100 nm) to 10 mm"),
    ("latch", "thickness"): (1e-7, 1e-2, "a printed flexure: from a voxel (about 100 nm) to 10 mm"),
    ("transducer", "gain"): (0.0, 1e6, "pressure per volt: focused HIFU transducers reach about 1e4 Pa/V; at 1e6 Pa/V "
                                      "water cavitates at 0.1 V"),
}


# ------------------------------------------------------------------------------------------------
# Key schemas: key -> (expected kind, dimension unit or None, required, default)
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Key:
    kind: str              # "q" quantity, "vec", "dir", "ref:<declkind>", "call", "ident", "table", "range", "any"
    unit: str | None = None
    required: bool = False
    default: object = None
    doc: str = ""


SCHEMAS: dict[str, dict[str, Key]] = {
    "medium": {
        "density": Key("q", "kg/m^3", True), "viscosity": Key("q", "Pa*s", True),
        "sound_speed": Key("q", "m/s", True), "surface_tension": Key("q", "N/m", True),
        "pressure": Key("q", "Pa", False, 101325.0), "polytropic": Key("q", "", False, _POLYTROPIC_DEFAULT),
        "thermal_diffusivity": Key("q", "m^2/s", False, 2.1e-5),
    },
    "material": {
        "youngs": Key("q", "Pa", True), "poisson": Key("q", "", False, 0.49),
        "density": Key("q", "kg/m^3", False, 1100.0),
    },
    "transducer": {
        "max_voltage": Key("q", "V", True), "band": Key("range", "Hz", True),
        "gain": Key("table", None, True), "gain_uncertainty": Key("q", "", False, None),
    },
    # the drive chain between a schedule and the transducer (docs/bench.md): used with `use generator`,
    # `use amplifier`; compile checks every step against it (E501, E502)
    "generator": {
        "max_voltage": Key("q", "V", True), "sample_rate": Key("q", "Hz", False, None),
        "memory": Key("q", "", False, None), "channels": Key("q", "", False, 1.0),
        "max_frequency": Key("q", "Hz", False, None),
    },
    "amplifier": {
        "gain": Key("q", "", True), "max_voltage": Key("q", "V", True), "bandwidth": Key("q", "Hz", False, None),
    },
    "capsule": {
        "center": Key("vec", "m"), "thrust": Key("q", "N/V^2"), "q": Key("q", ""),
    },
    "cavity": {  # nested in capsule; shape-specific keys checked in the builder
        "radius": Key("q", "m"), "height": Key("q", "m"), "side": Key("q", "m"),
        "volume": Key("q", "m^3"), "axis": Key("dir"), "facing": Key("dir"),
        "wall": Key("q", "m", False, 2e-6),
    },
    "orifice": {"radius": Key("q", "m", True), "normal": Key("dir"), "face": Key("any")},
    "beam": {
        "length": Key("q", "m", True), "section": Key("call", None, True), "material": Key("ref:material", None, True),
        "clamp": Key("vec", "m", True), "axis": Key("dir", None, False, (0.0, 0.0, 1.0)), "rigid": Key("q", "m"),
    },
    "spring": {
        "stiffness": Key("q", "N/m"), "axis": Key("dir", None, True), "length": Key("q", "m"),
        "section": Key("call"), "material": Key("ref:material"), "count": Key("q", "", False, 1.0),
    },
    "truss": {"length": Key("q", "m")},
    "latch": {
        "angle": Key("q", "", True), "length": Key("q", "m", True), "width": Key("q", "m", True),
        "thickness": Key("q", "m", True), "material": Key("ref:material", None, True),
        "at": Key("vec", "m", True), "axis": Key("dir", None, True), "state": Key("ident", None, False, "a"),
    },
    "anchor": {"at": Key("vec", "m", True)},
}



IDENTS = {"a", "b", "ground", "top", "bottom", "side"}


def what_is(v) -> str:
    """A value as words for a message: `length [m]`, `a 3-vector`, `the material `tpeta``."""
    if isinstance(v, Quantity):
        return describe(v.dims)
    if isinstance(v, VecVal):
        return f"a {len(v.items)}-vector"
    if isinstance(v, DirVal):
        return "a direction"
    if isinstance(v, DeclVal):
        return f"the {v.kind} `{v.name}`"
    if isinstance(v, CallVal):
        return f"`{v.name}(...)`"
    if isinstance(v, ListVal):
        return "a list"
    if isinstance(v, StrVal):
        return "a string"
    if isinstance(v, IdentVal):
        return f"the word `{v.name}`"
    if isinstance(v, RangeVal):
        return "a range"
    return type(v).__name__


_EXAMPLES = {"m": "40 um", "Hz": "85 kHz", "V": "8 V", "s": "200 ms", "Pa": "13 MPa", "N/m": "0.072 N/m",
             "kg/m^3": "1000 kg/m^3", "Pa*s": "1 mPa*s", "m/s": "1480 m/s", "m^3": "1.12e5 um^3",
             "N/V^2": "0.027 nN/V^2", "N*m^2/V^2": "174.5 nN*um^2/V^2", "Pa/V": "2 kPa/V", "": "1.5",
             "N": "30 nN", "V/s": "100 V/s", "m^2/s": "2.1e-5 m^2/s"}


def example(dims) -> str:
    return _EXAMPLES.get(si_unit(dims), f"1 {si_unit(dims)}")
