"""The path-following convex program (acl.schedule.path) on plain arrays."""
import numpy as np
import pytest

from acl.schedule.path import UM, DriveLimits, PathInfeasible, _build, plan_path

# three tones pushing at 0, 120 and 240 degrees, 1 um per 100 V^2 (a documented fake calibration)
G = np.array([[1.0, -0.5, -0.5], [0.0, np.sqrt(3) / 2, -np.sqrt(3) / 2]]) * UM / 100


def circle(n, r=0.5 * UM, c=(0.2 * UM, 0.0)):
    """(n, 2) waypoints on a circle, in the units of r and c."""
    a = np.linspace(0, 2 * np.pi, n)
    return np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])


def test_reachable_path_is_tracked_within_a_few_nanometres():
    plan = plan_path(G, circle(100), 0.01, DriveLimits(20.0))
    assert plan.result.ok
    assert plan.error.max() < 5e-9


def test_power_is_nonnegative_and_total_amplitude_never_exceeds_the_limit():
    plan = plan_path(G, circle(100, r=0.6, c=(0.0, 0.0)) * UM, 0.01, DriveLimits(20.0))
    assert plan.u.min() >= 0
    assert plan.amplitudes.sum(axis=0).max() <= 20.0 * (1 + 1e-6)


def test_more_drive_weight_trades_tracking_for_less_power():
    light = plan_path(G, circle(60), 0.01, DriveLimits(20.0), lam=1e-4)
    heavy = plan_path(G, circle(60), 0.01, DriveLimits(20.0), lam=0.5)
    assert heavy.u.sum() < light.u.sum()
    assert heavy.error.mean() > light.error.mean()


def test_slew_limit_on_voltage_holds_exactly_with_the_exact_model():
    dt, slew = 1e-3, 150.0
    plan = plan_path(G, circle(200), dt, DriveLimits(20.0, slew_rate=slew), slew_model="exact")
    assert plan.max_slew_v_per_s(dt) <= slew * (1 + 1e-4)


def test_auto_slew_falls_back_to_exact_cones_when_the_qp_relaxation_violates_the_limit():
    dt, slew = 1e-3, 150.0
    relaxed = plan_path(G, circle(200), dt, DriveLimits(20.0, slew_rate=slew), slew_model="linear")
    auto = plan_path(G, circle(200), dt, DriveLimits(20.0, slew_rate=slew))
    assert relaxed.max_slew_v_per_s(dt) > slew          # the relaxation alone is not enough here
    assert auto.max_slew_v_per_s(dt) <= slew * (1 + 1e-4)
    assert any("exact" in n for n in auto.notes)


def test_whole_path_is_one_problem_and_reaches_the_solver_as_a_qp():
    import cvxpy as cp

    prob, X, _ = _build(G, circle(500), 0.01, DriveLimits(20.0, slew_rate=1e4), 0.5 * UM, None,
                        1e-3, "linear")
    assert X.shape == (3, 500)
    assert prob.is_dcp() and prob.is_qp()
    data, _, _ = prob.get_problem_data(cp.CLARABEL)
    assert data["P"].nnz > 0                             # quadratic objective, not a cone epigraph


def test_out_of_reach_waypoint_is_diagnosed_with_its_index_and_the_binding_limit():
    pts = circle(50, r=0.2 * UM)
    # at 60 degrees, between the 0 and 120 degree tones: 250 V^2 on each, 15.8 V + 15.8 V > 20 V
    pts[30] = 2.5 * UM * np.array([0.5, np.sqrt(3) / 2])
    with pytest.raises(PathInfeasible) as exc:
        plan_path(G, pts, 0.01, DriveLimits(20.0))
    d = exc.value.diagnosis
    assert d.waypoint == 30
    assert np.isclose(d.time_s, 0.30)
    assert any("total amplitude" in b for b in d.binding)
    assert any("max voltage" in r for r in d.relax)


def test_direction_outside_the_cone_of_two_tones_is_diagnosed_as_such():
    two = G[:, :2]                                       # 0 and 120 degrees only
    pts = np.array([[0.1 * UM, 0.1 * UM], [0.0, -2 * UM]])
    with pytest.raises(PathInfeasible) as exc:
        plan_path(two, pts, 0.01, DriveLimits(20.0))
    assert exc.value.diagnosis.waypoint == 1
    assert any("cone" in b for b in exc.value.diagnosis.binding)


def test_too_tight_slew_is_diagnosed_at_the_first_waypoint_it_cannot_follow():
    pts = np.array([[0.1 * UM, 0.0]] * 10 + [[1.0 * UM, 0.0]] * 10)   # a jump at waypoint 10
    with pytest.raises(PathInfeasible) as exc:
        plan_path(G, pts, 1e-3, DriveLimits(20.0, slew_rate=100.0), tolerance=0.05 * UM)
    d = exc.value.diagnosis
    assert d.waypoint == 10
    assert any("slew" in b for b in d.binding)


def test_total_amplitude_refinement_stays_within_the_true_limit_and_never_raises_the_drive():
    pts = circle(80, r=0.6 * UM, c=(0.0, 0.0))
    base = plan_path(G, pts, 0.01, DriveLimits(20.0))
    refined = plan_path(G, pts, 0.01, DriveLimits(20.0), refine=2)
    assert refined.amplitudes.sum(axis=0).max() <= 20.0 * (1 + 1e-6)
    assert refined.u.sum() <= base.u.sum() * (1 + 1e-6)
    assert refined.error.max() <= 0.5 * UM * np.sqrt(2)


def test_a_single_tone_may_use_nearly_the_whole_limit_thanks_to_the_tangent_retry():
    pts = circle(20, r=0.2 * UM)
    pts[10] = (3 * UM, 0.0)          # 300 V^2 = 17.3 V on one tone: beyond Vmax^2/K, within Vmax
    plan = plan_path(G, pts, 0.01, DriveLimits(20.0))
    assert plan.error.max() <= 0.5 * UM * np.sqrt(2)
    assert plan.amplitudes.sum(axis=0).max() <= 20.0 * (1 + 1e-6)
    assert any("tangent" in n for n in plan.notes)
