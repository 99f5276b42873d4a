"""Error bands, robust path program, nonlinear correction and coverage warnings (acl.schedule.bands/robust/correct)."""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

import acl
from acl.schedule.bands import error_band, gain_sensitivity
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.gains import model_forward, model_gain_table

EX = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
FIG3 = os.path.join(EX, "fig3_three_orifice.acl")
FREQS = (73e3, 129.5e3, 178.5e3)


@pytest.fixture(scope="module")
def fig3():
    return acl.load(FIG3)


def _with_gain_sd(design, sd):
    t = design.transducer.model_copy(update={"gain_uncertainty": sd})
    return design.model_copy(update={"transducer": t})


def test_goals_carry_a_95_band_from_the_declared_uncertainty(fig3):
    s = compile_program(fig3, "circle", CompileOptions(band_samples=6, resim_points=20))
    for g in s.goals:
        d = g.as_dict()
        assert d["rms_error_p95_um"] is not None and d["max_error_p95_um"] is not None
        # 30 % on the (unmeasured) gain table: the band is far wider than the nominal prediction
        assert d["rms_error_p95_um"] > 10 * d["rms_error_um"]
        assert d["max_error_p95_um"] >= d["rms_error_p95_um"]
        assert g.details["band"]["samples"] == 6 and 0 <= g.details["band"]["failed"] <= 6


def test_band_grows_with_the_declared_uncertainty_and_vanishes_without(fig3):
    s = compile_program(fig3, "circle", CompileOptions(resim_points=20))
    g = next(x for x in s.goals if x.kind == "follow")
    idx = np.unique(np.linspace(0, len(g.target_m) - 1, 20).astype(int))
    u = (g.amplitudes_v ** 2).T[:, idx]
    fwd = lambda d: model_forward(d, "m", g.frequencies_hz)[0]      # noqa: E731
    narrow = error_band(_with_gain_sd(fig3, 0.05), fwd, u, g.target_m[idx], samples=8)
    wide = error_band(_with_gain_sd(fig3, 0.30), fwd, u, g.target_m[idx], samples=8)
    assert narrow.rms_p95_m < wide.rms_p95_m
    assert error_band(_with_gain_sd(fig3, None), fwd, u, g.target_m[idx], samples=8) is None
    none = compile_program(_with_gain_sd(fig3, None), "circle", CompileOptions(band_samples=4, resim_points=10))
    assert none.goals[0].rms_error_p95_m is None
    assert any("declares no uncertainty" in n for n in none.notes)


def test_a_draw_that_does_not_resolve_misses_the_path_not_left_out(fig3):
    """A draw of the declared uncertainty that does not resolve (a drawn value outside its physical range) or whose
    model fails counts as missing every waypoint (rms: the path's extent, max: unbounded), as margin bands count it a
    failing margin: left out, the 95 % band came from the draws that resolved only (it shrank as more of the declared
    spread became unphysical: optimistic)."""
    s = compile_program(fig3, "circle", CompileOptions(resim_points=20))
    g = next(x for x in s.goals if x.kind == "follow")
    idx = np.unique(np.linspace(0, len(g.target_m) - 1, 20).astype(int))
    u = (g.amplitudes_v ** 2).T[:, idx]
    calls = []

    def fwd(d):
        calls.append(d)
        if len(calls) % 4 == 0:          # every 4th draw: the model fails there
            raise ValueError("no equilibrium")
        return model_forward(d, "m", g.frequencies_hz)[0]

    design = _with_gain_sd(fig3, 0.05)
    band = error_band(design, fwd, u, g.target_m[idx], samples=20)
    assert band.samples == 20 and band.failed == 5
    assert np.sum(np.isinf(band.max_m)) == 5 and np.isinf(band.max_p95_m)
    extent = np.max(np.linalg.norm(g.target_m[idx] - g.target_m[idx].mean(axis=0), axis=1)) + \
        np.max(np.linalg.norm(g.target_m[idx], axis=1))
    assert np.sum(band.rms_m == extent) == 5 and band.rms_p95_m == extent
    # the same draws, none failing: a band far below the path's extent (what leaving them out gave)
    ok = error_band(design, lambda d: model_forward(d, "m", g.frequencies_hz)[0], u, g.target_m[idx], samples=20)
    assert ok.failed == 0 and ok.rms_p95_m < 0.5 * extent


def test_robust_plan_has_a_lower_expected_squared_error(fig3):
    from acl.schedule.path import DriveLimits, plan_path
    from acl.schedule.robust import robust_q

    G = model_gain_table(fig3, "m", FREQS).gains.T
    Q = robust_q(fig3, lambda d: model_gain_table(d, "m", FREQS).gains.T)
    assert Q.shape == (3, 3) and np.linalg.eigvalsh(Q).min() > -1e-30
    a = np.linspace(0, 2 * np.pi, 80)
    P = np.column_stack([1e-6 + 3e-6 * np.cos(a), 1e-6 + 3e-6 * np.sin(a)])
    lim = DriveLimits(max_voltage=20.0)

    def expected(plan):
        e = (G @ plan.u).T - P
        return float(np.mean(np.sum(e ** 2, axis=1) + np.einsum("kt,kj,jt->t", plan.u, Q, plan.u)))

    nominal = plan_path(G, P, 0.01, lim)
    robust = plan_path(G, P, 0.01, lim, robust_q=Q)
    assert expected(robust) < 0.8 * expected(nominal)
    # the nominal tolerance still holds for the robust plan (linear model)
    assert np.max(np.abs((G @ robust.u).T - P)) <= 0.5e-6 * (1 + 1e-3)


def test_uncertain_parameters_enter_through_reload(tmp_path):
    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
        shutil.copy(os.path.join(EX, name), tmp_path)
    f = tmp_path / "cal.acl"
    f.write_text('extends "fig2_stroke.acl"\nparam g = 1.0 +- 0.2\n'
                 "effect transducer_gain { gain_slope = 0, f_ref = 125 kHz, gain = g }\n")
    d = acl.load(str(f))
    freqs = (110e3, 125e3, 140e3)

    def gains(x):
        return model_gain_table(x, "act", freqs).gains.T

    q_table = gain_sensitivity(d, gains)
    q_all = gain_sensitivity(d, gains, reload=lambda ov: acl.load(str(f), overrides=ov))
    # thrust ~ gain^2: +20 % on g adds (1.2^2 - 1)^2 G^T G to Q
    G = gains(d)
    expected = q_table + (1.2 ** 2 - 1) ** 2 * G.T @ G
    assert np.allclose(q_all, expected, rtol=1e-6, atol=1e-30)


def test_coverage_warnings(tmp_path):
    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
        shutil.copy(os.path.join(EX, name), tmp_path)
    f = tmp_path / "cov.acl"
    f.write_text('extends "fig2_stroke.acl"\nuncertainty {\n  covered(voltage) = 0 V .. 1 V\n'
                 "  covered(frequency) = 120 kHz .. 130 kHz\n  covered(deflection) = 0 um .. 2 um\n}\n")
    s = compile_program(acl.load(str(f)), "stroke", CompileOptions(waypoint_dt_s=0.05, resim_points=5))
    warn = [n for n in s.notes if n.startswith("warning:")]
    assert any("calibration data covered 0 .. 1 V" in w for w in warn)
    assert any("110, 140 kHz lie outside" in w for w in warn)
    assert any("deflections up to 2 um" in w for w in warn)
    plain = compile_program(acl.load(os.path.join(EX, "fig2_stroke.acl")), "stroke",
                            CompileOptions(waypoint_dt_s=0.05, resim_points=5))
    # no coverage warning without covered ranges; the model's validity warnings (tests/test_compile_validity.py) stay
    assert {w.code for w in plain.warnings} <= {"W-ACOUSTIC-AMPLITUDE", "W-ACOUSTIC-STREAMING", "W-ACOUSTIC-MONOPOLE"}
    assert len(plain.warnings) == len([n for n in plain.notes if n.startswith("warning:")])


def test_nonlinear_correction_tracks_a_saturating_design():
    truth = acl.load(os.path.join(EX, "fig2_stroke_truth.acl"))
    linear = compile_program(truth, "stroke", CompileOptions(waypoint_dt_s=0.02))
    corrected = compile_program(truth, "stroke", CompileOptions(waypoint_dt_s=0.02, nonlinear_passes=3))
    assert corrected.goals[0].rms_error_m < 0.5 * linear.goals[0].rms_error_m


def test_robust_compile_narrows_the_band_of_an_uncalibrated_design(fig3):
    # the same seeded draws of the stdlib's 30 % table uncertainty for both plans
    # (the Fig. 3 paths reach the linear bubble limit eps/R ~ 0.25: docs/physics.md part A section 11)
    opts = dict(band_samples=10, resim_points=25, band_seed=3, allow_nonlinear=True)
    nominal = compile_program(fig3, "rectangle", CompileOptions(**opts)).goals[0]
    robust = compile_program(fig3, "rectangle", CompileOptions(robust=True, **opts)).goals[0]
    assert robust.details["robust"] is True
    assert robust.rms_error_m > nominal.rms_error_m           # it gives up nominal accuracy ...
    assert robust.rms_error_p95_m < 0.95 * nominal.rms_error_p95_m   # ... for a narrower band


def test_compile_cli_band_columns_and_bad_options(tmp_path):
    import json
    import subprocess
    import sys

    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    env = dict(os.environ, PYTHONPATH=root)
    src = os.path.join(EX, "fig2_stroke.acl")
    run = lambda *a: subprocess.run([sys.executable, "-m", "acl", "compile", src, "--program", "stroke", *a],  # noqa: E731
                                    capture_output=True, text=True, env=env)
    out = run("-o", str(tmp_path / "ok"), "--band-samples", "3", "--robust", "--waypoint-dt", "0.05", "--allow-nonlinear")
    assert out.returncode == 0, out.stderr
    assert "95 % band" in out.stderr
    goal = json.loads((tmp_path / "ok" / "schedule.json").read_text())["goals"][0]
    assert goal["rms_error_p95_um"] >= 0 and goal["max_error_p95_um"] >= goal["rms_error_p95_um"]
    assert goal["details"]["robust"] is True and goal["capsule"] == "act" and len(goal["target_um"]) == 40
    for bad in (("--band-samples", "-1"), ("--nonlinear-passes", "-2")):
        out = run("-o", str(tmp_path / "bad"), *bad)
        assert out.returncode == 2 and "E-COMPILE-OPTION" in out.stderr + out.stdout
        assert "Traceback" not in out.stderr and not (tmp_path / "bad").exists()


def test_worst_case_mode_lowers_the_worst_case_over_the_ellipsoid(fig3):
    from acl.schedule.path import DriveLimits, plan_path
    from acl.schedule.robust import robust_q

    G = model_gain_table(fig3, "m", FREQS).gains.T
    Q = robust_q(fig3, lambda d: model_gain_table(d, "m", FREQS).gains.T)
    w, V = np.linalg.eigh(Q)
    R = (V * np.sqrt(np.maximum(w, 0))).T                       # R^T R = Q
    a = np.linspace(0, 2 * np.pi, 60)
    P = np.column_stack([1e-6 + 3e-6 * np.cos(a), 1e-6 + 2e-6 * np.sin(a)])
    lim = DriveLimits(max_voltage=20.0)

    def worst(plan):    # bound of the error over |z| <= 1: |e_t| + |R u_t|, mean square over waypoints
        e = np.linalg.norm((G @ plan.u).T - P, axis=1)
        return float(np.mean((e + np.linalg.norm(R @ plan.u, axis=0)) ** 2))

    def expected(plan):
        e = np.linalg.norm((G @ plan.u).T - P, axis=1)
        return float(np.mean(e ** 2 + np.linalg.norm(R @ plan.u, axis=0) ** 2))

    nominal = plan_path(G, P, 0.01, lim)
    mean = plan_path(G, P, 0.01, lim, robust_q=Q)
    worst_plan = plan_path(G, P, 0.01, lim, robust_q=Q, robust_mode="worst")
    # each mode is best at its own criterion (the small drive-weight term aside)
    assert worst(worst_plan) <= min(worst(mean), worst(nominal)) * (1 + 1e-4)
    assert expected(mean) <= min(expected(worst_plan), expected(nominal)) * (1 + 1e-4)
    # the worst case is linear in |e|: unlike the mean, it does not trade tracking for a smaller spread
    assert worst(mean) > worst(worst_plan)
    with pytest.raises(ValueError):
        plan_path(G, P, 0.01, lim, robust_q=Q, robust_mode="typo")
