"""Program steps -> schedule segments (acl.schedule.compile), with fakes for the analysis stage."""
import numpy as np
import pytest

from acl.design import model as M
from acl.diagnostics import DiagnosticError, Span
from acl.schedule.compile import CompileOptions, compile_program

NN = 1e-9


def sp(line):
    return Span(file="prog.acl", line=line, column=1)


def latch(name, state="a"):
    return M.Latch(name=name, angle=np.radians(45), length=60e-6, width=3e-6, thickness=10e-6,
                   material="tpeta", youngs_modulus=13e6, anchor=(0, 0, 0), axis=(1, 0, 0),
                   state=state, span=sp(2))


def design(*steps, limit=20.0):
    tr = M.Transducer(name="t", max_voltage=limit, band=(40e3, 200e3), gain_frequencies=(40e3, 200e3),
                      gain_pa_per_v=(2e3, 2e3), span=sp(1))
    prog = M.Program(name="p", steps=tuple(steps), span=sp(10))
    return M.Design(file="prog.acl", transducer=tr, latches=(latch("gate"), latch("other")), programs=(prog,))


def fake_latches(design, freqs):
    """Fig. 6e: 85 kHz pushes `gate` to b, 170 kHz pushes it back; 125 kHz drives `other`."""
    table = {85e3: (1.0, 0.1), 125e3: (0.05, 1.0), 170e3: (-0.8, 0.0)}
    forces = np.array([[table.get(f, (0.0, 0.0))[i] for f in freqs] for i in range(2)]) * NN
    return forces, np.array([40.0, 60.0]) * NN, np.array([30.0, 50.0]) * NN


OPTS = CompileOptions(latch_provider=fake_latches)


def test_drive_pause_and_sweep_steps_become_timed_segments():
    d = design(M.DriveStep(drive=M.Drive(tones=(M.Tone(frequency=85e3, amplitude=2.0),)), duration=0.02, span=sp(11)),
               M.PauseStep(duration=0.005, span=sp(12)),
               M.SweepStep(f_start=40e3, f_stop=160e3, amplitude=1.0, duration=0.01, span=sp(13)))
    s = compile_program(d, "p")
    bounds = [t for g in s.segments for t in (g.start_s, g.end_s)]
    assert bounds == pytest.approx([0, 0.02, 0.02, 0.025, 0.025, 0.035])
    assert s.segments[1].tones == ()
    assert s.segments[2].tones[0].sweep == "linear" and s.segments[2].tones[0].frequency_end_hz == 160e3
    assert s.sample_rate_hz >= 10 * 160e3


def test_drive_above_the_transducer_limit_is_a_voltage_diagnostic_at_the_step():
    d = design(M.DriveStep(drive=M.Drive(tones=(M.Tone(frequency=85e3, amplitude=8.0),
                                                M.Tone(frequency=125e3, amplitude=7.0))), duration=0.01, span=sp(11)),
               limit=10.0)
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p")
    dg = exc.value.diagnostics[0]
    assert dg.code == "E-SCHED-VOLTAGE" and dg.span.line == 11


def test_switch_then_release_use_the_two_frequencies_of_fig_6e():
    d = design(M.SwitchStep(latch="gate", state="b", tones=(85e3, 125e3, 170e3), span=sp(11)),
               M.SwitchStep(latch="gate", state="a", tones=(85e3, 125e3, 170e3), span=sp(12)))
    s = compile_program(d, "p", OPTS)
    assert [t.frequency_hz for t in s.segments[0].tones] == [85e3]
    assert [t.frequency_hz for t in s.segments[1].tones] == [170e3]
    assert all(g.details["margin"] >= 1.2 - 1e-6 for g in s.goals)
    assert s.goals[0].details["other_latch_ratios"]["other"] <= 1 / 1.2 + 1e-6


def test_switching_a_latch_already_in_that_state_is_silent_and_noted():
    d = design(M.SwitchStep(latch="gate", state="a", tones=(85e3,), span=sp(11)))
    s = compile_program(d, "p", OPTS)
    assert s.segments[0].tones == () and any("already" in n for n in s.notes)


def test_infeasible_switch_names_the_goal_time_and_relaxation():
    d = design(M.PauseStep(duration=0.5, span=sp(11)),
               M.SwitchStep(latch="gate", state="b", tones=(85e3,), span=sp(12)), limit=5.0)
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p", OPTS)
    dg = exc.value.diagnostics[0]
    assert dg.code == "E-SCHED-INFEASIBLE" and "switch gate" in dg.message and dg.span.line == 12
    assert "t = 0.5 s" in dg.notes[0] and "max voltage" in dg.hint


def test_hold_and_cross_steps_use_the_snap_in_model():
    snap = lambda design, a, b, freqs, vmax, bound: np.array([6.0, np.inf])[: len(freqs)]   # noqa: E731
    d = design(M.HoldStep(a="x.jet", b="y.jet", mode="above", duration=0.1, tones=(85e3, 125e3), span=sp(11)),
               M.HoldStep(a="x.jet", b="y.jet", mode="cross", duration=0.1, tones=(85e3,), span=sp(12)))
    s = compile_program(d, "p", CompileOptions(snap_provider=snap))
    hold, cross = s.goals
    assert hold.details["snap_index"] <= 1 / 1.2 + 1e-6
    assert cross.details["snap_index"] >= 1.2 - 1e-6


def test_hold_without_a_snap_in_model_is_a_model_diagnostic():
    d = design(M.HoldStep(a="x.jet", b="y.jet", duration=0.1, tones=(85e3,), span=sp(11)))
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p", CompileOptions(snap_provider=lambda *a: None))
    assert exc.value.diagnostics[0].code == "E-SCHED-MODEL"


def follow_design(path, **kw):
    beam = M.Beam(name="arm", length=50e-6, section=M.Section(shape="circle", diameter=2e-6),
                  material="tpeta", youngs_modulus=13e6, clamp=(0, 0, 0), axis=(0, 0, 1),
                  tip=(0, 0, 50e-6), span=sp(3))
    step = M.FollowStep(capsule="module", path=path, duration=0.1, span=sp(11), **kw)
    d = design(step)
    return d.model_copy(update={"beams": (beam,), "joints": (
        M.Mount(capsule="module", target="arm", target_kind="beam", span=sp(4)),)})


def test_unsupported_glyph_is_a_path_diagnostic_at_the_step():
    d = follow_design(M.PathSpec(shape="text", text="A#", height=1e-6))
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p", CompileOptions(gain_provider=lambda d, c: None))
    dg = exc.value.diagnostics[0]
    assert dg.code == "E-SCHED-PATH" and "'#'" in dg.message and dg.span.line == 11


def test_missing_gain_model_is_a_tones_diagnostic():
    def no_model(design, capsule):
        raise ValueError("capsule `module` is not mounted")

    d = follow_design(M.PathSpec(shape="circle", radius=1e-6))
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p", CompileOptions(gain_provider=no_model))
    assert exc.value.diagnostics[0].code == "E-SCHED-TONES"
    assert "`, using [" in exc.value.diagnostics[0].hint   # the step's keyword (issue 11: not `tones`)


def test_solver_failure_is_a_diagnostic_not_a_traceback(monkeypatch):
    from acl.schedule import path as path_mod
    from acl.schedule.solve import SolverFailure
    from acl.schedule.tones import GainTable

    def broken(problem, what, **kw):
        raise SolverFailure(what, "solver error", ("CLARABEL", "OSQP", "SCS"))

    monkeypatch.setattr(path_mod, "solve", broken)
    f = np.array([60e3, 100e3, 140e3])
    g = np.array([[1, 0], [-0.5, 0.87], [-0.5, -0.87]]) * 1e-8
    d = follow_design(M.PathSpec(shape="circle", radius=0.1e-6))
    with pytest.raises(DiagnosticError) as exc:
        compile_program(d, "p", CompileOptions(calibration=GainTable(f, g)))
    assert exc.value.diagnostics[0].code == "E-SCHED-SOLVER"


def test_empty_program_is_a_diagnostic():
    with pytest.raises(DiagnosticError) as exc:
        compile_program(design(), "p")
    assert exc.value.diagnostics[0].code == "E-SCHED-EMPTY"
