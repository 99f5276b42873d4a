"""Tone choice from a gain table (acl.schedule.tones)."""
import numpy as np
import pytest

from acl.schedule.tones import GainTable, choose_tones, reach

UM = 1e-6


def fake_sweep():
    """A Fig. S4a-like sweep: three resonances pushing at 10, 130 and 250 degrees, plus weak noise floor."""
    f = np.arange(40e3, 160.5e3, 500.0)
    g = np.zeros((f.size, 2))
    for f0, ang in ((60e3, 10), (95e3, 130), (140e3, 250)):
        amp = 1.0 / (1 + ((f - f0) / 3e3) ** 2)
        g += amp[:, None] * [np.cos(np.radians(ang)), np.sin(np.radians(ang))]
    g += 0.01 * np.column_stack([np.ones_like(f), np.zeros_like(f)])   # weak +x everywhere
    return GainTable(f, g * UM / 100)


def test_chosen_tones_are_the_three_resonances_for_a_path_around_the_rest_position():
    a = np.linspace(0, 2 * np.pi, 50)
    path = np.column_stack([np.cos(a), np.sin(a)]) * 0.3 * UM
    choice = choose_tones(fake_sweep(), path, max_voltage=20.0)
    assert sorted(choice.frequencies) == [60e3, 95e3, 140e3]
    assert choice.margin >= 1


def test_a_path_along_one_direction_prefers_the_tone_pointing_that_way():
    path = np.column_stack([np.linspace(0.1, 1.0, 10), np.zeros(10)]) * UM * np.cos(np.radians(10))
    choice = choose_tones(fake_sweep(), path, max_voltage=20.0, k=1)
    assert choice.frequencies == (60e3,)


def test_pinned_tones_are_kept_and_scored():
    path = np.array([[0.0, -0.5 * UM]])
    choice = choose_tones(fake_sweep(), path, max_voltage=20.0, pinned=(60e3, 95e3))
    assert choice.frequencies == (60e3, 95e3)
    assert choice.margin == 0.0                          # -y lies outside the cone of 10 and 130 deg


def test_reach_is_the_hull_boundary_and_zero_outside_the_cone():
    v = np.array([[[1.0, 0.0], [0.0, 1.0]]])             # hull of 0, e_x, e_y
    d = np.array([[1.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5)], [-1.0, 0.0]])
    r = reach(v, d)[0]
    assert r[0] == pytest.approx(1.0)
    assert r[1] == pytest.approx(np.sqrt(0.5))
    assert r[2] == 0.0


def test_measured_tones_that_reach_the_path_are_chosen_over_stronger_guessed_ones():
    """A calibrated design measured the gain at some tones (measured(gain)): when k of them reach every waypoint, the
    compile plays them, not a tone the table's prior merely rates stronger (issue 28: a recompile moved from the
    measured 128.5 kHz to the table point 125 kHz, whose gain keeps its 30 % prior)."""
    a = np.linspace(0, 2 * np.pi, 50)
    path = np.column_stack([np.cos(a), np.sin(a)]) * 0.3 * UM
    measured = (61e3, 94e3, 141e3, 150e3)                 # near the resonances, weaker than their peaks
    choice = choose_tones(fake_sweep(), path, max_voltage=20.0, measured=measured)
    assert sorted(choice.frequencies) == [61e3, 94e3, 141e3] and choice.margin >= 1
    free = choose_tones(fake_sweep(), path, max_voltage=20.0)
    assert free.score > choice.score                      # unmeasured, the peaks would have won
    # measured tones that cannot reach the path together (all pushing one way): as many as reach with table tones
    mixed = choose_tones(fake_sweep(), path, 20.0, measured=(58e3, 60e3, 62e3))
    assert sorted(mixed.frequencies) == [60e3, 95e3, 140e3] and mixed.margin >= 1
    mixed = choose_tones(fake_sweep(), path, 20.0, measured=(61e3, 94e3))
    assert sorted(mixed.frequencies) == [61e3, 94e3, 140e3] and mixed.margin >= 1
    # none of them reaches with any other two: the whole table decides
    weak = choose_tones(fake_sweep(), path, 20.0, measured=(45e3,))
    assert sorted(weak.frequencies) == [60e3, 95e3, 140e3]
    # pinned tones (`using [...]`) still win over measured ones
    assert choose_tones(fake_sweep(), path, 20.0, pinned=(60e3, 95e3, 140e3), measured=measured).frequencies == \
        (60e3, 95e3, 140e3)


def test_a_measured_set_beyond_the_conservative_reach_is_offered_by_its_outer_bound():
    """measured_choice: k measured tones whose conservative polygon (budget Vmax^2/k) misses the path but whose outer
    bound conv{0, g_i Vmax^2} (every drive of summed amplitude <= Vmax lies inside) contains it are offered, to be
    planned first (acl.schedule.steps.follow falls back to choose_tones when the plan is infeasible); a path beyond
    the outer bound gets none."""
    from acl.schedule.tones import measured_choice, measured_count

    a = np.linspace(0, 2 * np.pi, 50)
    table = fake_sweep()
    measured = (61e3, 94e3, 141e3)
    g = np.linalg.norm(table.at(measured), axis=0).min() * 400.0     # the weakest measured tone's reach at 20 V
    path = np.column_stack([np.cos(a), np.sin(a)]) * 0.3 * g
    strict = choose_tones(table, path, 20.0, measured=measured)
    assert measured_count(strict, measured) < 3                      # beyond the conservative reach of all three
    more = measured_choice(table, path, 20.0, 3, measured, measured_count(strict, measured) + 1)
    assert more is not None and more.frequencies == measured and more.margin >= 1
    assert measured_choice(table, path * 10, 20.0, 3, measured) is None
