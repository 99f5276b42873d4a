"""Covered-range warnings for goals without a path (issue 9): hold, cross and switch.

A calibration records the range its data covered (``covered(voltage|frequency|deflection)``,
acl/fit/calibrated.py).  Before, a program outside it was warned about only as an unlocated note
(no code, no file:line:column, not printed with ``-q``, absent from ``--diagnostics json``), and
the deflection was checked for a follow goal's path only: a hold that bends the pair, a cross that
drives it through snap-in and a switch that moves a latch's shuttle were never compared with the
covered deflection.  Now each is ``W-SCHED-COVERAGE`` at the goal's step.

The calibrated pair is made as a lab would: a narrow ramp (0.5 and 1 V at 125 kHz) compiled,
played on the design (``acl synth``, 0.05 um noise) and fitted (``acl fit``); its programs
``keep_apart`` (hold) and ``snap`` (cross) need more than 1 V.
"""
from __future__ import annotations

import json
import os
import shutil

import pytest

import acl
from acl.cli import main
from acl.schedule.compile import CompileOptions, compile_program

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
CODE = "W-SCHED-COVERAGE"


def _line_of(path, text):
    with open(path) as fh:
        return next(i for i, line in enumerate(fh, 1) if text in line)


@pytest.fixture(scope="module")
def calibrated_pair(tmp_path_factory):
    from acl.fit import run_fit

    tmp = str(tmp_path_factory.mktemp("cov"))
    shutil.copy(os.path.join(EX, "fig4_facing_pair.acl"), tmp)
    design = os.path.join(tmp, "pair.acl")
    with open(design, "w") as fh:
        fh.write('extends "fig4_facing_pair.acl"\n'
                 "program narrow {\n  drive 125 kHz @ 0.5 V for dwell\n  drive 125 kHz @ 1 V for dwell\n}\n"
                 "program low_tone {\n  hold gap(left.jet, right.jet) above 10 um for 1 s, using [118 kHz], limit 8 V\n}\n")
    out = os.path.join(tmp, "out")
    assert main(["compile", design, "--program", "narrow", "-o", out, "-q", "--band-samples", "0"]) == 0
    csv = os.path.join(tmp, "run.csv")
    assert main(["synth", design, "--schedule", os.path.join(out, "schedule.json"), "-o", csv,
                 "--noise", "0.05um", "--seed", "1"]) == 0
    cal = os.path.join(tmp, "pair.calibrated.acl")
    fit = run_fit(design, [csv], free=("gamma", "alpha"), calibrated_path=cal)
    with open(cal, "w") as fh:
        fh.write(fit.calibrated)
    return tmp, cal


def _warnings(sched, quantity_words):
    return [w for w in sched.warnings if w.code == CODE and quantity_words in w.message]


def test_the_fit_covered_a_narrow_range(calibrated_pair):
    _, cal = calibrated_pair
    cover = {c.quantity: c for c in acl.load(cal).coverage}
    assert cover["voltage"].upper == pytest.approx(1.0)
    assert cover["frequency"].lower == cover["frequency"].upper == pytest.approx(125e3)
    assert 0 < cover["deflection"].upper < 1e-6


@pytest.mark.parametrize("program, what", [("keep_apart", "the drive holds capsule"),
                                           ("snap", "before it snaps in")])
def test_hold_and_cross_warn_at_their_step(calibrated_pair, program, what):
    tmp, cal = calibrated_pair
    d = acl.load(cal)
    cover = {c.quantity: c for c in d.coverage}
    s = compile_program(d, program, CompileOptions(band_samples=0))
    base = os.path.join(tmp, "fig4_facing_pair.acl")
    line = _line_of(base, "hold gap(" if program == "keep_apart" else "cross gap(")
    volts = _warnings(s, "calibration data covered 0 .. 1 V")
    bent = _warnings(s, "covered deflections up to")
    assert len(volts) == 1 and len(bent) == 1, [w.message for w in s.warnings]
    for w in volts + bent:
        assert w.span is not None and os.path.samefile(w.span.file, base) and w.span.line == line
    assert what in bent[0].message
    # the deflection it names is the mechanics' own: above the covered one, and the drive exceeds 1 V
    seg = next(g for g in s.segments if g.goal == s.goals[0].name)
    assert seg.amplitude_sum() > cover["voltage"].upper
    assert not _warnings(s, "lie outside")             # 125 kHz was covered
    # the help says what to measure on the bench (the step's tones, up to its drive), not which command to run
    v = seg.amplitude_sum()
    assert "on the bench, measure the displacement under this step's tones (125 kHz)" in volts[0].hint
    assert f"up to {v:.3g} V" in volts[0].hint or "margin" in volts[0].message
    assert "acl synth" not in volts[0].hint and "on the bench, measure" in bent[0].hint


def test_hold_outside_the_covered_tones_warns(calibrated_pair):
    _, cal = calibrated_pair
    s = compile_program(acl.load(cal), "low_tone", CompileOptions(band_samples=0))
    w = _warnings(s, "tones 118 kHz lie outside the calibrated 125 .. 125 kHz")
    assert len(w) == 1 and w[0].span.line == _line_of(os.path.join(calibrated_pair[0], "pair.acl"), "using [118 kHz]")
    assert "on the bench, measure the response at 118 kHz" in w[0].hint


def test_inside_the_covered_range_no_warning(calibrated_pair):
    """A hold whose drive, tone and deflection stay inside what the data covered is not warned about."""
    tmp, cal = calibrated_pair
    path = os.path.join(tmp, "inside.acl")
    with open(path, "w") as fh:
        fh.write('extends "pair.calibrated.acl"\n'
                 "program gentle {\n  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 0.5 V\n}\n")
    s = compile_program(acl.load(path), "gentle", CompileOptions(band_samples=0))
    assert not [w for w in s.warnings if w.code == CODE], [w.message for w in s.warnings]


def test_cli_reports_them_located_even_quiet(calibrated_pair, capsys):
    tmp, cal = calibrated_pair
    out = os.path.join(tmp, "o_snap")
    assert main(["compile", cal, "--program", "snap", "-o", out, "-q", "--band-samples", "0"]) == 0
    err = capsys.readouterr()
    text = err.out + err.err
    line = _line_of(os.path.join(tmp, "fig4_facing_pair.acl"), "cross gap(")
    assert f"fig4_facing_pair.acl:{line}:3: warning[{CODE}]" in text
    notes = json.loads(open(os.path.join(out, "schedule.json")).read())["notes"]
    assert any("covered deflections up to" in n for n in notes)     # schedule.json keeps them as notes


def test_switch_warns_for_its_shuttle_travel(tmp_path):
    """A latch calibration's state rows carry no deflection: switching moves the shuttle (and its capsule)
    between the latch's stable states, which the data never saw.  (A declared range: the fit of a latch
    alone writes none; tests/test_fit_mechanisms.py covers latch fits.)"""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    shutil.copy(os.path.join(EX, "fig6_bistable_latch.acl"), tmp_path)
    path = tmp_path / "cov.acl"
    path.write_text('extends "fig6_bistable_latch.acl"\nparam latch_youngs = 13 MPa\nparam vmax = 100 V\n'   # the latch it was written for
                    'uncertainty {\n  covered(voltage) = 0 V .. 100 V\n'
                    "  covered(frequency) = 100 kHz .. 150 kHz\n  covered(deflection) = 0 um .. 2 um\n}\n")
    d = acl.load(str(path))
    s = compile_program(d, "switch", CompileOptions(band_samples=0, allow_nonlinear=True))
    w = _warnings(s, "covered deflections up to 2 um")
    assert len(w) == 1 and "latch `snap` travels to state b" in w[0].message
    travel = latch_landscape(*latch_geometry(d.latches[0], d)).state_b
    assert f"{travel * 1e6:.3g} um" in w[0].message
    assert w[0].span.line == _line_of(str(tmp_path / "fig6_bistable_latch.acl"), "switch snap to b")
    assert len(s.warnings) == 1                         # voltage and tones inside the covered range


def test_json_output_carries_them(calibrated_pair, capsys):
    tmp, cal = calibrated_pair
    out = os.path.join(tmp, "o_json")
    assert main(["compile", cal, "--program", "keep_apart", "-o", out, "--band-samples", "0",
                 "--output-format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    found = [d for d in doc["diagnostics"] if d["code"] == CODE]
    assert {d["severity"] for d in found} == {"warning"} and len(found) == 2      # voltage, deflection
    assert all(d["file"].endswith("fig4_facing_pair.acl") and d["line"] and d["column"] == 3 for d in found)


def test_a_hold_whose_margin_lies_beyond_the_covered_voltage_warns(calibrated_pair):
    """A hold driven inside the covered 0..1 V promises no snap-in up to 1.2 x its drive: beyond 1 V that
    promise rests on the calibrated model where the data never went."""
    tmp, _ = calibrated_pair
    path = os.path.join(tmp, "edge.acl")
    with open(path, "w") as fh:
        fh.write('extends "pair.calibrated.acl"\n'
                 "program edge {\n  hold gap(left.jet, right.jet) above 10 um for 1 s, using [125 kHz], limit 0.95 V\n}\n")
    s = compile_program(acl.load(path), "edge", CompileOptions(band_samples=0))
    v = max(seg.amplitude_sum() for seg in s.segments)
    assert v <= 1.0 < 1.2 * v
    assert not _warnings(s, "drives up to")                      # the drive itself is inside
    (w,) = _warnings(s, "promises no snap-in up to 1.2 x its drive")
    assert "the margin is extrapolated" in w.message
    assert w.span.line == _line_of(path, "hold gap(")
