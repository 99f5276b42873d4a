"""Latches in the fit's rows: the rising branches of the holding force (acl.physics.latch) as tables, the shuttle
travel under a load from state a, and the probability that a ramp switches (latch states)."""
from __future__ import annotations

import numpy as np


def latch_table(geometry) -> tuple:
    """(F_a, u_a, F_switch, F_b, u_b): rising branches of the latch holding force (acl.physics.latch), from state a
    up to the switching force and beyond state b, for a vectorized inverse (load -> shuttle travel)."""
    from acl.physics.latch import latch_landscape

    land = latch_landscape(*geometry)
    u, F = np.asarray(land.u), np.asarray(land.force)
    i_peak = int(np.argmax(F[: np.searchsorted(u, land.unstable)] if land.bistable else F))
    Fa, ua = np.maximum.accumulate(F[: i_peak + 1]), u[: i_peak + 1]
    if land.bistable:
        ib = int(np.searchsorted(u, land.state_b))
        Fb, ub = np.maximum.accumulate(F[ib:]), u[ib:]
    else:
        Fb, ub = Fa[-1:], ua[-1:]
    return Fa, ua, float(Fa[-1]), Fb, ub


def latch_travel(load, table, e_scale=1.0, blend=0.0):
    """Shuttle travel under ``load`` from state a: the first branch below the switching force, the far branch above it
    (a fresh ramp from state a on every row; latch_force scales with E, acl.physics.latch).

    ``blend`` > 0 (a search device, never the model: acl.fit.select._cross_switch): the expected travel when the
    switching force scatters log-normally by ``blend`` (the probit of :func:`switch_probability`), (1 - p) u_a + p u_b,
    which is smooth in the load where the step is not."""
    Fa, ua, fsw, Fb, ub = table
    x = np.asarray(load, float) / e_scale
    if blend > 0:
        p = switch_probability(x / fsw, blend)
        return (1.0 - p) * np.interp(x, Fa, ua) + p * np.interp(x, Fb, ub)
    return np.where(x <= fsw, np.interp(x, Fa, ua), np.interp(x, Fb, ub))


def lone_latch_rows(P) -> np.ndarray:
    """(n,) bool: displacement rows of a latch on its own (not in a pair or a group; not a state row)."""
    if P.latch_id is None:
        return np.zeros(P.n, bool)
    grp = P.group_row if P.group_row is not None else np.zeros(P.n, bool)
    state = P.state if P.state is not None else np.zeros(P.n, bool)
    return (P.latch_id >= 0) & ~P.pair & ~grp & ~state & (P.s0 != 0)


def latch_branch_mismatch(P, y, prediction) -> np.ndarray:
    """(n,) bool: lone-latch displacement rows whose ``prediction`` lies on the other side of the switch than the
    measured value ``y`` (each side of the midpoint between the travel at the switching force and state b)."""
    out = np.zeros(P.n, bool)
    rows = lone_latch_rows(P)
    for tid in np.unique(P.latch_id[rows]):
        m = rows & (P.latch_id == tid)
        _, ua, _, _, ub = P.latch_tables[tid]
        mid = 0.5 * (ua[-1] + ub[0])
        meas = (np.asarray(y, float)[m] - P.base[m]) / P.s0[m] > mid
        pred = (np.asarray(prediction, float)[m] - P.base[m]) / P.s0[m] > mid
        out[np.flatnonzero(m)] = meas != pred
    return out


def latch_travel_exact(load, geometry, table, e_scale=1.0, steps=4):
    """Shuttle travel under ``load`` of either sign from state a, as the analysis solves the latch law: the branch of
    :func:`latch_travel` (a pull towards state a stretches the beams, u < 0, from the stiffness at rest) polished by
    Newton on acl.physics.latch.latch_force (von Mises truss), each step kept inside its branch."""
    from acl.physics.latch import latch_force

    th, L, w, t, E = geometry
    Fa, ua, fsw, Fb, ub = table
    x = np.asarray(load, float) / e_scale
    h = 1e-7 * L
    k0 = float((latch_force(h, th, L, w, t, E) - latch_force(-h, th, L, w, t, E)) / (2 * h))
    far = x > fsw
    lo = np.where(x < 0, -np.inf, np.where(far, ub[0], ua[0]))
    hi = np.where(x < 0, 0.0, np.where(far, ub[-1], ua[-1]))
    u = np.where(x < 0, x / k0, latch_travel(np.maximum(x, 0.0), table))
    for _ in range(steps):
        F = latch_force(np.stack([u, u + h, u - h]), th, L, w, t, E)
        slope = (F[1] - F[2]) / (2 * h)
        step = np.where(slope > 0, (F[0] - x) / np.where(slope > 0, slope, 1.0), 0.0)
        u = np.clip(u - step, lo, hi)
    return u


def switch_probability(ratio, spread):
    """Probability that a ramp from state a ends in state b: Phi(ln(push / F_switch) / s), the switching force
    log-normally scattered by s from ramp to ramp (a probit threshold model; F_switch of acl.physics.latch)."""
    from scipy.special import ndtr

    with np.errstate(divide="ignore"):
        z = np.log(np.maximum(ratio, 1e-300)) / max(spread, 1e-9)
    return ndtr(z)
