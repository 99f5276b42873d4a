"""Switching one bistable latch while the others stay put (paper Fig. 6e), as an LP in u = V^2.

``forces[l, k]`` is the force (N per V^2) of tone k on latch l along the latch's axis (+ pushes
towards state "b").  ``to_b[l]`` / ``to_a[l]`` are the forces that switch latch l a->b / b->a::

    minimise    sum_k u_k                                   (least drive)
    subject to  sigma_j F_j u >= margin * threshold_j        the target switches, with margin
                sigma_i F_i u <= threshold_i / margin       every other latch stays (i != j),
                                                             sigma_i its own switching direction
                0 <= u_k <= Vtone^2,  sum_k sqrt(u_k) <= Vmax   (peak bound, whatever the phases)

The peak bound is concave in u, so the program is solved in three sound steps:

1. the *relaxation* without it (per-tone caps only): if that is infeasible, so is the switch;
2. if its solution already meets ``sum_k sqrt(u_k) <= Vmax`` it is optimal;
3. otherwise the tones are chosen first -- the relaxation's support, and every single tone (closed
   form, exact) -- and each choice S is solved with the Cauchy-Schwarz plane
   ``sum_{k in S} u_k <= Vmax^2 / |S|`` (inner approximation, see path.py), then tangent planes of
   the exact bound at the previous solution (convex-concave steps, each sound).  The least drive
   found wins.

A Cauchy-Schwarz plane over *all* candidate tones (65 for an automatic choice) would cap every
tone at Vmax / sqrt(65) and call a 27 V switch infeasible at 100 V.

Releasing (b -> a) is the same program with sigma = -1: where the design has a tone that pushes
the other way (a second capsule, Fig. 6e), the LP finds it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.schedule.path import DriveLimits
from acl.schedule.solve import solve


@dataclass(frozen=True)
class SwitchPlan:
    u: np.ndarray                 # (K,) V^2
    target_force: float           # N, along the switching direction
    required_force: float         # N, margin * threshold
    other_ratios: np.ndarray      # (L,) force / threshold for every latch (target: its own ratio)
    status: str

    @property
    def amplitudes(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.u, 0.0))


class SwitchInfeasible(Exception):
    def __init__(self, binding: tuple[str, ...], relax: tuple[str, ...], status: str):
        self.binding, self.relax, self.status = binding, relax, status
        super().__init__("binding: " + ", ".join(binding))


def plan_switch(forces: np.ndarray, to_b: np.ndarray, to_a: np.ndarray, states: list[str],
                names: list[str], target: int, new_state: str, margin: float,
                limits: DriveLimits, refine: int = 4, either=(), extra=()) -> SwitchPlan:
    """The least drive that switches latch ``target`` to ``new_state`` and keeps the others put.

    ``either``: indices of other latches whose state is uncertain (an earlier drive pushed them near their
    switching force): each must stay below ``1/margin`` of its switching force in both directions, so
    that it stays put whichever state it is in.
    ``extra``: further (row (K,) N per V^2, limit N) pairs kept below ``1/margin`` of their limit, ``row @ u <= limit /
    margin`` (the target's push back from the state it is switched to, where it may be already).
    """
    import cvxpy as cp

    F = np.asarray(forces, dtype=float)
    L, K = F.shape
    sigma = np.array([1.0 if s == "a" else -1.0 for s in states])      # own switching direction
    sig_t = 1.0 if new_state == "b" else -1.0
    thr = np.where(sigma > 0, to_b, to_a)
    thr_t = to_b[target] if new_state == "b" else to_a[target]
    vmax2 = limits.max_voltage ** 2
    fs = max(float(np.max(np.abs(F))) * vmax2, 1e-30)                 # force scale
    Fs = F * vmax2 / fs                                                 # per unit x = u / Vmax^2
    cap = limits.tone_cap(K) ** 2 / vmax2
    others = [i for i in range(L) if i != target]
    goal_row, goal_rhs = sig_t * Fs[target], margin * thr_t / fs
    keep_rows = sigma[others, None] * Fs[others] if others else np.zeros((0, K))
    keep_rhs = thr[others] / margin / fs if others else np.zeros(0)
    both = [i for i in either if i != target and np.isfinite(np.where(sigma > 0, to_a, to_b)[i])]
    if both:              # the opposite direction too: it stays whichever state it is in
        opp = np.where(sigma > 0, to_a, to_b)
        keep_rows = np.vstack([keep_rows, -sigma[both, None] * Fs[both]])
        keep_rhs = np.concatenate([keep_rhs, opp[both] / margin / fs])
    for row, lim in extra:
        keep_rows = np.vstack([keep_rows, np.asarray(row, float)[None, :] * vmax2 / fs])
        keep_rhs = np.concatenate([keep_rhs, [float(lim) / margin / fs]])

    def lp(support, total=None):
        """Least sum x on ``support`` with per-tone caps and an optional plane (a, b): a @ x <= b."""
        idx = np.asarray(support, int)
        x = cp.Variable(idx.size, nonneg=True)
        cons = [x <= cap[idx], goal_row[idx] @ x >= goal_rhs]
        if keep_rows.shape[0]:
            cons.append(keep_rows[:, idx] @ x <= keep_rhs)
        if total is not None:
            cons.append(total[0] @ x <= total[1])
        res = solve(cp.Problem(cp.Minimize(cp.sum(x)), cons), f"switch latch {names[target]}")
        if not res.ok:
            return None, res
        full = np.zeros(K)
        full[idx] = np.maximum(np.asarray(x.value), 0.0)
        return full, res

    def peak(x):                                        # sum of amplitudes / Vmax
        return float(np.sum(np.sqrt(np.maximum(x, 0.0))))

    relaxed, res = lp(range(K))
    if relaxed is None:
        raise SwitchInfeasible(*_diagnose(Fs, thr, thr_t, sig_t, sigma, target, others, names,
                                          margin, cap, K, fs, limits), res.status)
    found: list[tuple[np.ndarray, object]] = []
    if peak(relaxed) <= 1.0 + 1e-9:
        found.append((relaxed, res))
    else:
        found += _singles(goal_row, goal_rhs, keep_rows, keep_rhs, cap, res)
        support = np.flatnonzero(relaxed > 1e-6 * relaxed.max())
        x, r = lp(support, (np.ones(support.size), 1.0 / support.size))
        for _ in range(refine if x is not None else 0):
            found.append((x, r))
            xs = np.maximum(x[support], 0.02 ** 2)      # tangent of sum sqrt(x) <= 1 at x (floored)
            a = 1.0 / (2.0 * np.sqrt(xs))
            b = 1.0 - float(np.sum(np.sqrt(xs) / 2.0))
            if b <= 0:
                break
            x_new, r_new = lp(support, (a, b))
            if x_new is None or x_new.sum() >= x.sum() * (1 - 1e-6):
                break
            x, r = x_new, r_new
        if x is not None:
            found.append((x, r))
    found = [(x, r) for x, r in found if peak(x) <= 1.0 + 1e-6]
    if not found:
        need = peak(relaxed) * limits.max_voltage
        raise SwitchInfeasible(
            (f"total amplitude: the least-power drive needs tones summing to {need:.4g} V and no "
             f"drive within {limits.max_voltage:g} V was found (single tones, and the relaxation's "
             f"{int(np.count_nonzero(relaxed > 1e-6 * relaxed.max()))} tones)",),
            (f"raise the max voltage above {limits.max_voltage:g} V",
             "pin the tones with `using`", "lower the required margin"), "infeasible")
    x, res = min(found, key=lambda p: float(p[0].sum()))
    u = x * vmax2
    force = F @ u
    ratios = np.where(np.arange(L) == target, sig_t * force / thr_t, sigma * force / thr)
    return SwitchPlan(u=u, target_force=float(sig_t * force[target]),
                      required_force=float(margin * thr_t), other_ratios=ratios, status=res.status)


def _singles(goal_row, goal_rhs, keep_rows, keep_rhs, cap, res) -> list:
    """Every single tone that switches the target alone within its cap (closed form; exact peak)."""
    out = []
    for k in np.flatnonzero(goal_row > 0):
        xk = goal_rhs / goal_row[k] * (1 + 1e-9)
        if xk > cap[k] or (keep_rows.size and np.any(keep_rows[:, k] * xk > keep_rhs)):
            continue
        x = np.zeros(goal_row.size)
        x[k] = xk
        out.append((x, res))
    return out


def _diagnose(Fs, thr, thr_t, sig_t, sigma, target, others, names, margin, cap, K, fs, limits):
    import cvxpy as cp

    x = cp.Variable(K, nonneg=True)
    best = cp.Problem(cp.Maximize(sig_t * Fs[target] @ x), [x <= cap])
    r = solve(best, "switch diagnosis")
    reachable = r.ok and r.value * fs >= margin * thr_t * (1 - 1e-9)
    if not reachable:
        most = max((r.value or 0.0) * fs, 0.0)       # solver dust below zero: no tone pushes that way
        if not np.any(sig_t * Fs[target] > 0):
            # no voltage helps: every candidate tone pushes the latch away from the new state where it is
            return (("direction: no candidate tone pushes the latch towards the new state (every one pushes it the "
                     "other way, or not at all, where its capsules are)",),
                    ("use a tone that pushes the latch towards the new state (e.g. a capsule on the other side of "
                     "the shuttle, paper Fig. 6e)", "reset the latch by hand"))
        return ((f"amplitude limits: at most {most:.3g} N towards the new state (each tone at "
                 f"the limit, an upper bound), "
                 f"{margin * thr_t:.3g} N needed (margin {margin:g})",),
                (f"raise the max voltage above {limits.max_voltage:g} V",
                 "lower the required margin", "use a tone nearer the actuator's resonance"))
    binding = []
    for i in others:
        rest = [j for j in others if j != i]
        cons = [x <= cap, sig_t * Fs[target] @ x >= margin * thr_t / fs]
        if rest:
            cons.append((sigma[rest, None] * Fs[rest]) @ x <= thr[rest] / margin / fs)
        if solve(cp.Problem(cp.Minimize(cp.sum(x)), cons), "switch diagnosis").ok:
            binding.append(f"latch `{names[i]}` would switch too (crosstalk)")
    if not binding:
        binding = ["crosstalk: every available tone also switches another latch"]
    return tuple(binding), ("pin a tone that acts mostly on the target latch",
                            "lower the margin", "separate the latches' resonance frequencies")
