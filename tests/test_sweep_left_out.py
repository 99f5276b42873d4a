"""`acl sweep` names every column it leaves out, and why (issue 23).

A calibrated design (`acl fit --calibrated`, with a declared `stiffness_scale` effect) lost its deflection
and lint columns from the sweep table without a word; the uncalibrated design had them.
"""
from __future__ import annotations

import os

from acl import load
from acl.sweep.driver import left_out

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")


def test_a_design_with_effects_names_the_columns_it_lacks():
    notes = left_out(load(os.path.join(DATA, "fit_cantilever.calibrated.acl")))
    text = "\n".join(notes)
    assert "stiffness_scale" in text
    assert "lint_acl201" in text
    # the deflection is given point by point (acl.sweep.points) once a drive is named; without one, it says so
    assert "tip_deflection: deflections need a drive" in text
    with_at = "\n".join(left_out(load(os.path.join(DATA, "fit_cantilever.calibrated.acl")), "125 kHz @ 2 V"))
    assert "deflection" not in with_at and "lint_acl201" in with_at
    assert "switching_force" not in text          # no latch: nothing of a latch to leave out
    assert "snap_in" not in text                  # one capsule: no pair


def test_the_same_design_without_effects_lacks_nothing_for_that_reason():
    notes = left_out(load(os.path.join(DATA, "fit_cantilever.acl")))
    assert not any("effects" in n for n in notes), notes


def test_the_note_reaches_the_table(tmp_path, capsys):
    from acl.cli import main

    rc = main(["sweep", os.path.join(DATA, "fit_cantilever.calibrated.acl"), "--samples", "4",
               "-o", str(tmp_path / "t.csv")])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert "columns not computed: tip_deflection" in " ".join((out.out + out.err).split())
