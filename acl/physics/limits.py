"""The limits a design is checked against, each written once over arrays with any leading batch axes: the lint
rules compare one design's values with them (acl.lint.rules: ACL103, ACL401, ACL402, ACL504), and a sweep
compares every point's at once (acl.sweep.checks: the ``lint_<rule>_pass`` columns).  SI units.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from acl.physics.beams import eq1_validity_limit


def clamp_strain(load, length, rigid_length, half_depth, bending_stiffness):
    """Bending strain P (L + l) c / (E I) at the clamp of a cantilever loaded at its tip through a rigid part l (flexure formula sigma = M c / I, M = P (L + l): Beer & Johnston, Mechanics of Materials, 4.4)."""
    return load * (length + rigid_length) * half_depth / bending_stiffness


def modes_overlap(f1, q1, f2, q2, k):
    """(whether two resonances overlap, the limit): |f1 - f2| < k (f1/Q1 + f2/Q2)/2, the mean half-power bandwidth f/Q of a damped oscillator times k (Morse, Vibration and Sound, ch. 2)."""
    limit = k * ((f1 / q1 + f2 / q2) / 2)
    return np.abs(np.subtract(f1, f2)) < limit, limit


def interface_cap_volume(radius):
    """Volume 2/3 pi R^3 of the hemispherical bulge of an interface pinned on an orifice of radius R (the most gas it can push out)."""
    return 2 / 3 * np.pi * np.asarray(radius, float) ** 3


@lru_cache(maxsize=512)
def eq1_limit_ratio(rigid_ratio: float, tolerance: float) -> float:
    """Deflection / L where paper Eq. 1 departs from the elastica by ``tolerance`` (l/L rounded to 0.01), cached (acl.physics.beams.eq1_validity_limit)."""
    return eq1_validity_limit(1.0, rigid_ratio, tolerance)
