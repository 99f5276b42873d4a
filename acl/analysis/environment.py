"""The environment of a design's acoustic analysis: medium and transducer with their documented fallbacks, and the
declared effects that scale the drive pressure and the forces (:mod:`acl.analysis.acoustics` re-exports every name).

Defaults: a design without ``medium`` uses :data:`acl.physics.constants.WATER_20C`; without ``transducer`` a flat
:data:`acl.physics.constants.DEFAULT_GAIN_PA_PER_V`.  :func:`defaults_used` lists what was assumed.
"""
from __future__ import annotations

import math

import numpy as np

from acl.analysis import effects as EF
from acl.design.model import Capsule, Design
from acl.physics import constants as C
from acl.physics import effects as PE
from acl.physics.transducer import pressure_per_volt


def medium_constants(design: Design) -> C.MediumConstants:
    m = design.medium
    if m is None:
        return C.WATER_20C
    return C.MediumConstants(
        density=m.density, viscosity=m.viscosity, sound_speed=m.sound_speed,
        surface_tension=m.surface_tension, ambient_pressure=m.ambient_pressure,
        polytropic_index=m.polytropic_index, gas_thermal_diffusivity=m.gas_thermal_diffusivity,
    )


def defaults_used(design: Design) -> tuple[str, ...]:
    """Notes naming every documented default the acoustic analysis of ``design`` relies on."""
    notes = []
    if design.medium is None:
        notes.append("no medium declared: water at 20 C assumed (acl.physics.constants.WATER_20C)")
    if design.transducer is None:
        notes.append(f"no transducer declared: flat {C.DEFAULT_GAIN_PA_PER_V:g} Pa/V assumed")
    return tuple(notes)


def drive_gain(design: Design, frequencies) -> tuple[np.ndarray, np.ndarray]:
    """Transducer gain (Pa/V) at ``frequencies`` and the mask of frequencies outside its table."""
    f = np.asarray(frequencies, float)
    t = design.transducer
    if t is None:
        return np.full(f.shape, C.DEFAULT_GAIN_PA_PER_V), np.zeros(f.shape, bool)
    return pressure_per_volt(f, t.gain_frequencies, t.gain_pa_per_v)


def effect_pressure_factor(design: Design, f, vtot: float | None = None) -> np.ndarray:
    """Factor on the drive pressure from declared transducer_gain (gain, tilt) and drive_saturation (at total amplitude ``vtot``).

    Formulas of :mod:`acl.physics.effects` (the fit's forward model uses the same); 1 without effects.
    """
    f = np.asarray(f, float)
    out = np.ones(f.shape)
    tg = EF.coefficients(design, "transducer_gain")
    if tg:
        out = out * tg["gain"]
        if tg["gain_slope"] and math.isfinite(tg["f_ref"]):
            out = out * PE.gain_tilt(f, tg["f_ref"], tg["gain_slope"])
    tr = EF.coefficients(design, "transducer_resonance")
    if tr and tr["inv_f_ratio"] and math.isfinite(tr["f_ref"]):
        out = out * PE.transducer_resonance(f, tr["f_ref"], tr["inv_f_ratio"], tr["gain_q"])
    sat = EF.coefficients(design, "drive_saturation")
    if sat and vtot is not None:
        out = out * PE.saturation(vtot, sat["inv_vsat2"])
    return out


def substrate_factor(design: Design, capsule) -> float:
    """Force factor of a declared substrate_proximity at the capsule's (first) orifice height at rest; 1 without it."""
    sp = EF.coefficients(design, "substrate_proximity")
    if not sp or sp["h_substrate"] <= 0:
        return 1.0
    cap = _capsule(design, capsule)
    z = cap.orifices[0].center[2] if cap.orifices else cap.center[2]
    return float(PE.substrate_factor(np.asarray(z, float), np.asarray(sp["h_substrate"], float)))


def _capsule(design: Design, capsule) -> Capsule:
    return capsule if isinstance(capsule, Capsule) else design.capsule(capsule)
