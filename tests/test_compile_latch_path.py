"""Follow (path) and hold steps move the tracked latch state too (acl.schedule.latch_state.latch_track).

A path's waypoints, or a hold's drive, can push a latch's shuttle capsule past its switching force as any drive
does: the latch then stays switched.  Before, only drive and sweep steps were followed, so a later `switch` was
planned from the wrong state (e.g. "already in state a; nothing to do" while the device sits in state b).  A
path is taken at its most-switching waypoint (and, for the "left for sure" side, at the most its tones' powers can
add up to while the renderer crossfades two waypoints); a follow or hold step that switches a latch, or may,
warns W-SCHED-LATCH-FLIP at the step (a user tracking a path rarely wants a latch to flip under it).

The pushes quoted are the compiler's own model (acl.schedule.gains.latch_forces: force per V^2 of each tone at
rest; tones add in power), recomputed here from the emitted amplitudes to set each case on its side.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl
from acl.design import model as M
from acl.diagnostics import DiagnosticError, Span
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.gains import latch_forces
from acl.schedule.model import ScheduledTone, Segment

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
DATA = os.path.join(ROOT, "samples", "latch_path.acl")
FLIP, STATE = "W-SCHED-LATCH-FLIP", "W-SCHED-LATCH-STATE"
OPTS = CompileOptions(band_samples=0, allow_nonlinear=True, resim_points=5)
M12 = 1.2          # the latch-state margin (LATCH_STATE_MARGIN, the switch step's default)


def _line_of(path, text):
    with open(path) as fh:
        return next(i for i, line in enumerate(fh, 1) if text in line)


def _warnings(s, code):
    return [w for w in s.warnings if w.code == code]


def _played(s, step):
    return [t for g in s.segments if g.step == step for t in g.tones if t.amplitude_v > 0]


def _path_push(design, sched):
    """Largest push of the emitted follow waypoints on `snap` over its switching force (latch_forces' model)."""
    g = next(g for g in sched.goals if g.kind == "follow")
    G, to_b, _ = latch_forces(design, g.frequencies_hz)
    return float(np.max((g.amplitudes_v ** 2) @ G[0]) / to_b[0])


@pytest.fixture(scope="module")
def switched():
    d = acl.load(DATA)
    return d, compile_program(d, "stroke", OPTS)


def test_the_data_file_sets_the_path_push_on_each_side():
    for lt, lo, hi in (("0.35um", M12, np.inf), ("0.45um", 1 / M12, M12), ("1.7um", 0.0, 1 / M12)):
        d = acl.load(DATA, overrides={"lt": lt})
        r = _path_push(d, compile_program(d, "stroke", OPTS))
        assert lo < r < hi, (lt, r)


def test_a_path_that_switches_a_latch_warns_at_the_follow_step(switched):
    d, s = switched
    (w,) = _warnings(s, FLIP)
    assert w.span.line == _line_of(DATA, "follow act") and w.span.column == 3
    assert "switches latch `snap` from state a to state b" in w.message
    push = _path_push(d, s)                       # the emitted waypoints' push, recomputed here
    assert 1.2 < push < 1.35                      # the data file's premise (its header)
    assert w.notes[0].startswith(f"step 1 (follow) pushed it to {push:.3g} x its switching force at waypoint ")
    assert any(n.startswith("warning: step 1: follow") for n in s.notes)


def test_a_release_after_a_path_that_switched_the_latch_is_planned_from_state_b():
    """Before: `switch snap to a` after the path was "already in state a; nothing to do" (the path was not
    followed) while the latch sits in b.  Now it is planned as a release: the latch's one capsule pushes towards
    b only, so no drive releases it: an infeasible switch at its step, naming the follow step."""
    with pytest.raises(DiagnosticError) as exc:
        compile_program(acl.load(DATA), "stroke_then_release", OPTS)
    (d,) = exc.value.diagnostics
    assert d.code == "E-SCHED-INFEASIBLE" and d.span.line == _line_of(DATA, "switch snap to a")
    assert any("step 1 (follow) pushed it" in n for n in d.notes)


def test_a_path_near_the_switching_force_leaves_the_state_uncertain():
    """lt = 0.45 um: the path's worst waypoint pushes the latch to 0.97 x its switching force."""
    d = acl.load(DATA, overrides={"lt": "0.45um"})
    s = compile_program(d, "stroke_then_release", OPTS)
    (w,) = _warnings(s, FLIP)
    assert "may switch latch `snap`" in w.message and "likelier a" in w.message
    (w2,) = _warnings(s, STATE)
    assert w2.span.line == _line_of(DATA, "switch snap to a") and "may be in state b" in w2.message
    # the worst waypoint's push with the capsules at the drive's equilibrium; where it differs (3 digits) from the
    # push undeflected (at rest, recomputed here), the note gives both
    push = _path_push(d, compile_program(d, "stroke", OPTS))
    assert 1 / M12 < push < 1.0
    n = w2.notes[0]
    assert n.startswith("step 1 (follow) pushed it to ") and " at waypoint 134 of 200 (t = 1.33 s)" in n
    assert (f"({push:.3g} x undeflected)" in n) if "static equilibrium" in n else n.startswith(
        f"step 1 (follow) pushed it to {push:.3g} x its switching force")
    g = next(g for g in s.goals if g.kind == "switch")
    assert g.details["state_before"] == "a or b" and _played(s, 1) == []


def test_a_path_well_below_the_switching_force_leaves_the_latch_alone():
    d = acl.load(DATA, overrides={"lt": "1.7um"})
    s = compile_program(d, "stroke_then_release", OPTS)
    assert not _warnings(s, FLIP) and not _warnings(s, STATE)
    g = next(g for g in s.goals if g.kind == "switch")
    assert g.details["state_before"] == "a" and g.details["already"] is True


def test_cli_prints_the_flip_warning_located(tmp_path, capsys):
    from acl.cli import main

    assert main(["compile", DATA, "--program", "stroke", "-o", str(tmp_path / "out"), "-q", "--band-samples", "0",
                 "--allow-nonlinear"]) == 0
    cap = capsys.readouterr()
    assert f"latch_path.acl:{_line_of(DATA, 'follow act')}:3: warning[{FLIP}]" in cap.out + cap.err


# ------------------------------------------------------------------------------------------------
# hold steps, and the path logic on injected latch forces (as tests/test_schedule_compile_steps.py)
# ------------------------------------------------------------------------------------------------

NN = 1e-9


def sp(line):
    return Span(file="prog.acl", line=line, column=3)


def _latch(name):
    return M.Latch(name=name, angle=np.radians(45), length=60e-6, width=3e-6, thickness=10e-6, material="tpeta",
                   youngs_modulus=13e6, anchor=(0, 0, 0), axis=(1, 0, 0), state="a", span=sp(2))


def _design(*steps, limit=20.0):
    tr = M.Transducer(name="t", max_voltage=limit, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp(1))
    return M.Design(file="prog.acl", transducer=tr, latches=(_latch("gate"),),
                    programs=(M.Program(name="p", steps=tuple(steps), span=sp(10)),))


def _provider(table, to_b=40.0, to_a=30.0):
    """Force per V^2 (nN) of each tone along `gate`; switching / release force (nN)."""
    def forces(design, freqs):
        return (np.array([[table.get(f, 0.0) for f in freqs]]) * NN, np.array([to_b]) * NN, np.array([to_a]) * NN)
    return forces


def test_a_hold_that_switches_a_latch_is_followed_and_warned():
    """The hold drives 85 kHz as hard as the snap-in margin allows (20 V: 400 V^2 x 1 nN/V^2 = 10 x the switching
    force).  Before: the later `switch gate to b` played a full switching drive planned from state a, and nothing
    said the hold flipped the latch."""
    snap = lambda design, a, b, freqs, vmax, bound: np.array([30.0])   # noqa: E731  (V: 20 V is below 30/1.2)
    d = _design(M.HoldStep(a="x.jet", b="y.jet", mode="above", duration=0.1, tones=(85e3,), span=sp(11)),
                M.SwitchStep(latch="gate", state="b", tones=(85e3,), span=sp(12)))
    s = compile_program(d, "p", CompileOptions(snap_provider=snap, latch_provider=_provider({85e3: 1.0})))
    assert _played(s, 0)[0].amplitude_v == pytest.approx(20.0, rel=1e-3)
    (w,) = _warnings(s, FLIP)
    assert w.span.line == 11 and "hold's drive switches latch `gate` from state a to state b" in w.message
    g = next(g for g in s.goals if g.kind == "switch")
    assert g.details["already"] is True and "step 1 (hold) pushed it to 10 x" in g.details["state_from"]
    assert _played(s, 1) == []


def _tracked(amps, table, kinds=("follow",)):
    """Latch state after a follow step whose waypoints play ``amps`` ({Hz: [V per waypoint]}), from the compiler's
    tracking alone (segments set by hand: the path planner is not what is tested here)."""
    from acl.schedule.latch_state import latch_track
    from acl.schedule.state import CompileState

    step = M.FollowStep(capsule="m", path=M.PathSpec(shape="circle", radius=1e-6), duration=0.1, span=sp(11))
    d = _design(step, M.PauseStep(duration=0.1, span=sp(12)))
    c = CompileState(d, d.programs[0], CompileOptions(latch_provider=_provider(table)))
    n = len(next(iter(amps.values())))
    c.segments = [Segment(0.01 * w, 0.01 * (w + 1), tuple(ScheduledTone(f, float(v[w])) for f, v in amps.items()), 0,
                          "step 1: follow m") for w in range(n)]
    return latch_track(c, 1)["gate"], c


def test_a_path_is_taken_at_its_most_switching_waypoint():
    """1 nN/V^2 at 85 kHz, switching force 40 nN: waypoints at 2, 7, 3 V push 0.1, 1.225, 0.225 x."""
    (state, certain, why), c = _tracked({85e3: [2.0, 7.0, 3.0]}, {85e3: 1.0})
    assert (state, certain) == ("b", True)
    assert why == "step 1 (follow) pushed it to 1.23 x its switching force at waypoint 2 of 3 (t = 0.01 s)"
    (w,) = c.step_warnings
    assert w.code == FLIP and w.span.line == 11


def test_a_path_pushing_both_ways_leaves_the_latch_uncertain_in_its_nominal_order_state():
    """85 kHz pushes to b (1 nN/V^2, 40 nN), 170 kHz back (-1 nN/V^2, release force 30 nN): the path switches the
    latch (7 V: 1.23 x) and then releases it (6 V: 1.2 x).  Nominally it ends in a, but each push is taken at the
    path's extreme over the uncertainty: not known for sure (conservative), likelier a."""
    (state, certain, why), _ = _tracked({85e3: [7.0, 0.0], 170e3: [0.0, 6.0]}, {85e3: 1.0, 170e3: -1.0})
    assert (state, certain) == ("a", False)
    assert "then pushed back" in why


def test_the_crossfade_between_waypoints_can_push_beyond_both_ends():
    """G = +1 (85 kHz) and -1 nN/V^2 (170 kHz), switching force 40 nN.  Waypoint 1: 30 V^2 at 85 kHz (0.75 x);
    waypoint 2: 60 and 40 V^2 (0.5 x).  Both ends stay below 1/1.2 = 0.833 x, but while the renderer crossfades
    them (amplitudes between their ends, same phase) the push reaches 0.86 x (a quarter of the way: 85 kHz at
    6.16 V, 170 kHz at 1.58 V): the bound sum_k max(G_k u_k) = 60 nN (1.5 x) makes the state uncertain instead of
    left-for-sure."""
    c_ = np.linspace(0, 1, 1001)
    a1, a2 = np.sqrt(30) + (np.sqrt(60) - np.sqrt(30)) * c_, np.sqrt(40) * c_
    assert np.max(a1 ** 2 - a2 ** 2) / 40.0 > 1 / M12 > max(30 / 40, 20 / 40)
    (state, certain, why), _ = _tracked({85e3: [np.sqrt(30), np.sqrt(60)], 170e3: [0.0, np.sqrt(40)]},
                                        {85e3: 1.0, 170e3: -1.0})
    assert (state, certain) == ("a", False)
    assert "up to 1.5 x while crossfading between waypoints" in why


# ------------------------------------------------------------------------------------------------
# the push with the capsules where the drive puts them (static equilibrium), not at rest
# ------------------------------------------------------------------------------------------------

DEFLECT = os.path.join(ROOT, "samples", "latch_deflect.acl")


def test_the_push_at_the_drives_equilibrium_differs_from_the_push_at_rest_in_the_fixture():
    """samples/latch_deflect.acl: 125 kHz at 10 V pushes the shuttle towards a at rest (-0.018 x), but bends the
    cantilever ~28 um towards `partner` before it snaps in; there the Bjerknes attraction pulls the shuttle towards
    b with ~1.2 x the switching force (acl.analysis.mechanics.equilibrium, acl.schedule.gains.latch_drive_forces)."""
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.schedule.gains import latch_drive_forces

    d = acl.load(DEFLECT)
    _, to_b, _ = latch_forces(d, [])
    rest = float(latch_drive_forces(d, [(125e3, 10.0)])[0] / to_b[0])
    st = mechanics.equilibrium(d, Drive(tones=(Tone(frequency=125e3, amplitude=10.0),)), acoustics.force_model_for(d))
    eq = float(latch_drive_forces(d, [(125e3, 10.0)], st.positions)[0] / to_b[0])
    assert st.status == "snap_in" and -20e-6 > st.displacements["arm_cap"][0] > -40e-6
    assert rest < 0 < 1 / M12 < eq


def test_a_drive_that_pushes_a_latch_only_once_its_neighbour_has_moved_leaves_the_state_uncertain():
    """Before (the push at rest, -0.018 x): the latch stayed in state a for sure, and `switch ctl to a` played nothing
    silently.  At the drive's equilibrium the push is ~1.2 x: the state is uncertain, and no 125 kHz drive within
    10 V releases the latch: W-SCHED-LATCH-STATE at the switch, quoting both pushes."""
    s = compile_program(acl.load(DEFLECT), "near", CompileOptions(band_samples=0, allow_nonlinear=True))
    (w,) = _warnings(s, STATE)
    assert w.span.line == _line_of(DEFLECT, "switch ctl to a")
    note = w.notes[0]
    assert note.startswith("step 1 (drive) pushed it to ") and " x its switching force at its static equilibrium (" \
        in note and "fall on either side of 0.833 .. 1.2 x" in note
    r = float(note.split("pushed it to ")[1].split(" x")[0])
    r0 = float(note.split("static equilibrium (")[1].split(" x undeflected")[0])
    assert r > 1 / M12 and r0 < 0
    g = next(g for g in s.goals if g.kind == "switch")
    assert g.details["state_before"] == "a or b"


def test_a_paths_margin_band_takes_each_draws_most_switching_waypoint(switched):
    """With the declared uncertainty (the stdlib transducer's 30 % gain prior) the 1.25 x path is uncertain: in some
    draws no waypoint reaches the switching force.  The band's lower end is the 5th percentile (of 20 draws: the
    smallest) of each draw's largest waypoint push, recomputed here draw by draw (acl.schedule.bands.sample_designs;
    the same seed).  The path is planned once without the band (its own error band is not what is tested)."""
    from acl.schedule.bands import sample_designs
    from acl.schedule.latch_state import latch_track
    from acl.schedule.state import CompileState

    d, s = switched
    c = CompileState(d, d.program("stroke"), CompileOptions(band_samples=20, allow_nonlinear=True))
    c.segments = list(s.segments)
    state, certain, why = latch_track(c, 1)["snap"]
    assert (state, certain) == ("b", False)
    lo = float(why.split("(")[-1].split(" .. ")[0])
    g = next(g for g in s.goals if g.kind == "follow")
    per_draw = []
    for _, dd in sample_designs(d, 20, 0, None):
        G, to_b, _ = latch_forces(dd, g.frequencies_hz)
        per_draw.append(np.max((g.amplitudes_v ** 2) @ G[0]) / to_b[0])
    assert lo == pytest.approx(min(per_draw), rel=2e-3) and lo < 1.0 < _path_push(d, s)
    assert "20 draws of the declared uncertainty" in why


def test_a_drive_under_which_no_equilibrium_stays_on_the_latchs_branch_leaves_its_state_uncertain(tmp_path):
    """Fig. 6f: once `ctl` is in state b, `partner` is 40 um from `arm_cap`, and 125 kHz at 6 V snaps the pair in:
    no equilibrium stays on branch b (acl.analysis.mechanics.equilibrium falls back to branch a).  Undeflected the
    release push is -0.017 x (the attraction holds the shuttle in b), but where the mechanism goes after the snap is
    not modelled: the latch is not taken as left for sure.  Before: the second `switch ctl to b` played nothing
    ("already in state b")."""
    import shutil

    shutil.copy(os.path.join(ROOT, "examples", "fig6f_control_module.acl"), tmp_path)
    path = tmp_path / "p.acl"
    path.write_text('extends "fig6f_control_module.acl"\nprogram p {\n'
                    "  switch ctl to b, margin 1.2, using [85 kHz], limit 30 V\n  drive 125 kHz @ 6 V for 1 s\n"
                    "  switch ctl to b, margin 1.2, using [85 kHz], limit 30 V\n}\n")
    s = compile_program(acl.load(str(path)), "p", CompileOptions(band_samples=0, allow_nonlinear=True))
    g = next(g for g in s.goals if g.kind == "switch" and g.step == 2)
    assert g.details["state_before"] == "a or b" and _played(s, 2)
    why = g.details["state_from"]
    assert why.startswith("step 2 (drive) pushed it to -") and float(why.split("pushed it to ")[1].split(" x")[0]) < 0
    assert " x its release force (undeflected): under the drive no equilibrium stays on that branch" in why


def test_the_re_simulation_follows_the_latch_through_its_snap_through(switched):
    """The path pushes `snap` over its switching force part-way: the device's latch snaps to state b and stays there
    as the drive falls (hysteresis).  Before, the re-simulation lost the equilibrium at the snap-through, counted the
    waypoints from there to where the push fell back as unconverged (the error unbounded, W-SCHED-TRACKING), and then
    continued from state a, where the latch no longer is.  Now it goes on from the switched branch
    (acl.schedule.gains.model_forward): the shuttle capsule is at rest before the first waypoint that pushes the latch
    over its switching force and one travel along the axis (-x here) from there to the end."""
    from acl.schedule.gains import model_forward

    d, s = switched
    g = next(g for g in s.goals if g.kind == "follow")
    U = g.amplitudes_v ** 2
    G, to_b, _ = latch_forces(d, g.frequencies_hz)
    over = np.flatnonzero(U @ G[0] >= to_b[0])
    assert over.size and over[0] > 0
    forward, _ = model_forward(d, "pusher", g.frequencies_hz)
    x = forward(U)[:, 0]
    assert np.all(np.isfinite(x))
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    travel = latch_landscape(*latch_geometry(d.latch("snap"), d)).state_b
    assert np.all(np.abs(x[:over[0] - 1]) < 0.05 * travel)          # state a before (its elastic give only)
    assert np.allclose(x[over[0] + 1:], -travel, rtol=0.05)          # state b after, to the end of the path
    full = compile_program(d, "stroke", CompileOptions(band_samples=0, allow_nonlinear=True, resim_points=200))
    f = next(g for g in full.goals if g.kind == "follow")
    assert "unconverged_waypoints" not in f.details and f.max_error_m < 0.5e-6
    assert not _warnings(full, "W-SCHED-TRACKING")


def test_a_pair_that_snaps_in_is_not_taken_for_a_latch_flip():
    """A lost equilibrium is continued on a latch's other branch only when the drive pushes that latch over its
    switching force: Fig. 4's facing pair (no latch) driven past its snap-in stays unconverged (NaN), and in contact
    until a waypoint with no drive."""
    from acl.schedule.gains import model_forward

    d = acl.load(os.path.join(ROOT, "examples", "fig4_facing_pair.acl"))
    forward, _ = model_forward(d, d.capsules[0].name, [125e3])
    x = forward(np.array([[0.0], [1.0], [400.0], [1.0], [0.0], [1.0]]))
    assert np.all(np.isfinite(x[:2])) and not np.any(np.isfinite(x[2]))
    # in contact while a drive plays (1 V^2 alone does not snap it, but does not release it either: no release
    # model), released by silence
    assert not np.any(np.isfinite(x[3])) and np.all(np.isfinite(x[4:])) and np.allclose(x[5], x[1])
