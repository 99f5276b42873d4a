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


DECL_KINDS = ("medium", "material", "transducer", "generator", "amplifier", "capsule", "beam", "spring", "truss", "latch",
              "anchor", "effect")

# Effects of the model library (docs/fit.md); `effect NAME { coefficient = quantity, ... }`: the one table is
# acl.physics.effects.EFFECT_TABLE; the names, units, domains and ranges below are read from it.
from acl.physics.effect_table import (EFFECT_TABLE, F_REF_RANGE, GAIN_BOUND, GRADIENT_BOUND,  # noqa: E402,F401
                                 GRADIENT_REFERENCE, MODULUS_DECADES, TILT_BOUND, EffectRange)

EFFECTS = tuple(EFFECT_TABLE)

D = parse_unit_static
LENGTH, FREQ, VOLT, TIME = D("m"), D("Hz"), D("V"), D("s")
_ONE = D("")

# The unit of each known effect coefficient (SI, aliases included): another dimension is E301 (`v_sat = 8 um` is
# not a saturation voltage).  Coefficients not listed are left to the analysis' note.
def _unit_dims(unit: str):
    """Dimensions of a table unit: a static unit, its reciprocal ``1/u`` or a power ``u^n``."""
    if unit.startswith("1/"):
        return tuple(-x for x in _unit_dims(unit[2:]))
    base, _, power = unit.partition("^")
    return tuple(int(power) * x for x in D(base)) if power else D(unit)


EFFECT_UNITS = {e.name: {c.name: (c.unit, _unit_dims(c.unit)) for c in e.coefficients}
                for e in EFFECT_TABLE.values()}

# The sign domain of effect coefficients (E401 outside it): "positive" (> 0), "nonneg" (>= 0), "unit" (0 .. 1).
EFFECT_DOMAIN = {(e.name, c.name): c.domain for e in EFFECT_TABLE.values() for c in e.coefficients if c.domain}

# The admissible range of every known effect coefficient (checked by acl.design.assemble._effect; the fit's
# bounds in acl/fit/effects.py lie inside every hard range, so a calibrated design written by `acl fit`
# is accepted; tests/test_effect_ranges.py).  A coefficient at its null value always lies inside.
EFFECT_RANGES = {(e.name, c.name): c.range for e in EFFECT_TABLE.values() for c in e.coefficients if c.range}


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


UNIT_EXAMPLES = {"m": "40 um", "Hz": "85 kHz", "V": "8 V", "s": "200 ms", "Pa": "13 MPa", "N/m": "0.072 N/m",
             "kg/m^3": "1000 kg/m^3", "Pa*s": "1 mPa*s", "m/s": "1480 m/s", "m^3": "1.12e5 um^3",
             "N/V^2": "0.027 nN/V^2", "N*m^2/V^2": "174.5 nN*um^2/V^2", "Pa/V": "2 kPa/V", "": "1.5",
             "N": "30 nN", "V/s": "100 V/s", "m^2/s": "2.1e-5 m^2/s"}


def example(dims) -> str:
    return UNIT_EXAMPLES.get(si_unit(dims), f"1 {si_unit(dims)}")
