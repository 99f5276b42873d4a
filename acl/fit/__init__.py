"""Fit a design to measured data, find missing physical effects, report before/after (docs/fit.md).

Pipeline (one way): data (acl.fit.data) -> design instances (acl.fit.mechanism) -> vectorized
forward model (acl.fit.forward) -> least squares (acl.fit.solve) -> residual tests
(acl.fit.residuals) -> effect selection (acl.fit.select, library acl.fit.effects) -> report
(acl.fit.report) and calibrated design (acl.fit.calibrated).  Synthetic data: acl.fit.synth.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class FitOutcome:
    problem: object
    selection: object
    report: dict
    calibrated: str              # source of the calibrated design
    calibrated_path: str = ""    # where it is meant to be written (report["calibrated_design"])


def run_fit(design_path, data_paths, free=(), search_paths=(), candidates=None, seed=0, progress=None,
            calibrated_path=None, report_dir=None, model: str = "coupled", jobs: int = 1) -> FitOutcome:
    """Everything `acl fit` does except writing files; raises DiagnosticError on bad input.

    ``model``: the force model of simple pairs, ``eq3`` (paper Eq. 3) or ``coupled`` (the analysis' own force
    model through acl.fit.group; far slower on large data sets: benchmarks/fit.py cases 4 and 5).  ``jobs``: worker processes that fit the
    candidate effects of a round at once (acl.fit.select._each: the same result as one process, in less time)."""
    from acl.fit.calibrated import calibrated_text, default_path, needs_path
    from acl.fit.problem import load_problem
    from acl.fit.report import build_report
    from acl.fit.residuals import covariates, examine, examine_groups
    from acl.fit.select import select_effects, withdraw_if_inadequate
    from acl.fit.solve import NOMINAL_SIGMA

    import numpy as np

    import time

    timing = {}
    t0 = time.perf_counter()
    from acl.fit.mechanism import MODELS

    if model not in MODELS:
        from acl.diagnostics import DiagnosticError, Span, error, suggest

        raise DiagnosticError([error("E-USAGE", f"--model {model}: not a pair model",
                                     Span(file="<--model>", line=1, column=1),
                                     suggest(str(model), MODELS) or f"models: {', '.join(MODELS)}")])
    problem = load_problem(design_path, data_paths, free=free, search_paths=search_paths, model=model)
    timing["load"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    selection = withdraw_if_inadequate(select_effects(problem, candidates=candidates, seed=seed, progress=progress,
                                                       jobs=jobs),
                                       problem)
    timing["fit_and_effect_search"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    w = 1.0 / np.where(np.isfinite(problem.sigma), problem.sigma, NOMINAL_SIGMA)
    # latch states (0/1) are left out of the residual tests: the sign of a binary residual is the outcome itself
    # (a threshold model's residuals are + below it and - above it by construction), not structure
    keep = ~problem.prepared.state if problem.prepared.state is not None else np.ones(problem.data.n, bool)
    kinds = {problem.design.observe(n).kind for n in set(problem.data.observable[keep])}
    pname = f"predicted {'deflection' if kinds == {'displacement'} else kinds.pop()}" if len(kinds) == 1 else "prediction"
    labels = {"observable": problem.data.observable[keep], "experiment": problem.data.experiment[keep]}
    sigma_given = problem.data.has_sigma
    before, after = [], []
    if np.any(keep):
        for out, fit in ((before, selection.base), (after, selection.final)):
            cov = {k: np.asarray(v)[keep] for k, v in covariates(problem.data, problem.prepared, fit.prediction,
                                                                   pname).items()}
            out += examine(fit.residual[keep], cov, w[keep], seed)
            out += examine_groups(fit.residual[keep], cov, w[keep], labels, fit.p, sigma_given, seed)
    timing["residual_tests"] = time.perf_counter() - t0
    import os

    cal_path = os.path.abspath(calibrated_path or default_path(design_path))
    report = build_report(problem, selection, before, after, calibrated_name=cal_path)
    report["calibrated_needs_path"] = needs_path(design_path, cal_path)
    report["timing_s"] = timing
    t0 = time.perf_counter()
    from acl.fit.report import tone_gain_entries, tone_gain_stderr, tone_gains

    # the gain at each tone when it adds what the coefficients do not fit; else the gain model's error there
    tones = None
    for figure in (tone_gains, tone_gain_stderr):
        try:
            with np.errstate(all="ignore"):          # a wild step is judged by its cost, not warned about
                tones = figure(problem, selection.final) or None
        except (ValueError, np.linalg.LinAlgError):  # no figure: the bands keep the table's prior at every tone
            tones = None
        if tones is not None:
            break
    timing["tone_gains"] = time.perf_counter() - t0
    report["tone_gains"] = tone_gain_entries(tones, problem)
    if getattr(tones, "residual", None) is not None:
        r = np.asarray(tones.residual, float)
        r = r[np.isfinite(r)]
        report["tone_gains_rmse"] = float(np.sqrt(np.mean(r * r))) if r.size else None
        report["tone_gains_p_value"] = tones.p_value
    report["tone_gain_stderr"] = [{"frequency_hz": e["frequency_hz"], "relative_stderr": e["relative_stderr"]}
                                  for e in report["tone_gains"]]
    text = calibrated_text(problem, selection, cal_path, data_paths, report_dir, tone_gain=tones)
    t0 = time.perf_counter()
    from acl.fit.modelcheck import MIN_SCALE_SD, pair_model_check, warning_text

    check = pair_model_check(problem, selection.final, text, cal_path, search_paths)
    timing["pair_model_check"] = time.perf_counter() - t0
    report["model"] = model
    if check is not None:
        report["pair_model_check"] = check
        snap = check.get("snap") or {}
        scale_sd = snap.get("scale_sd", 0.0) if snap.get("scale_sd", 0.0) >= MIN_SCALE_SD else 0.0
        if "error" in check or check["significant"] or scale_sd:
            report["final"]["warnings"] = [*report["final"]["warnings"], warning_text(check)]
        if check.get("significant") or scale_sd:
            text = calibrated_text(problem, selection, cal_path, data_paths, report_dir,
                                   model_discrepancy=check["max_m"] if check.get("significant") else 0.0,
                                   model_scale_sd=scale_sd, tone_gain=tones)
    return FitOutcome(problem, selection, report, text, cal_path)


# `acl.fit(...)` is also the Python API function (acl/__init__.py): keep it callable.
from acl._callable import make_callable as _make_callable  # noqa: E402

_make_callable(__name__)
