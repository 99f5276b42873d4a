"""Issue 24, "a new geometry falls back to first principles, with the uncertainty that the gap between the two
implies": a design whose pair (secondary Bjerknes) forces no bjerknes_scale calibrates has that force's spread
(the log-normal of the paper's measured / first-principles ratios, acl.physics.constants.PAIR_SCALE_ROWS) drawn in
`acl compile`'s bands and counted in `acl sweep`'s yield interval; a calibrated design is unchanged."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.physics import constants as C
from acl.schedule import bands
from acl.schedule.compile import CompileOptions, compile_program
from example_designs import first_principles_path

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = ROOT / "samples" / "pair_follow.acl"
FIG5C = ROOT / "examples" / "fig5c_linear_spring.acl"
SPRING = ROOT / "benchmarks" / "designs" / "sweep_spring.acl"
AT_ONE = "\neffect bjerknes_scale { factor = 1 }\n"     # the same force, declared: no spread to draw


def _stdlib_params() -> dict:
    text = (ROOT / "stdlib" / "calibrations.acl").read_text()
    return {k: float(v) for k, v in re.findall(r"(?m)^param (first_principles_pair_\w+) = ([0-9.]+)\s*$", text)}


def _alpha(p) -> float:        # attraction x gap^2 / V^2 in nN um^2/V^2 (paper Eq. 3's alpha)
    return p["force_n"] * p["gap_m"] ** 2 / p["voltage_v"] ** 2 * 1e21


def _pairs_125(design) -> list:
    return [p for p in acl.analyze(design, snap_in=False).as_dict()["pairs"] if p["frequency_hz"] == 125e3]


def test_the_spread_is_the_log_normal_of_the_stdlib_rows():
    par = _stdlib_params()
    rows = sorted(v for k, v in par.items() if k.startswith("first_principles_pair_ratio_"))
    assert rows == sorted(r for _, r in C.PAIR_SCALE_ROWS) and len(rows) == 3
    logs = np.log(rows)
    assert C.PAIR_SCALE_LOG_MEAN == pytest.approx(logs.mean(), rel=1e-12)
    assert C.PAIR_SCALE_LOG_SD == pytest.approx(logs.std(ddof=1), rel=1e-12)
    assert C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN == pytest.approx(math.exp(logs.mean()), rel=1e-12)
    # the stdlib's stated figures are these, rounded to the digits it prints
    assert par["first_principles_pair_scale_median"] == round(C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN, 2)
    assert par["first_principles_pair_scale_log_sd"] == round(C.PAIR_SCALE_LOG_SD, 2)
    # and the moment-matched declaration it suggests: the mean and sd of the predictive spread compile draws (midpoint
    # rule on 200,000 equal-probability cells), and the fitted log-normal's own, exp(mu + s^2/2) and mean sqrt(exp(s^2) - 1)
    text = (ROOT / "stdlib" / "calibrations.acl").read_text()
    draws = C.pair_scale_from_uniform((np.arange(200_000) + 0.5) / 200_000)
    assert f"param pair_scale = {draws.mean():.3g} +- {draws.std():.3g}" in text
    mean = math.exp(C.PAIR_SCALE_LOG_MEAN + C.PAIR_SCALE_LOG_SD ** 2 / 2)
    assert f"{mean:.3g} +- {mean * math.sqrt(math.exp(C.PAIR_SCALE_LOG_SD ** 2) - 1):.3g}, would be far narrower" in text
    assert C.pair_ratio_fit_quantile(0.5) == pytest.approx(C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN, rel=1e-12)


def test_the_drawn_spread_is_the_truncated_predictive_student_t():
    """The spread compile and sweep draw: the prediction of a 4th ratio from 3 (ln s = m + s_n sqrt(1 + 1/3) T,
    T ~ t with 2 dof; Hahn & Meeker sec. 4.5), truncated to 1e-3..1e3; recomputed here with scipy's t."""
    from scipy.stats import t as student

    logs = np.log([r for _, r in C.PAIR_SCALE_ROWS])
    m, scale = logs.mean(), logs.std(ddof=1) * math.sqrt(1 + 1 / 3)
    assert C.PAIR_SCALE_DOF == 2 and C.PAIR_SCALE_PREDICTIVE_LOG_SCALE == pytest.approx(scale, rel=1e-12)
    lo, hi = (student.cdf((math.log(b) - m) / scale, 2) for b in (1e-3, 1e3))
    for p in (0.025, 0.05, 0.5, 0.95, 0.975):
        want = math.exp(m + scale * student.ppf(lo + p * (hi - lo), 2))
        assert C.pair_scale_quantile(p) == pytest.approx(want, rel=1e-9)
    # wider than the known-sd log-normal at both ends of the 95 % range: that one would be the optimistic margin
    assert C.pair_scale_quantile(0.025) < 0.2 * C.pair_ratio_fit_quantile(0.025)
    assert C.pair_scale_quantile(0.975) > 4 * C.pair_ratio_fit_quantile(0.975)
    for dof in (1, 2, 5):
        for p in (0.01, 0.3, 0.9):
            assert C.student_t_quantile(p, dof) == pytest.approx(student.ppf(p, dof), rel=1e-9)
            assert C.student_t_cdf(C.student_t_quantile(p, dof), dof) == pytest.approx(p, rel=1e-9)


def test_each_row_is_the_papers_constant_over_acls_first_principles_value():
    """Recomputed from acl's analysis of the examples without their calibration (0.5 %: the rows are rounded)."""
    fig4 = str(first_principles_path("fig4_facing_pair"))
    got = {}
    for g in (20, 80):
        (p,) = _pairs_125(acl.load(fig4, overrides={"gap": f"{g} um"}))
        got[f"Fig. 4e pair, {g} um"] = 174.5 / _alpha(p)          # paper Eq. 3 alpha, fitted on Fig. 4e
    ps = _pairs_125(acl.load(str(first_principles_path("fig5a_gripper"))))
    got["Fig. 5b gripper"] = 745.6 / _alpha(max(ps, key=lambda p: p["force_n"]))   # Supplementary Note 3 beta
    for source, ratio in C.PAIR_SCALE_ROWS:
        assert got[source] == pytest.approx(ratio, rel=5e-3), source


def test_draws_scale_the_bjerknes_force_from_their_own_stream():
    fp = acl.load(str(FOLLOW))
    cal = acl.loads(FOLLOW.read_text() + AT_ONE, filename=str(FOLLOW))
    assert bands.declared(fp).pair and not bands.declared(cal).pair
    n = 400
    drawn = [d for _, d in bands.sample_designs(fp, n, seed=3)]
    plain = [d for _, d in bands.sample_designs(cal, n, seed=3)]
    f = np.array([d.effect("bjerknes_scale").params["factor"] for d in drawn])
    assert np.array_equal(f, bands.pair_scales(n, 3))
    assert f.min() >= 1e-3 and f.max() <= 1e3
    # the draws' quartiles are the spread's (order statistics of 400 draws: within 0.05 in probability)
    for p in (0.25, 0.5, 0.75):
        assert C.pair_scale_quantile(p - 0.05) < np.quantile(f, p) < C.pair_scale_quantile(p + 0.05)
    # the gain draws are those of the calibrated design: the pair's stream is its own
    for a, b in zip(drawn[:5], plain[:5]):
        assert a.transducer.gain_pa_per_v == b.transducer.gain_pa_per_v
        assert b.effect("bjerknes_scale").params["factor"] == 1.0


@pytest.fixture(scope="module")
def follow():
    opts = CompileOptions(band_samples=20, resim_points=20)
    over = {"gap": "120 um"}
    fp = compile_program(acl.loads(FOLLOW.read_text(), filename=str(FOLLOW), overrides=over), "stroke", opts)
    cal = compile_program(acl.loads(FOLLOW.read_text() + AT_ONE, filename=str(FOLLOW), overrides=over), "stroke", opts)
    return fp, cal


def test_a_first_principles_pair_widens_the_band_and_is_named_its_cause(follow):
    fp, cal = follow
    g, h = fp.goals[0], cal.goals[0]
    assert g.rms_error_m == pytest.approx(h.rms_error_m, rel=1e-9)           # the same plan and prediction
    assert g.rms_error_p95_m > 2 * h.rms_error_p95_m                         # the spread widens the band
    band = g.details["band"]
    pair = band["pair_scale"]
    assert pair["source"] == "first-principles pair force" and pair["median"] == C.pair_scale_quantile(0.5)
    assert pair["range_95"] == [C.pair_scale_quantile(0.025), C.pair_scale_quantile(0.975)] and pair["dof"] == 2
    assert [(r["source"], r["ratio"]) for r in pair["rows"]] == list(C.PAIR_SCALE_ROWS)
    (src,) = [s for s in band["cause"]["sources"] if s["kind"] == "pair"]
    assert src["source"].startswith("first-principles pair force") and src["share"] > 0.1
    assert band["cause"]["pair_force_share"] == src["share"]
    assert "pair_scale" not in h.details["band"] and "pair_force_share" not in h.details["band"]["cause"]
    assert all(s["kind"] != "pair" for s in h.details["band"]["cause"]["sources"])
    # a located note at the step, naming the source and its share; none on the declared design
    (note,) = [w for w in fp.warnings if w.code == "N-PAIR-SCALE"]
    line = next(i for i, t in enumerate(FOLLOW.read_text().splitlines(), 1) if t.strip().startswith("follow act"))
    assert (note.span.line, note.span.column, note.severity.value) == (line, 3, "info")
    assert "first-principles pair force" in note.message and f"{src['share']:.0%}" in note.message
    assert not [w for w in cal.warnings if w.code == "N-PAIR-SCALE"]


def test_a_hold_margin_band_draws_it_too():
    opts = CompileOptions(band_samples=20)
    fp = compile_program(acl.load(str(FIG5C)), "approach", opts).goals[0].details["band"]
    cal = compile_program(acl.loads(FIG5C.read_text() + AT_ONE, filename=str(FIG5C)), "approach", opts).goals[0]
    cal = cal.details["band"]
    assert fp["margin_p05"] < 0.5 * cal["margin_p05"] and fp["draws_below_1"] > cal["draws_below_1"]
    assert 0 < fp["pair_scale"]["variance_share"] <= 1 and "pair_scale" not in cal


def test_a_calibrated_pair_draws_nothing_new():
    d = acl.load(str(ROOT / "examples" / "fig4_facing_pair.acl"))
    assert d.effect("bjerknes_scale") is not None and not bands.declared(d).pair
    for (_, a), (_, b) in zip(bands.sample_designs(d, 4, seed=1), bands.sample_designs(d, 4, seed=1)):
        assert a.effects == d.effects == b.effects
    s = compile_program(d, "keep_apart", CompileOptions(band_samples=6))
    assert "pair_scale" not in s.goals[0].details["band"] and not [w for w in s.warnings if w.code == "N-PAIR-SCALE"]


def test_the_sweep_counts_verdicts_the_spread_flips_both_ways(tmp_path):
    """model_form_pair_uncertain equals the verdict changes of the same sweep with the scale declared in the language
    at the spread's 2.5 and 97.5 % quantiles (an independent path), model_form_pair_median_pass the verdict at its
    median; the interval counts them both ways, a note names the source, and a declared scale has neither column."""
    def run(extra=""):
        p = tmp_path / f"s{len(list(tmp_path.iterdir()))}.acl"
        p.write_text(SPRING.read_text() + extra)
        return acl.sweep(str(p), n=40, seed=5, search_paths=(str(ROOT),))

    t = run()
    ends = [run(f"\neffect bjerknes_scale {{ factor = {C.pair_scale_quantile(q)!r} }}\n")
            for q in (0.025, 0.975)]
    med = run(f"\neffect bjerknes_scale {{ factor = {C.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN!r} }}\n")
    valid = t.data["valid"]
    want = np.zeros(len(t), bool)
    for e in ends:
        want |= e.data["require_1_pass"] != t.data["require_1_pass"]
    assert np.array_equal(t.data["model_form_pair_uncertain"], want & valid) and want.any()
    assert np.array_equal(t.data["model_form_pair_median_pass"], med.data["require_1_pass"] & valid)
    assert np.all(t.data["model_form_uncertain"][want & valid])
    y = t.yields()["all"]
    assert y.widened >= int((want & valid).sum()) and t.yields()["require_1"].widened == y.widened   # a gap require
    assert any("first-principles" in n and "model_form_pair_median_pass" in n for n in t.notes)
    assert "first-principles pair force" in t.summary_line()
    for e in (*ends, med):
        assert "model_form_pair_uncertain" not in e.columns and "model_form_pair_median_pass" not in e.columns


def test_the_robust_program_sees_the_pair_direction():
    """--robust's Q gains the term dG^T dG of the Bjerknes force moved by the scale's root-mean-square log distance
    from first principles (computed here by quadrature of the spread's quantiles, the move through the language)."""
    from acl.schedule.gains import model_gain_table

    freqs = (110e3, 125e3, 140e3)
    gains = lambda d: model_gain_table(d, "act", freqs).gains.T       # noqa: E731
    fp = acl.load(str(FOLLOW))
    cal = acl.loads(FOLLOW.read_text() + AT_ONE, filename=str(FOLLOW))
    from scipy.integrate import quad

    r = math.sqrt(quad(lambda u: math.log(C.pair_scale_quantile(u)) ** 2, 0, 1, limit=200)[0])
    assert bands.pair_rms_log() == pytest.approx(r, rel=1e-3)
    r = bands.pair_rms_log()          # the move itself, through the language, at the value checked above
    moved = acl.loads(FOLLOW.read_text() + f"\neffect bjerknes_scale {{ factor = {math.exp(r)!r} }}\n", filename=str(FOLLOW))
    dG = gains(moved) - gains(cal)
    assert np.abs(dG).max() > 0
    np.testing.assert_allclose(bands.gain_sensitivity(fp, gains) - bands.gain_sensitivity(cal, gains), dG.T @ dG,
                               rtol=1e-9, atol=1e-12 * np.abs(dG.T @ dG).max())


def test_the_share_is_one_for_a_spread_the_scale_makes_and_small_for_one_it_does_not():
    fp = acl.load(str(FOLLOW))
    s = bands.pair_scales(200, seed=7)
    assert bands.pair_details(fp, 3.0 / np.sqrt(s), seed=7)["variance_share"] == 1.0          # monotone in the scale
    noise = np.random.default_rng(11).standard_normal(200)
    assert bands.pair_details(fp, noise, seed=7)["variance_share"] < 0.05
    assert bands.pair_details(acl.load(str(ROOT / "examples" / "fig4_facing_pair.acl")), noise) is None
