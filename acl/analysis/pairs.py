"""Critical distance of a capsule pair where the full force model's net force changes sign (issue 24).

The reduced law of paper Eq. 3, d_c = sqrt(alpha / 2 gamma) (:func:`acl.analysis.acoustics.pair_table`), takes the
pair's attraction and thrusts at one configuration and assumes the neighbour's jet drag equals one thrust.  The
force model differs: the coupled responses change with the gap and the jet drag is a laminar-jet law (about 0.8
of one thrust at the Fig. 4 geometry).  Here the second capsule is moved along the line between the capsule
centres, every other capsule at rest, and the gap between the two closest orifices where the closing force
(attraction positive, the mean of the two capsules' forces along the line) changes sign from attraction to
repulsion is returned: the d_c a user sees.
"""
from __future__ import annotations

import numpy as np

from acl.design.model import Design, Drive

GRID = 80             # gaps sampled between contact and the far end, geometric


def closing_force(design: Design, drive: Drive, a: str, b: str, shifts) -> tuple[np.ndarray, np.ndarray]:
    """(gap between the closest orifices (S,) m, closing force (S,) N, attraction positive) with capsule ``b`` moved
    by ``shifts`` (S,) m along the line from ``a``'s centre to ``b``'s (acoustics.force_batch: the full force model)."""
    from acl.analysis.acoustics import force_batch

    names = [c.name for c in design.capsules]
    ia, ib = names.index(a), names.index(b)
    rest = np.array([c.center for c in design.capsules], float)
    unit = rest[ib] - rest[ia]
    unit = unit / np.linalg.norm(unit)
    s = np.atleast_1d(np.asarray(shifts, float))
    centres = np.repeat(rest[None], s.size, axis=0)
    centres[:, ib] = centres[:, ib] + s[:, None] * unit
    f = force_batch(design, centres, drive)
    close = 0.5 * ((f[:, ia] - f[:, ib]) @ unit)
    ca, cb = design.capsule(a), design.capsule(b)
    oa = np.array([o.center for o in ca.orifices], float) - np.asarray(ca.center, float) + rest[ia]
    ob = np.array([o.center for o in cb.orifices], float) - np.asarray(cb.center, float)
    gaps = np.array([np.min(np.linalg.norm((ob + c)[:, None, :] - oa[None, :, :], axis=-1)) for c in centres[:, ib]])
    return gaps, close


def net_critical_distance(design: Design, drive: Drive, a: str, b: str, far: float = 400e-6) -> float | None:
    """Gap (m) between the closest orifices of ``a`` and ``b`` where the net closing force changes from attraction
    to repulsion as ``b`` moves away along the centre line (the first such change from near contact out to ``far``
    beyond the rest gap); None if it never does (always attracting or always repelling there)."""
    from acl.physics.roots import brentq          # analyze imports no scipy (tests/test_analyze_ties.py)

    ca, cb = design.capsule(a), design.capsule(b)
    touch = min(x.radius for x in ca.orifices) + min(y.radius for y in cb.orifices)
    g0, _ = closing_force(design, drive, a, b, [0.0])
    near = 1.05 * touch - float(g0[0])                  # a shift that brings the orifices close to touching
    grid = np.concatenate([np.linspace(near, 0.0, GRID // 2, endpoint=False),
                           np.geomspace(1e-7, far, GRID // 2)])
    grid.sort()
    gaps, close = closing_force(design, drive, a, b, grid)
    ok = np.isfinite(close) & (gaps >= touch)
    idx = np.flatnonzero(ok[:-1] & ok[1:] & (close[:-1] > 0) & (close[1:] <= 0))
    if idx.size == 0:
        return None
    k = int(idx[0])
    s = brentq(lambda x: float(closing_force(design, drive, a, b, [x])[1][0]), grid[k], grid[k + 1], xtol=1e-12)
    return float(closing_force(design, drive, a, b, [s])[0][0])
