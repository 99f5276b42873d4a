"""Covered-range warnings for drive and sweep steps, and the travel a latch calibration covers (issue 9 point 5).

A lab plays the waveforms into real devices: where the calibrated model is extrapolated, ``acl compile`` must say
so (``W-SCHED-COVERAGE`` at the step's file:line:column, a warning: exit 0).  Before, a ``drive`` step was never
compared with ``covered(deflection)`` (the compiler's reach of a goal knew holds and switches only), a ``sweep``
step had no goal record and was compared with nothing (voltage, band, deflection), and a latch fit on state rows
alone wrote no ``covered(deflection)``, so a later switch was not checked either.

The deflection a step drives is the analysis' own (acl.analysis.mechanics.equilibrium), which these tests call
directly to set the declared ranges on either side of it.
"""
from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

import acl
from acl.cli import main
from acl.schedule.compile import CompileOptions, compile_program

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
CODE = "W-SCHED-COVERAGE"


def _design(tmp_path, base, cover, program, name="cov.acl"):
    """A design extending the example ``base`` with declared ``covered(...)`` ranges (as ``acl fit`` writes them)."""
    shutil.copy(os.path.join(EX, base), tmp_path)
    path = tmp_path / name
    lines = [f'extends "{base}"', "uncertainty {"] + [f"  covered({q}) = {r}" for q, r in cover.items()] + ["}"]
    path.write_text("\n".join(lines) + "\nprogram p {\n" + "\n".join(f"  {s}" for s in program) + "\n}\n")
    return str(path)


def _line_of(path, text):
    with open(path) as fh:
        return next(i for i, line in enumerate(fh, 1) if text in line)


def _reach(design, tones, start=None):
    """(largest capsule displacement from rest, m, capsule) at the analysis' equilibrium under ``tones``."""
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone

    st = mechanics.equilibrium(design, Drive(tones=tuple(Tone(frequency=f, amplitude=a) for f, a in tones)),
                               acoustics.force_model_for(design), start=start)
    assert st.status == "ok"
    r = {c: float(np.linalg.norm(v)) for c, v in st.displacements.items()}
    from acl.physics.ties import first_max_item

    who, best = first_max_item(r)      # ties (a symmetric pair, equal to round-off): the first declared, as compile
    return best, who


def _cov(sched, words=""):
    return [w for w in sched.warnings if w.code == CODE and words in w.message]


WIDE = {"voltage": "0 V .. 100 V", "frequency": "50 kHz .. 200 kHz"}


# ------------------------------------------------------------------------------------------------
# drive steps
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("base, tone", [("fig4_facing_pair.acl", (125e3, 1.0)),      # a pair
                                        ("fig2_vertical_cantilever.acl", (125e3, 2.0)),  # a lone cantilever
                                        ("fig5c_linear_spring.acl", (125e3, 2.0)),   # a spring against a fixed capsule
                                        ("fig6_bistable_latch.acl", (125e3, 10.0))])  # a latch's shuttle
def test_a_drive_beyond_the_covered_deflection_warns_at_its_step(tmp_path, base, tone):
    """The drive's equilibrium lies 1.05 x beyond the covered deflection: warned, naming the capsule and the
    analysis' deflection; with the range at 1.05 x it, not warned (voltage and tones inside a wide range)."""
    f, v = tone
    step = f"drive {f / 1e3:g} kHz @ {v:g} V for 100 ms"
    r, who = _reach(acl.load(os.path.join(EX, base)), [tone])
    assert r > 1e-9
    for scale, warned in ((1 / 1.05, True), (1.05, False)):
        path = _design(tmp_path, base, {**WIDE, "deflection": f"0 m .. {r * scale:.9g} m"}, [step])
        s = compile_program(acl.load(path), "p", CompileOptions(band_samples=0, allow_nonlinear=True))
        got = _cov(s)
        if not warned:
            assert not got, [w.message for w in got]
            continue
        (w,) = got
        assert f"the drive moves capsule `{who}` {r * 1e6:.3g} um from rest" in w.message
        assert f"covered deflections up to {r * scale * 1e6:.3g} um" in w.message
        assert w.span.line == _line_of(path, step) and w.span.column == 3


def test_a_drive_after_a_switch_is_taken_on_the_latch_state_b(tmp_path):
    """After `switch snap to b` the shuttle rests ~70 um from rest: a 10 V drive then holds it there (the analysis'
    equilibrium from state b), far beyond a 1 um range, while the same drive before the switch moves it 0.02 um."""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    path = _design(tmp_path, "fig6_bistable_latch.acl", {**WIDE, "deflection": "0 um .. 1 um"},
                   ["drive 125 kHz @ 10 V for 100 ms", "switch snap to b, margin 1.2, using [125 kHz], limit vmax",
                    "drive 125 kHz @ 10.5 V for 100 ms"])
    d = acl.load(path)
    s = compile_program(d, "p", CompileOptions(band_samples=0, allow_nonlinear=True))
    lines = {w.span.line: w.message for w in _cov(s)}
    assert _line_of(path, "@ 10 V") not in lines                       # before the switch: inside
    assert "travels to state b" in lines[_line_of(path, "switch snap")]
    b = latch_landscape(*latch_geometry(d.latches[0], d)).state_b
    centre = np.asarray(d.capsule("act").center, float)
    r, _ = _reach(d, [(125e3, 10.5)], start={"act": centre + np.array([b, 0, 0])})
    assert r > b
    assert f"the drive moves capsule `act` {r * 1e6:.3g} um from rest" in lines[_line_of(path, "@ 10.5 V")]


def test_without_a_mechanics_answer_the_deflection_is_unknown_and_silent(tmp_path, monkeypatch):
    """No equilibrium (the mechanics fails or does not converge): no deflection warning and no crash; the
    voltage is still checked."""
    from acl.analysis import mechanics

    path = _design(tmp_path, "fig4_facing_pair.acl", {"voltage": "0 V .. 0.5 V", "deflection": "0 m .. 1e-12 m"},
                   ["drive 125 kHz @ 1 V for 100 ms"])
    d = acl.load(path)

    def broken(*a, **k):
        raise ValueError("no mechanics model")

    monkeypatch.setattr(mechanics, "equilibrium", broken)
    s = compile_program(d, "p", CompileOptions(band_samples=0))
    assert [w.message for w in _cov(s)] == [
        "step 1: drive: drives up to 1 V (sum of tone amplitudes) but the calibration data covered 0 .. 0.5 V: "
        "the calibrated model is extrapolated"]
    real = mechanics.MechanismState

    def lost(*a, **k):
        return real({}, {}, {}, "no_convergence", False, float("nan"))

    monkeypatch.setattr(mechanics, "equilibrium", lost)
    s = compile_program(d, "p", CompileOptions(band_samples=0))
    assert not _cov(s, "deflection")


@pytest.mark.parametrize("step, words", [
    ("drive 125 kHz @ 4 V for 100 ms", "the drive snaps the mechanism in; before it does, capsule `left` already moves"),
    ("sweep 110 kHz to 135 kHz @ 4 V in 1 s", "kHz the sweep snaps the mechanism in; before it does, capsule `left`")])
def test_a_step_that_snaps_the_pair_in_warns_whatever_the_covered_deflection(tmp_path, step, words):
    """4 V at 125 kHz snaps the Fig. 4 pair in (at about 3.25 V): it ends in contact, which the fit counts in no
    covered range, so it is warned even when the covered deflection (30 um) exceeds the last stable point."""
    path = _design(tmp_path, "fig4_facing_pair.acl", {**WIDE, "deflection": "0 um .. 30 um"}, [step])
    s = compile_program(acl.load(path), "p", CompileOptions(band_samples=0, allow_nonlinear=True))
    (w,) = _cov(s)
    assert words in w.message and "then into contact, which no calibration covers" in w.message
    r = float(w.message.split("already moves ")[1].split(" um")[0])
    assert 0 < r < 30
    assert w.span.line == _line_of(path, step) and w.span.column == 3


# ------------------------------------------------------------------------------------------------
# sweep steps
# ------------------------------------------------------------------------------------------------

def _dense_worst(design, f0, f1, v, n=81):
    fs = np.linspace(f0, f1, n)
    return max((_reach(design, [(f, v)])[0], f) for f in fs)


def test_a_sweep_is_checked_at_its_worst_frequency(tmp_path):
    """A 1 V sweep 115 -> 135 kHz on the Fig. 4 pair bends it most near the capsule's mode (~120 kHz), not at its
    ends: a range 2 % below that peak (found on a dense 81-point grid) is warned, naming the frequency; 1 % above
    it is not."""
    base = os.path.join(EX, "fig4_facing_pair.acl")
    worst, f_worst = _dense_worst(acl.load(base), 115e3, 135e3, 1.0)
    ends = max(_reach(acl.load(base), [(f, 1.0)])[0] for f in (115e3, 135e3))
    assert worst > 1.1 * ends                                 # the ends alone would miss it
    step = "sweep 115 kHz to 135 kHz @ 1 V in 1 s"
    for scale, warned in ((0.98, True), (1.01, False)):
        path = _design(tmp_path, "fig4_facing_pair.acl", {**WIDE, "deflection": f"0 m .. {worst * scale:.9g} m"},
                       [step])
        s = compile_program(acl.load(path), "p", CompileOptions(band_samples=0))
        got = _cov(s)
        if not warned:
            assert not got, [w.message for w in got]
            continue
        (w,) = got
        assert w.message.startswith("step 1: sweep: at ")
        f = float(w.message.split("at ")[1].split(" kHz")[0]) * 1e3
        assert abs(f - f_worst) <= 0.5e3                     # grid step of the dense check: 250 Hz
        assert f"moves capsule `left` {worst * 1e6:.3g} um from rest" in w.message
        assert w.span.line == _line_of(path, step) and w.span.column == 3


@pytest.mark.parametrize("step, words", [
    ("sweep 100 kHz to 135 kHz @ 0.2 V in 1 s", "sweeps 100 .. 135 kHz, beyond the calibrated 110 .. 140 kHz"),
    ("sweep 135 kHz to 145 kHz @ 0.2 V in 1 s log", "sweeps 135 .. 145 kHz, beyond the calibrated 110 .. 140 kHz"),
    ("sweep 115 kHz to 135 kHz @ 3 V in 1 s", "drives up to 3 V (sum of tone amplitudes) but the calibration "
                                              "data covered 0 .. 2 V")])
def test_a_sweep_outside_the_covered_band_or_voltage_warns(tmp_path, step, words):
    """A band that leaves the covered tones on either side (the end tone counts, not only the start), or an
    amplitude over the covered voltage."""
    path = _design(tmp_path, "fig4_facing_pair.acl", {"voltage": "0 V .. 2 V", "frequency": "110 kHz .. 140 kHz"},
                   [step])
    s = compile_program(acl.load(path), "p", CompileOptions(band_samples=0, allow_nonlinear=True))
    (w,) = _cov(s)
    assert words in w.message and w.span.line == _line_of(path, step) and w.span.column == 3


def test_a_sweep_inside_the_covered_range_is_silent_and_schedule_json_keeps_its_goals(tmp_path):
    """Inside voltage, band and deflection: no warning.  The sweep's record is internal: schedule.json's `goals`
    lists the drive goal only, as before."""
    path = _design(tmp_path, "fig4_facing_pair.acl",
                   {"voltage": "0 V .. 2 V", "frequency": "110 kHz .. 140 kHz", "deflection": "0 um .. 1 um"},
                   ["drive 125 kHz @ 0.5 V for 100 ms", "sweep 115 kHz to 135 kHz @ 1 V in 1 s"])
    out = str(tmp_path / "out")
    assert main(["compile", path, "--program", "p", "-o", out, "-q", "--band-samples", "0"]) == 0
    doc = json.loads(open(os.path.join(out, "schedule.json")).read())
    assert [g["kind"] for g in doc["goals"]] == ["drive"]
    assert not any("covered" in n for n in doc["notes"])


def test_cli_prints_drive_and_sweep_warnings_located_and_exits_0(tmp_path, capsys):
    path = _design(tmp_path, "fig4_facing_pair.acl",
                   {"voltage": "0 V .. 2 V", "frequency": "110 kHz .. 140 kHz", "deflection": "0 um .. 0.1 um"},
                   ["drive 125 kHz @ 1 V for 100 ms", "sweep 100 kHz to 135 kHz @ 0.2 V in 1 s"])
    out = str(tmp_path / "out")
    assert main(["compile", path, "--program", "p", "-o", out, "-q", "--band-samples", "0"]) == 0
    cap = capsys.readouterr()
    text = cap.out + cap.err
    drive, sweep = _line_of(path, "drive 125"), _line_of(path, "sweep 100")
    assert f"cov.acl:{drive}:3: warning[{CODE}]: step 1: drive: the drive moves capsule `left`" in text
    assert f"cov.acl:{sweep}:3: warning[{CODE}]: step 2: sweep: sweeps 100 .. 135 kHz" in text
    assert os.path.exists(os.path.join(out, "schedule.json"))
    notes = json.loads(open(os.path.join(out, "schedule.json")).read())["notes"]
    assert any(n.startswith("warning: step 1: drive: the drive moves") for n in notes)    # kept as notes too
    assert any(n.startswith("warning: step 2: sweep: sweeps 100 .. 135 kHz") for n in notes)


# ------------------------------------------------------------------------------------------------
# latch fits: the travel state rows cover
# ------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def latch_fits(tmp_path_factory):
    """The Fig. 6 latch fitted on state rows alone (no shuttle position): a ramp that switched it (10..80 V, state b
    from 60 V on), and one that never did (10, 40 V)."""
    from acl.fit import run_fit

    tmp = tmp_path_factory.mktemp("latchcov")
    design = tmp / "latch.acl"
    shutil.copy(os.path.join(ROOT, "samples", "fit_latch_state.acl"), design)
    out = {}
    for name, rows in (("switched", ((10, 0), (40, 0), (60, 1), (80, 1))), ("stayed", ((10, 0), (40, 0)))):
        csv = tmp / f"{name}.csv"
        csv.write_text("observable,value,unit,drive,sigma\n"
                       + "".join(f"switched,{s},1,125 kHz @ {v} V,0.5\n" for v, s in rows))
        cal = tmp / f"{name}.calibrated.acl"
        fit = run_fit(str(design), [str(csv)], free=("gamma", "spread"), calibrated_path=str(cal))
        cal.write_text(fit.calibrated)
        out[name] = str(cal)
    return out


def test_state_rows_cover_the_shuttle_travel_they_saw(latch_fits):
    """State b seen: the travel from state a to state b (the latch geometry's); only state a: none (0 .. 0)."""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    d = acl.load(latch_fits["switched"])
    b = latch_landscape(*latch_geometry(d.latches[0], d)).state_b
    cover = {c.quantity: c for c in d.coverage}
    assert cover["deflection"].lower == 0 and cover["deflection"].upper == pytest.approx(b, rel=1e-8)
    cover = {c.quantity: c for c in acl.load(latch_fits["stayed"]).coverage}
    assert cover["deflection"].upper == 0.0


def test_a_switch_the_data_never_saw_warns_and_one_it_saw_does_not(latch_fits):
    opts = CompileOptions(band_samples=0, allow_nonlinear=True)
    s = compile_program(acl.load(latch_fits["stayed"]), "switch", opts)
    (w,) = _cov(s, "deflection")
    assert "latch `snap` travels to state b" in w.message and "covered deflections up to 0 um" in w.message
    s = compile_program(acl.load(latch_fits["switched"]), "switch", opts)
    assert not _cov(s, "deflection"), [w.message for w in s.warnings]


def test_a_drive_after_a_drive_that_switched_the_latch_is_taken_on_state_b(tmp_path):
    """A ramp's 60 V step pushes the latch over its switching force (acl.analysis.mechanics.latch_margins): the
    shuttle stays in state b when the drive falls to 10 V, so that step holds it ~70 um from rest too, beyond the
    1 um range (before, it was taken from rest: 0.02 um, silent)."""
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone

    path = _design(tmp_path, "fig6_bistable_latch.acl", {**WIDE, "deflection": "0 um .. 1 um"},
                   ["drive 125 kHz @ 10 V for 100 ms", "drive 125 kHz @ 60 V for 100 ms", "pause 100 ms",
                    "drive 125 kHz @ 10.5 V for 100 ms"])
    d = acl.load(path)
    fm = acoustics.force_model_for(d)
    assert mechanics.latch_margins(d, Drive(tones=(Tone(frequency=125e3, amplitude=60.0),)), fm)["snap"].margin >= 1
    assert mechanics.latch_margins(d, Drive(tones=(Tone(frequency=125e3, amplitude=10.5),)), fm)["snap"].margin < 1
    s = compile_program(d, "p", CompileOptions(band_samples=0, allow_nonlinear=True))
    lines = {w.span.line: w.message for w in _cov(s)}
    assert _line_of(path, "@ 10 V") not in lines
    for step in ("@ 60 V", "@ 10.5 V"):
        text = lines[_line_of(path, step)]
        assert "the drive moves capsule `act` " in text
        assert float(text.split("capsule `act` ")[1].split(" um")[0]) > 60      # state b: ~70.7 um
