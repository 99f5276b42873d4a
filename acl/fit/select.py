"""Trace a structured residual to a missing effect: fit each candidate on top of the current model, keep the best.

A candidate is added when, against the current model, (1) the nested F-test gives p < ``P_LIMIT``
divided by the number of candidates tried in the round (Bonferroni),
(2) BIC improves, (3) the k-fold cross-validated weighted error improves (folds fixed by ``seed``),
and (4) its parameters are identifiable (full-rank Jacobian, relative standard error < 1).  Among
the candidates that pass, the lowest BIC wins; the loop repeats until none passes.  Before a
significant candidate is judged, the current model is refitted from the candidate's solution: if
that alone lowers its cost (a snap-in jump or a local minimum the optimizer had not left), the
better fit becomes the current model and the round starts over, so that an effect is never
credited with an improvement of the optimizer.  Cross-validation
is computed only for candidates that pass (1), (2) and (4) (documented; keeps the fit fast).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from acl.fit import solve
from acl.fit.effects import EFFECTS, SEARCHED

P_LIMIT = 0.01
K_FOLDS = 5
SCREEN_P = 0.5      # a candidate whose first fit gives an F-test p above this (and is no worse than the current
#                     model) is not refitted from its other starts
ALT_GAIN = 1e-3     # relative chi-square drop of a refit of the current model that restarts a round
MAX_RESTARTS = 3     # times a round starts over after a better fit of the current model is found


@dataclass
class Trial:
    effect: str
    round: int
    status: str                     # "selected" | "rejected" | "not applicable"
    reason: str
    fit: object = None
    f_stat: float = float("nan")
    p_value: float = float("nan")
    delta_bic: float = float("nan")
    delta_aicc: float = float("nan")
    cv: float | None = None
    cv_current: float | None = None
    cv_coefs: list | None = None


@dataclass
class Selection:
    base: object
    final: object
    selected: list
    trials: list = field(default_factory=list)
    effects: dict = field(default_factory=dict)      # effect id -> {param: value}
    tentative: list = field(default_factory=list)    # effects withdrawn because the final model stayed inadequate
    adequacy: dict = field(default_factory=dict)     # goodness of fit of the final model (sigma given)
    ambiguous: list = field(default_factory=list)    # alternative effect sets as good as the selected one (ambiguity)


def applicable(eid, problem, current_kinds) -> str | None:
    """Why effect ``eid`` cannot be tried on these data (None if it can)."""
    P, data = problem.prepared, problem.data
    eff = EFFECTS[eid]
    active = P.v.sum(axis=1) > 0
    for req in eff.requires:
        if req == "coupled" and not (P.group_row is not None and np.any(P.group_row)):
            return "the pairs are on the reduced Eq. (3) model (--model eq3), whose Bjerknes law is alpha/d^2"
        if req == "time" and not data.has_time:
            return "the data have no time column"
        if req == "frequencies" and np.unique(P.f[P.v > 0]).size < 2:
            return "the data have fewer than two drive frequencies"
        if req == "frequencies3" and np.unique(P.f[P.v > 0]).size < 4:
            return "the data have fewer than four drive frequencies (a resonance shape needs a sweep)"
        if req == "neighbour" and not np.any(_with_neighbour(P) & active):
            return ("no actuator in the data has a neighbour (only the capsules of a pair or a group do: capsules "
                    "of different units do not interact)")
        if req == "lengths" and np.unique(np.round(P.L[P.beam & active], 12)).size < 2:
            return "every row has the same beam length"
        if req == "heights" and np.unique(np.round(P.height[0][active], 12)).size < 2:
            return "every row has the actuator at the same height"
    if eid == "stiffness_scale" and "e_scale" in current_kinds:
        return "E is already free"
    if eid == "bjerknes_scale" and "alpha" in current_kinds:
        return "alpha is already free (the same freedom)"
    return None


def _with_neighbour(P) -> np.ndarray:
    """Rows whose capsules have a neighbour (neighbour_drag acts there): a pair's or a group's rows."""
    grp = getattr(P, "group_row", None)
    return P.pair | grp if grp is not None else P.pair


def effect_coefs(eid, problem) -> tuple[list, list]:
    """Coefficients of effect ``eid`` (start values scaled to the data) and extra starting points."""
    P, data = problem.prepared, problem.data
    defl = float(np.max(np.abs(data.value - P.base))) or 1e-6
    tspan = float(np.nanmax(data.time) - np.nanmin(data.time)) if data.has_time else 1.0
    tspan = tspan or 1.0
    mags = {"1": 1.0, "vmax": 1.0 / P.vmax**2, "deflection": defl, "deflection/time": defl / tspan,
            "1/time": 1.0 / tspan, "1/deflection": 1.0 / defl, "height": float(np.median(P.height[0]))}
    eff = EFFECTS[eid]
    coefs = []
    for p in eff.params:
        s = mags[p.scale]
        start = p.start * s if p.scale != "1" else p.start
        lower, upper = p.lower, p.upper
        if p.scale in ("vmax", "1/deflection", "1/time"):
            upper = min(upper, 1e3 * s)
        coefs.append(solve.Coef(f"{eid}.{p.name}", "effect", start, lower, upper, s if p.scale != "1" else 1.0,
                                p.unit, effect=eid, param=p.name))
    starts = []
    for st in eff.starts:
        starts.append([v * c.scale for v, c in zip(st, coefs)])
    return coefs, starts


def cross_validate(problem, coefs, x0, k=K_FOLDS, seed=0) -> float:
    """k-fold cross-validated mean squared weighted residual (folds from a fixed seed)."""
    P = problem.prepared
    n = problem.y.size
    folds = np.array_split(np.random.default_rng(seed).permutation(n), k)
    sq = []
    from acl.fit.forward import Model

    for fold in folds:
        train = np.setdiff1d(np.arange(n), fold)
        start = [dict(zip([c.name for c in coefs], x0))[c.name] for c in coefs]
        cs = [solve.Coef(c.name, c.kind, v, c.lower, c.upper, c.scale, c.unit, c.effect, c.param, c.design_param)
              for c, v in zip(coefs, start)]
        r = solve.fit(Model(P), problem.y, problem.sigma, cs, train=train, max_nfev=60)
        # a held-out row counts at most JUMP^2: a row near a snap-in fold that the fold's fit, moved by a fraction of
        # a standard error, predicts on the other branch (in contact, 40 um away) would otherwise outweigh all others;
        # a latch state by its deviance (held-out log-likelihood)
        sq.append(np.minimum(r.wresidual[fold] ** 2, solve.JUMP**2))
    return float(np.mean(np.concatenate(sq)))


def _beyond_jump(fit, problem) -> int:
    """Rows of ``fit`` beyond solve.JUMP sigma."""
    return int(np.sum(~(np.abs(fit.wresidual) <= solve.JUMP)))     # a latch state by its deviance residual


def _untrap(model, problem, coefs, starts, fit):
    """A fit of an effect that stops with rows beyond JUMP sigma may be trapped at a snap-in fold: from the current
    model's values the optimizer moves gamma and alpha little, rows stay predicted on the wrong branch and give no
    gradient (pair, planted drift, seed 105: chi-square 1,772 for 360 rows, while the same model reaches 360 from a
    robust start).  Fit again with a soft-l1 pass first (solve.fit ``robust_start``: the far rows cannot pull the
    start), from the same starts, and keep the lower chi-square (the final fit is plain least squares either way)."""
    if _beyond_jump(fit, problem):
        again = solve.fit(model, problem.y, problem.sigma, coefs, starts=starts or None, robust_start=True)
        fit = again if again.chi2 < fit.chi2 else fit
    return _cross_switch(model, problem, coefs, fit)


LATCH_BLEND = (0.2, 0.1, 0.05, 0.02, 0.01)    # continuation: relative scatter of the switching force, wide to narrow


def _cross_switch(model, problem, coefs, fit):
    """A lone latch's shuttle row predicted on the other side of the switch than measured (switched in the model, not
    in the data, or the reverse) is off by the whole stroke (~70 um, ~350 sigma) and gives no gradient: the model's
    travel is a step at the switching force, flat on both branches.  One such row outweighs every other row, and the
    fit of an effect stops there; and a row predicted at the switching force itself pins the fit at the step's kink
    (a step of any coordinate that moves it across costs the stroke), so the other coordinates stop too (xtol).  One
    latch with state rows, saturation + drift, seed 102: the saturation fitted with the drift stopped at chi-square
    247,207 with two rows across the switch, and from another start at 1,130 pinned at the kink with the offset at a
    fifth of its value; the planted pair reaches 440.4.

    When some row is across the switch, or the fit fails the goodness of fit of its Gaussian rows (p < GOF_P, sigma
    given) with a row within reach of the narrowest smoothing (its prediction with LATCH_BLEND[-1] differs from the
    exact one by more than its sigma), continue from the fit through fits of the same
    model with the step smoothed into the expected travel of a switching force scattered log-normally by s
    (acl.fit.latch.latch_travel ``blend``; the probit of the state rows), s from LATCH_BLEND[0] down to
    LATCH_BLEND[-1]; then fit the exact model from there and keep whichever exact fit has the lower chi-square.  The
    smoothed model only supplies a start: the model, its likelihood and every statistic stay the exact ones.  A fit
    that explains its rows to the noise is not trapped and is left alone (a latch whose saturated push stays just
    below the switching force on every ramp: the smoothing would only pull gamma to its bound, where the drift's fit
    was then judged not identifiable)."""
    from acl.fit.forward import predict
    from acl.fit.latch import latch_branch_mismatch, lone_latch_rows

    P = problem.prepared
    rows = lone_latch_rows(P)
    if not np.any(rows):
        return fit
    if not np.any(latch_branch_mismatch(P, problem.y, fit.prediction)):
        if problem.data.has_sigma:
            from scipy.stats import chi2

            if chi2.sf(fit.chi2_scale, max(fit.n_scale - fit.p, 1)) >= GOF_P:
                return fit
        near = np.abs(predict(P, *fit.as_inputs(), latch_blend=LATCH_BLEND[-1]) - fit.prediction) > problem.sigma
        if not np.any(near & rows):
            return fit
    values = list(fit.values)
    for s in LATCH_BLEND:
        smooth = solve.fit(lambda a, b, s=s: predict(P, a, b, latch_blend=s), problem.y, problem.sigma,
                           [_with_value(c, v) for c, v in zip(coefs, values)])
        values = list(smooth.values)
    again = solve.fit(model, problem.y, problem.sigma, [_with_value(c, v) for c, v in zip(coefs, values)])
    return again if again.chi2 < fit.chi2 else fit


ZOOM = (8.0, 1.5, 1.1)     # spans of the grids of :func:`_zoom`, coarse to fine


def _zoom(model, problem, fit):
    """The base model's fit when rows stop beyond JUMP sigma: on a pair the cost is a landscape of folds (each row's
    snap-in is a step), where the optimizer stops at the first kink.  Fit again from the best points of log grids
    around the best fit so far (solve.grid_starts, spans ZOOM, coarse to fine), keeping each lower chi-square.  A pair
    with a calibration beam, neighbour drag not in the model (the benchmark's case 3): chi-square 890,102 from the
    design's values, 93,975 / 54,829 / 51,650 after each grid, where the search's refits of the base from the
    candidates' solutions had reached 51,786 after three restarts of round 1 (each restart tries every candidate)."""
    for span in ZOOM:
        coefs = [_with_value(c, v) for c, v in zip(fit.coefs, fit.values)]
        starts = solve.grid_starts(model, problem.y, problem.sigma, coefs, span=span)
        if not starts:
            break
        again = solve.fit(model, problem.y, problem.sigma, coefs, starts=starts)
        if again.chi2 < fit.chi2:
            fit = again
    return fit


def _try_effect(problem, model, current, current_coefs, eid, limit):
    """Fit effect ``eid`` on top of the current model: (coefs, fit, F, p, alt).  ``alt`` is a refit of the current
    model alone from the effect's solution when that is better than the current model (None otherwise): the gain was
    then the optimizer's, not the effect's.  Depends only on its arguments, so candidates can be tried in any order
    or at once (:func:`_each`)."""
    ecoefs, estarts = effect_coefs(eid, problem)
    coefs = [_with_value(c, v) for c, v in zip(current_coefs, current.values)] + ecoefs
    starts = [list(current.values) + s for s in estarts]
    trial_fit = solve.fit(model, problem.y, problem.sigma, coefs)
    F, p = solve.nested_f_test(current, trial_fit)
    # the effect may matter, or the fit ended worse than the current model it contains (at the effect's
    # null value): a failed optimization, e.g. rows thrown past a snap-in fold by the first start.  Look
    # for a better minimum from the effect's other starts.
    if starts and (p < SCREEN_P or trial_fit.chi2 > current.chi2):
        again = solve.fit(model, problem.y, problem.sigma, coefs, starts=[list(trial_fit.values)] + starts)
        if again.chi2 < trial_fit.chi2:
            trial_fit = again
            F, p = solve.nested_f_test(current, trial_fit)
    again = _untrap(model, problem, coefs, starts, trial_fit)
    if again is not trial_fit:
        trial_fit = again
        F, p = solve.nested_f_test(current, trial_fit)
    alt = None
    if p < limit:
        # is the gain the effect's, or did the optimizer just find a better point of the current
        # model (a jump at a snap-in fold, a local minimum)?  Refit the current model from there.
        refit = solve.fit(model, problem.y, problem.sigma,
                          [_with_value(c, v) for c, v in zip(current_coefs, trial_fit.values)])
        if refit.chi2 < current.chi2 - max(ALT_GAIN * current.chi2, 1.0):   # a real jump, not round-off
            alt = refit
    return coefs, trial_fit, F, p, alt


_JOB = None     # the function a forked worker of :func:`_each` calls (set before the fork: nothing is pickled)


def _run_job(i):
    return _JOB(i)


def _each(fn, items, jobs=1):
    """``fn(item)`` for each item, in order, lazily: one at a time (``jobs`` <= 1), or on ``jobs`` forked worker
    processes at once, results still yielded in order.  A caller that stops early (a round that starts over) leaves
    the rest unused.  The workers inherit the prepared data set (fork); only results travel back (pickled).  Every
    result is a function of its item alone (the prediction memo and the pair-solve cache give bit-identical values,
    acl.fit.forward), so ``jobs`` changes the time, not one number (tests/test_fit_jobs.py)."""
    items = list(items)
    if jobs <= 1 or len(items) <= 1 or not _can_fork():
        for it in items:
            yield fn(it)
        return
    import multiprocessing
    import warnings
    from concurrent.futures import ProcessPoolExecutor

    global _JOB
    _JOB = lambda i: fn(items[i])       # noqa: E731
    try:
        with warnings.catch_warnings():
            # Python 3.12+ warns that fork() in a process with threads (BLAS) may deadlock; the workers only run
            # numpy/scipy code and never touch the parent's locks (progress display, logging)
            warnings.simplefilter("ignore", DeprecationWarning)
            pool = ProcessPoolExecutor(min(jobs, len(items)), mp_context=multiprocessing.get_context("fork"))
            futures = [pool.submit(_run_job, i) for i in range(len(items))]
        try:
            for f in futures:
                yield f.result()
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
    finally:
        _JOB = None


def _can_fork() -> bool:
    import multiprocessing

    return "fork" in multiprocessing.get_all_start_methods()


def select_effects(problem, candidates=None, p_limit=P_LIMIT, k_folds=K_FOLDS, seed=0, max_rounds=4,
                   progress=None, jobs=1) -> Selection:

    P = problem.prepared
    sigma_given = problem.data.has_sigma

    from acl.fit.forward import Model

    model = Model(P)
    base = solve.fit(model, problem.y, problem.sigma, problem.coefs)
    if _beyond_jump(base, problem):
        base = _zoom(model, problem, base)
    known: dict = {}          # model (coordinate names) -> its best fit seen (where the revisit's reduced models start)
    _remember(known, base)
    current_coefs = list(problem.coefs)
    current = base
    selected: list[str] = []
    trials: list[Trial] = []
    cv_current = None
    names = list(candidates) if candidates is not None else list(SEARCHED)
    for rnd in range(1, max_rounds + 1):
        for _restart in range(MAX_RESTARTS + 1):
            passing, round_trials, improved = [], [], None
            kinds = {c.kind for c in current_coefs}
            tried = [e for e in names if e not in selected and not applicable(e, problem, kinds)]
            limit = p_limit / max(len(tried), 1)          # Bonferroni over the candidates of this round
            todo = []
            for eid in names:
                if eid in selected:
                    continue
                why = applicable(eid, problem, kinds)
                if why:
                    if rnd == 1:
                        round_trials.append(Trial(eid, rnd, "not applicable", why))
                    continue
                todo.append(eid)
            judged = _each(lambda eid, cur=current, cc=current_coefs, lim=limit: _try_effect(problem, model, cur, cc,
                                                                                             eid, lim), todo, jobs)
            for eid, (coefs, trial_fit, F, p, alt) in zip(todo, judged):
                if progress:
                    progress(f"round {rnd}: tried {eid}")
                if alt is not None:
                    # the gain was not the effect's: the optimizer found a better point of the current model (a jump
                    # at a snap-in fold, a local minimum) from the effect's solution
                    improved = alt
                    break
                _remember(known, trial_fit)
                t = Trial(eid, rnd, "rejected", "", trial_fit, F, p, trial_fit.bic - current.bic,
                          trial_fit.aicc - current.aicc)
                loose = _loose(trial_fit, sigma_given)
                unknown = _not_determined(trial_fit, sigma_given)
                if unknown:
                    t.reason = "not identifiable from these data: " + "; ".join(unknown)
                elif not p < limit:
                    t.reason = f"not significant (F-test p = {p:.3g} >= {limit:.3g} = {p_limit}/{len(tried)} candidates)"
                elif loose:
                    t.reason = "not identifiable from these data: " + ", ".join(loose) + " (relative standard error > 1)"
                elif not t.delta_bic < 0:
                    t.reason = f"BIC does not improve (dBIC = {t.delta_bic:+.3g})"
                else:
                    t.reason = "passes F-test and BIC"
                    t.cv_coefs = coefs
                    passing.append(t)
                round_trials.append(t)
            judged.close()          # a round that starts over leaves the other candidates' fits unused
            round_trials.sort(key=lambda t: names.index(t.effect))     # the library's order, as tried one by one
            if improved is None:
                break
            if progress:
                progress(f"round {rnd}: a better fit of the current model was found; judging the candidates again")
            current, cv_current = improved, None
            _remember(known, improved)
            if not selected:
                base = improved
        # cross-validation, lazily: in order of BIC, until a candidate passes it (the lowest BIC among those
        # passing all tests wins, so later ones cannot change the choice)
        best = None
        for t in sorted(passing, key=lambda t: t.fit.bic):
            if best is not None:
                t.reason += f"; {best.effect} explains more (lower BIC; cross-validation not needed)"
                continue
            if cv_current is None:
                cv_current = cross_validate(problem, current_coefs, current.values, k_folds, seed)
            t.cv_current = cv_current
            t.cv = cross_validate(problem, t.cv_coefs, t.fit.values, k_folds, seed)
            if not t.cv < cv_current:
                t.reason = f"cross-validated error does not improve ({t.cv:.4g} >= {cv_current:.4g})"
            else:
                t.reason = "passes F-test, BIC and cross-validation"
                best = t
        trials.extend(round_trials)
        if best is None:
            break
        best.status = "selected"
        selected.append(best.effect)
        current = best.fit
        _remember(known, current)
        current_coefs = list(best.fit.coefs)
        cv_current = best.cv
    reps = {}
    if selected:
        current, selected, reps = _revisit(problem, model, names, selected, current, trials, p_limit, progress, jobs,
                                           known)
    _explain_rejections(trials)
    effects = solve.split_coefs(current.coefs, current.values)[1]
    sel = Selection(base, current, selected, trials, effects)
    sel.ambiguous = ambiguity(current, selected, reps)
    return sel


MAX_SWAPS = 2     # passes of the revisit step


def _effect_set(fit) -> tuple:
    """The model of ``fit``: its coordinates' names in order (the effects it carries and the free coefficients)."""
    return tuple(c.name for c in fit.coefs)


def _remember(known, fit) -> None:
    """Keep ``fit`` in ``known`` (model -> fit) if it is the lowest chi-square of its model seen so far."""
    key = _effect_set(fit)
    if key not in known or fit.chi2 < known[key].chi2:
        known[key] = fit


def _revisit(problem, model, names, selected, current, trials, p_limit, progress, jobs=1, known=None):
    """Forward selection can keep an effect that only stood in for one found later (a flexible transducer resonance
    absorbing part of a large deflection before the elastica was tried).  Revisit each selected effect E given the
    others: fit the model without E; if E is no longer significant there (nested F-test p >= the round's Bonferroni
    limit), drop it; otherwise try every other applicable effect C in E's place, and swap when C passes the same
    tests as in the search (F-test against the model without E, identifiable) and the model with C has a lower BIC
    than the model with E (an equal or better fit with no more parameters).  At most MAX_SWAPS passes.

    Returns (final fit, selected, replacements): for each selected effect of the final model, every other effect
    fitted in its place (:func:`_replacements`), from the pass that changed nothing (the material of
    :func:`ambiguity`)."""
    sigma_given = problem.data.has_sigma
    reps: dict = {}
    for _pass in range(MAX_SWAPS + 1):
        changed = False
        reps = {}
        for eid in list(selected):
            reduced, p_keep, limit, tries = _replacements(problem, model, names, selected, current, eid, p_limit,
                                                          progress, sigma_given, drop_check=_pass < MAX_SWAPS,
                                                          jobs=jobs, known=known)
            if not p_keep < limit and _pass < MAX_SWAPS:
                if progress:
                    progress(f"revisit: {eid} is not significant given the others; dropped")
                given = ", ".join(e for e in selected if e != eid)
                _retire(trials, eid, f"dropped on revisit: not significant given {given} "
                                     f"(F-test p = {p_keep:.3g} >= {limit:.3g})")
                selected = [e for e in selected if e != eid]
                current, changed = reduced, True
                break
            reps[eid] = tries
            best = None
            for alt in tries:
                if alt["explains"] and alt["fit"].bic < current.bic and (best is None or alt["fit"].bic < best["fit"].bic):
                    best = alt
            if best is not None and _pass < MAX_SWAPS:
                cid, trial, F, p = best["effect"], best["fit"], best["f_stat"], best["p_value"]
                if progress:
                    progress(f"revisit: {cid} replaces {eid}")
                _retire(trials, eid, f"replaced on revisit by {cid}: with the other selected effects, {cid} gives a "
                                     f"lower BIC ({trial.bic - current.bic:+.3g})")
                t = Trial(cid, max((t.round for t in trials), default=0) + 1, "selected",
                          f"replaces {eid} on revisit: F-test p = {p:.3g} < {limit:.3g} against the model without "
                          f"{eid}, identifiable, BIC lower than with {eid} ({trial.bic - current.bic:+.3g})",
                          trial, F, p, trial.bic - reduced.bic, trial.aicc - reduced.aicc)
                trials.append(t)
                selected = [cid if e == eid else e for e in selected]
                current, changed = trial, True
                if known is not None:
                    _remember(known, trial)
                break
        if not changed:
            break
    return current, selected, reps


def _replacements(problem, model, names, selected, current, eid, p_limit, progress, sigma_given, drop_check=True,
                  jobs=1, known=None):
    """The model without ``eid`` and every other applicable effect fitted in its place: (reduced fit, F-test p of
    ``eid`` given the others, the Bonferroni limit, [alternative dicts]).  An alternative ``explains`` the structure
    ``eid`` explains when it passes the search's tests against the model without ``eid`` (F-test, identifiable)."""
    rest = [c for c in current.coefs if c.effect != eid]
    vals = [v for c, v in zip(current.coefs, current.values) if c.effect != eid]
    reduced = solve.fit(model, problem.y, problem.sigma, [_with_value(c, v) for c, v in zip(rest, vals)])
    if known is not None:
        # refitted from the current values without ``eid``, the model may stop at a snap-in fold far above the best
        # fit of the same model the search has seen (a pair + calibration beam, neighbour drag selected: chi-square
        # 890,102 from there, 51,796 for the same model in round 1); judged against that trapped fit, any effect in
        # eid's place would look significant.  The lower of the two is the model without eid.
        _remember(known, reduced)
        reduced = known[_effect_set(reduced)]
    kinds = {c.kind for c in rest}
    others = [e for e in names if e not in selected and not applicable(e, problem, kinds)]
    limit = p_limit / max(len(others) + 1, 1)
    _, p_keep = solve.nested_f_test(reduced, current)
    tries = []
    if drop_check and not p_keep < limit:
        return reduced, p_keep, limit, tries
    def replace(cid):
        ecoefs, estarts = effect_coefs(cid, problem)
        coefs = [_with_value(c, v) for c, v in zip(rest, reduced.values)] + ecoefs
        rstarts = [list(reduced.values) + st for st in estarts]
        return _untrap(model, problem, coefs, rstarts,
                       solve.fit(model, problem.y, problem.sigma, coefs, starts=rstarts or None))

    for cid, trial in zip(others, _each(replace, others, jobs)):
        if progress:
            progress(f"revisit: tried {cid} in place of {eid}")
        F, p = solve.nested_f_test(reduced, trial)
        ok = bool(p < limit and not _not_determined(trial, sigma_given) and not _loose(trial, sigma_given))
        tries.append({"replaces": eid, "effect": cid, "fit": trial, "f_stat": F, "p_value": p, "explains": ok})
    return reduced, p_keep, limit, tries


AMBIGUOUS_CHI2 = 6.0    # an alternative whose clipped -2 ln L is within this of the selected model's is not ruled out:
#                         a likelihood ratio below e^3 = 20, at most "positive" evidence (Kass & Raftery 1995, 2 ln B < 6)
CLIP = solve.JUMP ** 2  # a row beyond JUMP sigma (on a fold: a latch switching one voltage step early or late, a pair
#                         past snap-in) counts this much: the least such a row adds, not its 1e5 (the shuttle model
#                         switches at the switching force itself while the device scatters from ramp to ramp)


_BY_VOLTAGE = ("switching or deflection at several voltages per frequency: latches of several switching forces "
               "(e.g. several angles), or a calibration beam ramped at each frequency")
_SEPARATE = {
    frozenset({"drive_saturation", "transducer_gain"}): _BY_VOLTAGE,
    frozenset({"drive_saturation", "transducer_resonance"}): _BY_VOLTAGE,
    frozenset({"transducer_gain", "transducer_resonance"}): "drive frequencies beyond the swept band (a resonance "
    "turns over, a tilt does not), or a calibrated hydrophone / calibration beam at each frequency",
    frozenset({"drive_saturation", "large_deflection"}): "ramps at two or more frequencies (saturation follows the "
    "voltage, stiffening the deflection)",
    frozenset({"offset_drift", "bubble_shrinkage"}): "rows at zero voltage spread over the run (an offset/drift is "
    "present there, shrinkage is not)",
    frozenset({"stiffness_gradient", "substrate_proximity"}): "actuators on pedestals of several heights",
}


def separating_experiment(a: str, b: str) -> str:
    """The experiment that would tell effect ``a`` from effect ``b`` (docs/fit.md, "What a given kind of data cannot
    tell apart")."""
    known = _SEPARATE.get(frozenset({a, b}))
    if known:
        return known
    return f"data that identify each: {a}: {EFFECTS[a].identified_by}; {b}: {EFFECTS[b].identified_by}"


def clipped_chi2(fit) -> float:
    """-2 ln L + const of a fit with every row's contribution clipped at CLIP (latch states: deviance)."""
    r2 = np.asarray(fit.wresidual, float)[fit.train] ** 2
    return float(np.sum(np.minimum(np.where(np.isfinite(r2), r2, CLIP), CLIP)))


def ambiguity(final, selected, reps) -> list[dict]:
    """Alternative effect sets that explain the data about as well as the selected one: each selected effect E
    replaced by another effect C (fitted in E's place with the other selected effects, :func:`_replacements`) that
    passes the search's tests against the model without E (F-test, identifiable) and whose clipped -2 ln L
    (:func:`clipped_chi2`) is within AMBIGUOUS_CHI2 of the selected model's (a likelihood ratio below 20; the
    alternative may have more parameters).  Best first."""
    out = []
    ref = clipped_chi2(final)
    for eid, tries in reps.items():
        for a in tries:
            d = clipped_chi2(a["fit"]) - ref
            if a["explains"] and d < AMBIGUOUS_CHI2:
                out.append({"effects": [a["effect"] if e == eid else e for e in selected], "replaces": eid,
                            "by": a["effect"], "delta_chi2": float(d), "delta_bic": float(a["fit"].bic - final.bic),
                            "separate_by": separating_experiment(eid, a["effect"]), "fit": a["fit"]})
    return sorted(out, key=lambda a: a["delta_chi2"])


def _explain_rejections(trials) -> None:
    """A rejected candidate whose reason starts with the tests it passed says why it was still not kept: the report
    showed "rejected" beside "passes F-test and BIC" and nothing else."""
    for t in trials:
        if t.status == "rejected" and t.reason.startswith("passes "):
            passed, _, why = t.reason.partition("; ")
            t.reason = ("passed " + passed[len("passes "):] + ", but "
                        + (why or "was not kept: another candidate of its round explained the data better"))


def _retire(trials, eid, reason):
    for t in trials:
        if t.effect == eid and t.status == "selected":
            t.status = "rejected"
            t.reason += "; " + reason


def _with_value(c, v):
    return solve.Coef(c.name, c.kind, v, c.lower, c.upper, c.scale, c.unit, c.effect, c.param, c.design_param)


def search_stderr(fit, sigma_given: bool) -> np.ndarray:
    """Standard errors that judge whether the data determine a candidate's parameters during the search.

    The reported intervals scale the Fisher covariance by the reduced chi-square (lmfit's default).  During the search
    that scale is the misfit of effects not yet in the model: with two missing effects acting on different rows
    (a drift on a latch's shuttle rows, a saturation on its switching thresholds) each one alone leaves a gross misfit
    that inflated the other's interval, so both were rejected as "not identifiable" and the fit ended with neither.
    With sigma given the information the data carry about a parameter is (J^T J)^-1 at that sigma, so a reduced
    chi-square above 1 is not applied here (below 1 it is, as before: never a looser test on a good fit).  Significance
    stays the F-test's, BIC's and cross-validation's; the final model's intervals keep the scale."""
    se = np.asarray(fit.stderr, float)
    if sigma_given and fit.redchi > 1.0:
        return se / math.sqrt(fit.redchi)
    return se


def _not_determined(fit, sigma_given: bool) -> list[str]:
    """Why the data do not determine a fit's coordinates (empty: they do): a rank-deficient Jacobian, or a model
    coefficient (gamma, alpha, ...) whose standard error (:func:`search_stderr`) exceeds its value."""
    if not fit.full_rank:
        return [w for w in fit.warnings if "identifiable" in w]
    out = []
    for c, v, se in zip(fit.coefs, fit.values, search_stderr(fit, sigma_given)):
        rel = se / max(abs(v), 1e-300)
        if c.kind != "effect" and np.isfinite(rel) and rel > 1.0:
            out.append(f"{c.name} is not identifiable (relative standard error {rel:.3g})")
    return out


def _loose(fit, sigma_given: bool = False) -> list[str]:
    """Effect parameters whose standard error (:func:`search_stderr`) exceeds their distance from the null value."""
    out = []
    for c, v, se in zip(fit.coefs, fit.values, search_stderr(fit, sigma_given)):
        if c.kind == "effect":
            null = next(p.null for p in EFFECTS[c.effect].params if p.name == c.param)
            if not np.isfinite(null):      # a shape parameter without a null value (e.g. a resonance's Q)
                continue
            if not np.isfinite(se) or se > abs(v - null):
                out.append(c.name)
    return out


GOF_P = 1e-3     # a final model whose chi-square goodness of fit is below this is inadequate (sigma given)


def withdraw_if_inadequate(selection, problem) -> Selection:
    """Claims need an adequate model: when the data give sigma and the final model still fails the chi-square
    goodness of fit (p < GOF_P; rows beyond solve.JUMP sigma left out), the selected effects are withdrawn
    (listed as ``tentative``: they improve the fit but do not explain the data) and the final model is the
    base model, whose residual structure is then reported as unexplained.  Something outside the library
    (creep, an out-of-plane tilt) is then reported as structure, not as a wrong effect."""
    from scipy.stats import chi2

    if not problem.data.has_sigma:
        selection.adequacy = {"tested": False, "reason": "no sigma column: the scale is estimated"}
        return selection
    fit = selection.final
    z = fit.residual / problem.sigma
    keep = np.abs(z) <= solve.JUMP
    dof = max(int(keep.sum()) - fit.p, 1)
    stat = float(np.sum(z[keep] ** 2))
    p = float(chi2.sf(stat, dof))
    selection.adequacy = {"tested": True, "chi2": stat, "dof": dof, "p_value": p, "adequate": p >= GOF_P}
    if p >= GOF_P or not selection.selected:
        return selection
    selection.tentative = list(selection.selected)
    for t in selection.trials:
        if t.status == "selected":
            t.status = "tentative"
            t.reason += (f"; withdrawn: the final model still fails the goodness of fit (chi2 = {stat:.4g} for "
                         f"{dof} dof, p = {p:.2g} < {GOF_P}), so what remains is outside the library")
    selection.selected = []
    selection.effects = {}
    selection.ambiguous = []
    selection.final = selection.base
    return selection
