"""The design stage's shared core: the failure signal, declaration kinds, key schemas, wording.

Everything else in :mod:`acl.design` builds on this module and it imports none of them: the stage
runs one way, core -> :mod:`~acl.design.evaluate` (expressions, parameters, blocks) ->
:mod:`~acl.design.builders` (one model per declaration) -> :mod:`~acl.design.programs` ->
:mod:`~acl.design.assemble` (the Design) -> :mod:`~acl.design.resolve` (the public ``load``).
"""
from __future__ import annotations

from dataclasses import dataclass

from acl.design.values import CallVal, DeclVal, DirVal, IdentVal, ListVal, RangeVal, StrVal, VecVal
from acl.units import Quantity, describe, parse_unit_static, si_unit


# One polytropic default for every medium: the physics constant (isothermal, 1.0; justified in
# docs/physics.md part A section 1 and acl.physics.constants.MediumConstants).
from acl.physics.constants import WATER_20C as _WATER  # noqa: E402

_POLYTROPIC_DEFAULT = _WATER.polytropic_index


class Fail(Exception):
    """Evaluation of one expression failed; the diagnostic is already recorded."""


DECL_KINDS = ("medium", "material", "transducer", "capsule", "beam", "spring", "truss", "latch", "anchor", "effect")

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
    "bjerknes_scale": {"factor": ("", _ONE)},
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
    ("bjerknes_scale", "factor"): "nonneg",
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
