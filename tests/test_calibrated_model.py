"""The calibrated design is the model: fit -> calibrated file -> analysis reproduces the fit's own predictions,
and the file carries the fit's covariance in the language (param +- s, uncertainty { correlation })."""
from __future__ import annotations

import math
import os
import shutil

import numpy as np
import pytest

import acl
from acl.fit import run_fit
from acl.fit.synth import Experiment, generate, write_csv

HERE = os.path.dirname(os.path.abspath(__file__))
PAIR = os.path.join(HERE, "..", "samples", "fit_pair.acl")
CANT = os.path.join(HERE, "..", "examples", "fig2_vertical_cantilever.acl")


def _fit(tmp_path, design, ex, effects, free, coeffs=None, noise=0.1e-6, seed=3):
    local = tmp_path / os.path.basename(design)
    shutil.copy(design, local)
    data, _ = generate(str(local), ex, effects, noise=noise, seed=seed, coeffs=coeffs)
    csv = tmp_path / "d.csv"
    write_csv(data, str(csv))
    out = run_fit(str(local), [str(csv)], free=free, seed=seed)
    cal = tmp_path / (local.stem + ".calibrated.acl")
    cal.write_text(out.calibrated)
    return out, str(cal)


def test_cantilever_calibrated_design_reproduces_the_fit(tmp_path):
    from acl.analysis import acoustics
    from acl.analysis import mechanics as mech
    from acl.design.model import Drive, Tone

    ex = Experiment(frequencies=(110e3, 125e3, 140e3), voltages=tuple(np.linspace(0, 9, 7)), observables=("delta",))
    out, cal = _fit(tmp_path, CANT, ex, {"drive_saturation": {"v_sat": 6.0}, "transducer_gain": {"gain_slope": 1.2}},
                    ["gamma"])
    assert set(out.selection.selected) == {"drive_saturation", "transducer_gain"}
    design = acl.load(cal)
    # positive coordinates are drawn log-normal by compile's bands; a signed one (gain_slope in -4 .. 4) is not
    assert "fit_gamma" in design.lognormal and "fit_drive_saturation_inv_vsat2" in design.lognormal
    assert "fit_transducer_gain_gain_slope" not in design.lognormal
    assert {p.name for p in design.uncertain_params()} >= set(design.lognormal)
    data, pred = out.problem.data, out.selection.final.prediction
    fm = acoustics.force_model_for(design)
    got = []
    for tones in data.tones:
        st = mech.equilibrium(design, Drive(tones=tuple(Tone(frequency=f, amplitude=v) for f, v in tones)), fm)
        got.append(float(np.asarray(st.displacements["act"]) @ np.array([-1.0, 0, 0])))
    # every row: the analysis of the calibrated file gives the fit's prediction (to 0.2 % of the range)
    assert np.max(np.abs(np.array(got) - pred)) < 2e-3 * np.ptp(pred)


def test_pair_calibrated_design_applies_alpha_and_gamma(tmp_path):
    from acl.analysis.acoustics import pair_forces
    from acl.design.model import Drive, Tone

    alpha, gamma = 2.6e-19, 0.022e-9          # d_c = sqrt(alpha / 2 gamma) = 76.9 um, far from the design's
    ex = Experiment(frequencies=(125e3,), voltages=tuple(np.linspace(0, 4, 17)),
                    sets={"gap": ["20 um", "30 um", "40 um", "50 um", "60 um"]})
    out, cal = _fit(tmp_path, PAIR, ex, {}, ["alpha"], coeffs={"alpha": alpha, "gamma": gamma}, noise=0.2e-6)
    dc_fit = out.report["critical_distance"]["value"]
    text = open(cal).read()
    assert "bjerknes_scale" in text and "correlation(" in text and " +- " in text
    design = acl.load(cal)
    pf = pair_forces(design, Drive(tones=(Tone(frequency=out.problem.prepared.f_ref, amplitude=1.0),)))[0]
    base = pair_forces(acl.load(PAIR), Drive(tones=(Tone(frequency=out.problem.prepared.f_ref, amplitude=1.0),)))[0]
    # the analysis of the calibrated design gives the fit's d_c (paper Eq. 3), the original does not
    assert pf.critical_distance == pytest.approx(dc_fit, rel=2e-3)
    assert abs(base.critical_distance - dc_fit) > 5e-6


def test_calibrated_file_carries_the_fit_covariance(tmp_path):
    ex = Experiment(frequencies=(115e3, 125e3), voltages=tuple(np.linspace(0, 9, 10)), observables=("delta",))
    out, cal = _fit(tmp_path, CANT, ex, {"drive_saturation": {"v_sat": 6.0}}, ["gamma"])
    assert out.selection.selected == ["drive_saturation"]
    design = acl.load(cal)
    fin = out.selection.final
    names = [c.name for c in fin.coefs]
    ig, isat = names.index("gamma"), names.index("drive_saturation.inv_vsat2")
    pg, ps = design.param("fit_gamma"), design.param("fit_drive_saturation_inv_vsat2")
    assert pg.value == pytest.approx(fin.values[ig], rel=1e-8)
    assert pg.stddev == pytest.approx(fin.stderr[ig], rel=1e-6)
    assert ps.stddev == pytest.approx(fin.stderr[isat], rel=1e-6)
    cov = design.covariance(["fit_gamma", "fit_drive_saturation_inv_vsat2"])
    assert cov[0, 1] / math.sqrt(cov[0, 0] * cov[1, 1]) == pytest.approx(fin.corr[ig, isat], abs=1e-5)
    cover = {c.quantity: (c.lower, c.upper) for c in design.coverage}
    assert cover["voltage"][1] == pytest.approx(9.0) and cover["frequency"] == (115e3, 125e3)
    assert set(design.lognormal) == {"fit_gamma", "fit_drive_saturation_inv_vsat2"}     # both fitted within >= 0
    # the effect coefficients are those parameters: analyze, compile and lint apply them
    assert design.effect("drive_saturation").params["inv_vsat2"] == pytest.approx(ps.value)
