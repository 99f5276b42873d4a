"""One physics in `acl fit` (issue 9 items 1 and 4): the fit's forward model is the analysis' equilibrium for every
example `acl synth` + `acl fit` run on, a design parameter declared as some capsules' `thrust` is fitted and applied
on exactly those capsules, and planted coefficients come back inside their 95 % intervals."""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl
from acl.fit.synth import Experiment, generate, observe_value, write_csv

HERE = os.path.dirname(__file__)
ROOT = os.path.join(HERE, "..")
EX = os.path.join(ROOT, "examples")
FREQS = (85e3, 125e3, 170e3)

# (design, routed through the group model by default, drives below every snap-in (V), free coefficients); simple
# pairs are groups by default (the analysis' force model), lone actuators keep paper Eq. (1)
DESIGNS = [
    ("examples/fig1f_selective_beams.acl", False, (0.75, 1.5, 2.25, 3.0), ("gamma",)),
    ("examples/fig2_vertical_cantilever.acl", False, (0.75, 1.5, 2.25, 3.0), ("gamma",)),
    ("examples/fig3_three_orifice.acl", True, (0.75, 1.5, 2.25, 3.0), ("gamma",)),
    ("examples/first_principles/fig4_facing_pair.acl", True, (0.5, 1.0, 1.5, 2.0), ("gamma", "alpha")),
    # the shipped pair declares the paper's calibration (bjerknes_scale factor and gap shape): the fit keeps it
    ("examples/fig4_facing_pair.acl", True, (0.25, 0.5, 0.75, 1.0), ("gamma", "alpha")),
    ("examples/fig4h_unequal_pair.acl", True, (0.75, 1.5, 2.25, 3.0), ("gamma", "alpha")),
    # alpha and gamma act on the arms' one observed direction with the same V^2: only gamma is fitted (alpha held)
    ("examples/first_principles/fig5a_gripper.acl", True, (2.0, 4.0, 6.0, 8.0, 10.0), ("gamma",)),
    ("examples/fig5c_linear_spring.acl", True, (3.0, 6.0, 9.0, 12.0), ("gamma", "alpha")),
    ("examples/fig6e_reversible_latch.acl", True, (2.0, 4.0, 6.0, 8.0, 10.0), ("gamma",)),   # 85 kHz switches at ~12.7 V
    # below the 12.2 V at which 85 kHz switches the Table S2 calibrated latch (docs/physics.md, issue 24)
    ("examples/fig6f_control_module.acl", True, (2.0, 4.0, 6.0, 8.0, 10.0), ("gamma", "alpha")),
    ("examples/figS6_flextensional.acl", True, (0.3, 0.6, 0.9, 1.2), ("gamma", "alpha")),
    ("samples/fit_group3.acl", True, (0.5, 1.0, 1.5, 2.0), ("gamma", "alpha")),
    ("samples/fit_body_pair.acl", True, (0.5, 1.0, 1.5, 2.0, 2.5), ("gamma", "alpha")),
]
IDS = [("calibrated_" if "first_principles" not in d[0] and "fig4_facing" in d[0] else "") + os.path.basename(d[0])[:-4] for d in DESIGNS]

# |fit - analysis| <= RTOL x |analysis - rest| + ATOL (the measured worst is 4.7e-6, fig4 near its fold)
RTOL, ATOL = 1e-5, 1e-13


@pytest.mark.parametrize("rel,grouped,volts,free", DESIGNS, ids=IDS)
def test_the_fit_predicts_what_the_analysis_computes(rel, grouped, volts, free):
    """Every observable at three frequencies and the design's own values: the fit's forward model (the whole design
    as one group of rigid bodies, acl.fit.group) against acl.analysis.mechanics.equilibrium with the full force
    model.  Designs with a group or a pair are routed so by default; lone actuators with ``coupled=True`` (by
    default they keep paper Eq. (1))."""
    from acl.analysis import acoustics as A
    from acl.analysis import mechanics as M
    from acl.design.model import Drive, Tone
    from acl.fit.forward import predict
    from acl.fit.mechanism import build_instance

    path = os.path.join(ROOT, rel)
    design = acl.load(path)
    assert (build_instance(design).kind == "group") == grouped
    names = [o.name for o in design.observes]
    fm = A.force_model_for(design)
    rest = M.equilibrium(design, Drive(tones=()), fm)
    base = np.array([observe_value(design, design.observe(o), rest) for o in names])
    for f in FREQS:
        _, P = generate(path, Experiment(frequencies=(f,), voltages=volts), coupled=not grouped)
        got = predict(P, {}, {}).reshape(len(volts), len(names))
        for V, row in zip(volts, got):
            st = M.equilibrium(design, Drive(tones=(Tone(frequency=f, amplitude=V),)), fm)
            assert st.status == "ok", (f, V, st.status)
            want = np.array([observe_value(design, design.observe(o), st) for o in names])
            assert np.all(np.abs(row - want) <= RTOL * np.abs(want - base) + ATOL), (f, V, row, want)


def test_a_group_is_the_whole_design():
    """The calibration capsule 400 um from the group of three is in the group: its Bjerknes pull and coupled
    volume move the far tip by 3 % (what the fit missed when units did not interact)."""
    from acl.fit.mechanism import build_instance

    inst = build_instance(acl.load(os.path.join(HERE, "..", "samples", "fit_group3.acl")))
    assert {u.net.caps for u in inst.units.values()} == {("a", "b", "c", "cal")}


SEEDS = (1, 2, 3)


@pytest.mark.parametrize("rel,grouped,volts,free", [pytest.param(*d, id=i, marks=pytest.mark.studies if i in (
    "fit_body_pair", "fig6f_control_module", "figS6_flextensional") else ()) for d, i in zip(DESIGNS, IDS)
    if not i.startswith("calibrated_")])   # (the calibrated pair: its prediction above; its recovery in test_fit_one_model)
def test_planted_coefficients_come_back_inside_their_intervals(tmp_path, rel, grouped, volts, free):
    """Truth: the design with gamma 1.2x (and alpha 1.3x where a pair can tell it), noise 0.1 um, every observable
    at 85/125/170 kHz below every snap-in; `acl fit` with those coefficients free and no effect search, seeds 1-3:
    each coefficient's 95 % (Wald) interval covers the truth in at least 2 of the 3 seeds (a nominal 95 % interval
    fails that with probability 0.007).  Known low: on the group of three gamma's interval covers 19 of 24 seeds
    (1..4, 10..29; alpha 20 of 24) and misses seeds 1 and 2 here, so there it must cover 1 of 3; on seed 1 the
    profile likelihood also excludes the truth (chi-square 4.49 above its minimum with alpha re-fitted): the data,
    not the Wald approximation, point there (docs/fit.md Limits).  How narrow an interval is depends on the design (gamma +-2 % on
    fig6f, +-70 % on fig4 at these drives, where the gap tells alpha/gamma; alpha +-140 % on fig4h's 160 um gap)."""
    from acl.fit.problem import load_problem
    from acl.fit.select import select_effects

    path = os.path.join(ROOT, rel)
    ex = Experiment(frequencies=FREQS, voltages=volts)
    _, P = generate(path, ex, coupled=not grouped)
    truth = {"gamma": 1.2 * P.gamma0}
    if "alpha" in free:
        truth["alpha"] = 1.3 * P.alpha0
    covered = {k: 0 for k in truth}
    for seed in SEEDS:
        data, _ = generate(path, ex, noise=0.1e-6, seed=seed, coeffs=truth, coupled=not grouped)
        csv = str(tmp_path / f"d{seed}.csv")
        write_csv(data, csv)
        fit = select_effects(load_problem(path, [csv], free=list(free), coupled=not grouped), candidates=[],
                             seed=seed).final
        assert [c.kind for c in fit.coefs] == list(free)
        for k, c in enumerate(fit.coefs):
            covered[c.kind] += int(fit.ci[k][0] <= truth[c.kind] <= fit.ci[k][1])
    assert all(n >= (1 if "group3" in rel else 2) for n in covered.values()), covered


def test_thrust_declared_on_some_capsules_is_fitted_and_applied_on_exactly_those(tmp_path):
    """samples/fit_body_pair.acl declares `thrust = gamma` on a, b and calcap, not on the rider: the fit's gamma
    scales those three (as the analysis applies the parameter), the calibrated design says so, and its analysis
    at a drive the data never used is the fit's own prediction (1e-5 relative: the file prints 9 digits)."""
    from acl.analysis import acoustics as A
    from acl.analysis import mechanics as M
    from acl.design.model import Drive, Tone
    from acl.fit import run_fit
    from acl.fit.forward import predict

    path = os.path.join(HERE, "..", "samples", "fit_body_pair.acl")
    obs = ("distance", "a_y", "cal")
    ex = Experiment(frequencies=(125e3, 175e3), voltages=tuple(np.linspace(0, 2.5, 6)), observables=obs)
    _, P = generate(path, ex)
    truth = {"gamma": 1.2 * P.gamma0, "alpha": 1.3 * P.alpha0}
    data, Pt = generate(path, ex, noise=0.05e-6, seed=3, coeffs=truth)
    assert Pt.gamma_caps == {"a", "b", "calcap"}
    csv = str(tmp_path / "d.csv")
    write_csv(data, csv)
    cal = str(tmp_path / "cal.acl")
    out = run_fit(path, [csv], free=["gamma", "alpha"], candidates=[], calibrated_path=cal)
    assert out.problem.prepared.gamma_caps == {"a", "b", "calcap"}
    text = out.calibrated
    assert "capsules `a`, `b`, `calcap`" in text and "`rider` keeps the physics' own thrust" in text
    with open(cal, "w") as fh:
        fh.write(text)
    fit = out.selection.final
    coeffs = {c.kind: fit.values[k] for k, c in enumerate(fit.coefs)}
    for k, c in enumerate(fit.coefs):
        assert fit.ci[k][0] <= truth[c.kind] <= fit.ci[k][1], c.name
    # the fit's prediction at an unseen drive, in the fit's units (gamma0, alpha at the data's f_ref)
    unseen = Experiment(frequencies=(150e3,), voltages=(2.8,), observables=obs)
    _, Pu = generate(path, unseen, coeffs={"gamma": P.gamma0})
    Pu.f_ref, Pu.gamma0, Pu.alpha0 = P.f_ref, P.gamma0, P.alpha0
    for blk in Pu.groups:
        blk.gamma0, blk.alpha_ref = P.groups[0].gamma0, P.groups[0].alpha_ref
    got = predict(Pu, coeffs, {})
    design = acl.load(cal, search_paths=[os.path.dirname(path)])
    st = M.equilibrium(design, Drive(tones=(Tone(frequency=150e3, amplitude=2.8),)), A.force_model_for(design))
    assert st.status == "ok"
    want = [observe_value(design, design.observe(o), st) for o in obs]
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-12)
    # the rider's thrust is not the fitted parameter: scaling every capsule instead would miss the analysis
    Pu.groups[0].gmask = None
    for blk in Pu.groups:
        blk.gmask, blk.cache, blk.fold = None, None, None
    Pu.__dict__.pop("_memo", None)        # predictions are memoised per data set (ForwardOptions.memo): Pu was changed
    assert not np.allclose(predict(Pu, coeffs, {}), want, rtol=1e-5, atol=1e-12)
