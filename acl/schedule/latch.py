"""Switching one bistable latch while the others stay put (paper Fig. 6e), as an LP in u = V^2.

``forces[l, k]`` is the force (N per V^2) of tone k on latch l along the latch's axis (+ pushes
towards state "b").  ``to_b[l]`` / ``to_a[l]`` are the forces that switch latch l a->b / b->a::

    minimise    sum_k u_k                                   (least drive)
    subject to  sigma_j F_j u >= margin * threshold_j        the target switches, with margin
                sigma_i F_i u <= threshold_i / margin       every other latch stays (i != j),
                                                             sigma_i its own switching direction
                0 <= u_k <= Vtone^2,  sum_k u_k <= Vmax^2 / K   (Cauchy-Schwarz, see path.py)

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
                limits: DriveLimits) -> SwitchPlan:
    import cvxpy as cp

    F = np.asarray(forces, dtype=float)
    L, K = F.shape
    sigma = np.array([1.0 if s == "a" else -1.0 for s in states])      # own switching direction
    sig_t = 1.0 if new_state == "b" else -1.0
    thr = np.where(sigma > 0, to_b, to_a)
    thr_t = to_b[target] if new_state == "b" else to_a[target]
    vmax2 = limits.max_voltage ** 2
    fs = max(float(np.max(np.abs(F))) * vmax2, 1e-30)                 # force scale
    x = cp.Variable(K, nonneg=True)                                     # x = u / Vmax^2
    Fs = F * vmax2 / fs
    cap = limits.tone_cap(K) ** 2 / vmax2
    base = [x <= cap, cp.sum(x) <= 1.0 / K]
    goal = [sig_t * Fs[target] @ x >= margin * thr_t / fs]
    others = [i for i in range(L) if i != target]
    keep = [(sigma[others, None] * Fs[others]) @ x <= thr[others] / margin / fs] if others else []
    prob = cp.Problem(cp.Minimize(cp.sum(x)), base + goal + keep)
    res = solve(prob, f"switch latch {names[target]}")
    if not res.ok:
        raise SwitchInfeasible(*_diagnose(Fs, thr, thr_t, sig_t, sigma, target, others, names,
                                          margin, cap, K, fs, limits), res.status)
    u = np.maximum(np.asarray(x.value), 0.0) * vmax2
    force = F @ u
    ratios = np.where(np.arange(L) == target, sig_t * force / thr_t, sigma * force / thr)
    return SwitchPlan(u=u, target_force=float(sig_t * force[target]),
                      required_force=float(margin * thr_t), other_ratios=ratios, status=res.status)


def _diagnose(Fs, thr, thr_t, sig_t, sigma, target, others, names, margin, cap, K, fs, limits):
    import cvxpy as cp

    x = cp.Variable(K, nonneg=True)
    best = cp.Problem(cp.Maximize(sig_t * Fs[target] @ x), [x <= cap, cp.sum(x) <= 1.0 / K])
    r = solve(best, "switch diagnosis")
    reachable = r.ok and r.value * fs >= margin * thr_t * (1 - 1e-9)
    if not reachable:
        most = (r.value or 0.0) * fs
        return ((f"amplitude limits: at most {most:.3g} N towards the new state, "
                 f"{margin * thr_t:.3g} N needed (margin {margin:g})",),
                (f"raise the max voltage above {limits.max_voltage:g} V",
                 "lower the required margin", "use a tone nearer the actuator's resonance"))
    binding = []
    for i in others:
        rest = [j for j in others if j != i]
        cons = [x <= cap, cp.sum(x) <= 1.0 / K, sig_t * Fs[target] @ x >= margin * thr_t / fs]
        if rest:
            cons.append((sigma[rest, None] * Fs[rest]) @ x <= thr[rest] / margin / fs)
        if solve(cp.Problem(cp.Minimize(cp.sum(x)), cons), "switch diagnosis").ok:
            binding.append(f"latch `{names[i]}` would switch too (crosstalk)")
    if not binding:
        binding = ["crosstalk: every available tone also switches another latch"]
    return tuple(binding), ("pin a tone that acts mostly on the target latch",
                            "lower the margin", "separate the latches' resonance frequencies")
