"""Nonlinear correction of a path plan: re-plan against the design's full forward model.

The path program (:mod:`acl.schedule.path`) is linear in the per-tone power: it cannot see a
saturating drive, a stiffening beam or a neighbour's drag, which a calibrated design declares as
effects.  A correction pass re-simulates the plan at every waypoint through the nonlinear forward
model (``forward(u) -> displacement``) and moves each linear target by the error it left,
``p' <- p' + (p - y(u(p')))`` (a fixed-point iteration on the model, as iterative learning control
does on a device), then solves the same convex program again.  Passes stop when the RMS error no
longer falls; the best plan is kept.  Waypoints where the model lost its equilibrium are left as is.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


def correct_plan(plan_for: Callable[[np.ndarray], object], forward: Callable[[np.ndarray], np.ndarray],
                 targets: np.ndarray, first, passes: int):
    """(best plan, [rms error per pass, m]) after up to ``passes`` corrections of ``first``.

    ``plan_for(linear_targets (N, 2)) -> PathPlan``; ``forward(u (N, K)) -> (N, 2)`` m.
    """
    plan, shifted = first, np.asarray(targets, float).copy()
    pred = np.asarray(forward(plan.u.T), float)
    best, history = plan, []
    best_rms = _rms(pred, targets)
    history.append(best_rms)
    for _ in range(passes):
        ok = np.all(np.isfinite(pred), axis=1)
        shifted[ok] += targets[ok] - pred[ok]
        plan = plan_for(shifted)
        pred = np.asarray(forward(plan.u.T), float)
        rms = _rms(pred, targets)
        history.append(rms)
        if not rms < best_rms:
            break
        best, best_rms = plan, rms
    return best, history


def _rms(pred, targets) -> float:
    err = np.linalg.norm(pred - targets, axis=1)
    err = np.where(np.isfinite(err), err, np.inf)
    return float(np.sqrt(np.mean(err ** 2)))
