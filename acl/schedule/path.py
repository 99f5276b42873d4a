"""Path following as ONE convex program (paper Fig. 3, made rigorous).

Decision variable: per-tone power ``u[k, t] = V[k, t]**2 >= 0`` at every waypoint ``t``.  The
displacement is linear in ``u`` through the gain matrix ``G`` (2 x K, metres per V^2; from the
model including the transducer, or from a calibration sweep)::

    minimise    sum_t |G u_t - p_t|^2 / N  +  lambda |g|max * sum_{k,t} u_kt / N   (um, u/Vmax^2)
    subject to  0 <= u_kt <= Vtone_k^2                          per-tone amplitude limit
                sum_k u_kt <= Vmax^2 / K                          total amplitude (see below)
                |G u_t - p_t|_inf <= tol                          the goal: track within tol
                |u_k,t+1 - u_k,t| <= 2 Vmax * slew * dt           slew limit on V (see below)

*Total amplitude.*  The peak of a K-tone waveform is at most ``sum_k V_k``; the set
``sum_k sqrt(u_k) <= Vmax`` is not convex in ``u``.  We use its inner approximation
``sum_k u_k <= Vmax^2 / K``: by Cauchy-Schwarz ``sum_k V_k <= sqrt(K sum_k V_k^2) <= Vmax``, so every
solution respects the limit whatever the phases (it is the tangent of the concave constraint at
the symmetric point).  Optionally (``refine > 0``) the tangent is moved to the previous solution
(a convex-concave iteration): each iterate stays sound and the objective can only decrease.
When the Cauchy-Schwarz plane makes the path infeasible, the program is re-solved once with the
tangent planes at each waypoint's least-power static solution (sound too; reaches up to
``sqrt(K)`` times further along a single tone).

*Slew.*  A slew limit ``|V_k,t+1 - V_k,t| <= s`` (``s = slew * dt``) is exactly convex in ``u``:
``sqrt(u2) <= sqrt(u1) + s``  <=>  ``u2 - u1 - s^2 <= 2 s sqrt(u1)`` (affine <= concave), and the same
with 1 and 2 swapped.  ``slew_model="exact"`` writes these (second-order cones).  The
linear bound ``|u2 - u1| <= 2 Vmax s`` (``slew_model="linear"``, a QP) follows from the voltage limit
but does not imply it near zero voltage: it is a relaxation.  ``slew_model="auto"`` (default)
solves the fast QP relaxation first, measures the real voltage slew of its solution and, only if
it exceeds the limit, re-solves with the exact cones: the result always respects the limit.

Everything is scaled (micrometres, ``x = u / Vmax^2``) so the solver sees numbers near one.
Built from vectorised cvxpy expressions: no per-waypoint Python loops.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acl.schedule.solve import SolveResult, solve

UM = 1e-6


@dataclass(frozen=True)
class DriveLimits:
    """Amplifier limits for one goal: total peak voltage, per-tone peak voltage, slew (V/s) or None."""

    max_voltage: float
    per_tone_voltage: float | None = None
    slew_rate: float | None = None

    def tone_cap(self, k: int) -> np.ndarray:
        v = self.per_tone_voltage if self.per_tone_voltage is not None else self.max_voltage
        return np.full(k, min(v, self.max_voltage))


@dataclass
class PathPlan:
    """The solution: per-tone power ``u`` (K, N) in V^2, amplitudes ``V`` (K, N), linear prediction."""

    u: np.ndarray
    targets: np.ndarray            # (N, 2) m
    predicted: np.ndarray          # (N, 2) m, G @ u (linear model)
    result: SolveResult
    build_time_s: float = 0.0
    solve_time_s: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def amplitudes(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.u, 0.0))

    @property
    def error(self) -> np.ndarray:
        return np.linalg.norm(self.predicted - self.targets, axis=1)

    def max_slew_v_per_s(self, dt: float) -> float:
        v = self.amplitudes
        return float(np.max(np.abs(np.diff(v, axis=1))) / dt) if v.shape[1] > 1 else 0.0


class PathInfeasible(Exception):
    """The path cannot be followed within the limits; carries the diagnosis (see :func:`diagnose_path`)."""

    def __init__(self, diagnosis: "PathDiagnosis"):
        self.diagnosis = diagnosis
        super().__init__(diagnosis.summary())


@dataclass(frozen=True)
class PathDiagnosis:
    waypoint: int                  # first waypoint that cannot be met
    time_s: float
    point_m: tuple[float, float]
    binding: tuple[str, ...]       # names of the binding constraints
    relax: tuple[str, ...]         # what to relax, in words
    status: str

    def summary(self) -> str:
        x, y = (c / UM for c in self.point_m)
        return (f"waypoint {self.waypoint} (t = {self.time_s:.4g} s, target ({x:.3g}, {y:.3g}) um) "
                f"cannot be reached: binding {', '.join(self.binding)}")


def plan_path(gains: np.ndarray, targets: np.ndarray, dt: float, limits: DriveLimits, *,
              tolerance: float = 0.5 * UM, u_start: np.ndarray | None = None,
              lam: float = 1e-3, slew_model: str = "auto", refine: int = 0,
              solvers: tuple[str, ...] | None = None, robust_q: np.ndarray | None = None,
              robust_mode: str = "mean") -> PathPlan:
    """Solve the whole path as one convex program; raise :class:`PathInfeasible` with a diagnosis.

    gains (2, K) m/V^2; targets (N, 2) m; dt s between waypoints; u_start (K,) V^2 the power at
    the start (slew from it; default 0); lam the weight of total drive: it biases the tracking error by about lam/2 micrometres.
    robust_q (K, K) m^2/V^4: the declared gain uncertainty (:mod:`acl.schedule.robust`); robust_mode
    "mean" adds ``sum_t u_t^T Q u_t / N`` (expected squared error, a QP), "worst" minimises
    ``sum_t (|e_t| + |R u_t|)^2 / N`` with ``R^T R = Q`` (worst case over the 1-sigma ellipsoid, SOC).
    """
    if robust_mode not in ("mean", "worst"):
        raise ValueError(f"unknown robust mode {robust_mode!r}")
    robust_q = None if robust_q is None else (robust_q, robust_mode)
    import time

    G = np.asarray(gains, dtype=float)
    P = np.asarray(targets, dtype=float)
    if G.ndim != 2 or G.shape[0] != 2 or P.ndim != 2 or P.shape[1] != 2:
        raise ValueError("gains must be (2, K) and targets (N, 2)")
    kw = {} if solvers is None else {"solvers": solvers}
    auto_slew = slew_model == "auto"
    model = "linear" if auto_slew else slew_model
    t0 = time.perf_counter()
    prob, X, scale = _build(G, P, dt, limits, tolerance, u_start, lam, model, robust=robust_q)
    t1 = time.perf_counter()
    result = solve(prob, "path following", **kw)
    t2 = time.perf_counter()
    notes: list[str] = []
    if (slew_model == "auto" and result.ok and limits.slew_rate is not None
            and _max_slew(np.asarray(X.value) * scale["vmax2"], u_start, dt)
            > limits.slew_rate * (1 + 1e-6)):
        notes.append("the QP slew relaxation was violated; re-solved with exact slew cones")
        model = "exact"
        prob, X, scale = _build(G, P, dt, limits, tolerance, u_start, lam, model, robust=robust_q)
        result = solve(prob, "path following (exact slew)", **kw)
        t2 = time.perf_counter()
    slew_model = model
    if result.infeasible:
        # the Cauchy-Schwarz plane is conservative; retry with the tangent planes of the true
        # total-amplitude limit at each waypoint's least-power static solution (still sound)
        u0 = _static_least_power(G, P, limits, tolerance, solvers)
        retry = None if u0 is None else _tangent_solve(G, P, dt, limits, tolerance, u_start, lam,
                                                        slew_model, u0, solvers, robust_q)
        if retry is None:
            raise PathInfeasible(diagnose_path(G, P, dt, limits, tolerance, u_start, slew_model,
                                               status=result.status))
        X, result = retry
        if (auto_slew and limits.slew_rate is not None and slew_model == "linear"
                and _max_slew(np.asarray(X.value) * scale["vmax2"], u_start, dt)
                > limits.slew_rate * (1 + 1e-6)):
            slew_model = "exact"
            retry = _tangent_solve(G, P, dt, limits, tolerance, u_start, lam, slew_model, u0, solvers, robust_q)
            if retry is None:
                raise PathInfeasible(diagnose_path(G, P, dt, limits, tolerance, u_start, slew_model,
                                                   status="infeasible"))
            X, result = retry
        t2 = time.perf_counter()
        notes.append("the conservative total-amplitude plane was infeasible; solved with tangent "
                     "planes of the exact limit at each waypoint's least-power solution")
    if not result.ok:
        raise PathInfeasible(PathDiagnosis(0, 0.0, tuple(P[0]), ("solver status " + result.status,),
                                           ("check the gains: a zero or non-finite gain vector",),
                                           result.status))
    if result.status != "optimal":
        notes.append(f"the solver ({result.solver}) reported an inaccurate optimum (badly scaled gains?); "
                     "the re-simulated error below is what counts")
    u = np.maximum(np.asarray(X.value), 0.0) * scale["vmax2"]
    for it in range(refine):
        u_new = _refine_total(G, P, dt, limits, tolerance, u_start, lam, slew_model, u, solvers, robust_q)
        if u_new is None:
            notes.append(f"total-amplitude refinement {it + 1} did not converge; kept previous")
            break
        u = u_new
    return PathPlan(u=u, targets=P, predicted=(G @ u).T, result=result,
                    build_time_s=t1 - t0, solve_time_s=t2 - t1, notes=notes)


def _max_slew(u, u_start, dt) -> float:
    v = np.sqrt(np.maximum(u, 0.0))
    if u_start is not None:
        v = np.hstack([np.sqrt(np.maximum(np.asarray(u_start, float), 0)).reshape(-1, 1), v])
    return float(np.max(np.abs(np.diff(v, axis=1)))) / dt if v.shape[1] > 1 else 0.0


def _scaled(G, P, limits):
    vmax2 = limits.max_voltage ** 2
    Gs = G * vmax2 / UM               # um per unit x (x = u / Vmax^2)
    Ps = P.T / UM                     # (2, N) um
    return Gs, Ps, vmax2


def _build(G, P, dt, limits, tolerance, u_start, lam, slew_model, total_coeffs=None,
           with_tolerance=True, with_total=True, with_tone=True, with_slew=True, robust=None):
    import cvxpy as cp

    K, N = G.shape[1], P.shape[0]
    Gs, Ps, vmax2 = _scaled(G, P, limits)
    X = cp.Variable((K, N), nonneg=True)
    err = Gs @ X - Ps
    # drive weight: with |g| um per unit x, the drive term biases the error by about lam/2 um
    gnorm = float(np.sqrt(np.max(np.sum(Gs ** 2, axis=0)))) or 1.0
    objective = cp.sum_squares(err) / N + lam * gnorm * cp.sum(X) / N
    if robust is not None:
        from acl.schedule.robust import scaled_factor

        Q, mode = robust
        R = scaled_factor(Q, vmax2)
        if mode == "worst":      # worst case over |z| <= 1: |e_t| + |R x_t| per waypoint (second-order cones)
            objective = (cp.sum_squares(cp.norm(err, 2, axis=0) + cp.norm(R @ X, 2, axis=0)) / N
                         + lam * gnorm * cp.sum(X) / N)
        else:                    # expected squared error: |e_t|^2 + x_t^T Q x_t
            objective = objective + cp.sum_squares(R @ X) / N
    cons = []
    if with_tone:
        cap = (limits.tone_cap(K) ** 2 / vmax2).reshape(K, 1)
        cons.append(X <= np.broadcast_to(cap, (K, N)))
    if with_total:
        if total_coeffs is None:
            cons.append(cp.sum(X, axis=0) <= 1.0 / K)
        else:
            a, b = total_coeffs      # tangent: sum_k c_kt x_kt <= b_t
            cons.append(cp.sum(cp.multiply(a, X), axis=0) <= b)
    if with_tolerance:
        tol = tolerance / UM
        cons += [err <= tol, -err <= tol]
    if with_slew and limits.slew_rate is not None:
        # consecutive waypoints; the first waypoint slews from u_start when one is given
        pairs = [(X[:, :-1], X[:, 1:])] if N > 1 else []
        if u_start is not None:
            x0 = np.asarray(u_start, float).reshape(K, 1) / vmax2
            pairs.append((cp.Constant(x0), X[:, :1]))
        for a, b in pairs:
            if slew_model == "linear":
                s = 2 * limits.slew_rate * dt / limits.max_voltage
                cons += [b - a <= s, a - b <= s]
            elif slew_model == "exact":
                s = limits.slew_rate * dt / limits.max_voltage     # in units of Vmax
                cons += [b - a - s ** 2 <= 2 * s * cp.sqrt(a), a - b - s ** 2 <= 2 * s * cp.sqrt(b)]
            else:
                raise ValueError(f"unknown slew model {slew_model!r}")
    prob = cp.Problem(cp.Minimize(objective), cons)
    return prob, X, {"vmax2": vmax2}


def _tangent_coeffs(u, vmax):
    """Tangent plane of sum_k sqrt(x_k) <= 1 at x = u / Vmax^2 (floored): sum_k a_k x_k <= b."""
    x = np.maximum(u / vmax ** 2, 0.02 ** 2)
    return 1.0 / (2.0 * np.sqrt(x)), 1.0 - np.sum(np.sqrt(x) / 2.0, axis=0)


def _tangent_solve(G, P, dt, limits, tolerance, u_start, lam, slew_model, u, solvers, robust=None):
    """Solve with the total limit replaced by its tangent planes at ``u``; (X, result) or None."""
    a, b = _tangent_coeffs(u, limits.max_voltage)
    if np.any(b <= 0):
        return None
    prob, X, _ = _build(G, P, dt, limits, tolerance, u_start, lam, slew_model, total_coeffs=(a, b), robust=robust)
    kw = {} if solvers is None else {"solvers": solvers}
    res = solve(prob, "path following (tangent total-amplitude limit)", **kw)
    return (X, res) if res.ok else None


def _refine_total(G, P, dt, limits, tolerance, u_start, lam, slew_model, u, solvers, robust=None):
    """One convex-concave step: tangent of sum_k sqrt(x_k) <= 1 at the current solution."""
    out = _tangent_solve(G, P, dt, limits, tolerance, u_start, lam, slew_model, u, solvers, robust)
    return None if out is None else np.maximum(np.asarray(out[0].value), 0.0) * limits.max_voltage ** 2


def _static_least_power(G, P, limits, tolerance, solvers):
    """Per waypoint, the least total power meeting the tolerance under per-tone caps (one LP), or
    None if some waypoint cannot be met or its least power breaks the true total limit."""
    import cvxpy as cp

    prob, X, _ = _build(G, P, 1.0, limits, tolerance, None, 0.0, "linear", with_total=False,
                        with_slew=False)
    kw = {} if solvers is None else {"solvers": solvers}
    res = solve(cp.Problem(cp.Minimize(cp.sum(X)), prob.constraints), "path (least power)", **kw)
    if not res.ok:
        return None
    u = np.maximum(np.asarray(X.value), 0.0) * limits.max_voltage ** 2
    a, b = _tangent_coeffs(u, limits.max_voltage)
    if np.any(np.sum(a * u / limits.max_voltage ** 2, axis=0) > b * (1 - 1e-9)):
        return None
    return u


# --------------------------------------------------------------------------------------------
# Diagnosis of an infeasible path
# --------------------------------------------------------------------------------------------

def diagnose_path(G, P, dt, limits, tolerance, u_start, slew_model, status="infeasible") -> PathDiagnosis:
    """Find the first waypoint that cannot be met and the constraints that bind there.

    1. Each waypoint alone (no slew): one separable LP with an elastic slack per waypoint; the
       first waypoint with a positive slack is statically out of reach.  Which limits bind is
       found by dropping the total / per-tone limits in turn.
    2. If every waypoint is reachable alone, the slew limit binds: a bisection on the prefix
       length (log2 N feasibility solves) finds the first waypoint the slew cannot follow.
    """
    bad = _first_elastic(G, P, dt, limits, tolerance, u_start, slew_model, with_slew=False)
    if bad is not None:
        binding, relax = [], []
        free_total = _first_elastic(G, P[bad:bad + 1], dt, limits, tolerance, None, slew_model,
                                    with_slew=False, with_total=False)
        free_tone = _first_elastic(G, P[bad:bad + 1], dt, limits, tolerance, None, slew_model,
                                   with_slew=False, with_total=False, with_tone=False)
        if free_total is None:
            binding.append("total amplitude limit (sum of tone amplitudes <= max voltage)")
            relax.append(f"raise the max voltage above {limits.max_voltage:g} V")
        elif free_tone is None:
            binding.append("per-tone amplitude limit")
            relax.append("raise the per-tone voltage limit" if limits.per_tone_voltage is not None
                         else f"raise the max voltage above {limits.max_voltage:g} V "
                              "(it also caps each tone alone)")
        else:
            binding.append("direction: the target lies outside the cone of the tones' gain vectors")
            relax.append("choose tones whose displacement directions surround the path")
        relax.append("shrink or re-centre the path towards the rest position")
        relax.append(f"increase the tracking tolerance (now {tolerance / UM:g} um)")
        return PathDiagnosis(bad, bad * dt, tuple(P[bad]), tuple(binding), tuple(relax), status)
    if limits.slew_rate is None:   # no slew limit to blame: every waypoint alone is reachable, together they are not
        return PathDiagnosis(0, 0.0, tuple(P[0]), ("the solvers could not find a plan although every waypoint "
                                                    "alone is reachable (a badly scaled problem)",),
                             ("check the gains and the declared uncertainty for absurd values",
                              f"increase the tracking tolerance (now {tolerance / UM:g} um)"), status)
    bad = _first_prefix_infeasible(G, P, dt, limits, tolerance, u_start, slew_model)
    return PathDiagnosis(bad, bad * dt, tuple(P[bad]),
                         (f"slew-rate limit ({limits.slew_rate:g} V/s)",),
                         ("raise the slew-rate limit", "slow down: a longer duration or lower speed",
                          f"increase the tracking tolerance (now {tolerance / UM:g} um)"), status)


def _first_elastic(G, P, dt, limits, tolerance, u_start, slew_model, with_slew,
                   with_total=True, with_tone=True) -> int | None:
    """Index of the first waypoint whose tolerance must be relaxed, or None if none must."""
    import cvxpy as cp

    prob, X, _ = _build(G, P, dt, limits, tolerance, u_start, 0.0, slew_model,
                        with_tolerance=False, with_slew=with_slew, with_total=with_total,
                        with_tone=with_tone)
    Gs, Ps, _ = _scaled(G, P, limits)
    slack = cp.Variable(P.shape[0], nonneg=True)
    tol = tolerance / UM
    err = Gs @ X - Ps
    cons = list(prob.constraints) + [cp.abs(err[0, :]) <= tol + slack,
                                     cp.abs(err[1, :]) <= tol + slack]
    res = solve(cp.Problem(cp.Minimize(cp.sum(slack)), cons), "path diagnosis")
    if not res.ok:
        return 0
    s = np.asarray(slack.value)
    hits = np.flatnonzero(s > 1e-4 * max(tol, 1e-3))
    return int(hits[0]) if hits.size else None


def _first_prefix_infeasible(G, P, dt, limits, tolerance, u_start, slew_model) -> int:
    """Smallest n such that waypoints 0..n cannot all be met (bisection on the prefix length)."""
    def feasible(n: int) -> bool:
        prob, _, _ = _build(G, P[:n + 1], dt, limits, tolerance, u_start, 0.0, slew_model)
        return solve(prob, "path diagnosis (prefix)").ok

    lo, hi = 0, P.shape[0] - 1          # invariant: prefix hi infeasible (the whole path is)
    if not feasible(lo):
        return 0
    while hi - lo > 1:                  # prefix lo feasible, prefix hi infeasible
        mid = (lo + hi) // 2
        if feasible(mid):
            lo = mid
        else:
            hi = mid
    return hi
