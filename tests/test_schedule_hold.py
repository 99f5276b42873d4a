"""Holding a gap above snap-in or crossing it (acl.schedule.hold)."""
import numpy as np
import pytest

from acl.schedule.hold import HoldInfeasible, plan_hold
from acl.schedule.path import DriveLimits

V_SNAP = np.array([6.0, np.inf, 9.0])        # per tone alone; the middle tone never snaps the pair


def test_hold_above_drives_hard_but_stays_below_snap_in_by_the_margin():
    plan = plan_hold("above", DriveLimits(20.0), v_snap=V_SNAP, margin=1.2)
    # the margin is on voltage: the drive scaled by 1.2 reaches at most the snap index 1
    assert plan.snap_index <= 1 / 1.2 ** 2 + 1e-6
    assert plan.u.sum() > 0


def test_hold_above_puts_the_drive_on_the_tone_that_cannot_snap():
    plan = plan_hold("above", DriveLimits(20.0), v_snap=V_SNAP)
    assert np.argmax(plan.u) == 1


def test_cross_uses_the_least_drive_beyond_snap_in():
    plan = plan_hold("cross", DriveLimits(20.0), v_snap=V_SNAP, margin=1.1)
    assert plan.snap_index >= 1.1 ** 2 - 1e-6
    # cheapest: the 6 V tone alone, at 1.1 x its snap-in voltage (the margin is on voltage)
    assert np.sqrt(plan.u.sum()) == pytest.approx(1.1 * 6.0, rel=1e-4)


def test_cross_beyond_the_amplitude_limit_is_infeasible():
    with pytest.raises(HoldInfeasible) as exc:
        plan_hold("cross", DriveLimits(5.0), v_snap=V_SNAP)
    assert "amplitude" in exc.value.binding[0]


def test_linearised_gap_bound_is_respected():
    plan = plan_hold("above", DriveLimits(20.0), gap0=30e-6, dgap=np.array([-0.1e-6, -0.05e-6]),
                     bound=20e-6)
    assert plan.gap_m >= 20e-6 - 1e-12
