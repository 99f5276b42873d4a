"""The compiler's safety margins (issue 11): every margin the compiler promises is re-checked here
by an independent computation of what the emitted schedule actually does."""
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.design.resolve import load_design
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.latch import plan_switch
from acl.schedule.path import DriveLimits

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NN = 1e-9


def _drive(segment):
    from acl.design.model import Drive, Tone

    return Drive(tones=tuple(Tone(frequency=t.frequency_hz, amplitude=t.amplitude_v) for t in segment.tones))


def _snap_scale(design, segment, s_max):
    """Scale of the scheduled drive at snap-in, by an independent continuation (inf if none)."""
    from acl.analysis import acoustics, mechanics

    sw = mechanics.sweep_voltage(design, _drive(segment), s_max, acoustics.force_model_for(design))
    assert sw.status in ("ok", "snap_in"), sw.message
    return np.inf if sw.snap_voltage is None else sw.snap_voltage


# -- hold / cross: the margin is on voltage --------------------------------------------------------

@pytest.fixture(scope="module")
def fig4():
    return load_design(str(EXAMPLES / "fig4_facing_pair.acl"))


def test_fig4_keep_apart_drive_can_be_raised_by_the_margin_before_snap_in(fig4):
    # before: 2.156 V against a 2.361 V snap-in, ratio 1.095 = sqrt(1.2) (margin applied to V^2)
    s = compile_program(fig4, "keep_apart")
    (seg,) = s.segments
    ratio = _snap_scale(fig4, seg, 3.0)
    assert ratio >= 1.2 * (1 - 1e-6)
    assert ratio == pytest.approx(1.2, rel=1e-3)          # and no more: the step drives as hard as allowed
    assert s.goals[0].details["resimulated_margin"] == pytest.approx(ratio, rel=1e-4)


def test_fig4_snap_drive_exceeds_snap_in_by_the_margin(fig4):
    s = compile_program(fig4, "snap")
    (seg,) = s.segments
    ratio = 1.0 / _snap_scale(fig4, seg, 1.0)             # drive / snapping drive along the same shape
    assert ratio >= 1.2 * (1 - 1e-6)


def _two_tone_hold(mode):
    from acl.design import model as M
    from acl.diagnostics import Span

    sp = Span(file="h.acl", line=1, column=1)
    tr = M.Transducer(name="t", max_voltage=20.0, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp)
    step = M.HoldStep(a="a.o", b="b.o", mode=mode, margin=1.2, duration=0.1, tones=(85e3, 125e3), span=sp)
    return M.Design(file="h.acl", transducer=tr,
                    programs=(M.Program(name="p", steps=(step,), span=sp),))


def test_multi_tone_hold_is_rescaled_when_the_whole_drive_snaps_earlier_than_the_snap_index_says():
    # each tone alone snaps at 3 V, but together their forces add in V, not V^2: the critical set
    # is V1 + V2 = 3 (inside the snap-index simplex u1/9 + u2/9 = 1), as when the tones' forces
    # peak at different gaps.  The compiler must re-simulate the whole drive and back off.
    def critical(design, a, b, tones, s_max, bound):
        s = 3.0 / sum(v for _, v in tones)
        return s if s <= s_max else np.inf

    opts = CompileOptions(snap_provider=lambda *a: np.array([3.0, 3.0]), critical_provider=critical)
    s = compile_program(_two_tone_hold("above"), "p", opts)
    total = sum(t.amplitude_v for t in s.segments[0].tones)
    assert 3.0 / total >= 1.2 * (1 - 1e-5)
    assert s.goals[0].details["resimulated_margin"] >= 1.2 * (1 - 1e-5)
    assert any("scaled" in n for n in s.notes)


def test_multi_tone_cross_is_scaled_up_when_the_whole_drive_does_not_snap_by_the_margin():
    def critical(design, a, b, tones, s_max, bound):     # snaps later than the simplex says
        s = 3.0 * np.sqrt(2) / np.sqrt(sum(v ** 2 for _, v in tones)) * 1.3
        return s if s <= s_max else np.inf

    opts = CompileOptions(snap_provider=lambda *a: np.array([3.0, 3.0]), critical_provider=critical)
    s = compile_program(_two_tone_hold("cross"), "p", opts)
    scale = critical(None, None, None, [(t.frequency_hz, t.amplitude_v) for t in s.segments[0].tones],
                     10.0, None)
    assert 1.0 / scale >= 1.2 * (1 - 1e-6)


# -- switch: automatic tone choice must not make a feasible switch infeasible ------------------

def test_fig6e_switch_with_automatic_tones_is_feasible_and_as_cheap_as_the_pinned_tone():
    # the uncalibrated latch (13 MPa, Table S2's simulation column) and the 100 V limit this was written for
    text = (EXAMPLES / "fig6e_reversible_latch.acl").read_text(encoding="utf-8").replace(
        "param latch_youngs = 2.8315 MPa", "param latch_youngs = 13 MPa").replace(
        "switch l to b, margin 1.2, using [85 kHz], limit 15 V", "switch l to b, margin 1.2, using [85 kHz], limit 100 V")
    auto = text.replace("switch l to b, margin 1.2, using [85 kHz], limit 100 V",
                        "switch l to b, margin 1.2, limit 100 V")
    assert auto != text
    # switching the latch needs ~30 V, eps/R ~ 1.9 in the coupled model: far beyond linear (issue 10), so the
    # planner is exercised with allow_nonlinear
    lax = CompileOptions(allow_nonlinear=True)
    pinned = compile_program(acl.loads(text, filename=str(EXAMPLES / "pinned.acl")), "forth", lax)
    # before: "raise the max voltage above 100 V" (65 candidates, each capped at 100 V / sqrt(65))
    free = compile_program(acl.loads(auto, filename=str(EXAMPLES / "auto.acl")), "forth", lax)
    (p,) = pinned.segments[0].tones
    # issue 11 measured 27 V with uncoupled bubbles; the coupled model (issue 10: the latch capsules hear
    # each other and the substrate's image) needs about 30 V: a regression value of this model, not the paper
    assert p.amplitude_v == pytest.approx(29.9, abs=0.5)
    assert sum(t.amplitude_v for t in free.segments[0].tones) <= p.amplitude_v * (1 + 1e-6)
    assert free.goals[0].details["margin"] >= 1.2 * (1 - 1e-6)


def test_switch_with_many_candidate_tones_uses_the_true_peak_limit():
    K = 65
    forces = np.full((1, K), 0.01) * NN
    forces[0, 17] = 1.0 * NN                      # one strong tone: needs u = 48 V^2, 6.93 V
    plan = plan_switch(forces, np.array([40.0]) * NN, np.array([30.0]) * NN, ["a"], ["l"], 0, "b",
                       1.2, DriveLimits(10.0))
    assert np.sum(plan.amplitudes) <= 10.0 * (1 + 1e-6)
    assert plan.target_force >= 1.2 * 40 * NN * (1 - 1e-6)
    assert plan.amplitudes[17] == pytest.approx(np.sqrt(48.0), rel=1e-4)


@pytest.mark.parametrize("seed", range(12))
def test_every_switch_plan_respects_the_sum_of_amplitudes_whatever_the_phases(seed):
    rng = np.random.default_rng(seed)
    L, K = 2, int(rng.integers(2, 9))
    forces = rng.uniform(-0.3, 1.0, (L, K)) * NN
    to_b, to_a = rng.uniform(5, 40, L) * NN, rng.uniform(5, 40, L) * NN
    vmax = float(rng.uniform(6, 15))
    from acl.schedule.latch import SwitchInfeasible

    try:
        plan = plan_switch(forces, to_b, to_a, ["a", "a"], ["l", "m"], 0, "b", 1.2, DriveLimits(vmax))
    except SwitchInfeasible:
        # then no single tone can do it either (a single tone's peak is exact)
        ok = [k for k in range(K) if forces[0, k] > 0 and 1.2 * to_b[0] / forces[0, k] <= vmax ** 2
              and forces[1, k] * 1.2 * to_b[0] / forces[0, k] <= to_b[1] / 1.2]
        assert not ok
        return
    assert np.sum(plan.amplitudes) <= vmax * (1 + 1e-6)
    assert plan.target_force >= plan.required_force * (1 - 1e-6)
    assert plan.other_ratios[1] <= 1 / 1.2 + 1e-6


# -- phases: an explicit phase is the user's; peaks are analog ------------------------------------

PHASED = """\
import stdlib.transducers
use transducer transducers.contact_piezo

program p {
  drive 100 kHz @ 1 V phase 0 deg + 105 kHz @ 1 V phase 0 deg + 110 kHz @ 1 V phase 0 deg for 10 ms
  drive 100 kHz @ 1 V + 105 kHz @ 1 V + 110 kHz @ 1 V for 10 ms
  drive 100 kHz @ 1 V phase 90 deg + 105 kHz @ 1 V + 110 kHz @ 1 V for 10 ms
}
"""


def _dense(seg, period=2e-4, n=200_001):
    t = np.linspace(0.0, period, n)
    return float(np.max(np.abs(sum(x.amplitude_v * np.sin(2 * np.pi * x.frequency_hz * t + x.phase_rad)
                                   for x in seg.tones))))


def test_explicit_zero_phases_are_not_overridden_by_the_crest_factor_search():
    s = compile_program(acl.loads(PHASED, filename="phased.acl"), "p")
    given, free, mixed = s.segments
    assert [t.phase_rad for t in given.tones] == [0.0, 0.0, 0.0]
    assert given.peak_v >= _dense(given) >= 2.9                      # all in phase at t = 0
    assert free.peak_v < 0.8 * given.peak_v                          # unspecified: searched
    assert mixed.tones[0].phase_rad == pytest.approx(np.pi / 2)
    for seg in s.segments:                                           # peak_v bounds the analog peak
        assert _dense(seg) <= seg.peak_v <= _dense(seg) + 1e-3


# -- the command line: full scale, warnings, absurd numbers, locations ----------------------------

HOSTILE_PROGRAMS = """
program longpause {
  drive 85 kHz @ 1 V for 10 ms
  pause 1e308 s
}
program tinylimit {
  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 1e-200 V
}
program hugeslew {
  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], slew 1e300 V/s
}
program tones {
  drive 85 kHz @ 3 V + 125 kHz @ 2 V for 20 ms
}
program keep_apart {
  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 8 V
}
"""


@pytest.fixture
def hostile(tmp_path):
    text = (EXAMPLES / "fig4_facing_pair.acl").read_text(encoding="utf-8")
    p = tmp_path / "hostile.acl"
    p.write_text(text[:text.index("program ramp")] + HOSTILE_PROGRAMS, encoding="utf-8")
    return str(p)


def cli(*args):
    from acl.cli import main

    return main(["compile", *args])


def _json_diags(capsys):
    import json

    return json.loads(capsys.readouterr().out)["diagnostics"]


@pytest.mark.parametrize("args,code,where", [
    (["--sample-rate", "1e400"], "E-COMPILE-RATE", "<--sample-rate>:1:1"),
    (["--sample-rate", "inf"], "E-COMPILE-RATE", "<--sample-rate>:1:1"),
    (["--ramp", "inf"], "E-COMPILE-OPTION", "<--ramp>:1:1"),
    (["--ramp", "-1"], "E-COMPILE-OPTION", "<--ramp>:1:1"),
    (["--tolerance", "inf"], "E-COMPILE-OPTION", "<--tolerance>:1:1"),
    (["--waypoint-dt", "inf"], "E-COMPILE-OPTION", "<--waypoint-dt>:1:1"),
    (["--waypoint-dt", "nan"], "E-COMPILE-OPTION", "<--waypoint-dt>:1:1"),
    (["--waypoint-dt", "1e-300"], "E-COMPILE-OPTION", "<--waypoint-dt>:1:1"),
    (["--full-scale", "inf"], "E-COMPILE-OPTION", "<--full-scale>:1:1"),
    (["--full-scale", "ten"], "E-COMPILE-OPTION", "<--full-scale>:1:1"),
    (["--sample-rate", "200k"], "E-EMIT-RATE", "<--sample-rate>:1:1"),
    (["--format", "mp3"], "E-COMPILE-FORMAT", "<--format>:1:1"),
    (["--program", "nope"], "E-COMPILE-PROGRAM", "<--program>:1:1"),
])
def test_absurd_options_are_usage_errors_naming_the_option(hostile, tmp_path, capsys, args, code, where):
    out = tmp_path / "out"
    rc = cli(hostile, "-o", str(out), *(args if "--program" in args else ["--program", "tones", *args]),
             "--diagnostics", "json")
    (d,) = _json_diags(capsys)
    assert rc == 2 and d["code"] == code
    assert f"{d['file']}:{d['line']}:{d['column']}" == where
    assert not out.exists()


@pytest.mark.parametrize("program,code,line", [("longpause", "E-SCHED-DURATION", "pause 1e308 s"),
                                               ("tinylimit", "E-SCHED-LIMIT", "limit 1e-200 V"),
                                               ("hugeslew", "E-SCHED-LIMIT", "slew 1e300 V/s")])
def test_absurd_numbers_in_a_design_are_located_design_errors(hostile, tmp_path, capsys, program, code, line):
    out = tmp_path / "out"
    assert cli(hostile, "-o", str(out), "--program", program, "--diagnostics", "json") == 1
    (d,) = _json_diags(capsys)
    assert d["code"] == code and d["file"] == hostile
    assert line in Path(hostile).read_text().splitlines()[d["line"] - 1]
    assert not out.exists()


def test_output_path_that_is_a_file_names_the_output_option(hostile, tmp_path, capsys):
    (tmp_path / "out").write_text("x")
    assert cli(hostile, "-o", str(tmp_path / "out"), "--program", "tones") == 2
    err = capsys.readouterr().err
    assert "<--output>:1:1" in err and "E-EMIT-OUTPUT" in err and "<unknown>" not in err


def test_wav_size_error_names_an_option(tmp_path):
    from acl.diagnostics import DiagnosticError
    from acl.emit.output import emit
    from acl.schedule.model import Schedule, ScheduledTone, Segment

    long = Schedule("p", [Segment(0.0, 600.0, (ScheduledTone(100e3, 1.0),), 0, None, 1.0)], [], 10.0, 10.0)
    with pytest.raises(DiagnosticError) as exc:
        emit(long, str(tmp_path / "out"), ("wav",), 2e6)
    assert exc.value.diagnostics[0].location() != "<unknown>"


def test_full_scale_defaults_to_the_transducer_and_is_printed(hostile, tmp_path, capsys):
    import json

    from acl.emit.writers import read_wav_float32

    out = tmp_path / "out"
    assert cli(hostile, "-o", str(out), "--program", "keep_apart") == 0
    data = json.loads((out / "schedule.json").read_text())
    # before: the step's 8 V limit became the scale (8, 15, 20, 30 or 100 V across the examples)
    assert data["full_scale_v"] == 20.0 and "transducer" in data["full_scale_source"]
    assert "WAV full scale 20 V" in " ".join(capsys.readouterr().err.split())
    out2 = tmp_path / "out2"
    assert cli(hostile, "-o", str(out2), "--program", "keep_apart", "--full-scale", "10V") == 0
    w10, _ = read_wav_float32(str(out2 / "waveform.wav"))
    w20, _ = read_wav_float32(str(out / "waveform.wav"))
    assert np.allclose(w10, 2 * w20, atol=1e-6)
    assert "WAV full scale 10 V (--full-scale)" in " ".join(capsys.readouterr().err.split())


def test_a_peak_beyond_the_full_scale_is_refused_and_nothing_written(hostile, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli(hostile, "-o", str(out), "--program", "tones", "--full-scale", "4V",
               "--diagnostics", "json") == 1
    (d,) = _json_diags(capsys)
    assert d["code"] == "E-SCHED-FULLSCALE" and d["file"] == hostile
    assert not out.exists()


def test_low_sample_rate_and_large_sample_csv_are_warned(hostile, tmp_path, capsys, monkeypatch):
    from acl.emit import output

    monkeypatch.setattr(output, "CSV_WARN_BYTES", 1000)
    out = tmp_path / "out"
    assert cli(hostile, "-o", str(out), "--program", "tones", "--sample-rate", "300k",
               "--format", "wav,csv", "--diagnostics", "json") == 0
    codes = {d["code"] for d in _json_diags(capsys)}
    # the model's validity warnings (W-ACOUSTIC-*, tests/test_compile_validity.py) are not what is tested here
    assert {c for c in codes if not c.startswith("W-ACOUSTIC-")} == {"W-EMIT-RATE", "W-EMIT-SIZE"}
    assert (out / "waveform-samples.csv").exists()


def test_a_crossfade_too_short_to_be_band_limited_is_warned(hostile, tmp_path, capsys):
    assert cli(hostile, "-o", str(tmp_path / "out"), "--program", "longpause", "--ramp", "0",
               "--diagnostics", "json") == 1          # (the pause is refused; use a program that runs)
    capsys.readouterr()
    Path(hostile).write_text(Path(hostile).read_text().replace("pause 1e308 s", "pause 10 ms"))
    assert cli(hostile, "-o", str(tmp_path / "out"), "--program", "longpause", "--ramp", "0",
               "--diagnostics", "json") == 0
    assert [d["code"] for d in _json_diags(capsys)] == ["W-EMIT-RAMP"]
    assert cli(hostile, "-o", str(tmp_path / "out"), "--program", "longpause", "--diagnostics", "json") == 0
    assert _json_diags(capsys) == []


def test_reusing_an_output_folder_through_the_cli_leaves_no_stale_file(hostile, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli(hostile, "-o", str(out), "--program", "tones", "--format", "npy,csv") == 0
    assert cli(hostile, "-o", str(out), "--program", "keep_apart") == 0
    assert sorted(p.name for p in out.iterdir()) == ["schedule.json", "segments.csv", "waveform.wav"]
    (out / "mine.txt").write_text("x")
    assert cli(hostile, "-o", str(out), "--program", "tones") == 2
    assert "mine.txt" in capsys.readouterr().err and (out / "mine.txt").exists()


def test_too_many_waypoints_is_a_located_error_not_a_memory_blow_up(tmp_path, capsys):
    text = (EXAMPLES / "fig3_three_orifice.acl").read_text(encoding="utf-8")
    p = tmp_path / "fig3.acl"
    p.write_text(text, encoding="utf-8")
    assert cli(str(p), "-o", str(tmp_path / "out"), "--program", "rectangle", "--waypoint-dt", "1e-5",
               "--diagnostics", "json") == 1
    (d,) = _json_diags(capsys)
    assert d["code"] == "E-SCHED-PATH" and d["file"] == str(p) and "waypoint-dt" in d["hint"]


# -- slew: the emitted envelope, crossfades included, obeys the limit ------------------------------

def _envelope_slew(s):
    """Largest |d/dt| of any tone's emitted amplitude, from the renderer's own crossfade weights."""
    from acl.emit.render import _rc, _Segments

    S = _Segments(s, 1e9)
    t = np.linspace(0.0, s.duration_s, 200_001)
    freqs = sorted({x.frequency_hz for seg in s.segments for x in seg.tones})
    env = np.zeros((len(freqs), t.size), complex)
    for i, seg in enumerate(s.segments):
        w = np.where((t >= S.a0[i]) & (t <= S.b1[i]), 1.0, 0.0)
        if S.a1[i] > S.a0[i]:
            w *= _rc((t - S.a0[i]) / (S.a1[i] - S.a0[i]))
        if S.b1[i] > S.b0[i]:
            w *= 1.0 - _rc((t - S.b0[i]) / (S.b1[i] - S.b0[i]))
        for x in seg.tones:
            env[freqs.index(x.frequency_hz)] += w * x.amplitude_v * np.exp(1j * x.phase_rad)
    return float(np.max(np.abs(np.diff(np.abs(env), axis=1))) / (t[1] - t[0]))


def test_a_follow_slew_limit_holds_for_the_emitted_waveform_not_only_between_waypoints():
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from test_compile_cli import DESIGN

    follow = "  follow module along circle(radius = r, center = (0.2 um, 0 um)) in 0.3 s\n"
    assert follow in DESIGN
    text = DESIGN.replace(follow, "  pause 50 ms\n  follow module along polyline([(0 um, 0 um), (1 um, 0.5 um), "
                                  "(0 um, 0 um)]) in 0.6 s, slew 80 V/s\n  pause 50 ms\n")
    s = compile_program(acl.loads(text, filename="slew.acl"), "circle", CompileOptions(ramp_s=0.01))
    # before: the plan kept |dV|/dt <= 80 V/s between waypoints (59 V/s) but the raised-cosine
    # crossfade played the steps at pi/2 x that: 92.9 V/s
    assert _envelope_slew(s) <= 80.0 * (1 + 1e-3)
    goal = next(g for g in s.goals if g.kind == "follow")
    assert goal.details["emitted_max_slew_v_per_s"] <= 80.0 * (1 + 1e-6)


def test_the_slew_bound_covers_a_first_segment_fading_in_and_out_at_once():
    from acl.schedule.compile import segment_slews
    from acl.schedule.model import Schedule, ScheduledTone, Segment

    segs = [Segment(0.0, 0.01, (ScheduledTone(100e3, 1.0),), 0), Segment(0.01, 0.02, (ScheduledTone(100e3, 3.0),), 0),
            Segment(0.02, 0.03, (ScheduledTone(100e3, 0.5),), 0)]
    s = Schedule("p", segs, [], 10.0, 10.0, ramp_s=0.01, sample_rate_hz=1e6)
    bound = segment_slews(s)
    assert _envelope_slew(s) <= bound.max() <= 1.01 * _envelope_slew(s)


def test_a_hold_slew_limit_the_crossfade_cannot_meet_is_a_located_error(hostile, tmp_path, capsys):
    text = Path(hostile).read_text().replace("slew 1e300 V/s", "slew 10 V/s")
    Path(hostile).write_text(text)
    assert cli(hostile, "-o", str(tmp_path / "out"), "--program", "hugeslew", "--diagnostics", "json") == 1
    (d,) = _json_diags(capsys)
    assert d["code"] == "E-SCHED-LIMIT" and "slew 10 V/s" in text.splitlines()[d["line"] - 1]


# -- snap-in models: what is not known is not safe ------------------------------------------------

def test_a_snap_in_between_the_limit_and_margin_times_the_limit_is_found():
    # fig4's pair snaps at 2.36 V; with `limit 2.2 V` the per-tone sweep used to stop at 2.2 V,
    # call the tone "never snaps" and drive it at 2.2 V: a ratio of 1.07 for a margin of 1.2
    text = (EXAMPLES / "fig4_facing_pair.acl").read_text(encoding="utf-8")
    text = text[:text.index("program ramp")] + (
        "program near {\n  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 2.2 V\n}\n")
    d = acl.loads(text, filename=str(EXAMPLES / "near.acl"))
    s = compile_program(d, "near")
    (seg,) = s.segments
    assert _snap_scale(d, seg, 3.0) >= 1.2 * (1 - 1e-6)


def test_a_lost_continuation_branch_counts_as_critical_where_it_was_lost(fig4):
    from types import SimpleNamespace

    from acl.schedule.gains import _critical_scale

    lost = SimpleNamespace(snap_voltage=None, status="no_convergence", voltage=np.array([0.0, 0.5, 1.3]))
    mech = SimpleNamespace(sweep_voltage=lambda *a, **k: lost)
    assert _critical_scale(mech, fig4, "left.jet", "right.jet", None, 5.0, None) == 1.3     # was inf


def test_a_sweep_just_beyond_the_hemisphere_is_refused(tmp_path, capsys):
    """The linear-regime check sampled a chirp at 9 frequencies: across 100-150 kHz it found eps/R 0.672 x V/15 V
    for a resonance peak of 0.686 x V/15 V, so a sweep just over a limit compiled.  The sweep is checked at its
    worst frequency (every mode inside, refined): just past the hemisphere (eps/R 1, issue 24) E-SCHED-NONLINEAR
    at the step; just past the soft limit 0.25 a located W-ACOUSTIC-AMPLITUDE (the paper's Fig. 2f)."""
    from acl.analysis.interfaces import interface_amplitudes
    from acl.cli import main
    from acl.design.model import Drive, Tone

    src = (EXAMPLES / "fig2_vertical_cantilever.acl").read_text().replace(
        "use transducer transducers.contact_piezo",
        "transducer amp like transducers.contact_piezo { max_voltage = 100 V }\nuse transducer amp")
    head = src[:src.index("\nprogram ") + 1]
    d = acl.loads(head, filename=str(tmp_path / "h.acl"))
    peak = max(max(interface_amplitudes(d, Drive(tones=(Tone(frequency=f, amplitude=1.0),))).values())
               for f in np.linspace(100e3, 150e3, 5001))
    line = head.count("\n") + 2
    for limit, code, rc in ((1.0, "error[E-SCHED-NONLINEAR]", 1), (0.25, "warning[W-ACOUSTIC-AMPLITUDE]", 0)):
        volts = 1.004 * limit / peak                               # the sweep's peak just past the limit
        path = tmp_path / f"sweep{rc}.acl"
        path.write_text(head + f"program scan {{\n  sweep 100 kHz to 150 kHz @ {volts:.4f} V in 2 s\n}}\n")
        out = tmp_path / f"out{rc}"
        assert main(["compile", str(path), "-o", str(out), "-q"]) == rc
        err = capsys.readouterr().err
        assert f"sweep{rc}.acl:{line}:3: {code}" in err and "Traceback" not in err
        if rc:
            assert not out.exists() or not any(out.iterdir())
