"""Each effect of the library, planted in synthetic data from an experiment that can identify it, is found.

Data come from `acl.fit.synth` (the documented generator behind `acl synth`) with fixed seeds and
0.2 um noise (sub-pixel tracking of a 50 um beam); every test fits with the whole library.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from acl.fit.effects import SEARCHED
from acl.fit.problem import load_problem
from acl.fit.select import select_effects
from acl.fit.synth import Experiment, generate, write_csv

HERE = os.path.dirname(__file__)
CANTILEVER = os.path.join(HERE, "..", "samples", "fit_cantilever.acl")
PAIR_CAL = os.path.join(HERE, "..", "samples", "fit_pair_cal.acl")    # a facing pair + an isolated calibration beam
NOISE = 0.2e-6

# voltage ramps at three frequencies, twice, timed: identifies drive, gain, beam and time effects
RAMPS = Experiment(frequencies=(110e3, 125e3, 140e3), voltages=tuple(np.linspace(0, 10, 11)), repeats=2)
# three beam lengths x three pedestal heights: identifies stiffness and substrate effects
GEOMETRY = Experiment(frequencies=(125e3,), voltages=tuple(np.linspace(0, 8, 9)),
                      sets={"length": ["35 um", "50 um", "65 um"], "pedestal": ["0 um", "30 um", "60 um"]})

# a sweep of five frequencies: identifies the shape of the transducer gain (a broad resonance)
SWEEP = Experiment(frequencies=(105e3, 115e3, 125e3, 135e3, 145e3), voltages=tuple(np.linspace(0, 10, 11)), repeats=2)

# neighbour drag needs a neighbour (the sides of a pair); the calibration beam, which sees the drive but no neighbour,
# tells it from drive saturation (docs/fit.md)
_GAPS = {"gap": ["40 um", "50 um", "60 um", "70 um"]}
PAIR_CAL_SET = [Experiment(frequencies=(105e3, 125e3, 145e3), voltages=tuple(np.linspace(0, 4, 9)), sets=_GAPS,
                           observables=("distance",), label="pair", interval=0.5),
                Experiment(frequencies=(105e3, 125e3, 145e3), voltages=tuple(np.linspace(0, 11, 12)),
                           observables=("cal",), repeats=2, label="calibration", interval=0.5)]
PAIR_COEFFS = {"alpha": 1.745e-19}

# (effect, parameters, experiment, free coefficients[, design, generator coefficients])
CASES = [
    ("transducer_gain", {"gain_slope": 1.5}, RAMPS, ["gamma"]),
    ("transducer_resonance", {"inv_f_ratio": 1 / 1.02, "gain_q": 2.0}, SWEEP, ["gamma"]),
    ("drive_saturation", {"v_sat": 6.0}, RAMPS, ["gamma"]),
    ("large_deflection", {"elastica_weight": 1.0}, RAMPS, ["gamma"]),
    ("offset_drift", {"offset": 0.5e-6, "drift": 0.01e-6}, RAMPS, ["gamma"]),
    ("bubble_shrinkage", {"shrink_rate": 0.01}, RAMPS, ["gamma"]),
    ("neighbour_drag", {"plateau": 8e-6}, PAIR_CAL_SET, ["gamma", "alpha"], PAIR_CAL, PAIR_COEFFS),
    ("stiffness_gradient", {"e_gradient": 1.0}, GEOMETRY, ["gamma"]),
    ("substrate_proximity", {"h_substrate": 40e-6}, GEOMETRY, ["gamma"]),
    ("stiffness_scale", {"e_scale": 0.7}, GEOMETRY, []),   # force known: gamma fixed
]


def _fit(tmp_path, experiment, effects, free, seed, design=CANTILEVER, coeffs=None):
    # the pair + calibration case keeps the reduced Eq. (3) pair model its figures (docs/fit.md) were recorded with:
    # its effect search on the analysis' coupled model costs over 20x the CPU (benchmarks/fit.py case 2), too slow for
    # the default set (neighbour drag on the coupled model has no identification test yet)
    model = "eq3" if design == PAIR_CAL else "coupled"
    data, _ = generate(design, experiment, effects, noise=NOISE, seed=seed, coeffs=coeffs, model=model)
    path = tmp_path / "data.csv"
    write_csv(data, str(path))
    problem = load_problem(design, [str(path)], free=free, model=model)
    return select_effects(problem)


def test_every_library_effect_has_an_identification_case():
    assert {c[0] for c in CASES} == set(SEARCHED)     # bjerknes_scale / _shape: tests/test_fit_one_model.py


@pytest.mark.parametrize("effect,params,experiment,free,design,coeffs",
                         [c if len(c) == 6 else c + (CANTILEVER, None) for c in CASES], ids=[c[0] for c in CASES])
def test_planted_effect_is_selected_and_rmse_reaches_the_noise(tmp_path, effect, params, experiment, free, design,
                                                               coeffs):
    sel = _fit(tmp_path, experiment, {effect: params}, free, seed=11, design=design, coeffs=coeffs)
    assert sel.selected == [effect]
    assert sel.base.rmse > 1.3 * NOISE          # the base model alone does not explain the data
    assert sel.final.rmse < 1.3 * NOISE


@pytest.mark.parametrize("experiment,free", [(RAMPS, ["gamma"]), (GEOMETRY, ["gamma"])], ids=["ramps", "geometry"])
def test_clean_data_select_nothing(tmp_path, experiment, free):
    sel = _fit(tmp_path, experiment, {}, free, seed=5)
    assert sel.selected == []
    assert sel.final.rmse < 1.3 * NOISE


def test_neighbour_drag_is_not_tried_on_an_actuator_without_a_neighbour(tmp_path):
    # paper Fig. 5b: the drag comes from a neighbour's jet; a lone cantilever has none.  It was selectable, and won over
    # a planted large_deflection in 3 of 10 seeds of benchmarks/fit_diagnosis.py (both are functions of the deflection
    # alone, so frequencies do not separate them; their chi-squares differed by 0-10 for a gain of ~100)
    sel = _fit(tmp_path, RAMPS, {"large_deflection": {"elastica_weight": 1.0}}, ["gamma"], seed=101)
    trial = next(t for t in sel.trials if t.effect == "neighbour_drag")
    assert trial.status == "not applicable" and "neighbour" in trial.reason
    assert sel.selected == ["large_deflection"]


def test_stiffness_scale_is_not_identifiable_when_the_thrust_is_free(tmp_path):
    # delta depends on P/EI only: with gamma free, E cannot be told apart (docs/fit.md)
    sel = _fit(tmp_path, GEOMETRY, {"stiffness_scale": {"e_scale": 0.7}}, ["gamma"], seed=3)
    assert "stiffness_scale" not in sel.selected
    trial = next(t for t in sel.trials if t.effect == "stiffness_scale")
    assert "identifiable" in trial.reason


def test_fitted_effect_parameter_is_close_to_the_planted_value(tmp_path):
    sel = _fit(tmp_path, RAMPS, {"drive_saturation": {"v_sat": 6.0}}, ["gamma"], seed=2)
    inv = sel.effects["drive_saturation"]["inv_vsat2"]
    k = [c.name for c in sel.final.coefs].index("drive_saturation.inv_vsat2")
    lo, hi = sel.final.ci[k]
    assert lo <= 1 / 36 <= hi
    assert abs(inv ** -0.5 - 6.0) < 0.6


def test_structure_no_effect_explains_is_reported_with_its_covariate(tmp_path, capsys):
    # one drive frequency responds 25 % weaker than the model (a notch no library effect has)
    from acl.fit import run_fit
    from acl.fit.report import render_table

    ex = Experiment(frequencies=(100e3, 112e3, 125e3, 137e3, 150e3), voltages=tuple(np.linspace(0, 10, 11)), repeats=2)
    data, _ = generate(CANTILEVER, ex, {}, noise=0.0, seed=1)
    f = np.array([t[0][0] if t else 0.0 for t in data.tones])
    data.value = np.where(f == 125e3, 0.75, 1.0) * data.value + np.random.default_rng(3).normal(0, NOISE, data.n)
    data.sigma = np.full(data.n, NOISE)
    path = tmp_path / "notch.csv"
    write_csv(data, str(path))
    out = run_fit(CANTILEVER, [str(path)], free=["gamma"])
    assert out.selection.final.rmse > 1.3 * NOISE
    assert "frequency" in {u["covariate"] for u in out.report["unexplained"]}
    render_table(out.report)
    assert "no effect in the library explains it" in capsys.readouterr().out
