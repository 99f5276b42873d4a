"""Holding a gap between two bubbles above its snap-in distance, or deliberately crossing it (LP in u).

Two descriptions of the gap, linear in ``u = V^2`` (forces superpose in V^2, paper Eq. 2):

* snap-in voltages ``v_snap[k]`` (V, per tone alone; ``inf`` if the tone never snaps the pair):
  the pair snaps when ``sum_k u_k / v_snap_k^2 >= 1``;
* a linearised gap ``gap0 + dgap @ u`` (m, dgap m per V^2) compared with ``bound`` (m).

The margin is on voltage (docs/language.md): the drive may be scaled by ``margin`` before it
snaps (``above``), or it is ``margin`` times a snapping drive (``cross``).  Scaling a drive by m
scales ``u`` by m^2, so mode ``above``: drive the tones as hard as allowed (maximise sum u) while
the snap index stays ``<= 1 / margin^2`` and the gap ``>= bound``.  mode ``cross``: the least
drive with snap index ``>= margin^2`` (or gap ``<= bound``).  Amplitude limits as in path.py.

The snap index is exact for one tone; with several tones it assumes the critical set is a
simplex in u, which is optimistic when the tones' forces have different shapes along the gap, so
the compiler re-simulates the chosen drive (:func:`acl.schedule.gains.critical_scale`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.schedule.path import DriveLimits
from acl.schedule.solve import solve


@dataclass(frozen=True)
class HoldPlan:
    u: np.ndarray
    snap_index: float | None      # sum u / v_snap^2 (1 = at snap-in)
    gap_m: float | None           # linearised gap under the drive
    status: str

    @property
    def amplitudes(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.u, 0.0))


class HoldInfeasible(Exception):
    def __init__(self, binding: tuple[str, ...], relax: tuple[str, ...], status: str):
        self.binding, self.relax, self.status = binding, relax, status
        super().__init__("binding: " + ", ".join(binding))


def plan_hold(mode: str, limits: DriveLimits, *, v_snap: np.ndarray | None = None,
              gap0: float | None = None, dgap: np.ndarray | None = None,
              bound: float | None = None, margin: float = 1.2, k: int | None = None) -> HoldPlan:
    import cvxpy as cp

    K = k or (len(v_snap) if v_snap is not None else len(dgap))
    vmax2 = limits.max_voltage ** 2
    x = cp.Variable(K, nonneg=True)
    cons = [x <= limits.tone_cap(K) ** 2 / vmax2, cp.sum(x) <= 1.0 / K]
    snap = None
    if v_snap is not None:
        w = vmax2 / np.asarray(v_snap, dtype=float) ** 2          # inf -> 0 weight
        snap = w @ x
        cons.append(snap <= 1.0 / margin ** 2 if mode == "above" else snap >= margin ** 2)
    gap = None
    if gap0 is not None and dgap is not None and bound is not None:
        gap = (gap0 + (np.asarray(dgap, float) * vmax2) @ x) / 1e-6        # um
        cons.append(gap >= bound / 1e-6 if mode == "above" else gap <= bound / 1e-6)
    if snap is None and gap is None:
        raise ValueError("plan_hold needs snap-in voltages or a linearised gap with a bound")
    obj = cp.Maximize(cp.sum(x)) if mode == "above" else cp.Minimize(cp.sum(x))
    res = solve(cp.Problem(obj, cons), f"hold ({mode})")
    if not res.ok:
        if mode == "cross":
            raise HoldInfeasible(("amplitude limits: the tones cannot close the gap to snap-in",),
                                 (f"raise the max voltage above {limits.max_voltage:g} V",
                                  "choose tones nearer the pair's resonance", "lower the margin"),
                                 res.status)
        raise HoldInfeasible(("the gap is below its bound even without drive",),
                             ("lower the bound", "widen the rest gap"), res.status)
    u = np.maximum(np.asarray(x.value), 0.0) * vmax2
    si = float(np.sum(u / np.asarray(v_snap, float) ** 2)) if v_snap is not None else None
    g = float(gap0 + np.asarray(dgap, float) @ u) if gap is not None else None
    return HoldPlan(u=u, snap_index=si, gap_m=g, status=res.status)
