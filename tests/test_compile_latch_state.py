"""The compiler plans a `switch` from the latch state earlier drives and sweeps left (not only earlier switches).

A bistable latch stays in state b when a drive that pushed it past its switching force stops (Fig. 6c: the ramp).
Before, ``acl compile`` tracked latch states through `switch` steps only: `drive 80 V` (which switches the Fig. 6
latch) then `switch snap to a` was planned as "already in state a; nothing to do" -- a schedule promising a state
the device is not in -- and `switch snap to b` as a full switching drive.  Now the planner follows the drives
(acl.schedule.gains.latch_drive_forces, the switch LP's own forces, against the latch's switching/release force),
and a drive whose push is near the switching force (within the switch step's default margin 1.2, or whose
margin band over the declared uncertainty straddles 1) leaves the state uncertain: a switch is then planned from
the other state (a drive that switches works from both), or warned (``W-SCHED-LATCH-STATE``) at its step.

The forces quoted are the compiler's own model (acl.schedule.gains), computed here to set drives on either side.
"""
from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.schedule.compile import CompileOptions, compile_program
LATCH_STATE_MARGIN = 1.2
from acl.schedule.gains import latch_drive_forces, latch_forces

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
CODE = "W-SCHED-LATCH-STATE"
OPTS = CompileOptions(band_samples=0, allow_nonlinear=True)
SWITCH6 = "switch snap to {s}, margin 1.2, using [125 kHz], limit 100 V"


# these scenarios were written for the uncalibrated Fig. 6 latch modulus (13 MPa, Table S2's simulation column);
# the examples now default to the Table S2 experimental calibration (docs/physics.md, issue 24)
UNCAL = {"latch_youngs": "13 MPa"}


def _design(tmp_path, base, program, extra=""):
    if base.startswith("fig6"):
        extra = "param latch_youngs = 13 MPa\n" + extra
    shutil.copy(os.path.join(EX, base), tmp_path)
    path = tmp_path / "p.acl"
    path.write_text(f'extends "{base}"\n{extra}program p {{\n' + "\n".join(f"  {s}" for s in program) + "\n}\n")
    return str(path)


def _line_of(path, text):
    with open(path) as fh:
        return next(i for i, line in enumerate(fh, 1) if text in line)


def _ratio(design, f, v, to="b"):
    """The compiler's push of one tone towards state ``to`` over the force that switches the latch there."""
    F = float(latch_drive_forces(design, [(f, v)])[0])
    _, to_b, to_a = latch_forces(design, [])
    return F / float(to_b[0]) if to == "b" else -F / float(to_a[0])


def _switch_goal(sched, step):
    return next(g for g in sched.goals if g.kind == "switch" and g.step == step)


def _played(sched, step):
    return [t for s in sched.segments if s.step == step for t in s.tones if t.amplitude_v > 0]


def _latch_warnings(sched):
    return [w for w in sched.warnings if w.code == CODE]


def test_the_ratios_the_tests_rely_on():
    d = acl.load(os.path.join(EX, "fig6_bistable_latch.acl"), overrides=UNCAL)
    assert _ratio(d, 125e3, 80) > 2 * LATCH_STATE_MARGIN            # 80 V switches it with room (3.6 x)
    assert 1 / LATCH_STATE_MARGIN < _ratio(d, 125e3, 42) < LATCH_STATE_MARGIN     # 42 V: about its switching force
    assert _ratio(d, 125e3, 20) < 0.5 / LATCH_STATE_MARGIN          # 20 V leaves it
    e = acl.load(os.path.join(EX, "fig6e_reversible_latch.acl"), overrides=UNCAL)
    assert _ratio(e, 85e3, 60) > 2 * LATCH_STATE_MARGIN and _ratio(e, 170e3, 100, "a") > 2 * LATCH_STATE_MARGIN


def test_a_switch_to_b_after_a_drive_that_switched_the_latch_plays_nothing_and_says_why(tmp_path):
    """Before: planned as a full switching drive (the latch taken in state a)."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 80 V for 100 ms", SWITCH6.format(s="b")])
    s = compile_program(acl.load(path), "p", OPTS)
    assert _played(s, 1) == []
    g = _switch_goal(s, 1)
    assert g.details["state_before"] == "b" and g.details["already"] is True
    assert "step 1 (drive) pushed it" in g.details["state_from"]
    assert any("already in state b" in n and "step 1 (drive)" in n for n in s.notes), s.notes
    assert not _latch_warnings(s)


def test_a_switch_to_a_after_a_drive_that_switched_the_latch_is_planned_as_a_release(tmp_path):
    """Before: "already in state a; nothing to do" while the device sits in state b.  The Fig. 6 latch has one
    capsule pushing towards b, so a release with 125 kHz alone is infeasible: an error at the switch step."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 80 V for 100 ms", SWITCH6.format(s="a")])
    with pytest.raises(DiagnosticError) as exc:
        compile_program(acl.load(path), "p", OPTS)
    (d,) = exc.value.diagnostics
    assert d.code == "E-SCHED-INFEASIBLE" and d.span.line == _line_of(path, "switch snap")
    assert any("step 1 (drive)" in n for n in d.notes)


def test_the_reversible_latch_is_released_after_a_drive_switched_it(tmp_path):
    """Fig. 6e: 60 V at 85 kHz switches the latch to b; the following `switch l to a` needs the 170 kHz release
    (before: nothing played).  A 170 kHz drive that releases it then makes `switch l to b` a real switch again."""
    steps = ["drive 85 kHz @ 60 V for 100 ms", "switch l to a, margin 1.2, using [170 kHz], limit 100 V",
             "switch l to b, margin 1.2, using [85 kHz], limit 100 V", "drive 170 kHz @ 100 V for 100 ms",
             "switch l to b, margin 1.2, using [85 kHz], limit 100 V"]
    path = _design(tmp_path, "fig6e_reversible_latch.acl", steps)
    d = acl.load(path)
    s = compile_program(d, "p", OPTS)
    rel = _switch_goal(s, 1)
    assert [t.frequency_hz for t in _played(s, 1)] == [170e3]
    _, _, to_a = latch_forces(d, [])
    assert rel.details["force_n"] >= 1.2 * float(to_a[0]) * (1 - 1e-6)
    assert rel.details["state_before"] == "b"
    assert [t.frequency_hz for t in _played(s, 2)] == [85e3]          # a real switch: the release worked
    assert _played(s, 4) and _switch_goal(s, 4).details["state_before"] == "a"    # the 170 kHz drive released it
    assert "step 4 (drive) pushed it" in _switch_goal(s, 4).details["state_from"]


def test_a_sweep_that_switches_the_latch_is_followed(tmp_path):
    path = _design(tmp_path, "fig6_bistable_latch.acl",
                   ["sweep 110 kHz to 140 kHz @ 80 V in 1 s", SWITCH6.format(s="b")])
    s = compile_program(acl.load(path), "p", OPTS)
    assert _played(s, 1) == [] and "step 1 (sweep) pushed it" in _switch_goal(s, 1).details["state_from"]


def test_a_drive_near_the_switching_force_leaves_the_state_uncertain_a_switch_to_b_works_from_both(tmp_path):
    """42 V pushes the Fig. 6 latch to about its switching force: it may or may not have switched.  `switch to b`
    is planned as the full switch (from a it switches; from b it pushes it further into b): no warning."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 42 V for 100 ms", SWITCH6.format(s="b")])
    s = compile_program(acl.load(path), "p", OPTS)
    g = _switch_goal(s, 1)
    assert _played(s, 1) and g.details["state_before"] == "a or b"
    assert g.details["force_n"] >= g.details["required_n"] * (1 - 1e-6)
    assert not _latch_warnings(s)
    assert any("planned from state a" in n for n in s.notes), s.notes


def test_a_release_that_cannot_be_planned_from_an_uncertain_state_warns_at_its_step(tmp_path):
    """42 V then `switch snap to a` with 125 kHz only: no drive releases the latch, and it may be in state b.
    Before: "already in a" silently.  Now W-SCHED-LATCH-STATE at the switch step, naming the drive's step."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 42 V for 100 ms", SWITCH6.format(s="a")])
    s = compile_program(acl.load(path), "p", OPTS)
    (w,) = _latch_warnings(s)
    assert w.span.line == _line_of(path, "switch snap") and w.span.column == 3
    assert "may be in state b" in w.message and w.notes[0].startswith("step 1 (drive) pushed it to 1 x its switching")
    assert _played(s, 1) == []
    assert _switch_goal(s, 1).details["state_before"] == "a or b"
    assert any(n.startswith("warning: step 2: switch snap -> a") for n in s.notes)


def test_a_drive_well_below_the_switching_force_leaves_the_state_certain(tmp_path):
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 20 V for 100 ms", SWITCH6.format(s="a")])
    s = compile_program(acl.load(path), "p", OPTS)
    assert not _latch_warnings(s) and _played(s, 1) == []
    assert _switch_goal(s, 1).details["state_before"] == "a"


def test_the_declared_uncertainty_makes_a_nominal_switch_uncertain(tmp_path):
    """50 V is 1.42 x the switching force nominally, but the Fig. 6 design declares a 30 % gain uncertainty: in some
    of 20 draws its push falls below the switching force (margin band, acl.schedule.bands.margin_band).  Without the
    band the drive is taken as switching (the switch plays nothing); with it the switch is planned from state a.
    60 V (2.05 x) stays above 1 in every draw: taken as switched with the band too."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 50 V for 100 ms", SWITCH6.format(s="b")])
    d = acl.load(path)
    assert _ratio(d, 125e3, 50) > LATCH_STATE_MARGIN
    s0 = compile_program(d, "p", OPTS)
    assert _played(s0, 1) == [] and _switch_goal(s0, 1).details["state_before"] == "b"
    s = compile_program(d, "p", CompileOptions(band_samples=20, allow_nonlinear=True))
    g = _switch_goal(s, 1)
    assert g.details["state_before"] == "a or b" and _played(s, 1)
    assert "margin band" in g.details["state_from"]
    lo = float(g.details["state_from"].split(" x in the margin band")[0].split("(")[-1].split(" .. ")[0])
    assert lo < 1.0
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 60 V for 100 ms", SWITCH6.format(s="b")])
    s = compile_program(acl.load(path), "p", CompileOptions(band_samples=20, allow_nonlinear=True))
    g = _switch_goal(s, 1)
    assert g.details["state_before"] == "b" and not _played(s, 1) and "20 draws of the declared uncertainty" in g.details["state_from"]


def test_cli_prints_the_latch_state_warning_located(tmp_path, capsys):
    from acl.cli import main

    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 42 V for 100 ms", SWITCH6.format(s="a")])
    out = str(tmp_path / "out")
    assert main(["compile", path, "--program", "p", "-o", out, "-q", "--band-samples", "0",
                 "--allow-nonlinear"]) == 0
    cap = capsys.readouterr()
    assert f"p.acl:{_line_of(path, 'switch snap')}:3: warning[{CODE}]" in cap.out + cap.err


# ------------------------------------------------------------------------------------------------
# cross goals end in contact
# ------------------------------------------------------------------------------------------------

def test_a_cross_goal_is_warned_as_contact_whatever_the_covered_deflection(tmp_path):
    """A cross drives the pair below snap-in: it ends in contact, which no calibration covers (as a drive that
    snaps, tests/test_coverage_steps.py).  Before, a covered deflection above the last stable point was silent."""
    path = _design(tmp_path, "fig4_facing_pair.acl",
                   ["cross gap(left.jet, right.jet) for 100 ms, using [125 kHz], limit 15 V"],
                   extra="uncertainty {\n  covered(deflection) = 0 um .. 30 um\n}\n")
    s = compile_program(acl.load(path), "p", OPTS)
    (w,) = [w for w in s.warnings if w.code == "W-SCHED-COVERAGE" and "deflection" in w.message]
    assert "then into contact, which no calibration covers" in w.message
    assert "before it snaps in" in w.message
    r = float(w.message.split(" um from rest")[0].split()[-1])
    assert 0 < r < 30
    assert w.span.line == _line_of(path, "cross gap(")


# ------------------------------------------------------------------------------------------------
# another latch in an uncertain state (two latches, injected forces as tests/test_schedule_compile_steps.py)
# ------------------------------------------------------------------------------------------------

def _two_latches(*steps):
    from acl.design import model as M
    from acl.diagnostics import Span

    def sp(line):
        return Span(file="prog.acl", line=line, column=3)

    def latch(name):
        return M.Latch(name=name, angle=np.radians(45), length=60e-6, width=3e-6, thickness=10e-6, material="tpeta",
                       youngs_modulus=13e6, anchor=(0, 0, 0), axis=(1, 0, 0), state="a", span=sp(2))

    tr = M.Transducer(name="t", max_voltage=20.0, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp(1))
    built = []
    for k, st in enumerate(steps):
        if st[0] == "drive":
            built.append(M.DriveStep(drive=M.Drive(tones=(M.Tone(frequency=st[1], amplitude=st[2]),)), duration=0.01,
                                     span=sp(11 + k)))
        else:
            built.append(M.SwitchStep(latch=st[1], state=st[2], tones=st[3], span=sp(11 + k)))
    return M.Design(file="prog.acl", transducer=tr, latches=(latch("gate"), latch("other")),
                    programs=(M.Program(name="p", steps=tuple(built), span=sp(10)),))


NN = 1e-9


def _provider(table, to_b, to_a):
    def forces(design, freqs):
        F = np.array([[table.get(f, (0.0, 0.0))[i] for f in freqs] for i in range(2)]) * NN
        return F.reshape(2, len(freqs)), np.array(to_b) * NN, np.array(to_a) * NN
    return forces


def test_another_latch_left_uncertain_is_kept_put_in_both_directions():
    """85 kHz switches `gate` (1 nN/V^2) and pulls `other` towards a (-1 nN/V^2, release force 20 nN); 100 kHz
    switches `gate` less well (0.8) and leaves `other`.  With `other` certainly in state a the least drive is 85 kHz
    alone (48 V^2 = 1.2 x 40 nN).  After 125 kHz at 7.3 V pushed `other` to 0.89 x its switching force (60 nN) it may
    be in b: the 85 kHz power must then stay below 20 nN / 1.2 (16.7 V^2), the rest comes from 100 kHz."""
    prov = _provider({85e3: (1.0, -1.0), 100e3: (0.8, 0.0), 125e3: (0.0, 1.0)}, [40.0, 60.0], [30.0, 20.0])
    sure = compile_program(_two_latches(("drive", 125e3, 1.0), ("switch", "gate", "b", (85e3, 100e3))), "p",
                           CompileOptions(latch_provider=prov))
    assert [t.frequency_hz for t in _played(sure, 1)] == [85e3]
    assert _played(sure, 1)[0].amplitude_v ** 2 == pytest.approx(48.0, rel=1e-4)
    s = compile_program(_two_latches(("drive", 125e3, 7.3), ("switch", "gate", "b", (85e3, 100e3))), "p",
                        CompileOptions(latch_provider=prov))
    assert not _latch_warnings(s)
    u = {t.frequency_hz: t.amplitude_v ** 2 for t in _played(s, 1)}
    assert u.get(85e3, 0.0) <= 20.0 / 1.2 * (1 + 1e-6)                     # other stays in b if it is there
    assert u.get(85e3, 0.0) + 0.8 * u[100e3] >= 1.2 * 40.0 * (1 - 1e-6)     # gate switches
    g = _switch_goal(s, 1)
    assert g.details["other_latch_ratios"]["other"] <= 1 / 1.2 + 1e-6


def test_another_uncertain_latch_that_no_drive_keeps_put_in_both_states_warns():
    """85 kHz switches `gate` (1 nN/V^2) and pulls `other` towards a (-1 nN/V^2), whose release force is 20 nN: if
    `other` is in state b (7.3 V at 125 kHz pushed it to 0.89 x its switching force: maybe), the switch (>= 48 V^2)
    releases it.  Planned for its likelier state a, and W-SCHED-LATCH-STATE at the switch step."""
    prov = _provider({85e3: (1.0, -1.0), 125e3: (0.0, 1.0)}, [40.0, 60.0], [30.0, 20.0])
    d = _two_latches(("drive", 125e3, 7.3), ("switch", "gate", "b", (85e3,)))
    s = compile_program(d, "p", CompileOptions(latch_provider=prov))
    (w,) = _latch_warnings(s)
    assert w.span.line == 12 and "latch `other` may be in state a or b" in w.message
    assert w.notes == ("latch `other`: step 1 (drive) pushed it to 0.888 x its switching force: within 1.2 x of it, "
                       "it may or may not have switched",)
    assert "keeps it in state a (`other`) only" in w.message
    assert _played(s, 1)


def test_the_coverage_check_takes_an_uncertain_latch_in_either_state(tmp_path):
    """40 V pushes the Fig. 6 latch to 0.91 x its switching force: likelier still in state a, but maybe in b.  A
    10.5 V drive then moves the shuttle 0.02 um from state a, ~70 um from state b: the covered 1 um is warned
    about, from state b (before, taken from state a only: silent)."""
    path = _design(tmp_path, "fig6_bistable_latch.acl", ["drive 125 kHz @ 40 V for 100 ms",
                                                         "drive 125 kHz @ 10.5 V for 100 ms"],
                   extra="uncertainty {\n  covered(voltage) = 0 V .. 100 V\n  covered(deflection) = 0 um .. 1 um\n}\n")
    d = acl.load(path)
    assert 1 / LATCH_STATE_MARGIN < _ratio(d, 125e3, 40) < 1.0
    s = compile_program(d, "p", OPTS)
    lines = {w.span.line: w.message for w in s.warnings if w.code == "W-SCHED-COVERAGE"}
    text = lines[_line_of(path, "@ 10.5 V")]
    assert "the drive moves (latch `snap` in state b, where an earlier drive may have left it) capsule `act`" in text
    assert float(text.split("capsule `act` ")[1].split(" um")[0]) > 60
