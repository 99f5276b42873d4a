"""Issue 9, done-when bullet 2: the closed loop runs in a test (docs/fit.md quotes the same run, tests/docs_sync.py).

compile on the nominal design -> play on a truth (per-tone gain tilt, tones differ by 25 %, level
+10 %, an undeclared drive saturation) with 0.05 um noise -> fit -> recompile on the calibrated
design -> play again.  The 20-truth figure (coverage of the band) is printed by
benchmarks/closed_loop.py (about 1 min per truth); here one truth, the walk-through's.
"""
from __future__ import annotations

import os
import shutil

import pytest

from acl.fit.loop import run_loop

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("loop")
    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl", "fig2_stroke_truth.acl"):
        shutil.copy(os.path.join(EX, name), tmp)
    return run_loop(str(tmp / "fig2_stroke.acl"), str(tmp / "fig2_stroke_truth.acl"), "stroke", str(tmp),
                    seed=0, band_samples=20, nonlinear_passes=3)


def test_calibration_closes_the_loop(loop):
    assert "drive_saturation" in loop.effects
    # after calibration the program tracks within 3x the floor (the program compiled on the truth itself)
    assert loop.after_rms_m <= 3 * loop.floor_rms_m
    assert loop.before_rms_m > 2 * loop.after_rms_m
    # the calibrated compile's 95 % band covers the error the truth really shows
    assert loop.covered
    assert any("calibration data covered" in n for n in loop.notes)      # the program extrapolates: warned


def _repeat_seed(kind, index, tmp_path):
    """Row ``index`` of benchmarks/closed_loop_<kind>.json run again (benchmarks/closed_loop.py run_seed): the same
    truth, its figures within 0.5 % (solver paths), the same coverage and effects; the LoopResult."""
    import json
    import sys

    sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
    from closed_loop import run_seed

    with open(os.path.join(ROOT, "benchmarks", f"closed_loop_{kind}.json")) as fh:
        study = json.load(fh)
    want = study["rows"][index]
    r, text = run_seed(kind, want["seed"], str(tmp_path), study["band_samples"])
    assert text == want["truth"]
    for key in ("before_rms_m", "after_rms_m", "floor_rms_m", "predicted_rms_m", "band_rms_p95_m", "band_max_p95_m"):
        assert getattr(r, key) == pytest.approx(want[key], rel=5e-3), key
    assert r.covered == want["covered"] and sorted(r.effects) == sorted(want["effects"])
    return r


@pytest.mark.studies
def test_fig3_study_seed_repeats(tmp_path):
    """One truth of the Fig. 3 study (benchmarks/closed_loop.py --kind fig3, docs/fit.md) run again:
    the figures in benchmarks/closed_loop_fig3.json come from this code (0.5 % tolerance: solver paths)."""
    r = _repeat_seed("fig3", 0, tmp_path)
    assert r.after_rms_m <= 3 * r.floor_rms_m
    # the calibration measured the gain at the tones it drove: the calibrated design says so, and the band holds the
    # gain table there instead of drawing its 30 % prior again (before: 3.68 um, 28x this error)
    import acl

    cal = acl.load(r.calibrated, search_paths=[str(tmp_path)])
    assert len(cal.measured_gain) == 3 and all(m.stddev < 0.01 for m in cal.measured_gain)
    assert r.covered and r.band_rms_p95_m <= 1.5 * r.after_rms_m and r.band_max_p95_m <= 1.5 * r.after_max_m


def test_fig3_study_band_is_honest_and_tight():
    """The 20-truth Fig. 3 study (issue 9, done-when bullet 2): the band covers the error in >= 90 % of the truths,
    and holding the measured tones keeps it tight (median under 3x the error; it was 21x)."""
    import json

    import numpy as np

    with open(os.path.join(ROOT, "benchmarks", "closed_loop_fig3.json")) as fh:
        rows = json.load(fh)["rows"]
    assert len(rows) >= 20
    assert sum(r["covered"] for r in rows) >= 0.9 * len(rows)
    assert all(r["after_rms_m"] <= 3 * r["floor_rms_m"] for r in rows)
    assert float(np.median([r["band_rms_p95_m"] / r["after_rms_m"] for r in rows])) < 3.0


def test_pair_hold_study_seed_repeats(tmp_path):
    """One truth of the pair-hold study (benchmarks/closed_loop.py --kind pair-hold, docs/fit.md): the
    calibrated hold's margin band covers the margin the truth shows, and the JSON's figures repeat."""
    import json
    import sys

    sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
    from closed_loop import run_hold_seed

    with open(os.path.join(ROOT, "benchmarks", "closed_loop_pair_hold.json")) as fh:
        study = json.load(fh)
    want = next(r for r in study["rows"] if r["margin_p05"] > 0)     # a band that says something (p05 0: a draw snapped)
    got = run_hold_seed(want["seed"], str(tmp_path), study["band_samples"])
    assert got["truth"] == want["truth"] and got["rows"] == want["rows"]
    for key in ("before_margin", "after_margin", "after_v", "margin_p05"):
        assert got[key] == pytest.approx(want[key], rel=5e-3), key
    assert got["covered"] and got["margin_p05"] <= got["after_margin"]


@pytest.mark.studies
def test_stroke_study_seed_repeats(tmp_path):
    """One truth of the 20-truth stroke study (benchmarks/closed_loop.py, docs/fit.md) run again: the figures in
    benchmarks/closed_loop_stroke.json come from this code (0.5 % tolerance: solver paths)."""
    _repeat_seed("stroke", 1, tmp_path)


def test_stroke_study_band_is_honest():
    """The 20-truth stroke study (issue 9, done-when bullet 2): after calibration within 3x the floor in every
    truth, the band covers the error in >= 90 % of them, the planted saturation is named."""
    import json

    with open(os.path.join(ROOT, "benchmarks", "closed_loop_stroke.json")) as fh:
        rows = json.load(fh)["rows"]
    assert len(rows) >= 20
    assert all(r["after_rms_m"] <= 3 * r["floor_rms_m"] for r in rows)
    assert sum(r["covered"] for r in rows) >= 0.9 * len(rows)
    assert sum("drive_saturation" in r["effects"] for r in rows) >= 0.9 * len(rows)
