"""Figures that explain themselves (issue 28): modal_response over the transducer's band and smooth, residual axes
in one unit per kind, fit.png titles inside the figure, phases written in [0, 2 pi)."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

import acl
from acl.emit.schedule_json import wrapped_phase

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG3 = os.path.join(ROOT, "examples", "fig3_three_orifice.acl")


def test_phases_are_written_in_zero_to_two_pi():
    assert wrapped_phase(2 * math.pi) == 0.0
    assert wrapped_phase(2 * math.pi - 1e-12) == 0.0
    assert wrapped_phase(-0.5) == pytest.approx(2 * math.pi - 0.5)
    assert wrapped_phase(7.0) == pytest.approx(7.0 - 2 * math.pi)
    assert wrapped_phase(1.25) == 1.25


def test_segments_csv_has_no_phase_of_two_pi(tmp_path):
    from acl.cli import main

    out = tmp_path / "o"
    assert main(["compile", FIG3, "--program", "circle", "-o", str(out), "--band-samples", "0", "-q"]) == 0
    rows = (out / "segments.csv").read_text().splitlines()[1:]
    phases = [float(r.split(",")[5]) for r in rows if r.split(",")[5]]
    assert phases and all(0 <= p < 2 * math.pi - 1e-9 for p in phases)


def test_residual_axes_use_one_unit_per_kind():
    from acl.fit.report import covariate_axis

    x, label = covariate_axis("frequency", np.array([72.5e3]))
    assert label == "frequency (kHz)" and x[0] == pytest.approx(72.5)
    x, label = covariate_axis("predicted deflection", np.array([3e-6]))
    assert label.endswith("(um)") and x[0] == pytest.approx(3.0)
    assert covariate_axis("height", np.array([1e-4]))[1] == "height (um)"
    assert covariate_axis("voltage", np.array([2.0]))[1] == "voltage (V)"


def test_modal_response_is_limited_to_the_band_and_smooth(tmp_path, saved_figures):
    from acl.analysis.report import analyze
    from acl.emit import analysis_figures

    design = acl.load(FIG3)
    analysis_figures.write_figures(design, analyze(design, None, snap_in=False), str(tmp_path))
    fig = next(f for f in saved_figures.values() if f.axes and "Modal response" in f.axes[0].get_title())
    ax = fig.axes[0]
    lo, hi = (b / 1e3 for b in design.transducer.band)
    assert ax.get_xlim() == pytest.approx((lo, hi))
    assert "per pascal" in ax.get_ylabel()
    for line in ax.get_lines():
        x, y = line.get_data()
        if len(x) < 10:
            continue                       # a mode marker
        assert x.min() >= lo - 1e-9 and x.max() <= hi + 1e-9
        # no kink at the gain table's points: the slope of log y changes smoothly there
        t = design.transducer
        ly = np.log(np.asarray(y, float))
        d2 = np.abs(np.diff(ly, 2))
        for ft in t.gain_frequencies:
            k = int(np.argmin(np.abs(np.asarray(x) - ft / 1e3)))
            if 5 <= k < len(d2) - 5:      # a kink: a spike of the second difference at one sample, not its neighbours'
                near = d2[k - 2:k + 1].max()
                around = max(d2[k - 5], d2[k + 4])
                assert near <= 3 * around + 1e-9, (ft, near, around)


def test_steps_are_counted_from_one_everywhere(tmp_path):
    """Issue 28, Counting: schedule.json (segments and goals), the notebook, segments.csv and the CLI's goal names
    all count program steps from 1."""
    import json

    from acl.cli import main

    out = tmp_path / "o"
    assert main(["compile", FIG3, "--program", "circle", "-o", str(out), "--band-samples", "0", "-q"]) == 0
    doc = json.loads((out / "schedule.json").read_text())
    assert doc["version"] == "1.2"
    assert sorted({s["step"] for s in doc["segments"]}) == [1, 2]
    assert [g["step"] for g in doc["goals"]] == [1, 2]
    for g in doc["goals"]:
        assert g["name"].startswith(f"step {g['step']}:")
    csv_steps = {int(r.split(",")[0]) for r in (out / "segments.csv").read_text().splitlines()[1:]}
    assert csv_steps == {1, 2}
    from acl.notebook import Compiled
    from acl.schedule.compile import CompileOptions, compile_program

    c = Compiled.from_schedule(compile_program(acl.load(FIG3), "circle", CompileOptions(band_samples=0)))
    assert sorted({s.step for s in c.segments}) == [1, 2] and [g["step"] for g in c.goals] == [1, 2]
    assert c.as_dict()["segments"][0]["step"] == 1


def test_fit_png_titles_lie_inside_the_figure_and_residual_axes_carry_units(tmp_path, saved_figures):
    from acl.cli import main
    from acl.fit.synth import Experiment, generate, write_csv

    pair = os.path.join(ROOT, "samples", "fit_pair.acl")
    text = open(pair, encoding="utf-8").read().replace("observe distance =", "observe orifice_distance_between_jets =")
    (tmp_path / "fit_pair.acl").write_text(text, encoding="utf-8")
    ex = Experiment(frequencies=(125e3,), voltages=tuple(np.linspace(0, 4, 9)), sets={"gap": ["30 um", "50 um"]})
    data, _ = generate(str(tmp_path / "fit_pair.acl"), ex, noise=0.3e-6, seed=2, coeffs={"alpha": 174.5e-21, "gamma": 0.027e-9})
    write_csv(data, str(tmp_path / "d.csv"))
    figs = saved_figures
    assert main(["fit", str(tmp_path / "fit_pair.acl"), str(tmp_path / "d.csv"), "--free", "alpha",
                 "--report", str(tmp_path / "rep"), "--effects", "none"]) == 0
    fig = figs["fit.png"]
    fig.canvas.draw()
    box = fig.bbox
    titled = [ax for ax in fig.axes if ax.get_title()]
    assert len(titled) >= 2                      # before and after
    for ax in titled:         # a long observable name (above): each title within its own panel
        assert ax.title.get_window_extent().width <= ax.get_window_extent().width + 0.5, ax.get_title()
    ext = sorted((ax.title.get_window_extent() for ax in titled), key=lambda t: t.x0)
    for t in ext:
        assert box.x0 - 0.5 <= t.x0 and t.x1 <= box.x1 + 0.5, (t, box)         # not cut at the figure's edge
    for a, b in zip(ext, ext[1:]):
        assert a.x1 <= b.x0 or a.y1 <= b.y0 or b.y1 <= a.y0, (a, b)           # nor run into the next panel's
    res = figs["residuals.png"]
    labels = [ax.get_xlabel() for ax in res.axes]
    # one driven frequency (125 kHz): no frequency panel (its undriven rows sat at 0 kHz before)
    assert "voltage (V)" in labels and "frequency (kHz)" not in labels
    assert all(lb.endswith(")") for lb in labels)


def test_a_one_voltage_frequency_sweep_is_drawn_against_frequency(tmp_path, saved_figures):
    """fit.png drew every run against voltage: a frequency sweep at one voltage was one stack of points at 4 V,
    and residuals.png put a one-frequency run's undriven rows at 0 kHz (newcomer review)."""
    from acl.cli import main
    from acl.fit.synth import Experiment, generate, write_csv

    pair = os.path.join(ROOT, "samples", "fit_pair.acl")
    freqs = tuple(np.linspace(110e3, 140e3, 7))
    ex = Experiment(frequencies=freqs, voltages=(0.0, 2.0), sets={"gap": ["40 um"]})
    data, _ = generate(pair, ex, noise=0.1e-6, seed=3, coeffs={"alpha": 174.5e-21, "gamma": 0.027e-9})
    write_csv(data, str(tmp_path / "d.csv"))
    assert main(["fit", pair, str(tmp_path / "d.csv"), "--free", "alpha", "--report", str(tmp_path / "rep"),
                 "--effects", "none", "--calibrated", str(tmp_path / "cal.acl")]) == 0
    ax = saved_figures["fit.png"].axes[0]
    assert ax.get_xlabel() == "frequency (kHz)"
    xs = np.concatenate([line.get_xdata() for line in ax.get_lines()])
    assert xs.min() == pytest.approx(110) and xs.max() == pytest.approx(140)
    res = [a for a in saved_figures["residuals.png"].axes if a.get_xlabel().startswith("frequency")]
    assert res and all(np.nanmin(np.concatenate([ln.get_xdata() for ln in a.get_lines()
                                                  if len(ln.get_xdata()) > 2])) >= 110 - 1e-9 for a in res)
