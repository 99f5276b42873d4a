"""Robust path following: the path program of :mod:`acl.schedule.path` with the declared uncertainty.

The gain matrix is uncertain: ``G = G0 + sum_j z_j dG_j`` with independent standard normal ``z_j``,
one ``dG_j`` per 1-sigma direction of the declared uncertainty (a transducer table point, a
principal axis of the parameter covariance; :func:`acl.schedule.bands.gain_sensitivity`), and, where a pair
force is first principles (no ``bjerknes_scale``), its scale moved by the root-mean-square log distance of the
paper's measured / first-principles ratios from 1 (:func:`acl.schedule.bands.pair_move`).  For a
plan ``u_t`` the tracking error is ``e_t + sum_j z_j dG_j u_t`` with ``e_t = G0 u_t - p_t``, so

    E |error_t|^2 = |e_t|^2 + u_t^T Q u_t,          Q = sum_j dG_j^T dG_j,

and over the ellipsoid ``|z| <= rho`` the worst error is at most ``|e_t| + rho |M u_t|_F`` with
``|M u_t|_F^2 = u_t^T Q u_t`` (M = [dG_1 u_t, ...]): so ``(worst)^2 <= 2 (|e_t|^2 + rho^2 u_t^T Q u_t)``.
The robust program minimises ``sum_t |e_t|^2 + u_t^T Q u_t`` (the expected squared error,
``rho = 1``), a convex quadratic in ``u`` with the same constraints as the nominal program
(the nominal tolerance still holds): it uses the tones' redundancy to drive with the
combination whose error is least sensitive to the gains, and gives up a little nominal accuracy
where that lowers the spread.  A QP of the nominal program's size, so as fast (benchmarks/compile.py).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from acl.design.model import Design
from acl.schedule.bands import Reload, gain_sensitivity

UM = 1e-6


def scaled_factor(Q: np.ndarray, vmax2: float) -> np.ndarray:
    """R with R^T R = Q in the path program's scaled units (um, x = u / Vmax^2)."""
    Qs = np.asarray(Q, float) * vmax2 ** 2 / UM ** 2
    w, V = np.linalg.eigh(0.5 * (Qs + Qs.T))
    return (V * np.sqrt(np.maximum(w, 0.0))).T


def robust_q(design: Design, gains_for: Callable[[Design], np.ndarray], reload: Reload | None = None) -> np.ndarray | None:
    """Q (K, K) m^2/V^4 of the declared uncertainty for the gains ``gains_for(design)`` (2, K); None if none declared."""
    return gain_sensitivity(design, gains_for, reload)
