"""Switching latches as an LP (acl.schedule.latch), as paper Fig. 6e."""
import numpy as np
import pytest

from acl.schedule.latch import SwitchInfeasible, plan_switch
from acl.schedule.path import DriveLimits

NN = 1e-9
TONES = (85e3, 125e3, 170e3)
# latch 0 (Fig. 6e): its 85 kHz capsule pushes towards b, its 170 kHz capsule back towards a.
# latch 1: a neighbour that 125 kHz pushes towards b and 85 kHz a little.
FORCES = np.array([[+1.0, 0.05, -0.8],
                   [+0.2, 1.0, 0.0]]) * NN            # N per V^2
TO_B = np.array([40.0, 60.0]) * NN                    # switching forces a -> b
TO_A = np.array([30.0, 50.0]) * NN                    # release forces b -> a


def switch(states, target, new, margin=1.2, vmax=20.0, forces=FORCES):
    return plan_switch(forces, TO_B, TO_A, states, ["gate", "other"], target, new, margin, DriveLimits(vmax))


def test_switching_reaches_the_required_margin_with_the_forward_tone():
    plan = switch(["a", "a"], 0, "b")
    assert plan.target_force >= 1.2 * 40 * NN * (1 - 1e-6)
    assert plan.amplitudes[0] == max(plan.amplitudes)          # 85 kHz does the work


def test_other_latches_stay_below_their_switching_force_over_margin():
    plan = switch(["a", "a"], 0, "b")
    assert plan.other_ratios[1] <= 1 / 1.2 + 1e-6


def test_release_uses_the_second_frequency():
    plan = switch(["b", "a"], 0, "a")
    assert plan.amplitudes[2] == max(plan.amplitudes)          # 170 kHz pushes back
    assert plan.target_force >= 1.2 * 30 * NN * (1 - 1e-6)


def test_least_drive_is_used():
    plan = switch(["a", "a"], 0, "b")
    # 85 kHz alone: u = 1.2 * 40 / 1.0 = 48 V^2 is the cheapest way
    assert plan.u.sum() == pytest.approx(48.0, rel=1e-4)


def test_too_little_voltage_names_the_amplitude_limit():
    with pytest.raises(SwitchInfeasible) as exc:
        switch(["a", "a"], 0, "b", vmax=5.0)
    assert "amplitude limits" in exc.value.binding[0]
    assert any("max voltage" in r for r in exc.value.relax)


def test_crosstalk_names_the_latch_that_would_switch_too():
    crosstalk = np.array([[1.0, 0.0, 0.0], [1.5, 1.0, 0.0]]) * NN    # 85 kHz switches `other` first
    with pytest.raises(SwitchInfeasible) as exc:
        switch(["a", "a"], 0, "b", forces=crosstalk)
    assert any("`other`" in b for b in exc.value.binding)


def test_an_extra_row_keeps_the_targets_push_back_below_its_limit():
    """``extra`` (the compiler's push back from the wanted state, where the latch may be already): the cheapest tone
    for the switch (85 kHz) pushes back from state b at 0.9 nN per V^2 there (its capsule faces a neighbour that
    repels it in b); with the row its push back must stay below 30 nN / 1.2, and the 125 kHz-like second tone does it."""
    forces = np.array([[+1.0, 0.5, 0.0]]) * NN
    extra = [(np.array([0.9, -0.2, 0.0]) * NN, 30.0 * NN)]      # push towards a, per V^2, in state b; release force
    free = plan_switch(forces, TO_B[:1], TO_A[:1], ["a"], ["gate"], 0, "b", 1.2, DriveLimits(20.0))
    held = plan_switch(forces, TO_B[:1], TO_A[:1], ["a"], ["gate"], 0, "b", 1.2, DriveLimits(20.0), extra=extra)
    assert free.amplitudes[0] == max(free.amplitudes)
    assert float(extra[0][0] @ free.u) > 30 * NN / 1.2            # without it the plan would push back
    assert float(extra[0][0] @ held.u) <= 30 * NN / 1.2 * (1 + 1e-6)
    assert held.target_force >= 1.2 * 40 * NN * (1 - 1e-6)
    assert held.u.sum() > free.u.sum()                             # a dearer drive, the price of staying put
