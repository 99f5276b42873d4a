"""`acl fit --model coupled` and honest margin bands after an Eq. 3 pair fit (docs/fit.md, Limits).

The scenario of tests/test_fit_pair_model.py: the Fig. 4 `ramp` (1..6 V at 125 kHz) played on the nominal design
itself (the full force model of acl.analysis; noise 0.02 um), gamma and alpha free.

* ``--model eq3`` (default, paper Eq. 3) returns effective coefficients: gamma ~0.66x and alpha ~0.80x the design's,
  with 95 % intervals that exclude them.  ``--model coupled`` fits the pair through acl.fit.group (the analysis'
  own forces) and recovers the design: both intervals contain the design's values, and the calibrated design's
  analysis reproduces the fit's predictions (the model check finds no difference beyond the residual).
* an Eq. 3 calibration used to give a `hold` margin band that ignored the Eq. 3 / analysis mismatch: on a design
  whose transducer is measured (2 % per table point, a hydrophone calibration) the 5th percentile of the
  `keep_apart` margin was 1.19 while the truth's margin under that drive is 1.12 (an optimistic margin: a safety
  defect).  The calibrated design now declares the snap-in drive-scale mismatch (fit_pair_model_scale), which
  the band draws.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

import acl

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
GAMMA = 0.027e-9            # the design's `param gamma` (examples/fig4_facing_pair.acl)
NOISE = 0.02e-6


def _measured_transducer(src_text: str) -> str:
    """The Fig. 4 design on a hydrophone-calibrated transducer (the stdlib table, 2 % per point instead of 30 %)."""
    table = ("transducer measured_piezo {\n  max_voltage = 20 V\n  band = 40 kHz .. 200 kHz\n"
             "  gain = [(40 kHz, 90 Pa/V), (60 kHz, 150 Pa/V), (85 kHz, 230 Pa/V), (105 kHz, 170 Pa/V),\n"
             "          (125 kHz, 230 Pa/V), (150 kHz, 180 Pa/V), (170 kHz, 230 Pa/V), (200 kHz, 110 Pa/V)]\n"
             "  gain_uncertainty = 2 %\n}\n")
    assert "use transducer transducers.contact_piezo" in src_text
    return src_text.replace("use transducer transducers.contact_piezo", table + "use transducer measured_piezo")


@pytest.fixture(scope="module")
def ramp(tmp_path_factory):
    """(folder, design path, data CSV): the nominal design's ramp, noise 0.02 um, measured transducer."""
    from acl.fit.loop import _compile, _play
    from acl.fit.synth import write_csv
    from acl.schedule.compile import CompileOptions

    tmp = str(tmp_path_factory.mktemp("coupled"))
    src = os.path.join(tmp, "fig4_facing_pair.acl")
    with open(os.path.join(EX, "first_principles", "fig4_facing_pair.acl")) as fh:
        text = _measured_transducer(fh.read())
    with open(src, "w") as fh:
        fh.write(text)
    run = _play(acl.load(src), _compile(src, "ramp", CompileOptions()), noise=NOISE, seed=0)
    csv = os.path.join(tmp, "run.csv")
    write_csv(run.data, csv)
    return tmp, src, csv


@pytest.fixture(scope="module")
def fits(ramp):
    from acl.fit import run_fit

    tmp, src, csv = ramp
    out = {}
    for model in ("eq3", "coupled"):
        cal = os.path.join(tmp, f"fig4_facing_pair.{model}.acl")
        res = run_fit(src, [csv], free=("gamma", "alpha"), seed=0, calibrated_path=cal, model=model)
        with open(cal, "w") as fh:
            fh.write(res.calibrated)
        out[model] = (res, cal)
    return out


def _alpha_physics(res):
    from acl.fit.calibrated import _alpha_physics

    return _alpha_physics(res.problem.prepared)


def _coef(res, name):
    fit = res.selection.final
    k = [c.name for c in fit.coefs].index(name)
    return fit.values[k], fit.ci[k]


@pytest.mark.studies
def test_coupled_recovers_the_design_where_eq3_does_not(fits):
    """gamma as the design parameter (the capsules' thrust); alpha against the physics' Bjerknes coefficient."""
    eq3, coupled = fits["eq3"][0], fits["coupled"][0]
    a0 = _alpha_physics(coupled)
    assert _alpha_physics(eq3) == pytest.approx(a0, rel=1e-12)
    for res, inside in ((eq3, False), (coupled, True)):
        factor = GAMMA / res.problem.prepared.gamma0           # fit coordinate -> the design parameter
        g, gci = _coef(res, "gamma")
        a, aci = _coef(res, "alpha")
        assert bool(gci[0] * factor <= GAMMA <= gci[1] * factor) is inside
        assert bool(aci[0] <= a0 <= aci[1]) is inside
    g, _ = _coef(coupled, "gamma")
    assert g * GAMMA / coupled.problem.prepared.gamma0 == pytest.approx(GAMMA, rel=0.01)   # measured 0.998
    assert _coef(coupled, "alpha")[0] == pytest.approx(a0, rel=0.01)                          # measured 0.998
    assert coupled.report["model"] == "coupled" and eq3.report["model"] == "eq3"
    assert coupled.report["critical_distance"] is not None


@pytest.mark.studies
def test_coupled_calibrated_design_is_its_fit(fits, ramp):
    """The analysis of the coupled calibration reproduces the fit (no W-FIT-PAIR-MODEL) and the truth at 3 V
    within the noise; the Eq. 3 calibration misses the truth there by >10x the noise."""
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.fit.synth import observe_value

    _, src, _ = ramp

    def gap(d):
        st = mechanics.equilibrium(d, Drive(tones=(Tone(frequency=125e3, amplitude=3.0),)),
                                   acoustics.force_model_for(d))
        return observe_value(d, d.observe("d"), st)

    truth = gap(acl.load(src))
    res, cal = fits["coupled"]
    chk = res.report["pair_model_check"]
    assert chk["model"] == "coupled" and not chk["significant"] and chk["max_m"] < 0.1 * chk["rmse_m"]
    assert not any(w.startswith("W-FIT-PAIR-MODEL") for w in res.report["final"]["warnings"])
    assert "fit_pair_model_scale" not in res.calibrated
    assert abs(gap(acl.load(cal)) - truth) < 2 * NOISE
    # the ramp's 4..6 V rows are in contact: they widen the covered range of a group's gap no more than a pair's
    # (before, the coupled calibration claimed covered(voltage) up to 6 V)
    cover = {c.quantity: c for c in acl.load(cal).coverage}
    assert cover["voltage"].upper == pytest.approx(3.0)
    assert abs(gap(acl.load(fits["eq3"][1])) - truth) > 10 * NOISE


def _keep_apart(cal, folder):
    """keep_apart compiled on a calibrated design with its band; (margin p05, promised, truth's margin)."""
    from acl.schedule.compile import CompileOptions, compile_program
    from acl.schedule.gains import critical_scale

    opts = CompileOptions(band_samples=20, band_seed=0, allow_nonlinear=True,
                          reload=lambda ov: acl.load(cal, overrides=ov, search_paths=[folder]))
    s = compile_program(acl.load(cal, search_paths=[folder]), "keep_apart", opts)
    g = s.goals[0]
    seg = next(x for x in s.segments if x.tones)
    tones = [(t.frequency_hz, t.amplitude_v) for t in seg.tones]
    truth = acl.load(os.path.join(folder, "fig4_facing_pair.acl"))
    return g.details["band"]["margin_p05"], g.details["resimulated_margin"], \
        critical_scale(truth, "left.jet", "right.jet", tones, 3.0, 10e-6)


@pytest.mark.studies
def test_eq3_calibration_margin_band_covers_the_truths_margin(fits, ramp):
    """The truth keeps less margin than the Eq. 3 calibration promises; the band's p05 lies below the truth's."""
    tmp = ramp[0]
    res, cal = fits["eq3"]
    p05, promised, truth = _keep_apart(cal, tmp)
    assert truth < promised * 0.97                           # the defect: measured 1.119 against 1.2
    assert p05 < truth, (p05, truth)                         # measured 1.03 (1.19 before the declared scale)
    snap = res.report["pair_model_check"]["snap"]
    assert snap["scale_sd"] > 0.03                           # measured 0.079: the analysis snaps ~8 % later
    assert "param fit_pair_model_scale = 1 +-" in res.calibrated
    assert any(w.startswith("W-FIT-PAIR-MODEL") and "fit_pair_model_scale" in w
               for w in res.report["final"]["warnings"])


@pytest.mark.studies
def test_coupled_calibration_margin_band_covers_the_truths_margin(fits, ramp):
    p05, promised, truth = _keep_apart(fits["coupled"][1], ramp[0])
    assert truth == pytest.approx(promised, rel=0.01)        # the coupled calibration is the truth's model
    assert p05 < truth


@pytest.mark.studies
def test_pair_model_scale_is_the_drive_scale(fits):
    """fit_pair_model_scale is wired to the drive (the bands draw it); its nominal value is 1."""
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.fit.synth import observe_value

    cal = fits["eq3"][1]
    d = acl.load(cal)
    drive = Drive(tones=(Tone(frequency=125e3, amplitude=2.0),))
    base = observe_value(d, d.observe("d"), mechanics.equilibrium(d, drive, acoustics.force_model_for(d)))
    d2 = acl.load(cal, overrides={"fit_pair_model_scale": "1.05"})
    moved = observe_value(d2, d2.observe("d"), mechanics.equilibrium(d2, drive, acoustics.force_model_for(d2)))
    assert base != moved                                     # it is the drive scale the bands draw
    assert d.param("fit_pair_model_scale").value == 1.0


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, timeout=1200, cwd=ROOT)


@pytest.mark.parametrize("value", ["eq4", "", "COUPLED", "group"])
def test_bad_model_option_is_a_located_usage_error(ramp, tmp_path, value):
    _, src, csv = ramp
    cal, rep = tmp_path / "c.acl", tmp_path / "rep"
    for fmt in ("text", "json"):
        r = _cli("fit", src, csv, "--free", "gamma,alpha", "--model", value, "--calibrated", str(cal),
                 "--report", str(rep), "--output-format", fmt)
        assert r.returncode == 2
        assert "<--model>:1:1" in r.stderr and "E-USAGE" in r.stderr and "Traceback" not in r.stderr + r.stdout
        assert r.stdout == ""
        assert not cal.exists() and not rep.exists()
    if value == "eq4":
        assert "did you mean `eq3`" in r.stderr


def test_bad_model_in_the_python_api_is_a_diagnostic(ramp):
    from acl.diagnostics import DiagnosticError
    from acl.fit import run_fit

    _, src, csv = ramp
    with pytest.raises(DiagnosticError) as exc:
        run_fit(src, [csv], free=("gamma",), model="eq4")
    d = exc.value.diagnostics[0]
    assert d.code == "E-USAGE" and d.span.file == "<--model>" and (d.span.line, d.span.column) == (1, 1)
    with pytest.raises(DiagnosticError):
        acl.fit(src, csv, free=["gamma"], model="coupld")             # the public API says the same


@pytest.mark.studies
def test_cli_model_coupled_json(ramp, tmp_path):
    folder, src, csv = ramp
    cal = tmp_path / "c.acl"
    r = _cli("fit", src, csv, "--free", "gamma,alpha", "--model", "coupled", "--calibrated", str(cal),
             "--output-format", "json")
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert rep["model"] == "coupled" and rep["pair_model_check"]["model"] == "coupled"
    assert acl.load(str(cal), search_paths=[folder]).param("fit_alpha") is not None



# -- the fast versions of the studies above: the same fits without the effect search (~1 s a fit instead of ~30 s) --

@pytest.fixture(scope="module")
def quick_fits(ramp):
    from acl.fit import run_fit

    tmp, src, csv = ramp
    out = {}
    for model in ("eq3", "coupled"):
        cal = os.path.join(tmp, f"fig4_facing_pair.quick-{model}.acl")
        res = run_fit(src, [csv], free=("gamma", "alpha"), seed=0, candidates=[], calibrated_path=cal, model=model)
        with open(cal, "w") as fh:
            fh.write(res.calibrated)
        out[model] = (res, cal)
    return out


def test_coupled_recovers_the_design_where_eq3_does_not_without_the_effect_search(quick_fits):
    """Eq. 3 returns effective coefficients whose intervals exclude the design's (measured gamma 0.66x, alpha 0.80x)
    and warns W-FIT-PAIR-MODEL with the declared drive scale; the coupled model recovers both within 1 % (measured
    0.998), its calibrated design declares no scale and the model check finds no difference."""
    for model, inside in (("eq3", False), ("coupled", True)):
        res = quick_fits[model][0]
        factor = GAMMA / res.problem.prepared.gamma0
        a0 = _alpha_physics(res)
        g, gci = _coef(res, "gamma")
        a, aci = _coef(res, "alpha")
        assert bool(gci[0] * factor <= GAMMA <= gci[1] * factor) is inside
        assert bool(aci[0] <= a0 <= aci[1]) is inside
        chk = res.report["pair_model_check"]
        assert res.report["model"] == model and chk["model"] == model and chk["significant"] is not inside
        warned = any(w.startswith("W-FIT-PAIR-MODEL") for w in res.report["final"]["warnings"])
        assert warned is not inside and ("param fit_pair_model_scale = 1 +-" in res.calibrated) is not inside
        if inside:
            assert g * factor == pytest.approx(GAMMA, rel=0.01) and a == pytest.approx(a0, rel=0.01)


def test_eq3_calibration_margin_band_covers_the_truths_margin_without_the_effect_search(quick_fits, ramp):
    """The declared drive scale is what the band draws: its p05 lies below the truth's margin, which is below the
    margin the Eq. 3 calibration promises."""
    p05, promised, truth = _keep_apart(quick_fits["eq3"][1], ramp[0])
    assert p05 < truth < promised * 0.97
    d = acl.load(quick_fits["eq3"][1])
    assert d.param("fit_pair_model_scale").value == 1.0


def test_cli_model_coupled_json_without_the_effect_search(ramp, tmp_path):
    folder, src, csv = ramp
    cal = tmp_path / "c.acl"
    r = _cli("fit", src, csv, "--free", "gamma,alpha", "--model", "coupled", "--effects", "none",
             "--calibrated", str(cal), "--output-format", "json")
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert rep["model"] == "coupled" and rep["pair_model_check"]["model"] == "coupled"
    assert acl.load(str(cal), search_paths=[folder]).param("fit_alpha") is not None
