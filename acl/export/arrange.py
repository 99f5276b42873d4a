"""Print variants on one substrate: names from the varied values, positions spaced so neighbours do not couple.

Spacing rule (docs/export.md, "Variants"): two bubbles couple through the field each radiates, a
monopole whose coupling falls as 1/(4 pi d) with distance d (acl.physics.coupling.green_matrix);
an interface's own radiation term scales as 1/(4 pi a), a the bubble's equivalent radius
(3 V / 4 pi)^(1/3).  Neighbouring variants are kept at a/d <= :data:`COUPLING_RATIO` (2 %): the
nearest capsules of two variants are at least a_max / 0.02 = 50 a_max apart, with a_max the
largest bubble of any variant.  The secondary Bjerknes force between them (1/d^2, paper Eq. 3) is
then below 1/2500 of its value at one radius.
"""
from __future__ import annotations

import math

import numpy as np

COUPLING_RATIO = 0.02


def equivalent_radius(volume_m3: float) -> float:
    """Radius (m) of the sphere of a cavity's volume."""
    return (3 * volume_m3 / (4 * math.pi)) ** (1 / 3)


def variant_label(values: dict[str, tuple[float, str]]) -> str:
    """``gap=40um_theta=0.785`` from {name: (SI value, SI unit)}: file-name safe."""
    from acl.units import format_si

    parts = []
    for name, (v, unit) in values.items():
        text = format_si(v, unit).replace(" ", "").replace("/", "per").replace("*", "").replace("^", "")
        parts.append(f"{name}={text}")
    return "_".join(parts)


def arrangement(variants: list[dict], unit_scale: float) -> dict:
    """Offsets (in the file's unit) placing each variant on one substrate, in a near-square grid.

    ``variants``: {"bounds": ((xmin, ymin), (xmax, ymax)) um, "bubble": largest equivalent radius (m), ...}.
    """
    a_max = max((v["bubble"] for v in variants), default=0.0) * 1e6          # um
    clearance = a_max / COUPLING_RATIO
    lo = np.array([v["bounds"][0] for v in variants], float)
    hi = np.array([v["bounds"][1] for v in variants], float)
    size = (hi - lo).max(axis=0)
    pitch = size + clearance
    cols = max(1, math.ceil(math.sqrt(len(variants))))
    placed = []
    for i, v in enumerate(variants):
        r, c = divmod(i, cols)
        # the variant's own footprint's lower-left corner goes to the grid cell's corner
        offset = np.array([c * pitch[0], -r * pitch[1]]) - lo[i]
        placed.append([float(x) * unit_scale for x in offset])
    return {
        "pitch": [float(x) * unit_scale for x in pitch],
        "clearance": clearance * unit_scale,
        "largest_bubble_radius": a_max * unit_scale,
        "coupling_ratio": COUPLING_RATIO,
        "rule": (f"nearest capsules of neighbouring variants at least a_max/{COUPLING_RATIO:g} = "
                 f"{1 / COUPLING_RATIO:g} a_max apart (a_max: the largest bubble's equivalent radius): their "
                 "monopole coupling 1/(4 pi d) stays below 2 % of a bubble's own radiation term"),
        "offsets": placed,
    }
