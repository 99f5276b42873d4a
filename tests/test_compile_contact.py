"""A pair snapped in by an earlier step stays in contact while a drive plays (W-SCHED-CONTACT).

Paper Fig. 4b: at contact the Bjerknes force between the two bubbles (1/d^2) is far stronger than at the rest gap, so
the pair does not come apart when the drive merely falls; only silence (no acoustic force: the beams pull the capsules
apart) releases it.  The compiler has no release model and takes a contact to last until a `pause`.  A `hold ... above`
on that pair, or a path of one of its capsules, is planned from the pair at rest: it warns at the step.  The snap-in is
the hold planner's own model (acl.schedule.gains.critical_scale: the whole drive re-simulated).
"""
from __future__ import annotations

import os
import shutil

import pytest

import acl
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.gains import critical_scale

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
OPTS = CompileOptions(band_samples=0, allow_nonlinear=True)
HOLD = "hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 8 V"
CROSS = "cross gap(left.jet, right.jet) for 200 ms, using [125 kHz], limit 15 V"
CODE = "W-SCHED-CONTACT"


def _compile(tmp_path, steps):
    shutil.copy(os.path.join(EX, "fig4_facing_pair.acl"), tmp_path)
    path = tmp_path / "p.acl"
    path.write_text('extends "fig4_facing_pair.acl"\nprogram p {\n' + "\n".join(f"  {s}" for s in steps) + "\n}\n")
    d = acl.load(str(path))
    return d, compile_program(d, "p", OPTS)


def _contact(s):
    return [w for w in s.warnings if w.code == CODE]


def test_the_premise_6_v_snaps_the_pair_in_and_1_v_does_not(tmp_path):
    d, _ = _compile(tmp_path, ["pause 1 s"])
    assert critical_scale(d, "left.jet", "right.jet", [(125e3, 6.0)], 1.0) <= 1.0
    assert critical_scale(d, "left.jet", "right.jet", [(125e3, 1.0)], 1.0) == float("inf")


@pytest.mark.parametrize("first, why", [("drive 125 kHz @ 6 V for 200 ms", "the drive of step 1 (drive) reaches its snap-in"),
                                        (CROSS, "step 1 (hold ... cross) snaps it in")])
def test_a_hold_after_a_snap_in_without_a_pause_warns_at_the_hold(tmp_path, first, why):
    _, s = _compile(tmp_path, [first, HOLD])
    (w,) = _contact(s)
    assert w.span.line == 4 and w.span.column == 3                 # the hold step (program p opens on line 2)
    assert why in w.message and "left / right" in w.message and "pause" in w.hint
    assert any(n.startswith("warning: step 2: hold: the pair") for n in s.notes)


@pytest.mark.parametrize("steps", [["drive 125 kHz @ 6 V for 200 ms", "pause 100 ms", HOLD],
                                   ["drive 125 kHz @ 1 V for 200 ms", HOLD],
                                   [CROSS, "pause 100 ms", HOLD],
                                   [HOLD, "drive 125 kHz @ 6 V for 200 ms"]])
def test_a_pause_a_drive_below_snap_in_or_no_later_hold_does_not_warn(tmp_path, steps):
    _, s = _compile(tmp_path, steps)
    assert not _contact(s)


def test_the_cli_prints_the_contact_warning_located(tmp_path, capsys):
    from acl.cli import main

    _compile(tmp_path, ["drive 125 kHz @ 6 V for 200 ms", HOLD])
    rc = main(["compile", str(tmp_path / "p.acl"), "--program", "p", "-o", str(tmp_path / "out"), "--band-samples",
               "0", "--allow-nonlinear"])
    out = capsys.readouterr()
    assert rc == 0 and f"p.acl:4:3: warning[{CODE}]" in out.out + out.err
