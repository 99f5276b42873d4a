"""Bounded, weighted nonlinear least squares with lmfit-style statistics (values, intervals, correlations, warnings).

Coordinates are fitted in units of their typical magnitude (``Coef.scale``) with
``scipy.optimize.least_squares(method="trf", x_scale="jac", diff_step=DIFF_STEP)``; weights are 1/sigma (unit weights of
1 um when the data give no sigma, the scale then estimated from the residual).  Covariance
cov = s^2 (J^T J)^-1 with s^2 the reduced chi-square (lmfit's default), intervals from Student's t.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

NOMINAL_SIGMA = 1e-6      # m: weight unit when the data give no sigma
DIFF_STEP = 1e-6          # relative finite-difference step of the Jacobian (well above the equilibrium solver's 1e-12 relative precision)
CORR_STRONG = 0.9
JUMP = 10.0             # weighted residual (in sigma) beyond which a row is a jump suspect
SPIKE = 100.0            # a Jacobian row this many times the median row norm is a fold row


@dataclass
class Coef:
    """One fitted coordinate: a model coefficient (gamma, alpha, E, gain) or an effect parameter."""

    name: str                 # shown to the user: gamma, alpha, E, gain, or effect.param
    kind: str                 # "gamma" | "alpha" | "e_scale" | "gain" | "effect"
    value: float              # current / initial value (internal coordinate, SI)
    lower: float
    upper: float
    scale: float              # typical magnitude (fit coordinate = value / scale)
    unit: str = ""
    effect: str | None = None
    param: str | None = None
    design_param: str | None = None   # the design parameter it stands for, if any


@dataclass
class FitResult:
    coefs: list
    values: np.ndarray
    stderr: np.ndarray
    ci: np.ndarray                    # (p, 2) 95 % interval
    corr: np.ndarray
    prediction: np.ndarray            # (n,) SI, all rows
    residual: np.ndarray              # (n,) prediction - data, SI (a latch state: its Pearson residual)
    train: np.ndarray                 # rows used
    n: int
    p: int
    chi2: float                       # weighted sum of squares (train rows)
    redchi: float
    rmse: float                       # SI, unweighted, train rows
    aicc: float
    bic: float
    success: bool
    message: str
    warnings: list = field(default_factory=list)
    identifiable: bool = True
    full_rank: bool = True            # the Jacobian has full rank (False: some direction is not determined at all)
    wresidual: np.ndarray = None      # (n,) weighted residual whose squares sum to -2 ln L + const (a latch state: its
    #                                   deviance residual); chi2 is its sum of squares over the train rows
    n_scale: int = 0                  # train rows whose weighted residual has a scale to estimate (all but latch states)
    chi2_scale: float = 0.0           # their weighted sum of squares (chi2 without the states' deviance)

    @property
    def covariance(self) -> np.ndarray:
        """(p, p) covariance of the fitted coordinates (SI): s^2 (J^T J)^-1, NaN where not identifiable."""
        return self.corr * np.outer(self.stderr, self.stderr)

    def value(self, name):
        for c, v in zip(self.coefs, self.values):
            if c.name == name:
                return float(v)
        raise KeyError(name)

    def as_inputs(self):
        return split_coefs(self.coefs, self.values)


def split_coefs(coefs, values, fixed_effects=None):
    """(coeffs dict, effects dict) for acl.fit.forward.predict from coordinates and values."""
    coeffs: dict = {}
    effects: dict = {k: dict(v) for k, v in (fixed_effects or {}).items()}
    for c, v in zip(coefs, values):
        if c.kind == "effect":
            effects.setdefault(c.effect, {})[c.param] = float(v)
        else:
            coeffs[c.kind] = float(v)
    return coeffs, effects


def fit(predict, y, sigma, coefs, train=None, starts=None, max_nfev=200, robust_start=False) -> FitResult:
    """Fit ``coefs`` so that ``predict(coeffs, effects)`` matches ``y`` on rows ``train``.

    ``starts``: extra starting vectors (values); the best (lowest cost) solution is kept.
    ``robust_start``: begin each start with a soft-l1 pass (f_scale 3 sigma), so that a few rows with
    huge residuals (e.g. predicted in contact past snap-in while measured before it) do not trap the
    optimizer; the final fit is always the plain weighted least squares.
    """
    n_all = y.size
    train = np.arange(n_all) if train is None else np.asarray(train)
    w = 1.0 / np.where(np.isfinite(sigma), sigma, NOMINAL_SIGMA)
    scale = np.array([c.scale for c in coefs], float)
    lo = np.array([c.lower for c in coefs], float) / scale if coefs else np.zeros(0)
    hi = np.array([c.upper for c in coefs], float) / scale if coefs else np.zeros(0)

    def full(u):
        coeffs, effects = split_coefs(coefs, u * scale)
        return predict(coeffs, effects)

    def resid(u):
        r = (full(u)[train] - y[train]) * w[train]
        return np.where(np.isfinite(r), r, 1e6)

    many = getattr(predict, "many", None)
    if many is not None:
        # [full(u) for u in us] and [resid(u) for u in us], the predictions made at once (acl.fit.forward.Model)
        full.many = lambda us: many([split_coefs(coefs, u * scale) for u in us])
        resid.many = lambda us: [np.where(np.isfinite(r), r, 1e6) for r in
                                 ((o[train] - y[train]) * w[train] for o in full.many(us))]

    def least_squares(fun, x0, **kw):
        if getattr(fun, "many", None) is not None:
            kw["fun_many"] = fun.many
        return fd_least_squares(fun, x0, **kw)

    best, message, success = None, "no free parameters", True
    from acl.fit.forward import REWEIGHT

    REWEIGHT.generation += 1           # latch states: this fit searches on their likelihood (acl.fit.forward)
    REWEIGHT.seen = False
    x0s = [np.array([c.value for c in coefs], float)] + [np.asarray(s, float) for s in (starts or [])]
    if coefs:
        # several starts: a short run from each, then the best one is continued (multi-start pruning)
        budget = max_nfev if len(x0s) == 1 else max(6, max_nfev // 30)
        for x0 in x0s:
            u0 = np.clip(x0 / scale, lo, hi)
            span = hi - lo
            u0 = np.clip(u0, lo + 1e-6 * span, hi - 1e-6 * span)
            try:
                if robust_start:   # soft-l1 pass first: jumps (snap-in rows) cannot trap the start
                    pre = least_squares(resid, u0, bounds=(lo, hi), method="trf", x_scale="jac", diff_step=DIFF_STEP, loss="soft_l1",
                                        f_scale=3.0, max_nfev=max_nfev // 2, xtol=1e-8, ftol=1e-8, gtol=1e-8)
                    u0 = np.clip(pre.x, lo + 1e-9 * span, hi - 1e-9 * span)
                sol = least_squares(resid, u0, bounds=(lo, hi), method="trf", x_scale="jac", diff_step=DIFF_STEP,
                                    max_nfev=budget, xtol=1e-10, ftol=1e-10, gtol=1e-10)
            except ValueError as exc:
                message, success = str(exc), False
                continue
            if best is None or sol.cost < best.cost:
                best = sol
        if best is not None and budget < max_nfev and best.status == 0:     # budget exhausted: continue the best
            try:
                span = hi - lo
                u0 = np.clip(best.x, lo + 1e-9 * span, hi - 1e-9 * span)
                sol = least_squares(resid, u0, bounds=(lo, hi), method="trf", x_scale="jac", diff_step=DIFF_STEP,
                                    max_nfev=max_nfev, xtol=1e-10, ftol=1e-10, gtol=1e-10)
                if sol.cost <= best.cost:
                    best = sol
            except ValueError:
                pass
        if best is not None:
            best = _escape_jumps(best, resid, train, full, y, w, lo, hi, max_nfev, least_squares)
        if best is not None:
            best = _reweighted(best, resid, full, lo, hi, max_nfev, least_squares)
        if best is None:
            u, J = x0s[0] / scale, np.zeros((train.size, len(coefs)))
        else:
            u, J, message, success = best.x, best.jac, best.message, bool(best.status > 0)
    else:
        u, J = np.zeros(0), np.zeros((train.size, 0))
    pred = full(u)
    r = pred - y
    rw_all = r * w
    seen_states = REWEIGHT.seen and REWEIGHT.rows is not None and np.shape(REWEIGHT.rows) == (n_all,)
    if REWEIGHT.seen:
        # latch states: the residual shown is the Pearson residual (variances held at the optimum), but the statistics
        # (chi-square, F-tests, information criteria, cross-validation) use the deviance residual, whose sum of
        # squares is -2 ln L: a row the model contradicts (p ~ 1, no switch) counts by its likelihood, not by a
        # Pearson residual divided by a variance clamped near zero.  A new generation drops the held variances.
        REWEIGHT.generation += 1
        rw_all = (full(u) - y) * w
    rw = rw_all[train]
    n, p = train.size, len(coefs)
    chi2 = float(rw @ rw)
    # latch states (0/1, acl.fit.forward) count by their deviance, which has no scale to estimate: the residual
    # variance (reduced chi-square, the covariance's scale, the F-test's denominator) and the Gaussian part of the
    # likelihood come from the other rows alone (with many states their near-zero deviances halved the reduced
    # chi-square: intervals too narrow by ~1.4x and F statistics doubled); states alone (binary outcomes) have their
    # dispersion fixed at 1 (McCullagh & Nelder 1989, sec. 4.5)
    states = np.asarray(REWEIGHT.rows, bool)[train] if seen_states else np.zeros(n, bool)
    n_scale = int(n - states.sum())
    chi2_scale = float(rw[~states] @ rw[~states]) if n_scale < n else chi2
    if n_scale < n and n_scale - p < 1:
        dof, redchi = max(n - p, 1), 1.0
    else:
        dof = max(n_scale - p, 1)
        redchi = chi2_scale / dof
    values = u * scale
    stderr = np.full(p, np.nan)
    corr = np.eye(p)
    warnings: list[str] = []
    identifiable = full_rank = True
    if p:
        rn = np.linalg.norm(J, axis=1)
        # the median over rows that carry information (a threshold observable, a latch state, has rows of
        # essentially zero slope far from its threshold: they must not make its informative rows look like spikes)
        live = rn > 1e-6 * rn.max() if rn.size else rn > 0
        med = float(np.median(rn[live])) if np.any(live) else 0.0
        spike = rn > SPIKE * med if med > 0 else np.zeros(rn.size, bool)
        if not REWEIGHT.seen and best is not None:
            # a jump's slope makes every other row look negligible (it is the max above), so a fold inside the step
            # went unnoticed: rows far above the median of all sloped rows are checked at a 100x smaller step
            nz = rn[rn > 0]
            cand = rn > SPIKE * float(np.median(nz)) if nz.size else np.zeros(rn.size, bool)
            if np.any(cand & ~spike):
                spike |= _jump_rows(resid, u, J, lo, hi, cand & ~spike)
        if np.any(spike) and spike.sum() < rn.size - p:
            J = J[~spike]
            warnings.append(f"{int(spike.sum())} row(s) sit where the model is nearly singular (e.g. at the "
                            "snap-in fold); left out of the interval estimate")
        sv = np.linalg.svd(J, compute_uv=False)
        if sv.size == 0 or sv[-1] <= 1e-9 * max(sv[0], 1e-300):
            identifiable = full_rank = False
            warnings.append("the parameters are not all identifiable from these data (rank-deficient Jacobian)")
        else:
            try:
                cov_u = np.linalg.inv(J.T @ J) * redchi
            except np.linalg.LinAlgError:
                cov_u = np.linalg.pinv(J.T @ J) * redchi
                identifiable = full_rank = False
                warnings.append("the parameters are not all identifiable from these data (singular J^T J)")
            stderr = np.sqrt(np.clip(np.diag(cov_u), 0, None)) * scale
            d = np.sqrt(np.clip(np.diag(cov_u), 1e-300, None))
            with np.errstate(all="ignore"):
                corr = np.nan_to_num(cov_u / np.outer(d, d))
    from scipy.stats import t as student

    tq = float(student.ppf(0.975, dof))
    ci = np.column_stack([values - tq * stderr, values + tq * stderr])
    for k, c in enumerate(coefs):
        span = c.upper - c.lower
        if c.lower > 0 and np.isfinite(span) and values[k] > 0:
            # bounds a factor apart (gamma's 1e-3..1e3 of its start): nearness on the log scale (1e-4 of the span, as
            # below); the linear test called anything under 0.1x the start "at a bound"
            lspan = math.log(c.upper / c.lower)
            low_end, high_end = (math.log(values[k] / c.lower) <= 1e-4 * lspan, math.log(c.upper / values[k]) <= 1e-4 * lspan)
        else:
            low_end = abs(values[k] - c.lower) <= 1e-4 * span
            high_end = abs(c.upper - values[k]) <= 1e-4 * span
        if np.isfinite(span) and (low_end or high_end):
            if not (c.kind == "effect" and low_end and c.lower == 0.0):
                warnings.append(f"{c.name} is at a bound ({_fmt(values[k])})")
        rel = stderr[k] / max(abs(values[k]), 1e-300)
        if c.kind != "effect" and np.isfinite(rel) and rel > 1.0:
            identifiable = False
            warnings.append(f"{c.name} is not identifiable (relative standard error {rel:.3g})")
    for i in range(p):
        for j in range(i + 1, p):
            if abs(corr[i, j]) > CORR_STRONG:
                warnings.append(f"strong correlation {coefs[i].name} / {coefs[j].name}: r = {corr[i, j]:+.3f}")
    k = p + 1
    if n_scale < n:
        # -2 ln L (+ const) with the Gaussian rows' scale profiled out, plus the states' deviance
        ll2 = n_scale * math.log(max(chi2_scale, 1e-300) / max(n_scale, 1)) + (chi2 - chi2_scale)
    else:
        ll2 = n * math.log(max(chi2, 1e-300) / n)
    aic = ll2 + 2 * k
    aicc = aic + (2 * k * (k + 1)) / max(n - k - 1, 1)
    bic = ll2 + k * math.log(n)
    rmse = float(np.sqrt(np.mean(r[train] ** 2)))
    return FitResult(list(coefs), values, stderr, ci, corr, pred, r, train, n, p, chi2, redchi, rmse, aicc, bic,
                     success, str(message), warnings, identifiable, full_rank, rw_all, n_scale, chi2_scale)


GRID_POINTS = 300     # model evaluations of the start grid (:func:`grid_starts`)
GRID_SPAN = 8.0       # the grid spans value / GRID_SPAN .. value * GRID_SPAN on each positive coordinate


def grid_starts(predict, y, sigma, coefs, k=2, points=GRID_POINTS, span=GRID_SPAN) -> list:
    """The ``k`` lowest-cost points of a log-spaced grid over the positive coordinates of ``coefs`` (within their
    bounds, the others held at their values), as extra starts of :func:`fit`: a fit trapped at a snap-in fold (rows
    predicted in contact that were measured apart give no gradient) starts again from the valley a grid sees (a pair
    with a calibration beam, neighbour drag not in the model: chi-square 890,102 from the design's values, 58,725
    from the grid's best point).  Empty when no coordinate is positive or the grid would be coarser than 3 points a
    side.  One model evaluation per point, at once when the model can (``predict.many``)."""
    free = [i for i, c in enumerate(coefs) if c.lower > 0 and c.value > 0]
    if not free:
        return []
    side = int(math.floor(points ** (1.0 / len(free)) + 1e-9))
    if side < 3:
        return []
    x0 = np.array([c.value for c in coefs], float)
    axes = []
    for i in free:
        c = coefs[i]
        lo, hi = max(c.lower, c.value / span), min(c.upper, c.value * span)
        axes.append(np.geomspace(lo, hi, side) if hi > lo else np.array([c.value]))
    mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(free))
    xs = np.repeat(x0[None, :], mesh.shape[0], axis=0)
    xs[:, free] = mesh
    w = 1.0 / np.where(np.isfinite(sigma), sigma, NOMINAL_SIGMA)
    inputs = [split_coefs(coefs, x) for x in xs]
    many = getattr(predict, "many", None)
    outs = many(inputs) if many is not None else [predict(*a) for a in inputs]
    cost = np.array([float(np.sum(np.where(np.isfinite(r), r, 1e6) ** 2)) for r in ((o - y) * w for o in outs)])
    return [list(xs[j]) for j in np.argsort(cost, kind="stable")[:k]]


def fd_least_squares(fun, x0, *, bounds, diff_step, fun_many=None, **kw):
    """``scipy.optimize.least_squares(fun, x0, bounds=bounds, diff_step=diff_step, **kw)`` with its "2-point" Jacobian
    made the same way (scipy's approx_derivative, the same steps and bounds) but evaluated inside
    acl.fit.forward.FD_COLUMNS: the columns are neighbours of the point just evaluated, so a pair's equilibrium starts
    from that solve (acl.fit.forward._pair_solve).  ``fun_many(us) = [fun(u) for u in us]`` (the same numbers), if
    given, evaluates the columns at once (approx_derivative's ``workers`` map, scipy >= 1.16; acl.fit.forward.predict_many).
    The optimizer's own steps are evaluated as before."""
    import inspect

    from scipy.optimize import least_squares

    try:
        from scipy.optimize._numdiff import approx_derivative
    except ImportError:     # a private scipy module: without it, scipy's own 2-point Jacobian (the same steps, no reuse)
        return least_squares(fun, x0, bounds=bounds, diff_step=diff_step, **kw)
    extra = {}
    if fun_many is not None and "workers" in inspect.signature(approx_derivative).parameters:
        extra["workers"] = lambda _f, xs: fun_many([np.asarray(x, dtype=float) for x in xs])

    from acl.fit.forward import FD_COLUMNS

    last: dict = {}

    def f(u):
        r = fun(u)
        if not FD_COLUMNS.active:
            last["u"], last["r"] = np.array(u, dtype=float, copy=True), r
        return r

    def jac(u):
        f0 = last["r"] if "u" in last and np.array_equal(last["u"], u) else f(u)
        with FD_COLUMNS:
            return approx_derivative(f, u, method="2-point", rel_step=diff_step, f0=np.atleast_1d(f0), bounds=bounds,
                                     **extra)

    return least_squares(f, x0, jac=jac, bounds=bounds, **kw)


def _jump_rows(resid, u, J, lo, hi, cand) -> np.ndarray:
    """Rows (among ``cand``) whose Jacobian entry is a jump, not a derivative (a snap-in fold inside the step): the
    slope at a 100x smaller step, forward or backward, differs from it by more than half (numerical differentiation:
    a smooth row agrees to the order of the step)."""
    r0 = resid(u)
    jump = np.zeros(J.shape[0], bool)
    for k in range(u.size):
        h = DIFF_STEP * max(1.0, abs(float(u[k]))) / 100.0
        for s in (1.0, -1.0):
            x = u.copy()
            x[k] += s * h
            if not lo[k] <= x[k] <= hi[k]:
                continue
            d = (resid(x) - r0) / (s * h)
            jump |= cand & (np.abs(d - J[:, k]) > 0.5 * np.abs(J[:, k]) + 1e-9 * np.linalg.norm(J[:, k]))
    return jump


def _reweighted(best, resid, full, lo, hi, max_nfev, least_squares):
    """Latch states (0/1 rows, acl.fit.forward): the search ran on their deviance residuals (maximum likelihood);
    hold their binomial variances at its optimum and take the Jacobian of the Pearson residuals there, whose J^T J is
    the Fisher information (the intervals).  The optimum is *not* moved: a least-squares polish on Pearson residuals
    with held variances agrees with the likelihood only near a good fit; where the model contradicts outcomes (p ~ 1
    for a ramp that did not switch, its variance clamped at 1e-10) a Pearson residual of 1e5 would drag the polish to
    an arbitrary point.  Nothing happens without state rows."""
    from scipy.optimize import OptimizeResult

    from acl.fit.forward import REWEIGHT

    if not REWEIGHT.seen:                   # no prediction of this fit had state rows
        return best
    with REWEIGHT:
        full(best.x)
    x = np.asarray(best.x, float)
    f0 = resid(x)
    J = np.empty((f0.size, x.size))
    for k in range(x.size):                 # forward differences as least_squares' "2-point" with DIFF_STEP
        h = DIFF_STEP * max(1.0, abs(x[k]))
        if x[k] + h > hi[k]:
            h = -h
        xk = x.copy()
        xk[k] += h
        J[:, k] = (resid(xk) - f0) / h
    return OptimizeResult(x=x, fun=f0, jac=J, cost=0.5 * float(f0 @ f0), status=best.status, message=best.message,
                          nfev=getattr(best, "nfev", 0), success=best.success)


def _escape_jumps(best, resid, train, full, y, w, lo, hi, max_nfev, least_squares):
    """Leave out the few rows beyond JUMP sigma (a discontinuity such as snap-in traps the optimizer there),
    refit, and keep the result only if the cost over *all* rows is lower; then polish on all rows.  Then probe
    across the fold (:func:`_probe_folds`)."""
    best = _leave_out_jumps(best, resid, train, full, y, w, lo, hi, max_nfev, least_squares)
    return _probe_folds(best, resid, lo, hi, max_nfev, least_squares)


PROBE_STEPS = (-4.0, -2.0, -1.0, -0.5, 0.5, 1.0, 2.0, 4.0)   # probe offsets along each principal axis, in standard errors
PROBE_POLISH = 2                                             # probes polished by a full fit


def _probe_folds(best, resid, lo, hi, max_nfev, least_squares):
    """Rows predicted on the other side of a fold (past snap-in in the model, not in the data) contribute no
    gradient: the optimizer cannot see that a move of a fraction of a standard error would bring them back.  Probe
    the solution along each principal axis of its covariance (the rows within JUMP sigma only) at PROBE_STEPS standard
    errors (one model evaluation each); from the PROBE_POLISH probes with the fewest rows beyond JUMP sigma (then the
    lowest cost) that have fewer than the solution, fit again, and keep a result whose cost over all rows is lower."""
    r = best.fun
    big = np.abs(r) > JUMP
    p = best.x.size
    if p == 0 or not big.any() or big.sum() > 0.05 * r.size or r.size - big.sum() <= p:
        return best
    J = best.jac[~big]
    s2 = float(np.sum(r[~big] ** 2)) / (r.size - big.sum() - p)
    lam, vec = np.linalg.eigh(J.T @ J)
    ok = lam > 1e-12 * max(lam.max(), 1e-300)
    probes = []
    us = []
    for k in np.flatnonzero(ok):
        step = np.sqrt(s2 / lam[k]) * vec[:, k]
        for m in PROBE_STEPS:
            us.append(np.clip(best.x + m * step, lo, hi))
    # the probes are independent evaluations: at once when the model can (resid.many, the same numbers)
    many = getattr(resid, "many", None)
    for u, rr in zip(us, many(us) if many is not None and us else map(resid, us)):
        probes.append((int(np.sum(np.abs(rr) > JUMP)), float(0.5 * rr @ rr), u))
    better = sorted((q for q in probes if q[0] < big.sum()), key=lambda q: (q[0], q[1]))[:PROBE_POLISH]
    span = hi - lo
    for _, _, u in better:
        try:
            sol = least_squares(resid, np.clip(u, lo + 1e-9 * span, hi - 1e-9 * span), bounds=(lo, hi), method="trf",
                                x_scale="jac", diff_step=DIFF_STEP, max_nfev=max_nfev, xtol=1e-10, ftol=1e-10,
                                gtol=1e-10)
        except ValueError:
            continue
        if sol.cost < best.cost:
            best = sol
    return best


def _leave_out_jumps(best, resid, train, full, y, w, lo, hi, max_nfev, least_squares):
    r = best.fun
    big = np.abs(r) > JUMP
    if not big.any() or big.sum() > 0.05 * r.size:
        return best
    keep = train[~big]

    def sub(u):
        rr = (full(u)[keep] - y[keep]) * w[keep]
        return np.where(np.isfinite(rr), rr, 1e6)

    if getattr(full, "many", None) is not None:      # [sub(u) for u in us] at once (the Jacobian's columns)
        sub.many = lambda us: [np.where(np.isfinite(rr), rr, 1e6) for rr in
                               ((o[keep] - y[keep]) * w[keep] for o in full.many(us))]

    try:
        alt = least_squares(sub, best.x, bounds=(lo, hi), method="trf", x_scale="jac", diff_step=DIFF_STEP, max_nfev=max_nfev,
                            xtol=1e-10, ftol=1e-10, gtol=1e-10)
        cost = 0.5 * float(np.sum(resid(alt.x) ** 2))
        if cost < best.cost:
            pol = least_squares(resid, alt.x, bounds=(lo, hi), method="trf", x_scale="jac", diff_step=DIFF_STEP, max_nfev=max_nfev,
                                xtol=1e-10, ftol=1e-10, gtol=1e-10)
            return pol if pol.cost <= cost else best
    except ValueError:
        pass
    return best


def f_test(chi2_small, p_small, chi2_big, p_big, n, scale=None) -> tuple[float, float]:
    """Nested-model F-test: F = ((RSS0 - RSS1)/(p1 - p0)) / (RSS1/(n - p1)); returns (F, p-value).

    ``scale``: (chi-square, rows) of the bigger model's rows that carry a scale, when some rows do not (latch states
    count by their deviance): the denominator is then that chi-square over (rows - p1), the residual variance of the
    Gaussian rows, and the numerator the drop of -2 ln L over all rows (a likelihood-ratio statistic in units of the
    estimated variance)."""
    from scipy.stats import f as fdist

    dp = p_big - p_small
    rss, rows = (chi2_big, n) if scale is None else scale
    dof = rows - p_big
    if dp <= 0 or dof <= 0 or rss <= 0:
        return float("nan"), 1.0
    F = ((chi2_small - chi2_big) / dp) / (rss / dof)
    return float(F), float(fdist.sf(F, dp, dof)) if F > 0 else 1.0


def nested_f_test(small: FitResult, big: FitResult) -> tuple[float, float]:
    """:func:`f_test` of fit ``big`` against the nested fit ``small`` (the Gaussian rows' scale when there are states)."""
    if big.n_scale < big.n and big.n_scale - big.p < 1:
        # states alone (or too few Gaussian rows to estimate a scale): dispersion fixed at 1, as fit() does, so the
        # drop of -2 ln L is a likelihood-ratio chi-square with p1 - p0 degrees of freedom
        from scipy.stats import chi2 as chi2dist

        dp, drop = big.p - small.p, small.chi2 - big.chi2
        if dp <= 0:
            return float("nan"), 1.0
        return float(drop / dp), float(chi2dist.sf(drop, dp)) if drop > 0 else 1.0
    scale = (big.chi2_scale, big.n_scale) if big.n_scale < big.n else None
    return f_test(small.chi2, small.p, big.chi2, big.p, big.n, scale)


def _fmt(v):
    return f"{v:.4g}"
