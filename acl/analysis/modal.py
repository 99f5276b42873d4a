"""Each capsule alone: its thermal length and its bare modes (no liquid coupling, no wall), cached per geometry and
medium so that every analysis of a design, and every design with the same capsule, computes them once
(:mod:`acl.analysis.acoustics` re-exports every name).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from acl.analysis.environment import _capsule, medium_constants
from acl.design.model import Cavity, Design
from acl.physics import constants as C
from acl.physics.resonance import BubbleModes, capsule_modes as _physics_modes


def thermal_radius(cavity: Cavity) -> float:
    """Length for the thermal model: 3 V / S (sphere-equivalent) of the gas, or the equal-volume sphere radius."""
    v = cavity.volume
    if cavity.shape == "cylinder" and cavity.radius and cavity.height:
        s = 2 * math.pi * cavity.radius**2 + 2 * math.pi * cavity.radius * cavity.height
        return 3 * v / s
    if cavity.shape == "prism" and cavity.side and cavity.height:
        s = math.sqrt(3) / 2 * cavity.side**2 + 3 * cavity.side * cavity.height
        return 3 * v / s
    return (3 * v / (4 * math.pi)) ** (1 / 3)


@lru_cache(maxsize=4096)
def _modes_for(volume: float, radii: tuple[float, ...], r_th: float, medium: tuple,
               q_override: float | None, n_modes: int) -> BubbleModes:
    rho, mu, c, sigma, p0, kappa, diff, gamma = medium
    return _physics_modes(volume, np.asarray(radii), rho, sigma, p0, kappa, mu, c, r_th,
                          heat_capacity_ratio=gamma, thermal_diffusivity=diff,
                          quality_override=q_override, n_modes=n_modes)


def modal_data(design: Design, capsule, n_modes: int = C.DEFAULT_MEMBRANE_MODES,
               predicted: bool = False) -> BubbleModes:
    """The physics-level modes of ``capsule`` alone (bare: no liquid coupling, no wall), cached per geometry and medium.

    ``predicted`` ignores a declared ``quality_factor`` (the physics' own damping).
    """
    cap = _capsule(design, capsule)
    radii = tuple(o.radius for o in cap.orifices)
    q = None if predicted else cap.quality_factor
    return _modes_for(cap.cavity.volume, radii, thermal_radius(cap.cavity),
                      medium_constants(design).as_tuple(), q, n_modes)
