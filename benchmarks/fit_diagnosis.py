"""Diagnosis rates of `acl fit` (issue 9, "Done when" bullet 1): planted effects found over seeds, per experiment kind.

Synthetic data from `acl.fit.synth` (the forward model of the fit) with one or two undeclared effects
planted, every library effect in every experiment kind that can identify it:

* ``cantilever``      samples/fit_cantilever.acl, ramps 0..10 V at 5 frequencies, twice, timed ("ramps");
                       or 3 lengths x 3 pedestals x 0..8 V at 125 kHz ("geometry")
* ``pair``            samples/fit_pair.acl, gaps 40..70 um x 5 frequencies x 0..4 V
* ``pair+cal``        samples/fit_pair_cal.acl: the pair, and the isolated calibration beam to 11 V
* ``spring+cal``      samples/fit_spring_cal.acl: paper Fig. 5c spring pair at 4 gaps x 5 frequencies x 0..4 V, and
                       the calibration beam; ``spring+cal/plateau`` the spring ramped to 5 V (into the drag plateau)
* ``body-pair+cal``   samples/fit_body_pair.acl: a two-orifice capsule facing a trussed body (acl.fit.group, the
                       analysis' coupled volumes where the capsules are), gap and sideways tip 0..3 V at 125 and
                       175 kHz (the side orifice's and the rider's mode), and the calibration beam to 11 V
* ``latch``           benchmarks/designs/fig6_latch_simulated_modulus.acl (Fig. 6a-d at 13 MPa), ramps 0..60 V (through the switch) at 4 frequencies
* ``latch+state``     samples/fit_latch_state.acl (the latch with `observe switched = state(snap)`), ramps
                       0..100 V in 2.5 V steps at 5 frequencies, twice: shuttle rows (noise) and 0/1 state rows
                       (drawn with the model's switching probability)
* ``latch+state/angles`` the same at latch angles 30/45/60 deg (several switching voltages per frequency), once
* ``.../known-force`` the same data with the thrust coefficient held at its declared value (a force known
                       independently): the only way to identify ``stiffness_scale`` (delta depends on P/EI)

Not planted where the experiment cannot identify the effect (docs/fit.md, "What a given kind of data cannot
tell apart"): ``neighbour_drag`` on a lone actuator (no neighbour: not applicable), ``drive_saturation`` and
``neighbour_drag`` on a pair alone (both bend the gap-voltage curve: the calibration beam separates them),
``large_deflection`` on a pair alone (snap-in keeps its beams within Eq. (1)'s range; the calibration beam
reaches it), ``stiffness_gradient`` and ``substrate_proximity`` without beams of several lengths and heights,
``stiffness_scale`` with the thrust coefficient free.

plus clean data (nothing may be claimed) and two effects outside the library, planted on the
cantilever ramps by hand: viscoelastic creep (deflection x (1 + 0.25 (1 - exp(-t / 40 s)))) and an
out-of-plane tilt (the observed deflection foreshortened by cos(phi), phi = 0.4 delta / 10 um rad);
for those, "correct" is: no effect selected and structure reported as unexplained with a covariate.

A case is diagnosed correctly when the selected set equals the planted set and the fit reports no alternative that
explains the data as well; "ambiguous" when the fit reports alternatives (`acl fit` report `ambiguous`) and the planted
set is among the selected and alternative sets; "wrong" otherwise.  Prints one row per case:
rate over seeds, mean RMSE after / noise, and the wrong selections seen; `--json PATH` writes every run (after each
case; `--merge` keeps the other cases already in the file).  The committed benchmarks/fit_diagnosis.json is the run
behind the table in docs/fit.md (rendered by tests/docs_sync.py with :func:`markdown`); tests/test_fit_diagnosis.py
checks its rates and repeats a subset of its runs.
Run: python benchmarks/fit_diagnosis.py [--seeds 10] [--only SUBSTRING] [--json benchmarks/fit_diagnosis.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
sys.path.insert(0, ROOT)
CANT = os.path.join(ROOT, "samples", "fit_cantilever.acl")
PAIR = os.path.join(ROOT, "samples", "fit_pair.acl")
# The committed sweep (benchmarks/fit_diagnosis.json, ~4.7 CPU-hours) was recorded with paper Eq. (3) as the pair model,
# the default of `acl fit` then; the default is now the analysis' coupled force model (10-20x slower on a pair), so the
# sweep names the reduced model it ran with, and its repeats (tests/test_fit_diagnosis.py) use the same.
MODEL = "eq3"
PAIR_CAL = os.path.join(ROOT, "samples", "fit_pair_cal.acl")
SPRING_CAL = os.path.join(ROOT, "samples", "fit_spring_cal.acl")
BODY_PAIR = os.path.join(ROOT, "samples", "fit_body_pair.acl")
LATCH = os.path.join(ROOT, "benchmarks", "designs", "fig6_latch_simulated_modulus.acl")   # the design of the committed runs
LATCH_STATE = os.path.join(ROOT, "samples", "fit_latch_state.acl")

FREQS = (105e3, 115e3, 125e3, 135e3, 145e3)


def kinds():
    from acl.fit.synth import Experiment

    ramps = Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 10, 11)), repeats=2)
    geometry = Experiment(frequencies=(125e3,), voltages=tuple(np.linspace(0, 8, 9)),
                          sets={"length": ["35 um", "50 um", "65 um"], "pedestal": ["0 um", "30 um", "60 um"]})
    gaps = {"gap": ["40 um", "50 um", "60 um", "70 um"]}
    pair = Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 4, 9)), sets=gaps, repeats=2, interval=0.5)
    pair_cal = [Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 4, 9)), sets=gaps, observables=("distance",),
                           label="pair", interval=0.5),
                Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 11, 12)), observables=("cal",),
                           repeats=2, label="calibration", interval=0.5)]
    spring_cal = [Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 4, 9)), sets=gaps, observables=("d",),
                             label="spring", interval=0.5),
                  Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 11, 12)), observables=("cal",),
                             repeats=2, label="calibration", interval=0.5)]
    # the same spring ramped two steps further, to 5 V: into the drag plateau (below)
    spring_plateau = [Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 5, 11)), sets=gaps, observables=("d",),
                                 label="spring", interval=0.5), spring_cal[1]]
    # (kept small: a group row is an equilibrium of the analysis' coupled forces, ~1 min of CPU per fit here)
    body_f = (125e3, 175e3)
    body_cal = [Experiment(frequencies=body_f, voltages=tuple(np.linspace(0, 3, 6)), observables=("distance", "a_y"),
                           label="pair", interval=0.5),
                Experiment(frequencies=body_f, voltages=tuple(np.linspace(0, 11, 9)), observables=("cal",),
                           label="calibration", interval=0.5)]
    latch = Experiment(frequencies=(115e3, 125e3, 135e3, 145e3), voltages=tuple(np.linspace(0, 60, 13)), repeats=2)
    # the switched state observed too: ramps to the declared vmax = 100 V in 2.5 V steps at 5 frequencies, so the
    # latch switches at 3-5 of them and the threshold voltage is seen per frequency and per repeat (time)
    latch_state = Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 100, 41)), repeats=2)
    # and latches of three angles (switching forces ~0.7x..1.4x): each frequency switches at several voltages, which
    # separates a drive nonlinearity in V from a gain shape in f (one threshold per frequency cannot); 0.25 s a row
    angles = Experiment(frequencies=FREQS, voltages=tuple(np.linspace(0, 100, 41)),
                        sets={"theta": ["30 deg", "45 deg", "60 deg"]}, interval=0.25)
    return {
        "cantilever": (CANT, ramps, ["gamma"], 0.2e-6, {}),
        "cantilever/geometry": (CANT, geometry, ["gamma"], 0.2e-6, {}),
        "cantilever/known-force": (CANT, geometry, [], 0.2e-6, {}),
        "pair": (PAIR, pair, ["gamma", "alpha"], 0.3e-6, {"alpha": 1.745e-19}),
        "pair+cal": (PAIR_CAL, pair_cal, ["gamma", "alpha"], 0.2e-6, {"alpha": 1.745e-19}),
        "spring+cal": (SPRING_CAL, spring_cal, ["gamma", "alpha"], 0.2e-6, {"alpha": 1.745e-19}),
        "spring+cal/plateau": (SPRING_CAL, spring_plateau, ["gamma", "alpha"], 0.2e-6, {"alpha": 1.745e-19}),
        "body-pair+cal": (BODY_PAIR, body_cal, ["gamma", "alpha"], 0.2e-6, {}),
        "latch": (LATCH, latch, ["gamma"], 0.2e-6, {}),
        "latch/known-force": (LATCH, latch, [], 0.2e-6, {}),
        "latch+state": (LATCH_STATE, latch_state, ["gamma"], 0.2e-6, {}),
        "latch+state/angles": (LATCH_STATE, angles, ["gamma"], 0.2e-6, {}),
    }


DRIFT = {"offset": 0.5e-6, "drift": 0.01e-6}
RESONANCE = {"inv_f_ratio": 1.0 / 1.02, "gain_q": 2.0}      # broad transducer resonance at 127.5 kHz
SAT, SAT_PAIR, SAT_LATCH = {"v_sat": 6.0}, {"v_sat": 3.0}, {"v_sat": 30.0}
SAT_STATE = {"v_sat": 60.0}     # at V_s = 30 V the capped force never reaches the switching force: no switch to 100 V
GAIN, SHRINK = {"gain_slope": 1.5}, {"shrink_rate": 0.004}
LARGE = {"elastica_weight": 1.0}
CASES = [
    # (kind, planted effects)
    ("cantilever", {"transducer_gain": GAIN}),
    ("cantilever", {"transducer_resonance": RESONANCE}),
    ("cantilever", {"drive_saturation": SAT}),
    ("cantilever", {"large_deflection": LARGE}),
    ("cantilever", {"offset_drift": DRIFT}),
    ("cantilever", {"bubble_shrinkage": SHRINK}),
    ("cantilever/geometry", {"stiffness_gradient": {"e_gradient": 1.0}}),
    ("cantilever/geometry", {"substrate_proximity": {"h_substrate": 40e-6}}),
    ("cantilever/known-force", {"stiffness_scale": {"e_scale": 0.7}}),
    ("cantilever", {"transducer_resonance": RESONANCE, "bubble_shrinkage": SHRINK}),
    ("cantilever", {"drive_saturation": SAT, "offset_drift": DRIFT}),
    ("cantilever", {"large_deflection": LARGE, "transducer_gain": GAIN}),
    ("cantilever/geometry", {"stiffness_gradient": {"e_gradient": 1.0}, "substrate_proximity": {"h_substrate": 40e-6}}),
    ("pair", {"transducer_gain": GAIN}),
    ("pair", {"transducer_resonance": RESONANCE}),
    ("pair", {"offset_drift": DRIFT}),
    ("pair", {"bubble_shrinkage": SHRINK}),
    ("pair", {"transducer_resonance": RESONANCE, "bubble_shrinkage": SHRINK}),
    ("pair+cal", {"drive_saturation": SAT_PAIR}),
    ("pair+cal", {"neighbour_drag": {"plateau": 8e-6}}),
    ("pair+cal", {"large_deflection": LARGE}),
    ("pair+cal", {"transducer_gain": GAIN}),
    ("pair+cal", {"transducer_resonance": RESONANCE}),
    ("pair+cal", {"offset_drift": DRIFT}),
    ("pair+cal", {"bubble_shrinkage": SHRINK}),
    ("pair+cal", {"drive_saturation": SAT_PAIR, "neighbour_drag": {"plateau": 8e-6}}),
    ("pair+cal", {"transducer_resonance": RESONANCE, "bubble_shrinkage": SHRINK}),
    ("spring+cal", {"drive_saturation": SAT_PAIR}),
    ("spring+cal", {"neighbour_drag": {"plateau": 4e-6}}),
    ("spring+cal", {"large_deflection": LARGE}),
    ("spring+cal", {"transducer_gain": GAIN}),
    ("spring+cal", {"transducer_resonance": RESONANCE}),
    ("spring+cal", {"offset_drift": DRIFT}),
    ("spring+cal", {"bubble_shrinkage": SHRINK}),
    # V_s = 6 V: at 3 V saturation caps the spring pair's force so that the drag changes its gap by 0.04 um RMS
    # (max 0.35 um) at 0.2 um noise: not in the data (measured 0/10, saturation alone found, RMSE/noise 1.01)
    ("spring+cal", {"drive_saturation": SAT, "neighbour_drag": {"plateau": 4e-6}}),
    # the lab's way to see a plateau (paper Fig. 5b, 5d: the spring actuator is ramped until it snaps): the same
    # spring ramped to 5 V (two more 0.5 V steps), where the drag changes the gap by 0.24 um RMS (0.13 at 4 V); the LRT's expected
    # non-centrality for the drag given saturation is 57 (17 at 4 V): docs/fit.md
    ("spring+cal/plateau", {"drive_saturation": SAT, "neighbour_drag": {"plateau": 4e-6}}),
    # bodies inside a pair (acl.fit.group): one effect and clean data, to show the search works there too
    ("body-pair+cal", {"drive_saturation": SAT_PAIR}),
    ("body-pair+cal", {}),
    ("latch", {"offset_drift": DRIFT}),
    ("latch", {"transducer_gain": GAIN}),
    ("latch", {"transducer_resonance": RESONANCE}),
    ("latch", {"drive_saturation": SAT_LATCH}),
    ("latch", {"bubble_shrinkage": SHRINK}),
    ("latch/known-force", {"stiffness_scale": {"e_scale": 0.7}}),
    ("latch", {"drive_saturation": SAT_LATCH, "offset_drift": DRIFT}),
    ("latch+state", {"transducer_gain": GAIN}),
    ("latch+state", {"transducer_resonance": RESONANCE}),
    ("latch+state", {"drive_saturation": SAT_STATE}),
    ("latch+state", {"bubble_shrinkage": SHRINK}),
    ("latch+state", {"offset_drift": DRIFT}),
    ("latch+state", {"drive_saturation": SAT_STATE, "offset_drift": DRIFT}),
    ("latch+state/angles", {"transducer_gain": GAIN}),
    ("latch+state/angles", {"transducer_resonance": RESONANCE}),
    ("latch+state/angles", {"drive_saturation": SAT_STATE}),
    ("latch+state/angles", {"bubble_shrinkage": SHRINK}),
    ("latch+state/angles", {"offset_drift": DRIFT}),
    ("latch+state/angles", {"drive_saturation": SAT_STATE, "offset_drift": DRIFT}),
    # clean data: nothing may be claimed
    ("cantilever", {}), ("cantilever/geometry", {}), ("pair", {}), ("pair+cal", {}), ("spring+cal", {}), ("spring+cal/plateau", {}),
    ("latch", {}),
    ("latch+state", {}), ("latch+state/angles", {}),
    # outside the library: reported as unexplained structure with a covariate, no effect claimed
    ("cantilever", {"(creep)": {}}),
    ("cantilever", {"(tilt)": {}}),
    ("pair+cal", {"(creep)": {}}),
]


# Cases measured but not counted against the 90 % bar, with the reason (docs/fit.md shows it): the experiment
# cannot identify the effect.  The latch's shuttle moves less than the noise (< 0.1 um at 0.2 um) before it
# switches and sits at state b after, so an effect that changes the switching voltage shows only in which 5 V step
# switched: a step that least squares cannot follow (no gradient), and which the base model with a re-fitted gamma
# often matches exactly.  (A `state(latch)` observable fitted by maximum likelihood is the way to identify
# them: the latch+state kinds; with one latch only partly, docs/fit.md.)
_SWITCH = ("the latch shows it only through which voltage step switched (shuttle travel before the switch is below "
           "the noise): not identifiable by least squares on the shuttle displacement")
LIMITS = {
    "spring+cal drive_saturation+neighbour_drag":
        ("at 0.2 um noise the 0..4 V ramps move the spring too little into the drag plateau: the likelihood-ratio "
         "test of the drag given saturation has power below 0.9 at the search's gate, and no test with the same "
         "error rate reaches it (power calculation above); the spring ramped to 5 V is counted"),
    "latch transducer_gain": _SWITCH,
    "latch transducer_resonance": _SWITCH,
    "latch drive_saturation": _SWITCH,
    "latch bubble_shrinkage": _SWITCH,
    "latch drive_saturation+offset_drift": _SWITCH,
}


def lrt_power(kind_name, planted, given, seed=0) -> dict:
    """Power of the search's test for the planted effects not in ``given``, given those: the expected non-centrality
    of the nested-model likelihood-ratio (F) test is the chi-square of the model with ``given`` alone fitted to the
    noise-free truth (Wald 1943; e.g. Seber & Wild, Nonlinear Regression, sec. 5.9), and the test's power at the
    search's gate (p < acl.fit.select.P_LIMIT / the candidates of that round) is the noncentral F tail beyond the
    gate's critical value.  Also: RMS and largest change of the observables by the extra effects (same coefficients),
    and the chance of at least 9 correct in 10 fits if this test were the only gate (RMS over the rows of the
    observables the extra effects change)."""
    from scipy.stats import binom, f as fdist, ncf

    from acl.fit import solve
    from acl.fit.forward import predict
    from acl.fit.problem import load_problem
    from acl.fit.select import P_LIMIT, applicable, effect_coefs
    from acl.fit.synth import effect_inputs, generate, write_csv

    design, experiment, free, noise, coeffs = kinds()[kind_name]
    data, prepared = generate(design, experiment, planted, noise=0.0, seed=seed, coeffs=coeffs, model=MODEL)
    null, _ = generate(design, experiment, {k: v for k, v in planted.items() if k in given}, noise=0.0, seed=seed,
                       coeffs=coeffs, model=MODEL)
    data.sigma = np.full(data.n, noise)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "d.csv")
        write_csv(data, path)
        problem = load_problem(design, [path], free=free, model=MODEL)
    coefs = list(problem.coefs)
    for eid in given:
        coefs += effect_coefs(eid, problem)[0]
    truth = effect_inputs({k: v for k, v in planted.items() if k in given})
    start = [c.value for c in problem.coefs] + [truth[c.effect][c.param] for c in coefs[len(problem.coefs):]]
    fit = solve.fit(lambda a, b: predict(problem.prepared, a, b), problem.y, problem.sigma, coefs, starts=[start])
    kinds_ = {c.kind for c in coefs}
    m = sum(1 for e in __import__("acl.fit.effects", fromlist=["SEARCHED"]).SEARCHED
            if e not in given and not applicable(e, problem, kinds_))
    gate = P_LIMIT / m
    q = sum(len(effect_coefs(e, problem)[0]) for e in planted if e not in given)
    dfd = problem.y.size - fit.p - q
    crit = float(fdist.isf(gate, q, dfd))
    power = float(ncf.sf(crit, q, dfd, fit.chi2))
    # the same test one-sided (an effect whose null value is a bound of its parameter: under the null the statistic is
    # 0 half the time, Self & Liang 1987, so the gate doubles) and without any multiplicity adjustment (gate P_LIMIT)
    one_sided = float(ncf.sf(fdist.isf(2 * gate, q, dfd), q, dfd, fit.chi2))
    unadjusted = float(ncf.sf(fdist.isf(P_LIMIT, q, dfd), q, dfd, fit.chi2))
    change = data.value - null.value
    moved = np.isin(data.observable, data.observable[change != 0])      # rows of the observables the effects change
    return {"noncentrality": float(fit.chi2), "gate": gate, "candidates": m, "critical": crit, "power": power,
            "power_one_sided": one_sided, "power_unadjusted": unadjusted,
            "p9of10": float(binom.sf(8, 10, power)), "rms_change_m": float(np.sqrt(np.mean(change[moved] ** 2))),
            "max_change_m": float(np.max(np.abs(change))), "rows": int(problem.y.size),
            "max_travel_m": float(np.max(np.abs(data.value - prepared.base)[moved]))}


# Cases where the experiment identifies the planted effect only up to an alternative the fit names (docs/fit.md, "What a
# given kind of data cannot tell apart"): the bar there is "correct or ambiguous with the truth among the alternatives"
# in 9 of 10 (the fit must say it cannot decide, never claim a wrong effect); with the reason shown in docs/fit.md.
_THRESHOLD = ("one latch gives one switching voltage per frequency, along which a drive nonlinearity and a gain shape "
              "trade: on some data sets the fit cannot tell them apart and says so")
_FLANK = ("over the swept band (105..145 kHz) a gain tilt and the flank of a broad transducer resonance have the same "
          "shape: frequencies beyond the band would separate them")
CONFOUNDED = {
    "latch+state transducer_gain": _THRESHOLD,
    "latch+state transducer_resonance": _THRESHOLD,
    "latch+state drive_saturation": _THRESHOLD,
    "latch+state drive_saturation+offset_drift": _THRESHOLD,
    "cantilever transducer_gain": _FLANK,
    "cantilever large_deflection+transducer_gain": _FLANK,
    "pair transducer_gain": _FLANK,           # the same band (FREQS) on the pair, alone and with the calibration beam,
    "pair+cal transducer_gain": _FLANK,       # and on the spring with it
    "spring+cal transducer_gain": _FLANK,
}


def meets_bar(case: dict, rate: float = 0.9) -> bool:
    """A case meets the issue-9 bar: correct in ``rate`` of the fits, or, where the experiment identifies the effect
    only up to a named alternative (CONFOUNDED), correct or ambiguous with the truth among the alternatives."""
    good = case["correct"] + (case["ambiguous"] if case["case"] in CONFOUNDED else 0)
    return good >= rate * case["n"]


def outside(kind_name, effects, data, rest):
    """Apply the hand-planted effects outside the library to noise-free values (see module docstring), on each
    row's displacement from its rest value ``rest`` (a cantilever's deflection, a pair's closing of the gap)."""
    u = data.value - rest
    if "(creep)" in effects:
        u = u * (1.0 + 0.25 * (1.0 - np.exp(-data.time / 40.0)))
    if "(tilt)" in effects:
        u = u * np.cos(0.4 * u / 10e-6)
    return rest + u


def run_case(kind_name, planted, seed):
    from acl.fit import run_fit
    from acl.fit.synth import generate, write_csv

    design, experiment, free, noise, coeffs = kinds()[kind_name]
    lib = {k: v for k, v in planted.items() if not k.startswith("(")}
    if "+state" in kind_name:
        # state rows (0/1) drawn with the model's switching probability, no noise on them (acl.fit.synth.generate)
        data, P = generate(design, experiment, lib, noise=noise, seed=seed, coeffs=coeffs, model=MODEL)
    else:
        data, P = generate(design, experiment, lib, noise=0.0, seed=seed, coeffs=coeffs, model=MODEL)
        data.value = outside(kind_name, planted, data, P.base) + np.random.default_rng(seed).normal(0, noise, data.n)
        data.sigma = np.full(data.n, noise)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "d.csv")
        write_csv(data, path)
        t0 = time.perf_counter()
        out = run_fit(design, [path], free=free, seed=seed, model=MODEL)
        dt = time.perf_counter() - t0
    r = out.report
    selected = list(r["effects_selected"])
    alternatives = [sorted(a["effects"]) for a in r.get("ambiguous", [])]
    if any(k.startswith("(") for k in planted):
        ok = not selected and bool(r["unexplained"])
        verdict = "correct" if ok else "wrong"
    else:
        # correct: exactly the planted set, and nothing else said to explain the data as well; ambiguous: the fit says
        # it cannot decide, and the planted set is the selected one or one of its alternatives; wrong: anything else
        exact = sorted(selected) == sorted(lib)
        ok = exact and not alternatives
        verdict = ("correct" if ok else
                   "ambiguous" if alternatives and (exact or sorted(lib) in alternatives) else "wrong")
    return {"case": label(kind_name, planted), "kind": kind_name, "planted": sorted(planted), "seed": seed, "selected": selected, "ok": bool(ok),
            "verdict": verdict, "alternatives": alternatives,
            "rmse_after_over_noise": r["rmse_after"] / noise, "rmse_before_over_noise": r["rmse_before"] / noise,
            "unexplained": sorted({u["covariate"] for u in r["unexplained"]}), "rows": r["rows"], "seconds": dt}


def label(kind_name, planted) -> str:
    return f"{kind_name} {'+'.join(sorted(planted)) or 'clean'}"


def summary(rows) -> list[dict]:
    """One entry per case (in the order first met): rate, mean RMSE after / noise, wrong selections, covariates."""
    out = {}
    for r in rows:
        out.setdefault(r["case"], []).append(r)
    table = []
    for case, res in out.items():
        outside_ = any(k.startswith("(") for k in res[0]["planted"])
        table.append({"case": case, "kind": res[0]["kind"], "planted": res[0]["planted"], "outside": outside_,
                      "limit": LIMITS.get(case, ""), "confounded": CONFOUNDED.get(case, ""),
                      "n": len(res), "correct": sum(r["ok"] for r in res),
                      # rows run before the ambiguity report (no `verdict`) said nothing ambiguous: correct or wrong
                      "ambiguous": sum(r.get("verdict") == "ambiguous" for r in res),
                      "wrong_n": sum(r.get("verdict", "correct" if r["ok"] else "wrong") == "wrong" for r in res),
                      "seeds": [r["seed"] for r in res],
                      "rmse_after_over_noise": float(np.mean([r["rmse_after_over_noise"] for r in res])),
                      "rmse_after_over_noise_max": float(np.max([r["rmse_after_over_noise"] for r in res])),
                      "wrong": sorted({"+".join(r["selected"]) or "none" for r in res
                                       if not r["ok"] and r.get("verdict") != "ambiguous"}),
                      "unexplained": sorted({c for r in res for c in r["unexplained"]}) if outside_ else []})
    return table


def markdown(rows) -> str:
    """The docs/fit.md table of a run (tests/docs_sync.py renders it from benchmarks/fit_diagnosis.json)."""
    lines = ["| kind | planted | correct | ambiguous (truth among the alternatives) | wrong | RMSE/noise mean (max) | "
             "wrong choices / structure reported |",
             "|---|---|---|---|---|---|---|"]
    for c in summary(rows):
        planted = " + ".join(c["planted"]) or "none (clean)"
        note = ", ".join(c["wrong"])
        if c["outside"]:
            note = (note + "; " if note else "") + "structure vs " + ", ".join(c["unexplained"])
        if c["limit"]:
            note = (note + "; " if note else "") + "not counted: " + c["limit"]
        if c["confounded"]:
            note = (note + "; " if note else "") + "bar: correct or ambiguous: " + c["confounded"]
        lines.append(f"| {c['kind']} | {planted} | {c['correct']}/{c['n']} | {c['ambiguous'] or ''} | {c['wrong_n'] or ''} | "
                     f"{c['rmse_after_over_noise']:.2f} ({c['rmse_after_over_noise_max']:.2f}) | {note} |")
    return "\n".join(lines)


NOTE = ("benchmarks/fit_diagnosis.py --seeds 10 (seeds 100..109); noise 0.2 um (pair 0.3 um); `code`: the commit each "
        "case ran at")


def _commit() -> str:
    """The short commit of the code a case runs at (the `code` field of its rows); "+" when the tree has changes."""
    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "acl", "benchmarks/fit_diagnosis.py"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+" if dirty else "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--only", default="")
    ap.add_argument("--json", default="")
    ap.add_argument("--exclude", default="", help="comma-separated substrings of case labels to skip")
    ap.add_argument("--cases", default="", help="semicolon-separated case labels to run (exact), in this order")
    ap.add_argument("--merge", action="store_true",
                    help="keep the other cases already in --json (rerun only the cases selected here)")
    args = ap.parse_args(argv)
    rows = []
    kept = []
    if args.merge and args.json and os.path.exists(args.json):
        with open(args.json) as fh:
            kept = json.load(fh)["rows"]
    order = [label(k, p) for k, p in CASES]
    code = _commit()

    def save():
        if not args.json:
            return
        names = {r["case"] for r in rows}
        every = [r for r in kept if r["case"] not in names and r["case"] in order] + rows
        every.sort(key=lambda r: (order.index(r["case"]), r["seed"]))
        with open(args.json + ".tmp", "w") as fh:
            json.dump({"note": NOTE, "rows": every}, fh, indent=0)
        os.replace(args.json + ".tmp", args.json)
    print(f"{'kind':20s} {'planted':52s} {'rate':>6s} {'rmse/noise':>10s}  wrong selections / unexplained")
    chosen = CASES
    if args.cases:
        wanted = [c.strip() for c in args.cases.split(";") if c.strip()]
        by_label = {label(k, p): (k, p) for k, p in CASES}
        unknown = [w for w in wanted if w not in by_label]
        if unknown:
            ap.error(f"unknown case(s): {', '.join(unknown)}")
        chosen = [by_label[w] for w in wanted]
    for kind_name, planted in chosen:
        name = label(kind_name, planted)
        if args.only and args.only not in name:
            continue
        if any(x and x in name for x in args.exclude.split(",")):
            continue
        res = [dict(run_case(kind_name, planted, s), code=code)
               for s in range(args.first_seed, args.first_seed + args.seeds)]
        rows.extend(res)
        rate = sum(r["ok"] for r in res) / len(res)
        rm = float(np.mean([r["rmse_after_over_noise"] for r in res]))
        wrong = sorted({"+".join(r["selected"]) or "none" for r in res if not r["ok"]})
        unexp = sorted({c for r in res for c in r["unexplained"]}) if any(k.startswith("(") for k in planted) else []
        print(f"{kind_name:20s} {'+'.join(sorted(planted)) or 'clean':52s} {rate:6.0%} {rm:10.2f}  "
              f"{', '.join(wrong)}{' | unexplained: ' + ', '.join(unexp) if unexp else ''}  "
              f"({np.mean([r['seconds'] for r in res]):.1f} s/fit)", flush=True)
        save()
    return 0


if __name__ == "__main__":
    sys.exit(main())
