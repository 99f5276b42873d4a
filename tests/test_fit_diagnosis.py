"""Issue 9, first "done when": planted effects are diagnosed over seeds in every experiment kind that identifies them.

The full sweep (every library effect in every kind, two-effect truths, clean data, creep and tilt outside the library,
10 seeds each) takes about an hour on the shared machine, so it runs in `benchmarks/fit_diagnosis.py`; its run is
committed as benchmarks/fit_diagnosis.json and rendered into docs/fit.md by tests/docs_sync.py.  Here:

* the committed run meets the bar (>= 9 of 10 correct per case; where the experiment identifies the effect only up to a
  named alternative, FD.CONFOUNDED, >= 9 of 10 correct or ambiguous with the truth among the alternatives; nothing
  claimed on clean data, RMSE after <= 1.3 x noise), with the cases below the bar listed exactly (KNOWN_BELOW), so a
  regression or an improvement both show;
* a representative subset of its runs is repeated (same selection, same RMSE), so the file is what the code gives;
* the three mechanisms the sweep needed are checked on the seeds that showed the defects.
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(__file__)
ROOT = os.path.join(HERE, "..")
SWEEP = os.path.join(ROOT, "benchmarks", "fit_diagnosis.json")
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import fit_diagnosis as FD  # noqa: E402

RATE = 0.9          # issue 9: diagnosed correctly at least 90 % of the time
RMSE_RATIO = 1.3    # issue 9: RMSE after within 1.3 x the noise
# case -> correct runs of 10, for cases below the bar (FD.meets_bar: 9 of 10 correct, or for the FD.CONFOUNDED cases
# 9 of 10 correct or ambiguous with the truth among the alternatives); the Fig. 5c spring with saturation at 6 V and a
# 4 um drag plateau, ramped to 4 V, is a measured limit (FD.LIMITS: the drag test's power there is 0.82, docs/fit.md;
# ramped to 5 V it is counted).  One latch with saturation + drift was below (4 correct, 1 ambiguous: a fit stopped with
# a shuttle row across the latch's switch, no gradient); with the continuation through a smoothed switch
# (acl.fit.select._cross_switch) 6 correct, 3 ambiguous, 1 wrong (seed 108: resonance + drift fits 10 better in -2 ln L,
# as resonance alone does on that seed's saturation-only data).  Listed exactly.
KNOWN_BELOW: dict[str, int] = {}
# clean data on which something was claimed, listed exactly
KNOWN_CLEAN_CLAIMS: dict[str, int] = {}


def _rows():
    with open(SWEEP) as fh:
        return json.load(fh)["rows"]


def _summary():
    return {c["case"]: c for c in FD.summary(_rows())}


# cases of the script not in the committed run (each takes 10-15 min of the shared machine; docs/fit.md lists them)
NOT_RUN: set[str] = set()


def test_committed_sweep_covers_every_case_with_ten_seeds():
    summary = _summary()
    assert set(summary) == {FD.label(k, p) for k, p in FD.CASES} - NOT_RUN
    assert all(c["n"] == 10 for c in summary.values())
    from acl.fit.effects import SEARCHED
    planted = {e for c in summary.values() for e in c["planted"] if not e.startswith("(")}
    # every effect of the default search is planted somewhere (bjerknes_scale, fitted when named, is the freedom of
    # alpha: tests/test_fit_one_model.py recovers it)
    assert planted == set(SEARCHED)
    assert {c["kind"].split("/")[0] for c in summary.values()} == {"cantilever", "pair", "pair+cal", "spring+cal",
                                                                   "body-pair+cal", "latch", "latch+state"}
    # the run is one version of the code per case (`code`: its commit); a subset is repeated below with this one
    assert all(len({r["code"] for r in _rows() if r["case"] == case}) == 1 for case in summary)


def test_committed_sweep_diagnoses_at_least_nine_in_ten():
    """Cases the experiment cannot identify (FD.LIMITS, with the reason shown in docs/fit.md) are measured but not
    counted; there an effect that was not planted must still not be claimed often (in at most 1 of 10)."""
    summary = _summary()
    below = {case: c["correct"] for case, c in summary.items() if not FD.meets_bar(c, RATE) and not c["limit"]}
    assert below == KNOWN_BELOW
    for case, reason in FD.CONFOUNDED.items():
        assert reason and case in summary
        # where the fit may say "ambiguous", it must not claim a wrong effect often
        c = summary[case]
        assert c["n"] - c["wrong_n"] >= RATE * c["n"] or case in KNOWN_BELOW, case
    for case, reason in FD.LIMITS.items():
        assert reason and case in summary
        runs = [r for r in _rows() if r["case"] == case]
        safe = [r for r in runs if set(r["selected"]) <= set(r["planted"])]
        assert len(safe) >= RATE * len(runs), case


def test_committed_sweep_claims_nothing_on_clean_data_and_reaches_the_noise():
    rows = _rows()
    clean = [r for r in rows if not r["planted"]]
    claims = {}
    for r in clean:
        if r["selected"]:
            claims[r["case"]] = claims.get(r["case"], 0) + 1
    assert clean and claims == KNOWN_CLEAN_CLAIMS
    library = [r for r in rows if not any(p.startswith("(") for p in r["planted"]) and r["case"] not in FD.LIMITS]
    # every correct diagnosis ends within 1.3 x the noise (a wrong one, or none, is counted as a failure above)
    assert max(r["rmse_after_over_noise"] for r in library if r["ok"]) <= RMSE_RATIO


def test_effects_outside_the_library_are_structure_with_a_covariate_in_the_committed_sweep():
    for c in _summary().values():
        if c["outside"]:
            assert c["correct"] == c["n"], c["case"]      # nothing claimed, structure reported
            assert c["unexplained"], c["case"]


# a representative subset of the committed runs, repeated: (case, seed)
REPEAT = [
    ("cantilever large_deflection", 101),
    ("cantilever large_deflection+transducer_gain", 101),
    ("cantilever bubble_shrinkage+transducer_resonance", 104),
    ("cantilever/known-force stiffness_scale", 102),
    ("cantilever clean", 100),
    ("cantilever (tilt)", 103),
    ("latch drive_saturation", 105),
    ("pair+cal neighbour_drag", 100),
    ("latch+state/angles drive_saturation", 100),
    ("latch+state transducer_resonance", 104),
    ("latch+state clean", 109),
    ("body-pair+cal clean", 109),          # bodies inside a pair: the group model with the analysis' forces
]


# the repeats that take 4-100 s each are studies (pytest -m studies); their kinds are fitted in the default run by the
# faster repeats above and by test_held_out_latch_angle_seeds_meet_the_bar_and_a_run_is_repeated, test_fit_mechanisms.py
# (pair + calibration beam) and test_fit_one_physics.py (the body pair)
STUDY_REPEATS = {"pair+cal neighbour_drag", "latch+state/angles drive_saturation", "latch+state transducer_resonance",
                 "body-pair+cal clean"}


@pytest.mark.parametrize("case,seed", [pytest.param(c, s, id=f"{c}-{s}", marks=pytest.mark.studies if c in STUDY_REPEATS
                                                   else ()) for c, s in REPEAT])
def test_a_committed_run_is_repeated(case, seed):
    row = next(r for r in _rows() if r["case"] == case and r["seed"] == seed)
    kind, planted = next((k, p) for k, p in FD.CASES if FD.label(k, p) == case)
    again = FD.run_case(kind, planted, seed)
    assert again["selected"] == row["selected"] and again["ok"] == row["ok"]
    assert again["rmse_after_over_noise"] == pytest.approx(row["rmse_after_over_noise"], rel=1e-3)


def _problem(tmp_path, kind, planted, seed):
    from acl.fit.problem import load_problem
    from acl.fit.synth import generate, write_csv

    design, experiment, free, noise, coeffs = FD.kinds()[kind]
    data, _ = generate(design, experiment, planted, noise=0.0, seed=seed, coeffs=coeffs, model=FD.MODEL)
    data.value = data.value + np.random.default_rng(seed).normal(0, noise, data.n)
    data.sigma = np.full(data.n, noise)
    path = str(tmp_path / "d.csv")
    write_csv(data, path)
    return load_problem(design, [path], free=free, model=FD.MODEL)


def _base_then_effect(problem, effect):
    """The base model's fit, then ``effect`` fitted from the base values (as the search's first round does)."""
    from acl.fit import solve
    from acl.fit.forward import predict
    from acl.fit.select import _with_value, effect_coefs

    def model(a, b):
        return predict(problem.prepared, a, b)

    base = solve.fit(model, problem.y, problem.sigma, problem.coefs)
    coefs = [_with_value(c, v) for c, v in zip(problem.coefs, base.values)] + effect_coefs(effect, problem)[0]
    return base, solve.fit(model, problem.y, problem.sigma, coefs)


def test_the_fit_leaves_a_snap_in_trap_that_gives_no_gradient(tmp_path):
    """Pair, planted tilt, seed 109: from the base model's values the gain fit stopped with 4 rows predicted in contact
    (past snap-in) while measured 37-48 um apart (chi-square 81,804 for 360 rows); the rows give no gradient, so only a
    probe across the fold finds the minimum near the truth (a neighbour_drag was selected to get there)."""
    from acl.fit import solve

    problem = _problem(tmp_path, "pair", {"transducer_gain": FD.GAIN}, 109)
    _, fit = _base_then_effect(problem, "transducer_gain")
    assert fit.chi2 < 1.2 * problem.y.size
    assert not np.any(np.abs(fit.residual / problem.sigma) > solve.JUMP)
    assert fit.value("transducer_gain.gain_slope") == pytest.approx(1.5, abs=0.1)


def test_a_selected_effect_that_stood_in_for_a_later_one_is_replaced(tmp_path):
    """Cantilever, tilt + large deflection, seed 101: the flexible resonance won round 1 (it absorbs part of the
    stiffening too), the elastica came in round 2; given the elastica, the one-parameter tilt explains as much."""
    from acl.fit.select import select_effects

    planted = {"transducer_gain": FD.GAIN, "large_deflection": FD.LARGE}
    sel = select_effects(_problem(tmp_path, "cantilever", planted, 101), seed=101)
    assert sorted(sel.selected) == sorted(planted)
    res = next(t for t in sel.trials if t.effect == "transducer_resonance" and t.round == 1)
    assert res.status == "rejected" and "replaced on revisit by transducer_gain" in res.reason


def trap_figures(tmp_path) -> dict:
    """Pair, planted offset + drift, seed 105 (docs/fit.md shows these): the drift's fit from the base model's values,
    plain and after :func:`acl.fit.select._untrap`."""
    from acl.fit import solve
    from acl.fit.forward import predict
    from acl.fit.select import _untrap, _with_value, effect_coefs

    problem = _problem(tmp_path, "pair", {"offset_drift": FD.DRIFT}, 105)

    def model(a, b):
        return predict(problem.prepared, a, b)

    base = solve.fit(model, problem.y, problem.sigma, problem.coefs)
    coefs = [_with_value(c, v) for c, v in zip(problem.coefs, base.values)] + effect_coefs("offset_drift", problem)[0]
    trapped = solve.fit(model, problem.y, problem.sigma, coefs)
    fit = _untrap(model, problem, coefs, [], trapped)
    return {"rows": problem.y.size, "trapped": trapped.chi2, "untrapped": fit.chi2,
            "offset": fit.value("offset_drift.offset"), "drift": fit.value("offset_drift.drift")}


def test_an_effect_fit_trapped_at_a_snap_in_fold_is_refitted_from_a_robust_start(tmp_path):
    """Pair, planted offset + drift, seed 105: from the base model's values (no drift: gamma 20 % high) the drift fit
    stopped far above one chi-square per row with 3 rows beyond 10 sigma, an optimum of the wrong branch; the effect
    was then rejected (its cross-validation failed) and nothing was claimed.  A soft-l1 start reaches the truth."""
    f = trap_figures(tmp_path)
    assert f["trapped"] > 3 * f["rows"]                     # the defect: a plain fit from there stays trapped
    assert f["untrapped"] < 1.2 * f["rows"]
    assert f["offset"] == pytest.approx(FD.DRIFT["offset"], rel=0.1)
    assert f["drift"] == pytest.approx(FD.DRIFT["drift"], rel=0.1)


def zoom_figures(tmp_path) -> dict:
    """Pair + calibration beam, planted neighbour drag, seed 100 (docs/fit.md shows these): the base model fitted from
    the design's values, after :func:`acl.fit.select._zoom`, and the revisit's model without the drag (fitted from
    the drag model's values, and as :func:`acl.fit.select._replacements` takes it)."""
    from acl.fit import solve
    from acl.fit.forward import Model
    from acl.fit.select import _beyond_jump, _remember, _replacements, _try_effect, _zoom

    problem = _problem(tmp_path, "pair+cal", {"neighbour_drag": {"plateau": 8e-6}}, 100)
    model = Model(problem.prepared)
    base = solve.fit(model, problem.y, problem.sigma, problem.coefs)
    zoomed = _zoom(model, problem, base)
    coefs, drag, _, _, _ = _try_effect(problem, model, zoomed, problem.coefs, "neighbour_drag", 0.01)
    known: dict = {}
    _remember(known, zoomed)
    refit, *_ = _replacements(problem, model, [], ["neighbour_drag"], drag, "neighbour_drag", 0.01, None, True)
    reduced, *_ = _replacements(problem, model, [], ["neighbour_drag"], drag, "neighbour_drag", 0.01, None, True,
                                known=known)
    return {"rows": problem.y.size, "base": base.chi2, "base_jumps": _beyond_jump(base, problem),
            "zoomed": zoomed.chi2, "drag": drag.chi2, "refit": refit.chi2, "reduced": reduced.chi2}


def test_a_base_fit_trapped_at_folds_starts_again_from_zoomed_grids(tmp_path):
    """Pair + calibration beam, neighbour drag planted, not in the model: from the design's values the base fit stops
    with rows beyond 10 sigma at a snap-in fold; the zoomed grids find a far lower chi-square of the same model (round 1
    then judges every candidate against it: before, the refits from the candidates' solutions walked the base down
    over three restarts of the round).  The revisit's model without the drag is that best fit, not a refit from the
    drag model's values that stops at a fold (judged against it, any effect in the drag's place looked significant)."""
    f = zoom_figures(tmp_path)
    assert f["base_jumps"] > 0                        # the trap: rows past snap-in in the model, not in the data
    assert f["zoomed"] < 0.7 * f["base"]
    assert f["drag"] < 1.3 * f["rows"]                 # the planted effect explains the data from the zoomed base
    assert f["refit"] > 1.2 * f["zoomed"]              # the defect the revisit had: refitted from the drag's values
    assert f["reduced"] == f["zoomed"]


def cv_figures(tmp_path) -> dict:
    """Pair, planted resonance + shrinkage, seed 105 (docs/fit.md shows these): chi-square and cross-validated error
    of the resonance-only model and of resonance + shrinkage, each fitted from the truth."""
    from acl.fit import solve
    from acl.fit.forward import predict
    from acl.fit.select import cross_validate, effect_coefs
    from acl.fit.synth import effect_inputs

    planted = {"transducer_resonance": FD.RESONANCE, "bubble_shrinkage": FD.SHRINK}
    problem = _problem(tmp_path, "pair", planted, 105)
    P = problem.prepared
    truth = effect_inputs(planted)

    def model(a, b):
        return predict(P, a, b)

    out = {"rows": problem.y.size}
    for key, effects in (("one", ["transducer_resonance"]), ("two", ["transducer_resonance", "bubble_shrinkage"])):
        coefs = list(problem.coefs) + [c for e in effects for c in effect_coefs(e, problem)[0]]
        start = [P.gamma0, FD.kinds()["pair"][4]["alpha"]] + [truth[c.effect][c.param] for c in coefs[2:]]
        fit = solve.fit(model, problem.y, problem.sigma, coefs, starts=[start])
        out[key] = fit.chi2
        out["cv_" + key] = cross_validate(problem, coefs, fit.values, seed=105)
    return out


def test_cross_validation_is_not_swamped_by_a_row_flipped_across_a_snap_in_fold(tmp_path):
    """Pair, planted resonance + shrinkage, seed 105: given the resonance, the shrinkage fit reaches one chi-square per
    row, but a fold's fit put a held-out row on the other side of snap-in (tens of um, hundreds of sigma) and its
    cross-validated error lost to the resonance-only model's: nothing was claimed.  Each held-out row now counts at
    most 10^2 (fails on the code before)."""
    f = cv_figures(tmp_path)
    assert f["two"] < 1.2 * f["rows"] < f["one"]
    assert f["cv_two"] < 2.0 < f["cv_one"]


def test_the_spring_drag_case_is_a_power_limit_that_the_longer_ramp_lifts():
    """The Fig. 5c spring, saturation at 6 V and a 4 um drag plateau (FD.LIMITS): at 0.2 um noise and 0..4 V the
    likelihood-ratio test of the drag given saturation cannot reach 90 % power at the search's gate, nor one-sided
    (its boundary counted); ramped to 5 V (spring+cal/plateau, counted) it can."""
    drag = {"drive_saturation": FD.SAT, "neighbour_drag": {"plateau": 4e-6}}
    at4 = FD.lrt_power("spring+cal", drag, ["drive_saturation"])
    at5 = FD.lrt_power("spring+cal/plateau", drag, ["drive_saturation"])
    assert "spring+cal drive_saturation+neighbour_drag" in FD.LIMITS
    assert at4["gate"] == pytest.approx(0.01 / 8)
    assert at4["power"] < at4["power_one_sided"] < RATE
    assert at4["p9of10"] < 0.5
    assert at5["power"] > 0.999 and at5["noncentrality"] > 3 * at4["noncentrality"]
    assert at5["max_travel_m"] > at4["max_travel_m"]


def _state_problem(tmp_path, kind, planted, seed):
    """The harness's latch-state data (states drawn with the model's switching probability) as a fit problem."""
    from acl.fit.problem import load_problem
    from acl.fit.synth import generate, write_csv

    design, experiment, free, noise, coeffs = FD.kinds()[kind]
    data, _ = generate(design, experiment, planted, noise=noise, seed=seed, coeffs=coeffs, model=FD.MODEL)
    path = str(tmp_path / f"{kind.replace('/', '_')}-{seed}.csv")
    write_csv(data, path)
    return load_problem(design, [path], free=free, model=FD.MODEL), path


@pytest.mark.studies
def test_one_latch_cannot_always_tell_saturation_from_a_gain_shape_three_angles_can(tmp_path):
    """One latch seen through its switched state gives one threshold voltage per frequency: saturation (planted) and a
    broad transducer resonance fitted in its place explain seed 103 equally well (clipped -2 ln L 2.7 apart, within 6;
    seed 105, used before, sits at the threshold: 5.x on one machine, 6.8 and rank-deficient on another), and the fit
    says so (`ambiguous`, with the experiment that separates them).  Latches of three angles switch at several voltages
    per frequency: the best gain shape fitted in saturation's place is far outside the noise there."""
    from acl.fit.forward import predict
    from acl.fit.select import AMBIGUOUS_CHI2, _replacements, clipped_chi2, select_effects

    planted = {"drive_saturation": FD.SAT_STATE}
    one, _ = _state_problem(tmp_path, "latch+state", planted, 103)
    sel = select_effects(one, seed=103)
    sets = [sorted(sel.selected)] + [sorted(a["effects"]) for a in sel.ambiguous]
    assert ["drive_saturation"] in sets and ["transducer_resonance"] in sets
    alt = next(a for a in sel.ambiguous if a["by"] in ("transducer_resonance", "drive_saturation"))
    assert abs(alt["delta_chi2"]) < AMBIGUOUS_CHI2 and "angles" in alt["separate_by"]

    three, _ = _state_problem(tmp_path, "latch+state/angles", planted, 100)
    sel3 = select_effects(three, seed=100)
    assert sel3.selected == ["drive_saturation"] and sel3.ambiguous == []
    P = three.prepared
    from acl.fit.effects import SEARCHED

    _, _, _, tries = _replacements(three, lambda a, b: predict(P, a, b), list(SEARCHED), sel3.selected, sel3.final,
                                   "drive_saturation", 0.01, None, True)
    best = min(clipped_chi2(t["fit"]) for t in tries if t["effect"] in ("transducer_resonance", "transducer_gain"))
    assert best - clipped_chi2(sel3.final) > 10 * AMBIGUOUS_CHI2


def test_the_ambiguity_is_in_the_report_and_the_calibrated_design(tmp_path):
    """`acl fit --output-format json` lists the alternatives (`ambiguous`); the calibrated design says AMBIGUOUS, names
    the alternative effect with its values and the separating experiment, and its discrepancy covers the alternative's
    predictions (larger than the fit's own RMS residual)."""
    import json as _json
    import re
    import shutil
    import subprocess

    _, path = _state_problem(tmp_path, "latch+state", {"drive_saturation": FD.SAT_STATE}, 103)
    design = tmp_path / "latch.acl"
    shutil.copy(FD.LATCH_STATE, design)
    cal = tmp_path / "latch.calibrated.acl"
    out = subprocess.run([sys.executable, "-m", "acl", "fit", str(design), path, "--free", "gamma", "--output-format",
                          "json", "--calibrated", str(cal)], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": os.path.abspath(ROOT)})
    assert out.returncode == 0, out.stderr
    rep = _json.loads(out.stdout)
    assert rep["ambiguous"] and all(a["delta_chi2"] < a["threshold_chi2"] for a in rep["ambiguous"])
    assert {a["by"] for a in rep["ambiguous"]} & {"transducer_resonance", "drive_saturation"}
    text = cal.read_text()
    assert "# AMBIGUOUS" in text and "to separate" in text
    disc = float(re.search(r"discrepancy\(position\) = (\S+) m", text).group(1))
    assert disc > rep["rmse_after"]
    import acl

    assert acl.load(str(cal)).discrepancy == pytest.approx(disc)


def test_latch_state_statistics_are_the_likelihood(tmp_path):
    """A fit with latch states: its chi-square is -2 ln L (the states' deviance plus the other rows' weighted squares),
    not the Pearson sum at held variances, and the Fisher step leaves the maximum-likelihood optimum where it is."""
    from acl.fit import solve
    from acl.fit.forward import predict

    problem, _ = _state_problem(tmp_path, "latch+state", {"drive_saturation": FD.SAT_STATE, "offset_drift": FD.DRIFT},
                                102)
    P = problem.prepared
    fit = solve.fit(lambda a, b: predict(P, a, b), problem.y, problem.sigma, problem.coefs)
    st = P.state
    g = fit.value("gamma")
    # the switching probability at the fitted gamma, through the forward model with no reweighting held
    saved, P.pearson = P.pearson, None
    try:
        p = predict(P, {"gamma": g}, {})[st]
        shuttle = predict(P, {"gamma": g}, {})[~st]
    finally:
        P.pearson = saved
    y = problem.y[st]
    dev = -2.0 * np.sum(np.log(np.maximum(np.where(y > 0.5, p, 1.0 - p), 1e-300)))
    gauss = float(np.sum(((shuttle - problem.y[~st]) / problem.sigma[~st]) ** 2))
    assert fit.chi2 == pytest.approx(dev + gauss, rel=1e-9)
    # the Pearson residuals shown are another quantity: their sum of squares is not what the statistics use
    assert not np.sum((fit.residual / problem.sigma) ** 2) == pytest.approx(fit.chi2, rel=1e-6)


def test_saturation_and_drift_on_latch_states_are_both_found(tmp_path):
    """Latches of three angles, saturation + drift, seed 102: each effect alone leaves a gross misfit (the drift on the
    shuttle rows, the thresholds on the state rows) whose reduced chi-square inflated the other's interval, so both
    were rejected as not identifiable and the fit ended with neither (RMSE 63 x noise).  The search now judges
    identifiability at the data's sigma, and latch states by their likelihood."""
    from acl.fit.select import select_effects, withdraw_if_inadequate

    planted = {"drive_saturation": FD.SAT_STATE, "offset_drift": FD.DRIFT}
    problem, _ = _state_problem(tmp_path, "latch+state/angles", planted, 102)
    sel = withdraw_if_inadequate(select_effects(problem, seed=102), problem)
    assert sorted(sel.selected) == sorted(planted) and not sel.ambiguous
    st = problem.prepared.state
    assert np.sqrt(np.mean(sel.final.residual[~st] ** 2)) < RMSE_RATIO * 0.2e-6


def switch_figures(tmp_path) -> dict:
    """One latch with state rows, saturation + drift, seed 102 (docs/fit.md shows these): the planted pair fitted from
    the base model's values, plain and continued through the smoothed switch (:func:`acl.fit.select._cross_switch`)."""
    from acl.fit import solve
    from acl.fit.forward import predict
    from acl.fit.latch import latch_branch_mismatch
    from acl.fit.select import _cross_switch, _with_value, effect_coefs

    planted = {"drive_saturation": FD.SAT_STATE, "offset_drift": FD.DRIFT}
    problem, _ = _state_problem(tmp_path, "latch+state", planted, 102)
    P = problem.prepared

    def model(a, b):
        return predict(P, a, b)

    base = solve.fit(model, problem.y, problem.sigma, problem.coefs)
    coefs = [_with_value(c, v) for c, v in zip(problem.coefs, base.values)]
    coefs += [c for e in ("offset_drift", "drive_saturation") for c in effect_coefs(e, problem)[0]]
    trapped = solve.fit(model, problem.y, problem.sigma, coefs)
    fit = _cross_switch(model, problem, coefs, trapped)
    return {"rows": problem.y.size, "trapped": trapped.chi2, "continued": fit.chi2,
            "across": int(np.sum(latch_branch_mismatch(P, problem.y, trapped.prediction))),
            "across_after": int(np.sum(latch_branch_mismatch(P, problem.y, fit.prediction))),
            "offset": fit.value("offset_drift.offset"), "drift": fit.value("offset_drift.drift"),
            "v_sat": fit.value("drive_saturation.inv_vsat2") ** -0.5}


def test_a_latch_fit_stopped_at_the_switch_is_continued_through_a_smoothed_switch(tmp_path):
    """One latch with state rows, saturation + drift, seed 102 (the case below the bar): from the base model's values
    the fit of the planted pair stopped (xtol) with 8 shuttle rows on the other side of the switch than measured, each
    ~350 sigma off and without gradient (chi-square ~1e6 for 820 rows), so the search never reached the pair and chose
    a transducer resonance + drift.  :func:`acl.fit.select._cross_switch` continues from there through the same model
    with the switch smoothed (a scattered switching force, narrowed to the step) and reaches the planted values."""
    f = switch_figures(tmp_path)
    assert f["across"] >= 1 and f["trapped"] > 100 * f["rows"]          # the defect
    assert f["across_after"] == 0
    assert f["continued"] < 0.6 * f["rows"]           # 410 shuttle rows at 1 each, 410 states by their deviance
    assert f["offset"] == pytest.approx(FD.DRIFT["offset"], rel=0.1)
    assert f["drift"] == pytest.approx(FD.DRIFT["drift"], rel=0.05)
    assert f["v_sat"] == pytest.approx(FD.SAT_STATE["v_sat"], rel=0.1)


def test_one_latch_with_states_finds_saturation_and_drift_where_a_resonance_stood_in(tmp_path):
    """The same data, the whole search: before the continuation it selected transducer_resonance + offset_drift
    (chi-square 477.0) and named no alternative, because the saturation fitted in the resonance's place stopped at the
    switch (826.6); the planted pair reaches 440.4 and is selected, nothing else within the ambiguity threshold."""
    from acl.fit.select import select_effects, withdraw_if_inadequate

    planted = {"drive_saturation": FD.SAT_STATE, "offset_drift": FD.DRIFT}
    problem, _ = _state_problem(tmp_path, "latch+state", planted, 102)
    sel = withdraw_if_inadequate(select_effects(problem, seed=102), problem)
    assert sorted(sel.selected) == sorted(planted) and not sel.ambiguous
    assert sel.final.chi2 < 0.6 * problem.y.size


def test_the_smoothed_switch_is_the_step_in_the_limit_and_smooth_across_it(tmp_path):
    """acl.fit.latch.latch_travel ``blend`` (a search device only): 0 gives the step; a narrow blend agrees with the
    step away from the switching force; at it, the travel is the mean of the two branches; every blend is continuous."""
    from acl.fit.latch import latch_travel

    problem, _ = _state_problem(tmp_path, "latch+state", {}, 100)
    table = problem.prepared.latch_tables[0]
    fsw = table[2]
    x = fsw * np.linspace(0.5, 1.5, 2001)
    step = latch_travel(x, table)
    assert np.array_equal(latch_travel(x, table, blend=0.0), step)
    far = np.abs(x / fsw - 1.0) > 0.01
    assert np.allclose(latch_travel(x, table, blend=1e-3)[far], step[far], rtol=0, atol=1e-12)
    mid = latch_travel(np.array([fsw]), table, blend=0.05)[0]
    assert mid == pytest.approx(0.5 * (latch_travel(np.array([fsw]), table)[0] + np.interp(fsw, table[3], table[4])))
    assert np.max(np.abs(np.diff(step))) > 0.5 * (table[4][0] - table[1][-1])        # the step jumps by the stroke
    assert np.max(np.abs(np.diff(latch_travel(x, table, blend=0.05)))) < 0.05 * (table[4][0] - table[1][-1])


def scale_figures(tmp_path) -> dict:
    """Three latch angles, clean data, held-out seed 202 (docs/fit.md shows these): the offset_drift's F-test against
    the base model with the variance of all rows (the former test) and of the shuttle rows (states have no scale)."""
    from acl.fit import solve

    problem, _ = _state_problem(tmp_path, "latch+state/angles", {}, 202)
    base, drift = _base_then_effect(problem, "offset_drift")
    st = problem.prepared.state
    return {"problem": problem, "drift": drift, "rows": problem.y.size, "states": int(st.sum()),
            "redchi_all": drift.chi2 / (problem.y.size - drift.p), "redchi": drift.redchi,
            "p_diluted": solve.f_test(base.chi2, base.p, drift.chi2, drift.p, problem.y.size)[1],
            "p": solve.nested_f_test(base, drift)[1], "gate": 0.01 / 7}


def test_states_alone_test_an_effect_by_the_likelihood_ratio():
    """State rows alone carry no scale (dispersion fixed at 1, as solve.fit's reduced chi-square): the F-test had
    0 - p rows for its variance and returned p = 1, so no effect could ever pass on state rows alone.  The drop of
    -2 ln L is a chi-square with p1 - p0 degrees of freedom."""
    from types import SimpleNamespace

    from scipy.stats import chi2

    from acl.fit import solve

    small = SimpleNamespace(chi2=130.0, p=2, n=120, n_scale=0, chi2_scale=0.0)
    big = SimpleNamespace(chi2=112.0, p=3, n=120, n_scale=0, chi2_scale=0.0)
    F, p = solve.nested_f_test(small, big)
    assert F == pytest.approx(18.0) and p == pytest.approx(chi2.sf(18.0, 1)) and p < 1e-4
    assert solve.nested_f_test(big, small)[1] == 1.0            # not nested that way round
    # with shuttle rows the scale is theirs (the F-test above), unchanged
    mixed = SimpleNamespace(chi2=112.0, p=3, n=120, n_scale=60, chi2_scale=57.0)
    assert solve.nested_f_test(small, mixed) == solve.f_test(130.0, 2, 112.0, 3, 120, (57.0, 60))


def test_latch_states_do_not_dilute_the_scale_of_the_f_test(tmp_path):
    """Three latch angles, clean data, held-out seed 202: 615 shuttle rows carry the noise's scale, 615 state rows only
    their deviance (near 0 each).  The F-test's variance estimate was the chi-square over all 1,230 rows (half the
    shuttle rows' reduced chi-square), so F doubled and the noise's trend in time passed as an offset_drift (F-test p
    0.0004 against the gate 0.0014; the same draw made gain, resonance and shrinkage truths claim a drift too).  With
    the shuttle rows' scale the drift's p is about 0.02 and nothing is claimed; the reduced chi-square is the shuttle
    rows'."""
    from acl.fit.select import select_effects

    f = scale_figures(tmp_path)
    problem, drift = f["problem"], f["drift"]
    st = problem.prepared.state
    assert drift.n_scale == int((~st).sum()) and drift.chi2_scale < drift.chi2
    assert drift.redchi == pytest.approx(np.sum(drift.wresidual[~st] ** 2) / ((~st).sum() - drift.p))
    assert f["redchi_all"] < 0.6 < 0.9 < f["redchi"]
    assert f["p_diluted"] < f["gate"] < f["p"]
    sel = select_effects(problem, seed=202)
    assert sel.selected == [] and sel.ambiguous == []


HELDOUT = os.path.join(ROOT, "benchmarks", "fit_diagnosis_heldout.json")


def test_held_out_latch_angle_seeds_meet_the_bar_and_a_run_is_repeated():
    """benchmarks/fit_diagnosis_heldout.json: three latch angles at seeds 200..209, before (b3a0aea) and after the latch
    continuation and the states' scale.  After: every case meets the bar and nothing is claimed on clean data; its
    clean run of seed 202 (where the former F-test claimed an offset_drift) is repeated."""
    with open(HELDOUT) as fh:
        held = json.load(fh)
    after = FD.summary(held["after"]["rows"])
    assert {c["case"] for c in after} == {FD.label(k, p) for k, p in FD.CASES if k == "latch+state/angles"}
    assert all(c["n"] == 10 and c["seeds"] == list(range(200, 210)) for c in after)
    assert all(FD.meets_bar(c, RATE) for c in after)
    assert all(not r["selected"] for r in held["after"]["rows"] if not r["planted"])
    before = next(r for r in held["before"]["rows"] if r["case"] == "latch+state/angles clean" and r["seed"] == 202)
    assert before["selected"] == ["offset_drift"]                  # the defect, as recorded at b3a0aea
    row = next(r for r in held["after"]["rows"] if r["case"] == "latch+state/angles clean" and r["seed"] == 202)
    again = FD.run_case("latch+state/angles", {}, 202)
    assert again["selected"] == row["selected"] == [] and again["ok"] == row["ok"]
    assert again["rmse_after_over_noise"] == pytest.approx(row["rmse_after_over_noise"], rel=1e-3)
