"""Declared effects change the analysis exactly as the fit's forward model, and `acl fit` writes them back.

The comparison case is the fit's cantilever (samples/fit_cantilever.acl): the tip deflection from
`acl.analysis.mechanics.equilibrium` of a design extending it with `effect ID { ... }` against
`acl.fit.forward` (through `acl.fit.synth.generate`, noise 0) with the same effect parameters.
Both use the formulas of `acl.physics.effects`; the analysis inverts the deflection law with a
bisection (relative 1e-13) and solves the equilibrium by Newton: agreement to 1e-6 relative is
required (observed 1e-15 .. 7e-10).  neighbour_drag needs a neighbour: it is checked on the pair +
calibration beam design (the pair dragged, the isolated beam not).
"""
from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

import acl
from acl.analysis import acoustics as AC
from acl.analysis import mechanics as ME
from acl.analysis.report import analyze
from acl.cli import main
from acl.design.model import Drive, Tone
from acl.fit.synth import Experiment, generate

HERE = os.path.dirname(__file__)
CANTILEVER = os.path.join(HERE, "..", "samples", "fit_cantilever.acl")
REL = 1e-6

# (effect, fit parameters (acl.fit.synth form), declaration, frequency, voltage, data frequencies -> f_ref)
CASES = [
    ("transducer_gain", {"gain_slope": 1.5}, "effect transducer_gain { gain_slope = 1.5, f_ref = 125 kHz }",
     140e3, 6.0, (110e3, 125e3, 140e3)),
    ("drive_saturation", {"v_sat": 6.0}, "effect drive_saturation { v_sat = 6 V }", 125e3, 8.0, None),
    ("drive_saturation", {"inv_vsat2": 1 / 36}, "effect drive_saturation { inv_vsat2 = 0.0277777777778 V^-2 }",
     125e3, 8.0, None),
    ("large_deflection", {"elastica_weight": 1.0}, "effect large_deflection { elastica_weight = 1 }", 125e3, 10.0, None),
    ("large_deflection", {"elastica_weight": 0.4}, "effect large_deflection { elastica_weight = 0.4 }", 125e3, 10.0, None),
    ("stiffness_scale", {"e_scale": 0.7}, "effect stiffness_scale { e_scale = 0.7 }", 125e3, 6.0, None),
    ("stiffness_gradient", {"e_gradient": 1.0}, "effect stiffness_gradient { e_gradient = 1 }", 125e3, 6.0, None),
    ("substrate_proximity", {"h_substrate": 40e-6}, "effect substrate_proximity { h_substrate = 40 um }",
     125e3, 6.0, None),
]


def _forward(effects, f, v, freqs=None):
    data, P = generate(CANTILEVER, Experiment(frequencies=freqs or (f,), voltages=(v,)), effects)
    row = next(i for i, t in enumerate(data.tones) if t and t[0][0] == f)
    return float(data.value[row])


def _design(tmp_path, text):
    shutil.copy(CANTILEVER, tmp_path / "fit_cantilever.acl")
    path = tmp_path / "with.acl"
    path.write_text('extends "fit_cantilever.acl"\n' + text + "\n")
    return acl.load(str(path))


def _tip(design, f, v):
    st = ME.equilibrium(design, Drive(tones=(Tone(frequency=f, amplitude=v),)), AC.force_model_for(design))
    assert st.status == "ok"
    return st.deflections["arm"]


@pytest.mark.parametrize("effect,params,decl,f,v,freqs", CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_declared_effect_gives_the_fit_forward_prediction(tmp_path, effect, params, decl, f, v, freqs):
    with_effect = _tip(_design(tmp_path, decl), f, v)
    without = _tip(acl.load(CANTILEVER), f, v)
    assert with_effect == pytest.approx(_forward({effect: params}, f, v, freqs), rel=REL)
    assert without == pytest.approx(_forward({}, f, v, freqs), rel=REL)      # the old value without it
    assert abs(with_effect / without - 1) > 0.02                                # and the effect matters here


def test_saturation_makes_the_force_model_non_quadratic_and_sweeps_agree(tmp_path):
    d = _design(tmp_path, "effect drive_saturation { v_sat = 6 V }")
    assert AC.force_model_for(d).quadratic_in_amplitude is False
    assert AC.force_model_for(acl.load(CANTILEVER)).quadratic_in_amplitude is True
    sw = ME.sweep_voltage(d, Drive(tones=(Tone(frequency=125e3, amplitude=1.0),)), 8.0, AC.force_model_for(d))
    tip = np.linalg.norm(sw.positions["act"][-1] - np.asarray(d.capsule("act").center))
    assert sw.voltage[-1] == pytest.approx(8.0)
    assert tip == pytest.approx(_forward({"drive_saturation": {"v_sat": 6.0}}, 125e3, 8.0), rel=1e-4)


def test_neighbour_drag_acts_on_the_pair_not_on_the_isolated_calibration_actuator(tmp_path):
    """Paper Fig. 5b: drag 'applied to the moving actuators by the anchored ones' needs a neighbour.  In the
    analysis (force on each capsule x (1 - displacement/plateau)) and in the fit's forward model alike, the sides of
    the pair are dragged and the calibration actuator 400 um away (no neighbour) is not."""
    pair_cal = os.path.join(HERE, "..", "samples", "fit_pair_cal.acl")
    shutil.copy(pair_cal, tmp_path / "fit_pair_cal.acl")
    path = tmp_path / "with.acl"
    path.write_text('extends "fit_pair_cal.acl"\neffect neighbour_drag { plateau = 8 um }\n')
    with_drag, without = acl.load(str(path)), acl.load(pair_cal)
    drive = Drive(tones=(Tone(frequency=125e3, amplitude=3.0),))
    names = [c.name for c in with_drag.capsules]
    rest = np.array([c.center for c in with_drag.capsules], float)
    moved = rest + np.array([[2e-6, 0, 0]] * len(names))          # every capsule 2 um from rest
    fd, f0 = AC.force_batch(with_drag, moved[None], drive)[0], AC.force_batch(without, moved[None], drive)[0]
    for cap in ("a", "b"):
        i = names.index(cap)
        np.testing.assert_allclose(fd[i], f0[i] * (1 - 2 / 8), rtol=1e-12)
    i = names.index("c")
    np.testing.assert_array_equal(fd[i], f0[i])
    # the fit's forward model: the calibration beam's rows do not change, the pair's gap does
    ex = [Experiment(frequencies=(125e3,), voltages=(0.0, 6.0, 11.0), observables=("cal",)),
          Experiment(frequencies=(125e3,), voltages=(2.0, 3.0), observables=("distance",))]
    plain, _ = generate(pair_cal, ex, {}, coeffs={"alpha": 1.745e-19})
    dragged, _ = generate(pair_cal, ex, {"neighbour_drag": {"plateau": 8e-6}}, coeffs={"alpha": 1.745e-19})
    cal = plain.observable == "cal"
    np.testing.assert_array_equal(dragged.value[cal], plain.value[cal])
    assert np.all(np.abs(dragged.value[~cal] - plain.value[~cal]) > 0.05e-6)


@pytest.mark.parametrize("decl,word", [("effect offset_drift { offset = 0.5 um, drift = 10 nm/s }", "offset_drift"),
                                       ("effect bubble_shrinkage { shrink_rate = 0.004 s^-1 }", "bubble_shrinkage")])
def test_time_and_measurement_effects_leave_static_predictions_and_are_noted(tmp_path, decl, word):
    d = _design(tmp_path, decl)
    assert _tip(d, 125e3, 6.0) == _tip(acl.load(CANTILEVER), 125e3, 6.0)
    notes = analyze(d, at=Drive(tones=(Tone(frequency=125e3, amplitude=6.0),)), snap_in=False).notes
    assert any(n.startswith(f"declared effect {word} does not change static predictions") for n in notes)


def test_stiffness_scale_also_scales_latches():
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    class L:   # the latch fields the mechanics reads
        angle, length, width, thickness, youngs_modulus = 0.5, 40e-6, 4e-6, 10e-6, 1e9
    design = acl.loads("effect stiffness_scale { e_scale = 0.5 }\n")
    geo = latch_geometry(L, design)
    assert geo[-1] == 0.5e9
    assert latch_landscape(*geo).switching_force == pytest.approx(0.5 * latch_landscape(*latch_geometry(L)).switching_force)


def _run(capsys, argv):
    capsys.readouterr()
    code = main(argv)
    return code, capsys.readouterr().out


def test_synth_fit_calibrated_analyze_end_to_end(tmp_path, capsys):
    """Planted saturation: the calibrated design predicts an unseen drive within noise; the base design does not."""
    shutil.copy(CANTILEVER, tmp_path / "cant.acl")
    design, data, rep = str(tmp_path / "cant.acl"), str(tmp_path / "d.csv"), str(tmp_path / "rep")
    noise = 0.05e-6
    code, _ = _run(capsys, ["synth", design, "-o", data, "--effect", "drive_saturation=v_sat:5V",
                            "--frequencies", "100kHz,125kHz,150kHz", "--voltages", "0V..10V:11",
                            "--noise", "0.05um", "--seed", "4"])
    assert code == 0
    code, _ = _run(capsys, ["fit", design, data, "--free", "gamma", "--report", rep])
    assert code == 0
    report = json.loads(open(os.path.join(rep, "report.json")).read())
    cal = report["calibrated_design"]
    assert cal == str(tmp_path / "cant.calibrated.acl") and report["effects_selected"] == ["drive_saturation"]
    # the file: extends the original, fitted param, the selected effects with the fitted coefficients
    text = open(cal).read()
    assert 'extends "cant.acl"' in text
    d = acl.load(cal)
    gamma = next(p for p in report["final"]["parameters"] if p["name"] == "gamma")
    # the calibrated design's thrust at f_ref is the fitted gamma (up to the 9 printed digits); no absolute
    # slack (pytest.approx's default abs=1e-12 N/V^2 would pass any two thrusts of this size)
    from acl.fit.mechanism import build_instance, thrust_per_v2
    t = next(iter(thrust_per_v2(build_instance(d), report["f_ref"]).values()))   # the one capsule
    assert t == pytest.approx(gamma["value"], rel=1e-7, abs=0)
    assert [e.name for e in d.effects] == report["effects_selected"]
    assert d.effect("drive_saturation").params["inv_vsat2"] == pytest.approx(
        report["final"]["effects"]["drive_saturation"]["inv_vsat2"], rel=1e-8)
    # an unseen drive (137 kHz, 9.5 V): truth from the generator without noise
    truth = _forward({"drive_saturation": {"v_sat": 5.0}}, 137e3, 9.5)
    preds = {}
    for path in (cal, design):
        code, out = _run(capsys, ["analyze", path, "--json", "--at", "137 kHz @ 9.5 V"])
        assert code == 0
        r = json.loads(out)
        preds[path] = r["equilibrium"]["deflections_m"]["arm"]
    assert any(n.startswith("effect drive_saturation active") for n in json.loads(
        _run(capsys, ["analyze", cal, "--json"])[1])["notes"])
    assert abs(preds[cal] - truth) < 3 * noise
    assert abs(preds[design] - truth) > 20 * noise


def test_calibrated_elsewhere_needs_path_and_says_so(tmp_path, capsys):
    shutil.copy(CANTILEVER, tmp_path / "cant.acl")
    data = str(tmp_path / "d.csv")
    code, _ = _run(capsys, ["synth", str(tmp_path / "cant.acl"), "-o", data, "--effect", "stiffness_scale=e_scale:0.7",
                            "--noise", "0.05um", "--voltages", "0V..8V:9"])
    assert code == 0
    other = tmp_path / "elsewhere" / "cal.acl"
    code, out = _run(capsys, ["fit", str(tmp_path / "cant.acl"), data, "--effects", "stiffness_scale",
                              "--calibrated", str(other), "--json"])
    assert code == 0
    report = json.loads(out)
    assert report["calibrated_design"] == str(other) and report["calibrated_needs_path"] == str(tmp_path)
    assert "--path" in other.read_text()
    from acl.diagnostics import DiagnosticError

    with pytest.raises(DiagnosticError):
        acl.load(str(other))
    d = acl.load(str(other), search_paths=[str(tmp_path)])
    assert d.effect("stiffness_scale").params["e_scale"] == pytest.approx(0.7, rel=0.02)


def _assert_one_error_at_value(tmp_path, decl, where, words, code):
    """``decl`` appended to the cantilever: exactly one error, ``code``, located just after ``where``."""
    text = open(CANTILEVER).read() + "\n" + decl + "\n"
    path = tmp_path / "cant.acl"
    path.write_text(text)
    from acl.design.resolve import check_design

    _, diags = check_design(str(path))
    errors = [d for d in diags if d.is_error]
    line = text.count("\n", 0, text.index(decl)) + 1
    column = decl.index(where) + len(where) + 1
    assert [(d.code, d.span.line, d.span.column) for d in errors] == [(code, line, column)]
    assert words in errors[0].message


@pytest.mark.parametrize("decl, where, words", [
    ("effect drive_saturation { v_sat = 8 um }", "v_sat = ", "expected voltage [V], found length [m]"),
    ("effect offset_drift { offset = 0.5 um, drift = 3 V }", "drift = ", "expected speed"),
    ("effect large_deflection { elastica_weight = 0.5 um }", "elastica_weight = ", "expected a plain number"),
    ("effect transducer_gain { gain_slope = 0.5, f_ref = 125 um }", "f_ref = ", "expected frequency"),
])
def test_declared_effect_coefficient_in_the_wrong_unit_is_located_e301(tmp_path, decl, where, words):
    """The design-side twin of `synth --effect v_sat:8um`: a coefficient's unit is checked against the
    unit acl.fit.effects declares (was accepted: `v_sat = 8 um` became a saturation at 8e-6 "V")."""
    _assert_one_error_at_value(tmp_path, decl, where, words, "E301")


def test_design_effect_units_agree_with_the_fit_library():
    """acl.design.core.EFFECT_UNITS (checked at load) names every coefficient of acl.fit.effects in its unit."""
    from acl.design.core import EFFECT_UNITS, EFFECTS as DESIGN_EFFECTS
    from acl.fit.effects import ANALYSIS_NAME, EFFECTS
    from acl.units import DIMENSIONLESS, parse_unit

    assert set(EFFECT_UNITS) == set(DESIGN_EFFECTS)
    for eid, eff in EFFECTS.items():
        for p in eff.params:      # (bjerknes_shape's gap_exponent is written as bjerknes_scale's: ANALYSIS_NAME)
            e, k = ANALYSIS_NAME.get((eid, p.name), (eid, p.name))
            unit, dims = EFFECT_UNITS[e][k]
            assert unit == p.unit and dims == (parse_unit(p.unit)[1] if p.unit else DIMENSIONLESS), (eid, p.name)


@pytest.mark.parametrize("decl, where, words", [
    ("effect drive_saturation { v_sat = -5 V }", "v_sat = ", "must be positive, got -5 V"),
    ("effect transducer_gain { gain = 0 }", "gain = ", "must be positive, got 0"),
    ("effect large_deflection { elastica_weight = 1.5 }", "elastica_weight = ", "must be in 0 .. 1"),
    ("effect stiffness_scale { factor = -1 }", "factor = ", "must be positive"),
    ("effect neighbour_drag { plateau = 0 um }", "plateau = ", "must be positive"),
    ("effect bubble_shrinkage { shrink_rate = -0.1 Hz }", "shrink_rate = ", "must be not negative"),
    ("effect bjerknes_scale { factor = -0.5 }", "factor = ", "must be not negative"),
])
def test_declared_effect_coefficient_outside_its_physical_range_is_e401(tmp_path, decl, where, words):
    """`v_sat = -5 V` was taken as no saturation at all (1/v_sat^2 -> 0 for v_sat <= 0), a negative modulus or
    Bjerknes scale was applied as written: now E401 at the value."""
    _assert_one_error_at_value(tmp_path, decl, where, words, "E401")


def test_effect_domain_contains_the_fit_library_bounds():
    """Every coefficient acl fit can write lies in the range the design accepts (acl.design.core.EFFECT_DOMAIN)."""
    from acl.design.core import EFFECT_DOMAIN
    from acl.fit.effects import EFFECTS

    for eid, eff in EFFECTS.items():
        for p in eff.params:
            dom = EFFECT_DOMAIN.get((eid, p.name))
            lo = {"positive": 0.0, "nonneg": 0.0, "unit": 0.0}.get(dom, -np.inf)
            hi = 1.0 if dom == "unit" else np.inf
            assert (p.lower > lo if dom == "positive" else p.lower >= lo) and p.upper <= hi, (eid, p.name, dom)
