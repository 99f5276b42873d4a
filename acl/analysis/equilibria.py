"""Stable equilibria of many copies of one mechanism at once, each row under its own drive (issue 23).

The mechanics of :mod:`acl.analysis.mechanics` (its degrees of freedom, restoring force and contact check, built once
per design) with the Newton iteration of :func:`acl.physics.equilibrium.solve_equilibrium_batch` over rows: the
re-simulation of a schedule solves every draw of its band at a waypoint as one batch, each row warm-started from its
own previous waypoint.  A row the batch does not settle is the caller's to solve alone
(:func:`acl.analysis.mechanics.equilibrium`, with its continuation from rest and fold detection).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from acl.analysis.mechanics import _Mechanism, _placement, _prepared, _restoring_rows
from acl.design.model import Design
from acl.physics import equilibrium as EQ


@dataclass(frozen=True)
class RowEquilibria:
    """:func:`equilibria`: per row whether a stable equilibrium was found and where the capsules are."""

    found: np.ndarray            # (B,) bool: converged, stable (and for a ramp: every step so)
    positions: np.ndarray        # (B, C, 3) capsule centres (m), design.capsules order
    displacements: np.ndarray    # (B, C, 3) from the declared centres (m)


ForceRows = Callable[[np.ndarray, np.ndarray, float], np.ndarray]   # (centres (A, C, 3), rows (A,), amplitude scale) -> (A, C, 3)


def _newton_rows(mech: _Mechanism, place: np.ndarray, rest: np.ndarray, adm, forces, z0: np.ndarray, h: float):
    """Newton (EQ.solve_equilibrium_batch) for the rows of ``z0`` (B, m), row b's acoustic forces ``forces(centres (A,
    C, 3), rows (A,))``: the residual and tangent of mechanics' scalar solve (central differences of step h, the
    point and its 2m neighbours in one evaluation)."""
    restoring = _restoring_rows(mech)
    m = z0.shape[1]
    e = h * np.eye(m)
    ncap = rest.shape[0]

    def rt(zs, idx):
        a = zs.shape[0]
        f, K = restoring(zs)
        pts = np.concatenate([zs[:, None], zs[:, None] + e[None], zs[:, None] - e[None]], axis=1).reshape(-1, m)
        centres = rest[None] + (pts @ place).reshape(pts.shape[0], ncap, 3)
        fe_all = (forces(centres, np.repeat(idx, 1 + 2 * m)).reshape(pts.shape[0], -1) @ place.T).reshape(a, 1 + 2 * m, m)
        fe = fe_all[:, 0]
        J = np.swapaxes(fe_all[:, 1:m + 1] - fe_all[:, m + 1:], 1, 2) / (2 * h)
        scale = np.maximum(np.abs(f).max(axis=1), np.abs(fe).max(axis=1))
        return f - fe, K - J, scale

    return EQ.solve_equilibrium_batch(rt, z0, admissible=adm.rows)


def equilibria(design: Design, force_rows: ForceRows, starts, *, mode: str = "eq1", h: float = 1e-12) -> RowEquilibria:
    """Stable equilibria of B copies of the mechanism at once, row b under its own drive (``force_rows(centres, rows,
    s)``: the acoustic forces on configurations of rows ``rows`` with their drive amplitudes times ``s``), each by
    Newton from ``starts[b]`` (capsule centres (C, 3)): the warm start of :func:`equilibrium`, the same iteration
    (:func:`acl.physics.equilibrium.solve_equilibrium_batch`).  Found where it converges to a stable admissible
    point; rows not found are the caller's to solve one by one (:func:`equilibrium`)."""
    mech, _, adm = _prepared(design, mode)
    rest, place = _placement(design, mech)
    starts = np.asarray(starts, float)
    nb, ncap = starts.shape[0], rest.shape[0]
    if mech.m == 0:
        return RowEquilibria(np.ones(nb, bool), np.broadcast_to(rest, (nb, ncap, 3)).copy(), np.zeros((nb, ncap, 3)))
    # the start's coordinates as equilibrium() takes them: each group's first capsule's displacement on its basis
    q0 = np.zeros((nb, mech.n))
    index = {c.name: i for i, c in enumerate(design.capsules)}
    for gi, g in enumerate(mech.groups):
        A, o = mech.bases[gi], mech.offsets[gi]
        d = starts[:, index[g[0]]] - np.asarray(design.capsule(g[0]).center)
        q0[:, o:o + A.shape[1]] = d @ A
    out = _newton_rows(mech, place, rest, adm, lambda c, r: force_rows(c, r, 1.0), q0 @ mech.Z, h)
    disp = (out.q @ place).reshape(nb, ncap, 3)
    return RowEquilibria((out.status == "ok") & out.stable, rest[None] + disp, disp)


def equilibria_from_rest(design: Design, force_rows: ForceRows, rows: int, *, mode: str = "eq1", steps: int = 4,
                         h: float = 1e-12) -> RowEquilibria:
    """:func:`equilibria` of ``rows`` rows from rest: the drive's power raised in ``steps`` equal steps (amplitudes
    times sqrt(k / steps)), each Newton solve warm-started from the last; found only where every step converges to a
    stable point whose smallest tangent stiffness stays above half of that at rest (far from any fold, so on the branch
    the continuation from rest of :func:`equilibrium` follows; other rows are the caller's to solve one by one)."""
    mech, _, adm = _prepared(design, mode)
    rest, place = _placement(design, mech)
    ncap = rest.shape[0]
    z = np.zeros((rows, mech.m))
    found = np.ones(rows, bool)
    if mech.m:
        _, K0 = _restoring_rows(mech)(np.zeros((1, mech.m)))
        floor = 0.5 * float(np.min(np.linalg.eigvals(K0[0]).real))
        for k in range(1, steps + 1):
            live = np.flatnonzero(found)
            if live.size == 0 or not floor > 0:
                found[:] = False
                break
            s = float(np.sqrt(k / steps))
            sub = _newton_rows(mech, place, rest, adm, lambda c, r, s=s, live=live: force_rows(c, live[r], s), z[live], h)
            good = (sub.status == "ok") & sub.stable & (sub.min_eig >= floor)
            z[live] = sub.q
            found[live[~good]] = False
    disp = (z @ place).reshape(rows, ncap, 3)
    return RowEquilibria(found, rest[None] + disp, disp)
