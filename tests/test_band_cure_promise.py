"""The band compile promises after its proposed readings (issue 28): a 95 % promise over the devices the declared
uncertainty allows, each read with the stated noise and fitted as `acl fit --free gain` fits it (the gain at each
read tone, acl.fit.report.tone_gains), and the goal whose readings it assumes.

The promise was the band at the nominal design's Fisher information alone.  Through the lab's commands
(benchmarks/band_cure.py, 20 truths) it covered 17 of 20 on goal 1 and 14 of 20 on goal 2 (whose promise assumed
step 2's readings while the loop took step 1's): a device with a lower gain at a read tone moves less under the
proposed voltage, so its gain there is measured worse, and the nominal design does not see it
(:func:`acl.schedule.experiment.promise`).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl
from acl.design.model import MeasuredGain, with_measured_gain
from acl.diagnostics import Span
from acl.physics.transducer import pressure_per_volt
from acl.schedule import experiment
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.gains import model_forward_many

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG3 = os.path.join(ROOT, "examples", "fig3_three_orifice.acl")


@pytest.fixture(scope="module")
def circle(fig3):
    return compile_program(fig3, "circle", CompileOptions(band_samples=2, resim_points=20))


def _many(ds, f, u):
    return model_forward_many(ds, "m", f, u)


def _fit_tone_gain(design, f, v, y, iterations=8):
    """log gain factor at tone ``f`` (over ``design``'s) that makes the single-tone reading ``y`` (2,) at ``v`` volts:
    Gauss-Newton in the log gain, as acl.fit.report.tone_gains (no prior), with its standard error per unit noise."""
    h = 0.0
    for _ in range(iterations):
        moved = [experiment.gain_scaled(design, float(np.exp(x))) for x in (h, h + 1e-3, h - 1e-3)]
        p, a, b = (np.asarray(g, float)[0] for g in _many(moved, [f], np.array([[v * v]])))
        d = (a - b) / 2e-3
        step = float(d @ (y - p) / (d @ d))
        h += step
        if abs(step) < 1e-8:
            break
    return h, 1.0 / float(np.sqrt(d @ d))


def _calibrated(design, gains):
    """The design with a measured gain-table point at each tone ({tone Hz: (log factor, log sd)}), as `acl fit`
    writes it (measured(gain) = [(tone, Pa/V, sd)])."""
    t = design.transducer
    measured = tuple(MeasuredGain(frequency=f, gain=float(pressure_per_volt(f, t.gain_frequencies,
                                                                           t.gain_pa_per_v)[0]) * np.exp(h),
                                  stddev=sd, span=Span(file=FIG3, line=1, column=1)) for f, (h, sd) in gains.items())
    return design.model_copy(update={"transducer": with_measured_gain(t, measured), "measured_gain": measured})


def _rms(pred, target) -> float:
    return float(np.sqrt(np.mean(np.sum((np.asarray(pred, float) - target) ** 2, axis=1))))


def _loop(design, circle, truths: int, seed: int):
    """The lab's loop in process: truths from the declared prior, the first goal's proposed readings made on each with
    the stated noise, the gain at each read tone fitted (:func:`_fit_tone_gain`) and carried as measured(gain), the
    program recompiled on it and played on the truth.  [(RMS error per goal, m)] per truth."""
    m = circle.goals[0].details["band"]["cause"]["measurement"]
    reads = [(r["frequency_hz"], r["voltage_v"]) for r in m["readings"]]
    noise = m["noise_m"]
    dirs, _ = experiment.directions(design)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(truths):
        truth = experiment.moved(design, rng.standard_normal(len(dirs)))
        gains = {}
        for f, v in reads:
            y = np.asarray(_many([truth], [f], np.array([[v * v]]))[0], float)[0] + rng.normal(0.0, noise, 2)
            h, se = _fit_tone_gain(design, f, v, y)
            gains[f] = (h, se * noise)
        plan = compile_program(_calibrated(design, gains), "circle", CompileOptions(band_samples=0, resim_points=40))
        errs = []
        for g in plan.goals:
            idx = np.unique(np.linspace(0, len(g.target_m) - 1, 100).astype(int))
            assert sorted(g.frequencies_hz) == sorted(gains), (g.frequencies_hz, gains)      # plays the read tones
            played = _many([truth], g.frequencies_hz, (g.amplitudes_v ** 2)[idx])[0]
            errs.append(_rms(played, g.target_m[idx]))
        out.append(errs)
    return np.array(out)


def _promised(circle) -> list[float]:
    """Each goal's promise on the first goal's readings (the ones the loop takes)."""
    first = circle.goals[0].name
    out = []
    for g in circle.goals:
        m = g.details["band"]["cause"]["measurement"]
        own = first in (m["readings_of"], m.get("same_readings_as"))
        out.append(m["expected_rms_p95_m"] if own else m["with_readings_of"]["expected_rms_p95_m"])
    return out


@pytest.mark.studies
def test_the_promise_covers_the_lab_loop_over_twenty_truths(fig3, circle):
    """20 truths drawn from the prior (rng seed 29), the loop in process: a 95 % promise must hold on about 19 of 20
    per goal (at most 2 above it: binomial(20, 0.05) gives 2 or fewer with probability 0.92), and it must not be
    needlessly wide: at most 4x the median achieved error (the achieved error is about log-normal over the truths'
    gains: the promise's own 95th percentile is 2.5-2.6x its median).  Measured (seeds 29 and 30, 100 truths): 6 and
    4 of 100 above the promise (goal 1 / goal 2: 0.221 / 0.354 um), medians 0.090 / 0.150 um against the promise's
    own 0.086 / 0.143; seed 29's first 20: 1 and 1 above."""
    achieved = _loop(fig3, circle, 20, 29)
    promised = np.array(_promised(circle))
    assert np.all(np.sum(achieved > promised, axis=0) <= 2), (achieved, promised)
    assert np.all(promised <= 4.0 * np.median(achieved, axis=0)), (achieved, promised)


def test_each_goal_states_the_readings_its_promise_assumes(circle):
    """Goal 1's promise is on its own readings; goal 2 proposes its own (higher voltages) and is promised on goal 1's
    too, the readings a lab that takes one set makes: wider, since lower voltages teach less."""
    g1, g2 = circle.goals
    m1 = g1.details["band"]["cause"]["measurement"]
    m2 = g2.details["band"]["cause"]["measurement"]
    assert m1["readings_of"] == g1.name and "with_readings_of" not in m1 and "same_readings_as" not in m1
    assert m2["readings_of"] == g2.name and "same_readings_as" not in m2
    w = m2["with_readings_of"]
    assert w["goal"] == g1.name
    assert [(r["frequency_hz"], r["voltage_v"]) for r in w["readings"]] == \
        [(r["frequency_hz"], r["voltage_v"]) for r in m1["readings"]]
    assert max(r["voltage_v"] for r in m1["readings"]) < max(r["voltage_v"] for r in m2["readings"])
    assert w["expected_rms_p95_m"] > 1.2 * m2["expected_rms_p95_m"]
    notes = [n for n in circle.notes if "dominant cause" in n]
    assert f"on these readings ({g1.name}'s)" in notes[0] and f"on these readings ({g2.name}'s)" in notes[1]
    assert f"on {g1.name}'s readings alone" in notes[1] and "readings alone" not in notes[0]
    assert f"{w['expected_rms_p95_m'] * 1e6:.3g} um RMS" in notes[1]


def test_the_promise_counts_devices_that_move_less(circle):
    """Over the devices the declared 30 % allows, some move less under the proposed voltages and are measured worse:
    the promise is wider than the band at the nominal design's information alone (the promise before the fix, which
    the lab's loop exceeded on 3 and 6 of 20 truths), and the note says why."""
    for g in circle.goals:
        m = g.details["band"]["cause"]["measurement"]
        assert m["promise"] == "over truths"
        assert m["expected_rms_p95_m"] > 1.2 * m["nominal_rms_p95_m"], m
    assert "a device with a lower gain moves less" in next(n for n in circle.notes if "dominant cause" in n)


def test_fitted_gain_sd_is_the_reading_noise_over_the_readings_slope(fig3, circle):
    """The log sd each read tone's gain is fitted to at the nominal design is the noise over the reading's slope per
    log gain, |dy/dlog g|: about 2 |y| where the displacement is quadratic in the pressure (tolerance 15 %: the beam
    stiffens), and within 3 % of a Gauss-Newton fit's standard error of that reading (independent finite
    differences)."""
    m = circle.goals[0].details["band"]["cause"]["measurement"]
    sd = {e["frequency_hz"]: e["log_sd"] for e in m["tone_gain_sd"]}
    assert sorted(sd) == sorted(r["frequency_hz"] for r in m["readings"])
    for r in m["readings"]:
        f, v = r["frequency_hz"], r["voltage_v"]
        y = np.array(r["expected_displacement_m"])
        assert sd[f] == pytest.approx(m["noise_m"] / (2 * np.linalg.norm(y)), rel=0.15)
        h, se = _fit_tone_gain(fig3, f, v, y)
        assert abs(h) < 1e-3 and sd[f] == pytest.approx(se * m["noise_m"], rel=0.03)


def test_a_goal_proposing_the_first_goals_readings_says_so(fig3):
    """The rectangle's two steps propose the same readings: the second says they are the first's, and needs no
    second promise."""
    s = compile_program(fig3, "rectangle", CompileOptions(band_samples=2, resim_points=20, allow_nonlinear=True))
    g1, g2 = s.goals
    m1 = g1.details["band"]["cause"]["measurement"]
    m2 = g2.details["band"]["cause"]["measurement"]
    assert m1["readings"] == m2["readings"]
    assert m2["same_readings_as"] == g1.name and "with_readings_of" not in m2
    note = next(n for n in s.notes if n.startswith(f"{g2.name}: the 95 % band"))
    assert f"({g2.name}'s, the same as {g1.name}'s)" in note


def test_a_parameter_the_fitted_gain_absorbs_leaves_the_promise_as_without_it(tmp_path):
    """A declared gain scale (`param g = 1.0 +- 0.2` through a transducer_gain effect) is an uncertain parameter `acl
    fit --free gain` does not fit, but the gain it fits at the read tone takes it up entirely: the promise is the one
    without that parameter (within 10 %: the draws differ), not the 20 % scale's band (before: 2.75 um against 0.188)."""
    import shutil

    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
        shutil.copy(os.path.join(ROOT, "examples", name), tmp_path)
    f = tmp_path / "cal.acl"
    f.write_text('extends "fig2_stroke.acl"\nparam g = 1.0 +- 0.2\n'
                 "effect transducer_gain { gain_slope = 0, f_ref = 125 kHz, gain = g }\n")
    opts = dict(band_samples=2, resim_points=20, nonlinear_passes=1)
    with_g = compile_program(acl.load(str(f)), "stroke", CompileOptions(
        reload=lambda ov: acl.load(str(f), overrides=ov), **opts)).goals[0]
    plain = compile_program(acl.load(str(tmp_path / "fig2_stroke.acl")), "stroke", CompileOptions(**opts)).goals[0]
    cause = with_g.details["band"]["cause"]
    assert any(s["kind"] == "parameter" for s in cause["sources"])
    m, m0 = cause["measurement"], plain.details["band"]["cause"]["measurement"]
    assert m["readings"] == m0["readings"]
    assert m["expected_rms_p95_m"] == pytest.approx(m0["expected_rms_p95_m"], rel=0.10)
    assert m["expected_rms_p95_m"] < 0.1 * with_g.rms_error_p95_m
