"""Crossfades between program steps (docs/explanation/steps.md, Crossfades between steps): a kept tone with a counter-pushing
tone that changes can push a latch over its switching force, or a held pair nearer snap-in, while each step alone is
within its margin; the compiler fades through silence there.  Every check here recomputes the push independently:
from the worst phases by brute force, or from the rendered waveform itself."""
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.emit.render import render_chunks
from acl.schedule.compile import FADE_GOAL, LATCH_STATE_MARGIN, CompileOptions, compile_program
from acl.schedule.crossfade import crossfade_peak
from acl.schedule.gains import latch_forces
from acl.schedule.model import Schedule, Segment

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "samples" / "crossfade_latch.acl"
OPTS = CompileOptions(allow_nonlinear=True, band_samples=0)   # the Fig. 6e latch needs eps/R > 0.25 (docs/physics.md)


@pytest.fixture(scope="module")
def design():
    return acl.load(str(DATA), search_paths=[str(ROOT / "examples")])



def _warned(schedule):
    """The schedule's warnings, without its info notes (a first-principles pair's N-PAIR-SCALE on every step)."""
    return [w for w in schedule.warnings if w.severity.value != "info"]

def _fades(s):
    return [g for g in s.segments if not g.tones and (g.goal or "").endswith(FADE_GOAL)]


def _ends(seg_a, seg_b):
    """{freq: (amplitude before, after)} at a boundary (constant tones)."""
    fa = {t.frequency_hz: t.amplitude_v for t in seg_a.tones}
    fb = {t.frequency_hz: t.amplitude_v for t in seg_b.tones}
    return {f: (fa.get(f, 0.0), fb.get(f, 0.0)) for f in sorted(set(fa) | set(fb))}


def _push_towards_b(design, amps):
    """Force of tones {f: V} along the latch axis over its switching force (forces add in V^2, paper Eq. 2)."""
    fr = sorted(amps)
    G, to_b, _ = latch_forces(design, fr)
    return float(G[0] @ np.array([amps[f] ** 2 for f in fr]) / to_b[0])


# -- the bound itself ------------------------------------------------------------------------------

def test_the_worst_phase_bound_is_the_brute_force_maximum_over_phases_and_weights():
    """Two tones on both sides, one pushing (g > 0) and one counter-pushing: the closed form equals the maximum of
    sum_k g_k |(1-x) p_k + x q_k e^(i theta_k)|^2 over a grid of weights x and phase differences theta_k."""
    rng = np.random.default_rng(3)
    x = np.linspace(0, 1, 401)[:, None, None]
    th = np.linspace(0, 2 * np.pi, 73)
    t1, t2 = np.meshgrid(th, th, indexing="ij")
    for _ in range(20):
        g = np.array([rng.uniform(0.2, 2.0), -rng.uniform(0.2, 2.0)])
        p, q = rng.uniform(0, 3, 2), rng.uniform(0, 3, 2)
        f = (g[0] * np.abs((1 - x) * p[0] + x * q[0] * np.exp(1j * t1)) ** 2
             + g[1] * np.abs((1 - x) * p[1] + x * q[1] * np.exp(1j * t2)) ** 2)
        (peak,), _ = crossfade_peak(g, p, q)
        assert peak == pytest.approx(f.max(), rel=2e-3, abs=1e-9)
        assert peak >= f.max() * (1 - 1e-12)          # never below the sampled maximum: a bound
        # with the phase differences known: the maximum over the weights of that one waveform
        th1, th2 = rng.uniform(0, 2 * np.pi, 2)
        (known,), _ = crossfade_peak(g, p, q, np.cos([th1, th2]))
        x1 = x[:, 0, 0]
        f1 = (g[0] * np.abs((1 - x1) * p[0] + x1 * q[0] * np.exp(1j * th1)) ** 2
              + g[1] * np.abs((1 - x1) * p[1] + x1 * q[1] * np.exp(1j * th2)) ** 2)
        assert known == pytest.approx(f1.max(), rel=1e-4, abs=1e-9) and known <= peak * (1 + 1e-12)


def test_without_a_kept_tone_or_with_one_sign_the_crossfade_never_exceeds_the_larger_end():
    """No frequency on both sides: f(x) <= max(f(0), f(1), 0) (two ends pulling the other way weaken in between);
    every tone pushing the same way (a snap index): f(x) <= max(f(0), f(1))."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        g = rng.normal(size=(3, 4))
        p, q = rng.uniform(0, 3, 4), rng.uniform(0, 3, 4)
        p[2:], q[:2] = 0.0, 0.0                        # disjoint tones
        peak, _ = crossfade_peak(g, p, q)
        assert np.all(peak <= np.maximum(np.maximum(g @ p ** 2, g @ q ** 2), 0.0) * (1 + 1e-12) + 1e-12)
        gpos = np.abs(g)
        p2, q2 = rng.uniform(0, 3, 4), rng.uniform(0, 3, 4)
        peak, _ = crossfade_peak(gpos, p2, q2)
        assert np.all(peak <= np.maximum(gpos @ p2 ** 2, gpos @ q2 ** 2) * (1 + 1e-12))


# -- a latch: the Fig. 6e latch, 85 kHz kept, the counter tone swapped -------------------------------

def test_swapping_the_counter_tone_would_switch_the_latch_and_the_compiler_fades_through_silence(design):
    """Each step alone pushes the Fig. 6e latch to ~0.78 x its switching force (< 1/1.2: left for sure); a direct
    crossfade keeps 85 kHz while 170 kHz fades out and 180 kHz in, the counter push dips to half: ~1.08 x."""
    s = compile_program(design, "swap", OPTS)
    one, two = [g for g in s.segments if g.tones]
    alone = [_push_towards_b(design, {t.frequency_hz: t.amplitude_v for t in seg.tones}) for seg in (one, two)]
    assert max(alone) < 1 / LATCH_STATE_MARGIN
    ends = _ends(one, two)
    fr = sorted(ends)
    G, to_b, _ = latch_forces(design, fr)
    (direct,), (x,) = crossfade_peak(G[0] / to_b[0], [ends[f][0] for f in fr], [ends[f][1] for f in fr])
    assert direct > 1.0 and x == pytest.approx(0.5, abs=0.05)
    # the schedule: silence of --ramp between the steps, and every boundary within its ends
    (fade,) = _fades(s)
    assert fade.duration_s == pytest.approx(s.ramp_s) and fade.step == 1
    assert s.segments == [one, fade, two]
    assert two.start_s == pytest.approx(0.1 + s.ramp_s) and s.goals[1].start_s == pytest.approx(two.start_s)
    assert any("faded through 1 ms of silence after step 1" in n and "latch `l`" in n for n in s.notes)
    assert not _warned(s)
    _assert_no_boundary_overshoots(design, s)


def _assert_no_boundary_overshoots(design, s):
    for a, b in zip(s.segments, s.segments[1:]):
        ends = _ends(a, b)
        fr = sorted(ends)
        if not fr:
            continue
        G, to_b, _ = latch_forces(design, fr)
        p, q = np.array([ends[f][0] for f in fr]), np.array([ends[f][1] for f in fr])
        (peak,), _ = crossfade_peak(G[0] / to_b[0], p, q)
        assert peak <= max(1 / LATCH_STATE_MARGIN, G[0] @ p ** 2 / to_b[0], G[0] @ q ** 2 / to_b[0]) * (1 + 1e-9)


def _rendered_push(design, sched, t0, t1):
    """Largest push towards b (over the switching force) of the rendered waveform on [t0, t1]: the 85 and 170 kHz
    amplitudes demodulated over windows of one 85 kHz period (20 samples at 1.7 MS/s), forces adding in power."""
    fs = 1.7e6
    x = np.concatenate([c for _, c in render_chunks(sched, fs)])
    n0, n1 = int(t0 * fs), int(t1 * fs)
    G, to_b, _ = latch_forces(design, [85e3, 170e3])
    w = 20
    worst = -np.inf
    for n in range(n0, n1 - w, 2):
        t = np.arange(n, n + w) / fs
        amps = [2 / w * abs(np.sum(x[n:n + w] * np.exp(-2j * np.pi * f * t))) for f in (85e3, 170e3)]
        worst = max(worst, float(G[0] @ np.square(amps) / to_b[0]))
    return worst


def test_a_phase_flip_of_the_kept_counter_tone_is_caught_and_the_rendered_waveform_no_longer_switches(design):
    """170 kHz in anti-phase in the second step passes through zero mid-crossfade while 85 kHz plays on: the
    rendered waveform of the direct crossfade pushes the latch to ~1.37 x its switching force; the compiled one
    stays at the steps' ~0.78 x.  (A per-tone larger-end bound, which assumes each tone's power lies between its
    ends, says 0.78 x here.)"""
    s = compile_program(design, "flip", OPTS)
    (fade,) = _fades(s)
    one, two = [g for g in s.segments if g.tones]
    assert {t.frequency_hz: t.phase_rad for t in two.tones}[170e3] == pytest.approx(np.pi)
    # the direct crossfade: the same segments without the silence
    direct = Schedule(s.program, [one, Segment(one.end_s, one.end_s + two.duration_s, two.tones, 1, two.goal)],
                      s.goals, s.max_voltage_v, s.full_scale_v, s.ramp_s)
    b = one.end_s
    steps_alone = _rendered_push(design, direct, 0.05, 0.06)
    assert steps_alone == pytest.approx(0.783, rel=0.01) and steps_alone < 1 / LATCH_STATE_MARGIN
    assert _rendered_push(design, direct, b - 1e-3, b + 1e-3) > 1.3
    assert _rendered_push(design, s, b - 1e-3, b + 2e-3) <= steps_alone * (1 + 1e-3)


def test_tones_that_push_the_same_way_are_left_alone(design):
    """85 kHz then 90 kHz, both towards b: no tone is kept, the push never exceeds the larger end (the larger-end sum
    would say 0.53 + 0.47 = 1.0 x and fade needlessly).  Nothing inserted, nothing noted."""
    s = compile_program(design, "same_way", OPTS)
    assert len(s.segments) == 2 and not _fades(s)
    assert not any("fade" in n for n in s.notes) and not _warned(s)
    one, two = s.segments
    a = _push_towards_b(design, {85e3: 20.0})
    b = _push_towards_b(design, {90e3: 30.0})
    assert a + b > 1 / LATCH_STATE_MARGIN > max(a, b)
    _assert_no_boundary_overshoots(design, s)


def test_fig6e_toggle_is_unchanged():
    d = acl.load(str(ROOT / "examples" / "fig6e_reversible_latch.acl"))
    s = compile_program(d, "toggle", OPTS)
    assert not _fades(s) and len(s.segments) == 5


def _latch_program(slew):
    """One latch (injected forces: 85 kHz +1 nN/V^2 towards b, 170 and 180 kHz -4 nN/V^2; switching force 40 nN,
    release 30 nN), phases pinned: 85 kHz at 7.35 V (1.35 x) kept, 170 kHz then 180 kHz at 2.45 V (0.6 x each)
    counter-pushing: each step 0.75 x, a direct crossfade up to 1.05 x.  Step 2 has the slew limit ``slew``; step 3
    repeats it without one (the program's own fade-out)."""
    from acl.design import model as M
    from acl.diagnostics import Span

    def sp(line):
        return Span(file="prog.acl", line=line, column=3)

    def drive(counter, line, lim=None):
        tones = (M.Tone(frequency=85e3, amplitude=7.35, phase_given=True),
                 M.Tone(frequency=counter, amplitude=2.45, phase_given=True))
        return M.DriveStep(drive=M.Drive(tones=tones), duration=0.01, span=sp(line),
                           limits=M.Limits(slew_rate=lim))

    lt = M.Latch(name="gate", angle=np.radians(45), length=60e-6, width=3e-6, thickness=10e-6, material="tpeta",
                 youngs_modulus=13e6, anchor=(0, 0, 0), axis=(1, 0, 0), state="a", span=sp(2))
    tr = M.Transducer(name="t", max_voltage=20.0, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp(1))
    steps = (drive(170e3, 11), drive(180e3, 12, slew), drive(180e3, 13))
    return M.Design(file="prog.acl", transducer=tr, latches=(lt,),
                    programs=(M.Program(name="p", steps=steps, span=sp(10)),))


def _latch_provider(design, freqs):
    g = {85e3: 1.0, 170e3: -4.0, 180e3: -4.0}
    F = np.array([[g.get(f, 0.0) for f in freqs]]) * 1e-9
    return F.reshape(1, len(freqs)), np.array([40e-9]), np.array([30e-9])


def test_when_a_slew_limit_forbids_the_fade_the_crossfade_is_warned_at_the_step():
    """Step 2's 5 kV/s slew limit: the direct crossfade changes only the 2.45 V counter tones (~3.8 kV/s), fading its
    7.35 V out and in alone would take ~11.5 kV/s.  Kept, and W-SCHED-CROSSFADE at step 2 gives the overshoot
    (1.05 / (1/1.2) = 1.26); without the slew limit the same program fades through silence."""
    opts = CompileOptions(latch_provider=_latch_provider)
    s = compile_program(_latch_program(5e3), "p", opts)
    assert not _fades(s) and len(s.segments) == 3
    (w,) = [w for w in s.warnings if w.code == "W-SCHED-CROSSFADE"]
    assert w.span.line == 12 and "latch `gate` (in state a) to 1.05 x its switching force" in w.message
    assert float(w.message.split(": ")[-1].split(" x beyond")[0]) == pytest.approx(1.05 * 1.2, rel=1e-3)
    assert "over its slew limit 5000 V/s" in w.notes[0]
    free = compile_program(_latch_program(None), "p", opts)
    assert len(_fades(free)) == 1 and _fades(free)[0].step == 1 and not _warned(free)


# -- a held pair: an injected critical set that two tones reach together --------------------------

def _hold_then_drive(v_drive):
    from acl.design import model as M
    from acl.diagnostics import Span

    sp = Span(file="h.acl", line=1, column=1)
    tr = M.Transducer(name="t", max_voltage=20.0, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp)
    hold = M.HoldStep(a="a.o", b="b.o", mode="above", margin=1.2, duration=0.1, tones=(85e3,), span=sp)
    drive = M.DriveStep(drive=M.Drive(tones=(M.Tone(frequency=125e3, amplitude=v_drive),)), duration=0.1,
                        span=Span(file="h.acl", line=2, column=3))
    return M.Design(file="h.acl", transducer=tr, programs=(M.Program(name="p", steps=(hold, drive), span=sp),))


def _critical(design, a, b, tones, s_max, bound):
    """Snap-in where (V85/3)^2 + (V125/3)^2 + 6 (V85/3)(V125/3) = 1: each tone alone snaps at 3 V, together much
    earlier (a critical set that is not the snap index's simplex, as when the tones' forces peak at different gaps)."""
    v = dict(tones)
    a1, a2 = v.get(85e3, 0.0) / 3, v.get(125e3, 0.0) / 3
    q = a1 * a1 + a2 * a2 + 6 * a1 * a2
    s = 1 / np.sqrt(q) if q > 0 else np.inf
    return s if s <= s_max else np.inf


def _opts(**kw):
    return CompileOptions(snap_provider=lambda *a: np.array([3.0]), critical_provider=_critical, **kw)


def test_a_hold_then_a_drive_at_another_tone_that_would_snap_the_pair_mid_crossfade_fades_through_silence():
    s = compile_program(_hold_then_drive(2.4), "p", _opts())
    hold, fade, drive = s.segments
    s0 = _critical(None, 0, 0, [(t.frequency_hz, t.amplitude_v) for t in hold.tones], 10, None)
    s1 = _critical(None, 0, 0, [(t.frequency_hz, t.amplitude_v) for t in drive.tones], 10, None)
    mid = _critical(None, 0, 0, [(t.frequency_hz, t.amplitude_v / 2) for t in hold.tones + drive.tones], 10, None)
    assert min(s0, s1) >= 1.2 * (1 - 1e-4) and mid < 1.0       # each alone keeps the margin; mixed, it snaps
    assert _fades(s) == [fade] and fade.step == 1
    assert any("the pair a.o/b.o that step 1 holds apart" in n for n in s.notes)


def test_a_drive_the_mix_keeps_apart_is_left_alone():
    s = compile_program(_hold_then_drive(0.1), "p", _opts())
    assert len(s.segments) == 2 and not _fades(s)


def test_the_fig4_pair_held_at_its_margin_then_driven_at_another_tone_is_left_alone():
    """Real mechanics: the hold's 125 kHz at its 1.2 margin, then 100 kHz at 2 V.  The mixed drive mid-crossfade,
    re-simulated independently (mechanics.sweep_voltage through critical_scale), keeps more than the margin, and the
    schedule is the two steps' segments with nothing between."""
    from acl.schedule.gains import critical_scale

    d = acl.load(str(ROOT / "samples" / "crossfade_hold.acl"), search_paths=[str(ROOT / "examples")])
    s = compile_program(d, "hold_then_drive", CompileOptions(band_samples=0))
    hold, drive = s.segments
    assert hold.goal.startswith("step 1: hold") and not _fades(s)
    mid = [(t.frequency_hz, t.amplitude_v / 2) for t in hold.tones + drive.tones]
    assert critical_scale(d, "left.jet", "right.jet", mid, 3.0, 10e-6) > 1.2
    assert not any("fade" in n or "crossfade" in n for n in s.notes)


def test_with_declared_drive_saturation_the_mixed_drive_is_sampled_and_faded(tmp_path):
    """The swap program under `drive_saturation { v_sat = 200 V }` (forces no longer ~V^2): each step alone
    ~0.65 x, the mixed drive mid-crossfade (85 kHz kept at 32 V, 170 and 180 kHz halved), evaluated independently with
    the full force model, ~0.9 x > 1/1.2; the compiler samples it and fades through silence."""
    import shutil

    from acl.schedule.gains import latch_drive_forces, latch_forces as lf

    shutil.copy(ROOT / "examples" / "fig6e_reversible_latch.acl", tmp_path)
    body = DATA.read_text(encoding="utf-8").split("param v85", 1)[1]
    (tmp_path / "sat.acl").write_text('extends "fig6e_reversible_latch.acl"\n'
                                      "effect drive_saturation { v_sat = 200 V }\nparam latch_youngs = 13 MPa\nparam v85" + body, encoding="utf-8")
    d = acl.load(str(tmp_path / "sat.acl"))
    _, to_b, _ = lf(d, [])

    def push(tones):
        return float(latch_drive_forces(d, tones)[0] / to_b[0])

    ends = [push([(85e3, 32.0), (170e3, 48.0)]), push([(85e3, 32.0), (180e3, 65.0)])]
    mid = push([(85e3, 32.0), (170e3, 24.0), (180e3, 32.5)])
    assert max(ends) < 1 / LATCH_STATE_MARGIN < mid
    s = compile_program(d, "swap", OPTS)
    assert len(_fades(s)) == 1
    assert any("sampled at weights 0.25, 0.5, 0.75 (declared drive saturation)" in n for n in s.notes)


def test_the_cli_writes_the_faded_schedule_and_says_why(tmp_path, capsys):
    """`acl compile` end to end on the `swap` program: exit 0, schedule.json carries the silent segment as its own
    goal between the two drive steps, and the note that explains it."""
    import json

    from acl.cli import main

    out = tmp_path / "out"
    rc = main(["compile", str(DATA), "--program", "swap", "-o", str(out), "--path", str(ROOT / "examples"),
               "--allow-nonlinear", "--band-samples", "0", "-q"])
    capsys.readouterr()
    assert rc == 0
    sched = json.loads((out / "schedule.json").read_text())
    fades = [g for g in sched["segments"] if not g["tones"] and (g.get("goal") or "").endswith(FADE_GOAL)]
    assert len(fades) == 1 and fades[0]["goal"].startswith("step 2")
    (note,) = [n for n in sched["notes"] if n.startswith("step 2: faded through")]
    assert "of silence after step 1" in note and "latch `l` (in state a)" in note
