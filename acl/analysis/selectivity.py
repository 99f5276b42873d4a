"""Frequency selectivity of a design: each capsule's thrust per V^2 over frequency and its share of the total
(the capsules at rest, coupled responses; :mod:`acl.analysis.acoustics` assembles them)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.analysis import acoustics as AC
from acl.design.model import Design


@dataclass(frozen=True)
class Selectivity:
    """Thrust per V^2 of each capsule vs frequency and its share of the total at each frequency."""

    frequencies: np.ndarray
    capsules: tuple[str, ...]
    thrust_per_v2: np.ndarray      # (n_capsules, F) N/V^2
    share: np.ndarray              # (n_capsules, F)
    outside_table: np.ndarray      # (F,) bool: transducer gain extrapolated
    notes: tuple[str, ...] = ()


def selectivity(design: Design, frequencies) -> Selectivity:
    """Thrust magnitude per V^2 of every capsule over ``frequencies`` (coupled responses at rest) and its share per frequency."""
    f = np.atleast_1d(np.asarray(frequencies, float))
    lay = AC._layout(design)
    u = AC.coupled_response(design, f) * AC.effect_pressure_factor(design, f)[:, None]
    thr = AC._thrust_from_volumes(design, lay.radii, f, u)                      # (F, n)
    rows = []
    for c, cap in enumerate(lay.caps):
        sel = lay.body == c
        per = thr[:, sel] * AC._thrust_scale(design, cap) * AC.substrate_factor(design, cap)
        rows.append(np.linalg.norm((per[:, :, None] * -lay.normals[sel][None]).sum(axis=1), axis=-1))
    t = np.array(rows).reshape(len(lay.caps), f.size)
    tot = t.sum(axis=0, keepdims=True)
    share = np.divide(t, tot, out=np.zeros_like(t), where=tot > 0)
    _, outside = AC.drive_gain(design, f)
    return Selectivity(frequencies=f, capsules=tuple(c.name for c in design.capsules),
                       thrust_per_v2=t, share=share, outside_table=outside,
                       notes=AC.defaults_used(design))
