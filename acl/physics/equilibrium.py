"""Quasi-static equilibrium of a mechanism under a drive voltage, with continuation and snap detection.

Generic in the degrees of freedom ``q`` (an array, SI lengths) and the drive amplitude ``V``:

* ``restoring(q) -> (f, K)``: the elastic force the structure needs to be held at ``q`` (the
  gradient of its strain energy, or any nonlinear force law) and its Jacobian ``K`` (or ``None``:
  finite differences);
* ``external(q, V) -> f``: the applied (acoustic) generalized force.

Equilibrium is ``R(q, V) = restoring(q) - external(q, V) = 0`` with tangent stiffness
``K_T = dR/dq``; an equilibrium is stable when every eigenvalue of ``K_T`` has a positive real part
(divergence stability; Bazant & Cedolin, Stability of Structures, Ch. 4).  Continuation in ``V`` is
pseudo-arclength (Keller 1977; Allgower & Georg, Introduction to Numerical Continuation Methods,
Ch. 2); a saddle-node (snap-in, latch switching) is where ``det K_T`` changes sign along the branch and
is refined by Brent's method on the arclength.  Every reported equilibrium has its residual checked
and its stability computed; failure is a status, never a silent answer.  Pure numpy/scipy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

Restoring = Callable[[np.ndarray], tuple]
External = Callable[[np.ndarray, float], np.ndarray]
Admissible = Optional[Callable[[np.ndarray], bool]]


@dataclass(frozen=True)
class Equilibrium:
    """One solve: ``status`` is ``"ok"``, ``"no_convergence"`` or ``"inadmissible"``."""

    q: np.ndarray
    voltage: float
    residual: float            # |R| (N) at q, recomputed after the solve
    min_eig: float             # smallest real part of the eigenvalues of K_T (N/m)
    stable: bool
    status: str
    iterations: int
    message: str = ""


@dataclass(frozen=True)
class SnapIn:
    """The saddle-node where the equilibrium branch is lost."""

    voltage: float
    q: np.ndarray


@dataclass(frozen=True)
class Branch:
    """Stable equilibria along increasing voltage; ``status`` ``"ok"`` | ``"snap_in"`` | ``"no_convergence"``."""

    voltage: np.ndarray        # (m,)
    q: np.ndarray              # (m, n)
    residual: np.ndarray       # (m,)
    min_eig: np.ndarray        # (m,)
    status: str
    snap: Optional[SnapIn] = None
    message: str = ""
    extra: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------
# Derivatives
# ----------------------------------------------------------------------------------------------

def _force_only(restoring: Restoring, q: np.ndarray) -> np.ndarray:
    out = restoring(q)
    return np.atleast_1d(np.asarray(out[0] if isinstance(out, tuple) else out, dtype=float))


def _restoring(restoring: Restoring, q: np.ndarray, h: float):
    out = restoring(q)
    f, K = (out if isinstance(out, tuple) else (out, None))
    f = np.atleast_1d(np.asarray(f, dtype=float))
    if K is None:
        K = np.empty((q.size, q.size))
        for j in range(q.size):
            e = np.zeros(q.size)
            e[j] = h
            K[:, j] = (_force_only(restoring, q + e) - _force_only(restoring, q - e)) / (2 * h)
    return f, np.atleast_2d(np.asarray(K, dtype=float))


def _external_jacobian(external: External, q: np.ndarray, V: float, h: float) -> np.ndarray:
    batch = getattr(external, "batch", None)
    if batch is not None:                      # all 2n perturbed points in one vectorised call
        e = h * np.eye(q.size)
        f = np.atleast_2d(batch(np.concatenate([q + e, q - e]), V))
        return (f[:q.size] - f[q.size:]).T / (2 * h)
    J = np.empty((q.size, q.size))
    for j in range(q.size):
        e = np.zeros(q.size)
        e[j] = h
        J[:, j] = (np.atleast_1d(external(q + e, V)) - np.atleast_1d(external(q - e, V))) / (2 * h)
    return J


_RT_MEMO: dict = {}
CORRECTOR_ITERATIONS = 12     # corrector iterations before a continuation step is rejected (and halved)


def residual_and_tangent(restoring: Restoring, external: External, q, V: float, h: float = 1e-12):
    """Residual R = restoring - external and tangent stiffness K_T = dR/dq (Bazant & Cedolin Ch. 4); central differences where no Jacobian is given.

    Memoised on (functions, q, V, h) for the last few points: continuation asks for the same point's
    tangent several times (convergence check, stability, determinant, next tangent).
    """
    q = np.atleast_1d(np.asarray(q, dtype=float))
    key = (restoring, external, q.tobytes(), float(V), h)
    hit = _RT_MEMO.get(key)
    if hit is not None:
        return hit
    out = _residual_and_tangent(restoring, external, q, V, h)
    if len(_RT_MEMO) >= 8:
        _RT_MEMO.pop(next(iter(_RT_MEMO)))
    _RT_MEMO[key] = out
    return out


def _residual_and_tangent(restoring, external, q, V, h):
    f, K = _restoring(restoring, q, h)
    batch = getattr(external, "batch", None)
    if batch is not None:                  # the point and its 2n central-difference neighbours in one call
        e = h * np.eye(q.size)
        out = np.atleast_2d(batch(np.concatenate([q[None], q + e, q - e]), V))
        fe = out[0]
        J = (out[1:q.size + 1] - out[q.size + 1:]).T / (2 * h)
    else:
        fe = np.atleast_1d(np.asarray(external(q, V), dtype=float))
        J = _external_jacobian(external, q, V, h)
    return f - fe, K - J, max(np.abs(f).max(), np.abs(fe).max())


def _min_eig(KT: np.ndarray) -> float:
    return float(np.min(np.linalg.eigvals(KT).real))


# ----------------------------------------------------------------------------------------------
# One equilibrium
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Equilibria:
    """:func:`solve_equilibrium_batch` for B systems: per row what :class:`Equilibrium` holds for one."""

    q: np.ndarray              # (B, n)
    residual: np.ndarray       # (B,)
    min_eig: np.ndarray        # (B,)
    stable: np.ndarray         # (B,) bool
    status: np.ndarray         # (B,) str
    iterations: np.ndarray     # (B,) int
    message: np.ndarray        # (B,) str


ResidualTangent = Callable[[np.ndarray, np.ndarray], tuple]   # (q (A, n), rows (A,)) -> (R (A, n), K_T (A, n, n), scale (A,))


def _solve_rows(KT: np.ndarray, R: np.ndarray):
    """Newton steps -K_T^-1 R per row, and the rows whose K_T is singular (LinAlgError of that row alone)."""
    try:
        return np.linalg.solve(KT, -R[..., None])[..., 0], np.zeros(R.shape[0], bool)
    except np.linalg.LinAlgError:
        out, bad = np.zeros_like(R), np.zeros(R.shape[0], bool)
        for i in range(R.shape[0]):
            try:
                out[i] = np.linalg.solve(KT[i], -R[i])
            except np.linalg.LinAlgError:
                bad[i] = True
        return out, bad


def solve_equilibrium_batch(residual_tangent: ResidualTangent, q0, *, admissible=None, rtol: float = 1e-10,
                            atol: float = 1e-20, max_iter: int = 60) -> Equilibria:
    """Newton with backtracking on |R| for B independent systems R_b(q_b) = 0 at once (Dennis & Schnabel, Numerical Methods for Unconstrained Optimization, Ch. 6).

    Each row takes exactly the iterations of a lone solve: converged when |R| <= rtol * (force scale) + atol; a
    step is halved until |R| falls by the Armijo factor (1 - 1e-4 t) at an admissible point (``admissible(q (A, n))
    -> (A,) bool``), else the row fails; rows that converge or fail leave the batch.  ``residual_tangent(q, rows)``
    evaluates the rows still solving in one call.  Failure is a status per row (``"no_convergence"``,
    ``"inadmissible"``), never a silent answer; stability is the sign of the smallest real eigenvalue of K_T.
    """
    q = np.array(np.atleast_2d(np.asarray(q0, dtype=float)), dtype=float)
    nb, n = q.shape
    ok = admissible or (lambda qs: np.ones(qs.shape[0], bool))
    rows = np.arange(nb)
    R, KT, scale = (np.asarray(x, float) for x in residual_tangent(q, rows))
    norm = np.linalg.norm(R, axis=1)
    status = np.full(nb, "no_convergence", dtype=object)
    message = np.full(nb, f"no convergence in {max_iter} Newton steps", dtype=object)
    iterations = np.full(nb, max_iter, int)
    live = np.ones(nb, bool)
    for it in range(1, max_iter + 1):
        act = np.flatnonzero(live)
        if act.size == 0:
            break
        finite = np.all(np.isfinite(R[act]), axis=1)
        done = act[~finite]
        message[done], iterations[done], live[done] = "non-finite force", it, False
        act = act[finite]
        conv = norm[act] <= rtol * scale[act] + atol
        done = act[conv]
        status[done], iterations[done], live[done] = "ok", it, False
        act = act[~conv]
        if act.size == 0:
            continue
        step, singular = _solve_rows(KT[act], R[act])
        done = act[singular]
        message[done], iterations[done], live[done] = "singular tangent stiffness", it, False
        step, act = step[~singular], act[~singular]
        t = np.ones(act.size)
        pending = np.ones(act.size, bool)
        while pending.any():
            idx = np.flatnonzero(pending)
            trial = q[act[idx]] + t[idx, None] * step[idx]
            adm = np.asarray(ok(trial), bool)
            good = np.zeros(idx.size, bool)
            if adm.any():
                a = np.flatnonzero(adm)
                Rt, KTt, st = (np.asarray(x, float) for x in residual_tangent(trial[a], act[idx[a]]))
                nt = np.linalg.norm(Rt, axis=1)
                fine = np.all(np.isfinite(Rt), axis=1) & (nt < (1 - 1e-4 * t[idx[a]]) * norm[act[idx[a]]])
                j = np.flatnonzero(fine)
                r = act[idx[a[j]]]                    # distinct rows: one assignment for all
                q[r], R[r], KT[r], scale[r], norm[r] = trial[a[j]], Rt[j], KTt[j], st[j], nt[j]
                good[a[fine]] = True
            pending[idx[good]] = False
            t[idx[~good]] *= 0.5
            lost = idx[~good][t[idx[~good]] <= 1e-6]
            pending[lost] = False
            gone = act[lost]
            message[gone], iterations[gone], live[gone] = "line search failed (no admissible descent)", it, False
    last = np.flatnonzero(live)
    status[last[norm[last] <= rtol * scale[last] + atol]] = "ok"
    okk = status == "ok"
    if okk.any():
        inadm = np.flatnonzero(okk)[~np.asarray(ok(q[okk]), bool)]
        status[inadm], message[inadm] = "inadmissible", "equilibrium outside the admissible set"
    message[status == "ok"] = ""
    mev = np.full(nb, np.nan)
    fin = np.all(np.isfinite(KT.reshape(nb, -1)), axis=1)
    if fin.any():
        mev[fin] = np.min(np.linalg.eigvals(KT[fin]).real, axis=1)
    return Equilibria(q, norm, mev, mev > 0, status, iterations, message)


def solve_equilibrium(restoring: Restoring, external: External, q0, V: float, *,
                      admissible: Admissible = None, rtol: float = 1e-10, atol: float = 1e-20,
                      max_iter: int = 60, h: float = 1e-12) -> Equilibrium:
    """Newton with backtracking on |R| for R(q, V) = 0 (Dennis & Schnabel, Numerical Methods for Unconstrained Optimization, Ch. 6).

    Converged when |R| <= rtol * (force scale) + atol; the answer is rejected (``inadmissible``) if
    ``admissible(q)`` is false, and the residual is recomputed at the returned point.
    :func:`solve_equilibrium_batch` at batch size 1.
    """
    def rt(qs, _rows):
        R, KT, sc = residual_and_tangent(restoring, external, qs[0], V, h)
        return R[None], KT[None], np.array([sc])

    adm = None if admissible is None else (lambda qs: np.array([bool(admissible(x)) for x in qs]))
    out = solve_equilibrium_batch(rt, np.atleast_1d(np.asarray(q0, dtype=float))[None], admissible=adm,
                                  rtol=rtol, atol=atol, max_iter=max_iter)
    return Equilibrium(out.q[0], float(V), float(out.residual[0]), float(out.min_eig[0]), bool(out.stable[0]),
                       str(out.status[0]), int(out.iterations[0]), str(out.message[0]))


# ----------------------------------------------------------------------------------------------
# Continuation in voltage
# ----------------------------------------------------------------------------------------------

def continuation(restoring: Restoring, external: External, q0, v_max: float, *, v_start: float = 0.0,
                 admissible: Admissible = None, length_scale: float = 1e-6, ds: float = 0.05,
                 ds_min: float = 1e-7, ds_max: float = 0.5, max_steps: int = 2000,
                 rtol: float = 1e-10, h: float = 1e-12) -> Branch:
    """Pseudo-arclength continuation of stable equilibria from ``v_start`` to ``v_max`` (Keller 1977), stopping at a saddle-node.

    Variables are scaled as (q / length_scale, V / v_max).  Returns the stable branch; status
    ``"snap_in"`` with the refined saddle-node (det K_T = 0), ``"ok"`` if ``v_max`` is reached, or
    ``"no_convergence"`` (with a message) if a step cannot be completed even at ``ds_min``.
    """
    ok = admissible or (lambda _q: True)
    qs, vs = float(length_scale), float(v_max)
    restoring = _memoized(restoring)
    first = solve_equilibrium(restoring, external, q0, v_start, admissible=admissible, rtol=rtol, h=h)
    if first.status != "ok" or not first.stable:
        reason = first.message or "starting equilibrium is unstable"
        return Branch(np.array([]), np.empty((0, np.size(q0))), np.array([]), np.array([]),
                      "no_convergence", None, f"no stable equilibrium at V = {v_start:g}: {reason}")
    pts = [first]
    y = np.concatenate([first.q / qs, [first.voltage / vs]])
    t = _tangent(restoring, external, first.q, first.voltage, qs, vs, h, None)
    det_prev = _det(restoring, external, first.q, first.voltage, h)

    def correct(y_prev, t_prev, sigma):
        """Pseudo-arclength corrector from y_prev along t_prev by sigma.

        Chord iterations (the Jacobian of the predicted point reused, Keller 1977) while they
        contract; a fresh Jacobian when they stall.  Convergence is judged on the true residual.
        """
        y_new = y_prev + sigma * t_prev
        J = None
        last = np.inf
        fresh = False           # the last step was a Newton step (fresh Jacobian)
        stalls = 0
        for _ in range(CORRECTOR_ITERATIONS):
            q, V = y_new[:-1] * qs, y_new[-1] * vs
            if not ok(q):
                return None
            if J is None:
                R, KT, scale = residual_and_tangent(restoring, external, q, V, h)
            else:
                f_int, _ = _restoring(restoring, q, h)
                fe = np.atleast_1d(np.asarray(external(q, V), dtype=float))
                R, scale = f_int - fe, max(np.abs(f_int).max(), np.abs(fe).max())
            g = float(t_prev @ (y_new - y_prev) - sigma)
            if not np.all(np.isfinite(R)):
                return None
            res = np.linalg.norm(R)
            if res <= rtol * scale + 1e-20 and abs(g) < 1e-12:
                return y_new
            if res > 0.5 * last:
                if fresh:                                # even Newton does not contract (a kink, or no
                    stalls += 1                          # branch near the predictor): give up early
                    if stalls >= 2:
                        return None
                if J is not None:                        # chord stalls: refresh the Jacobian
                    R, KT, scale = residual_and_tangent(restoring, external, q, V, h)
                    J = None
            fresh = J is None
            last = res
            fscale = max(scale, 1e-300)
            if J is None:
                fV = (np.atleast_1d(external(q, V + 1e-6 * vs)) - np.atleast_1d(external(q, V - 1e-6 * vs))) / (2e-6 * vs)
                J = np.zeros((y.size, y.size))
                J[:-1, :-1] = KT * qs
                J[:-1, -1] = -fV * vs
                J[-1] = t_prev
                J_scale = fscale
            try:
                dy = np.linalg.solve(J / np.r_[np.full(R.size, J_scale), 1.0][:, None],
                                     -np.r_[R / J_scale, g])
            except np.linalg.LinAlgError:
                return None
            y_new = y_new + dy
        return None

    step = ds
    for _ in range(max_steps):
        y_new = correct(y, t, step)
        if y_new is None:
            step *= 0.5
            if step < ds_min:
                here, above = _equilibrium_just_above(restoring, external, y[:-1] * qs, y[-1] * vs,
                                                      admissible, rtol, h)
                if above is not None:
                    # the corrector cannot cross a kink of the force law, a natural-parameter step can
                    pts.append(above)
                    y = np.concatenate([above.q / qs, [above.voltage / vs]])
                    t = _tangent(restoring, external, above.q, above.voltage, qs, vs, h, t)
                    det_prev = _det(restoring, external, above.q, above.voltage, h)
                    step = 4 * ds_min
                    continue
                if here:
                    # a limit point where K_T jumps (a kink in the force law): the branch ends here
                    return _branch(pts, "snap_in", snap=SnapIn(float(y[-1] * vs), y[:-1] * qs),
                                   message="non-smooth limit point (kink in the force law)")
                return _branch(pts, "no_convergence",
                               message=f"continuation step below {ds_min:g} at V = {y[-1] * vs:.6g}")
            continue
        q_new, V_new = y_new[:-1] * qs, y_new[-1] * vs
        det_new = _det(restoring, external, q_new, V_new, h)
        if np.sign(det_new) != np.sign(det_prev) or y_new[-1] < y[-1]:
            snap, sigma = _refine_fold(restoring, external, correct, y, t, step, qs, vs, h)
            if snap is not None and snap.voltage <= v_max:
                return _branch(pts, "snap_in", snap=snap)
            if snap is not None:
                # the fold lies past v_max: the stable branch reaches v_max first (between y and the fold)
                eq = _land_before_fold(restoring, external, correct, y, t, sigma, v_max, qs, vs, h, admissible)
                if eq is not None and np.sign(_det(restoring, external, eq.q, v_max, h)) == np.sign(det_prev):
                    pts.append(eq)
                    return _branch(pts, "ok")
            step *= 0.5
            if step < ds_min:
                return _branch(pts, "no_convergence", message="fold refinement failed")
            continue
        if V_new >= v_max:
            # land exactly on v_max: natural-parameter solve from the chord between the two points
            w = (v_max - y[-1] * vs) / (V_new - y[-1] * vs)
            guess = (1 - w) * y[:-1] * qs + w * q_new
            eq = solve_equilibrium(restoring, external, guess, v_max, admissible=admissible, rtol=rtol, h=h)
            if eq.status == "ok" and eq.stable and \
                    np.sign(_det(restoring, external, eq.q, v_max, h)) == np.sign(det_prev):
                pts.append(eq)
                return _branch(pts, "ok")
            step *= 0.5
            if step < ds_min:
                return _branch(pts, "no_convergence", message="could not land on v_max")
            continue
        eq = _verified(restoring, external, q_new, V_new, h)
        if not eq.stable:
            step *= 0.5
            if step < ds_min:
                return _branch(pts, "no_convergence", message="branch lost stability without a fold")
            continue
        pts.append(eq)
        t = _tangent(restoring, external, q_new, V_new, qs, vs, h, t)
        y, det_prev = y_new, det_new
        step = min(step * 1.5, ds_max)
    return _branch(pts, "no_convergence", message=f"no end after {max_steps} steps")


def _memoized(restoring: Restoring) -> Restoring:
    """``restoring`` remembering its last results by the exact coordinates (it is a pure function of q)."""
    memo: dict = {}

    def wrapped(q):
        q = np.asarray(q, dtype=float)
        key = q.tobytes()
        hit = memo.get(key)
        if hit is None:
            hit = restoring(q)
            if len(memo) >= 16:
                memo.pop(next(iter(memo)))
            memo[key] = hit
        return hit

    return wrapped


def _equilibrium_just_above(restoring, external, q, V, admissible, rtol, h):
    """(whether (q, V) is a stable equilibrium, a stable equilibrium near ``q`` just above ``V`` or None)."""
    here = _verified(restoring, external, q, V, h)
    if not here.stable:
        return False, None
    for dv in (1e-6, 1e-4):
        trial = solve_equilibrium(restoring, external, q, V * (1 + dv) + dv, admissible=admissible,
                                  rtol=rtol, h=h, max_iter=30)
        if trial.status == "ok" and trial.stable and np.linalg.norm(trial.q - q) <= 1e-2 * max(np.linalg.norm(q), 1e-300):
            return True, trial
    return True, None


def _verified(restoring, external, q, V, h) -> Equilibrium:
    R, KT, _ = residual_and_tangent(restoring, external, q, V, h)
    mev = _min_eig(KT)
    return Equilibrium(q, float(V), float(np.linalg.norm(R)), mev, bool(mev > 0), "ok", 0)


def _det(restoring, external, q, V, h) -> float:
    _, KT, _ = residual_and_tangent(restoring, external, q, V, h)
    return float(np.linalg.det(KT))


def _tangent(restoring, external, q, V, qs, vs, h, t_prev):
    """Unit tangent of the branch in scaled variables: K_T dq = f_V dV (implicit function theorem)."""
    _, KT, _ = residual_and_tangent(restoring, external, q, V, h)
    fV = (np.atleast_1d(external(q, V + 1e-6 * vs)) - np.atleast_1d(external(q, V - 1e-6 * vs))) / (2e-6 * vs)
    dq = np.linalg.solve(KT, fV)
    t = np.concatenate([dq * vs / qs, [1.0]])
    t /= np.linalg.norm(t)
    if t_prev is not None and t @ t_prev < 0:
        t = -t
    return t


def _refine_fold(restoring, external, correct, y, t, step, qs, vs, h) -> tuple[Optional[SnapIn], float]:
    """Brent's method on the arclength for det K_T = 0 between the last stable point and the trial step: (fold, its arclength)."""
    from acl.physics.roots import brentq

    def det_at(sigma):
        yy = correct(y, t, sigma)
        if yy is None:
            raise ValueError("corrector failed")
        return _det(restoring, external, yy[:-1] * qs, yy[-1] * vs, h)

    try:
        d0 = _det(restoring, external, y[:-1] * qs, y[-1] * vs, h)
        hi = step
        d1 = det_at(hi)
        if np.sign(d1) == np.sign(d0):
            return None, float("nan")
        sigma = brentq(det_at, 0.0, hi, xtol=1e-13, rtol=1e-12)
        yy = correct(y, t, sigma)
    except ValueError:
        return None, float("nan")
    if yy is None:
        return None, float("nan")
    return SnapIn(float(yy[-1] * vs), yy[:-1] * qs), float(sigma)


def _land_before_fold(restoring, external, correct, y, t, sigma_fold, v_max, qs, vs, h,
                      admissible) -> Optional[Equilibrium]:
    """The stable equilibrium at ``v_max`` between the last stable point y (below v_max) and a fold past v_max at
    arclength ``sigma_fold``: Brent's method on the arclength for V = v_max (V increases up to the fold), then
    Newton at v_max; None if it is not found stable."""
    from acl.physics.roots import brentq

    def v_at(sigma):
        yy = correct(y, t, sigma)
        if yy is None:
            raise ValueError("corrector failed")
        return yy[-1] * vs - v_max

    try:
        sigma = brentq(v_at, 0.0, sigma_fold, xtol=1e-15, rtol=1e-13)
        yy = correct(y, t, sigma)
    except ValueError:
        return None
    if yy is None:
        return None
    eq = solve_equilibrium(restoring, external, yy[:-1] * qs, v_max, admissible=admissible, h=h)   # polished at v_max
    return eq if eq.status == "ok" and eq.stable else None


def _branch(pts, status, snap=None, message="") -> Branch:
    n = pts[0].q.size if pts else 0
    return Branch(np.array([p.voltage for p in pts]),
                  np.array([p.q for p in pts]).reshape(len(pts), n),
                  np.array([p.residual for p in pts]),
                  np.array([p.min_eig for p in pts]),
                  status, snap, message)


def settle(restoring: Restoring, external: External, q0, V: float, *, admissible: Admissible = None,
           length_scale: float = 1e-6, max_iter: int = 20000, rtol: float = 1e-10, h: float = 1e-12) -> Equilibrium:
    """Where the mechanism goes after losing equilibrium: pseudo-transient continuation of the overdamped flow (Kelley & Keyes, SIAM J. Numer. Anal. 35, 1998).

    Returns ``inadmissible`` if the flow leaves the admissible set (e.g. contact), or the
    equilibrium it reaches (e.g. a latch's other state) with its stability.
    """
    ok = admissible or (lambda _q: True)
    q = np.atleast_1d(np.asarray(q0, dtype=float)).copy()
    _, K = _restoring(restoring, q, h)
    rate = max(float(np.max(np.abs(np.linalg.eigvals(K)))), 1e-300)
    R, KT, scale = residual_and_tangent(restoring, external, q, V, h)
    dt = 1e-2
    eye = np.eye(q.size)
    for it in range(1, max_iter + 1):
        norm = np.linalg.norm(R)
        if norm <= rtol * scale + 1e-20:
            eq = solve_equilibrium(restoring, external, q, V, admissible=admissible, rtol=rtol, h=h)
            return Equilibrium(eq.q, eq.voltage, eq.residual, eq.min_eig, eq.stable, eq.status,
                               it + eq.iterations, eq.message)
        try:
            # shift so that the step never climbs back along an unstable direction
            shift = rate / dt + 2.0 * max(0.0, -_min_eig(0.5 * (KT + KT.T)))
            s = np.linalg.solve(shift * eye + KT, -R)
        except np.linalg.LinAlgError:
            dt *= 0.25
            continue
        trial = q + s
        if not ok(trial) or not np.all(np.isfinite(trial)):
            dt *= 0.25
            if np.linalg.norm(s) <= 1e-9 * length_scale or dt < 1e-30:
                return Equilibrium(q, float(V), float(norm), float("nan"), False, "inadmissible", it,
                                   "the mechanism leaves the admissible set (contact)")
            continue
        R_new, KT_new, scale = residual_and_tangent(restoring, external, trial, V, h)
        if not np.all(np.isfinite(R_new)):
            dt *= 0.25
            continue
        if np.linalg.norm(s) <= 1e-9 * length_scale and np.linalg.norm(R_new) > norm:
            return Equilibrium(trial, float(V), float(np.linalg.norm(R_new)), float("nan"), False,
                               "inadmissible", it, "the mechanism runs into the admissible set's boundary (contact)")
        dt = min(dt * max(norm / max(np.linalg.norm(R_new), 1e-300), 2.0), 1e12)
        q, R, KT = trial, R_new, KT_new
    return Equilibrium(q, float(V), float(np.linalg.norm(R)), _min_eig(KT), False, "no_convergence",
                       max_iter, f"no rest state after {max_iter} pseudo-time steps")
