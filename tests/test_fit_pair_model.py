"""A pair's calibrated design must not be more confident than the analysis it feeds (docs/fit.md, Limits).

The labloop scenario: the Fig. 4 `ramp` played on the nominal design itself (noise 0.02 um), fitted with
gamma and alpha free by the Eq. 3 pair model; the calibrated design's analysis (full force model) misses the
truth's gap at 3 V by ~0.5 um while the fit's RMS residual is ~0.02 um.  Before W-FIT-PAIR-MODEL the written
``discrepancy(position)`` was that residual, so the miss was ~30 of its sigmas; now the 95 % band
(1.96 x discrepancy) covers it, and the fit says why.
"""
from __future__ import annotations

import os
import shutil

import pytest

import acl

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.fit import run_fit
    from acl.fit.synth import write_csv
    from acl.fit.loop import _compile, _play
    from acl.fit.synth import observe_value
    from acl.schedule.compile import CompileOptions

    tmp = str(tmp_path_factory.mktemp("pairmodel"))
    src = os.path.join(tmp, "fig4_facing_pair.acl")
    shutil.copy(os.path.join(EX, "fig4_facing_pair.acl"), src)
    nominal = acl.load(src)
    run = _play(nominal, _compile(src, "ramp", CompileOptions()), noise=0.02e-6, seed=0)
    csv = os.path.join(tmp, "run.csv")
    write_csv(run.data, csv)
    cal_path = os.path.join(tmp, "cal.acl")
    out = run_fit(src, [csv], free=("gamma", "alpha"), seed=0, calibrated_path=cal_path)
    with open(cal_path, "w") as fh:
        fh.write(out.calibrated)
    cal = acl.load(cal_path)

    def gap(d):
        st = mechanics.equilibrium(d, Drive(tones=(Tone(frequency=125e3, amplitude=3.0),)),
                                   acoustics.force_model_for(d))
        return observe_value(d, d.observe("d"), st)

    return out, cal, abs(gap(cal) - gap(nominal)), src, csv


def test_calibrated_pair_band_covers_the_truth(scenario):
    out, cal, miss, _, _ = scenario
    assert miss > 10 * out.report["rmse_after"]            # the defect is there: the fit's residual alone is optimistic
    assert miss <= 1.96 * cal.discrepancy                   # the written 95 % band covers the truth at 3 V


def test_pair_model_warning_in_report(scenario):
    out, *_ = scenario
    chk = out.report["pair_model_check"]
    assert chk["significant"] and chk["max_m"] > chk["factor"] * chk["rmse_m"]
    assert any(w.startswith("W-FIT-PAIR-MODEL") for w in out.report["final"]["warnings"])
    assert "W-FIT-PAIR-MODEL" in out.calibrated


def test_pair_model_warning_in_cli_text_and_json(scenario, tmp_path, capsys):
    import json

    from acl.cli import main

    _, _, _, src, csv = scenario
    cal = str(tmp_path / "c.acl")
    assert main(["fit", src, csv, "--free", "gamma,alpha", "--calibrated", cal, "--output-format", "json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert any(w.startswith("W-FIT-PAIR-MODEL") for w in rep["final"]["warnings"])
    assert main(["fit", src, csv, "--free", "gamma,alpha", "--calibrated", cal]) == 0
    assert "W-FIT-PAIR-MODEL" in capsys.readouterr().out


def test_a_check_that_cannot_run_is_said_not_silent(scenario, monkeypatch):
    """When the calibrated design's analysis fails, the fit warns that the pair-model check did not run."""
    from acl.analysis import mechanics
    from acl.fit import run_fit

    _, _, _, src, csv = scenario

    def broken(*a, **k):
        raise RuntimeError("equilibrium did not converge")

    monkeypatch.setattr(mechanics, "equilibrium", broken)
    out = run_fit(src, [csv], free=("gamma", "alpha"), seed=0,
                  calibrated_path=os.path.join(os.path.dirname(csv), "cal2.acl"))
    chk = out.report["pair_model_check"]
    assert "error" in chk and not chk["significant"]
    warn = [w for w in out.report["final"]["warnings"] if w.startswith("W-FIT-PAIR-MODEL")]
    assert warn and "could not run" in warn[0]
