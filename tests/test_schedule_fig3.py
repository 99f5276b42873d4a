"""Paper Fig. 3: the three-orifice module follows the rectangle, circle and EPFL paths.

Gains come from the model (acoustics thrust x cantilever compliance), and, separately, from a
documented fake calibration sweep (Fig. S4a-like: three resonances pushing 120 degrees apart).
The paths at 20 V put the largest interface at eps/R ~ 0.20-0.25, the linear limit of the bubble model
(issue 10, docs/physics.md): these tests check the planner, so they opt in with allow_nonlinear.
"""
import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.tones import GainTable

FIG3 = """\
import stdlib.capsules
import stdlib.beams
import stdlib.media
import stdlib.transducers

use medium media.pbs
use transducer transducers.contact_piezo

beam arm like beams.cantilever50 { clamp = (0 um, 0 um, 0 um) }
capsule module like capsules.prism3 { }
mount module on arm.tip

program rectangle {
  follow module along rectangle(width = 2 um, height = 1.5 um, center = (0.3 um, 0.2 um)) in 4 s
}
program circle {
  follow module along circle(radius = 1 um, center = (0.2 um, 0 um)) in 4 s
}
program epfl {
  follow module along text("EPFL", height = 1.5 um) in 8 s
}
program far {
  follow module along circle(radius = 60 um) in 1 s, limit 2 V
}
"""


@pytest.fixture(scope="module")
def design():
    return acl.loads(FIG3, filename="fig3.acl")


def fake_calibration() -> GainTable:
    """Three Lorentzian resonances (70, 110, 150 kHz) pushing at 0, 120, 240 deg, 1 um / 10 V^2 at peak."""
    f = np.arange(40e3, 160.5e3, 500.0)
    g = np.zeros((f.size, 2))
    for f0, ang in ((70e3, 0), (110e3, 120), (150e3, 240)):
        amp = 1.0 / (1 + ((f - f0) / 4e3) ** 2)
        g += amp[:, None] * [np.cos(np.radians(ang)), np.sin(np.radians(ang))]
    return GainTable(f, g * 1e-6 / 10, source="fake calibration")


@pytest.mark.parametrize("program", ["rectangle", "circle", "epfl"])
def test_paper_paths_compile_with_model_gains_and_report_a_small_predicted_error(design, program):
    s = compile_program(design, program, CompileOptions(resim_points=12, allow_nonlinear=True))
    (goal,) = s.goals
    assert len(goal.frequencies_hz) == 3
    assert goal.rms_error_m is not None and goal.max_error_m is not None
    assert goal.max_error_m < 0.05e-6                     # nonlinear re-simulation, well within 50 nm
    assert "Eq. (1)" in goal.model or "equilibrium" in goal.model


@pytest.mark.parametrize("program", ["rectangle", "circle", "epfl"])
def test_paper_paths_compile_with_a_calibration_and_pick_its_three_resonances(design, program):
    s = compile_program(design, program, CompileOptions(calibration=fake_calibration(), allow_nonlinear=True))
    (goal,) = s.goals
    assert sorted(goal.frequencies_hz) == [70e3, 110e3, 150e3]
    assert goal.max_error_m < 0.01e-6
    assert goal.model == "linear calibration gains"


def test_model_tones_surround_every_direction_of_the_circle(design):
    from acl.schedule.gains import model_gain_table
    from acl.schedule.tones import reach

    goal = compile_program(design, "circle", CompileOptions(resim_points=5, allow_nonlinear=True)).goals[0]
    g = model_gain_table(design, "module").at(goal.frequencies_hz).T        # (3, 2)
    a = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    assert reach(g[None], np.column_stack([np.cos(a), np.sin(a)])).min() > 0
    assert goal.details["tone_margin"] >= 1


def test_every_segment_respects_the_voltage_limit(design):
    s = compile_program(design, "epfl", CompileOptions(resim_points=2, allow_nonlinear=True))
    assert max(seg.peak_v for seg in s.segments) <= s.max_voltage_v


def test_out_of_reach_path_is_an_infeasible_diagnostic_naming_goal_waypoint_and_relaxation(design):
    with pytest.raises(DiagnosticError) as exc:
        compile_program(design, "far")
    d = exc.value.diagnostics[0]
    assert d.code == "E-SCHED-INFEASIBLE"
    assert "follow module" in d.message and "waypoint" in d.message
    assert d.span.line == 23
    assert "max voltage" in d.hint


def test_waypoints_the_forward_model_cannot_settle_are_counted_not_averaged(design):
    def flaky(design, capsule, freqs):
        def forward(u):
            out = np.zeros((u.shape[0], 2))
            out[::2] = np.nan                                  # every other waypoint "snaps"
            return out
        return forward, "flaky"

    s = compile_program(design, "circle", CompileOptions(forward_provider=flaky, resim_points=10, allow_nonlinear=True))
    goal = s.goals[0]
    assert goal.details["unconverged_waypoints"] == 5
    assert np.isfinite(goal.rms_error_m) and any("no stable equilibrium" in n for n in s.notes)
    assert goal.max_error_m == np.inf          # not the largest error of the waypoints that settled
