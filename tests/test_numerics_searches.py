"""acl.physics.roots: the batched golden section, grid refinement, bracketing and Illinois searches, against closed forms."""
import math

import numpy as np

from acl.physics.roots import (first_sign_change, golden_max, grid_max, illinois, illinois_ascending,
                               illinois_step)


def test_golden_max_finds_the_peak_of_each_element_to_its_bracket_width():
    rng = np.random.default_rng(1)
    peak = rng.uniform(-2, 3, 50)
    width = rng.uniform(0.1, 2, 50)
    lo, hi = peak - rng.uniform(0.01, 1, 50) * 4, peak + rng.uniform(0.01, 1, 50) * 4
    value, x = golden_max(lambda s: -np.abs(s - peak) / width + 1.0, lo, hi, iterations=80)  # a kink at the peak
    assert np.all(np.abs(x - peak) <= 1e-12 * (hi - lo) + 1e-14)
    assert np.allclose(value, 1.0, atol=1e-11)


def test_golden_max_scalar_and_batched_paths_agree_and_rtol_stops():
    f = lambda s: math.sin(s) if np.ndim(s) == 0 else np.sin(s)  # noqa: E731
    v1, x1 = golden_max(f, 0.5, 2.9, iterations=50)
    vb, xb = golden_max(f, np.array([0.5, 0.5]), np.array([2.9, 2.9]), iterations=50)
    assert isinstance(v1, float) and v1 == vb[0] == vb[1] and x1 == xb[0]
    assert abs(x1 - math.pi / 2) < 3e-8        # a smooth peak: x to ~sqrt(machine eps)
    calls = []
    golden_max(lambda s: calls.append(s) or math.sin(s), 0.5, 2.9, iterations=200, rtol=1e-6)
    assert 20 < len(calls) < 40              # (2.4 / 1e-6) shrinks by 0.618 per step: ~31 steps, not 200
    v, x = golden_max(np.sin, np.array([0.5, 1.0]), np.array([2.9, 2.0]), iterations=200, rtol=1e-9)
    assert np.allclose(x, math.pi / 2, atol=3e-8)


def test_golden_max_hands_the_state_of_the_probing_point_on():
    # state = the point itself, so the state returned with the best point must be that point
    def fn(s, st):
        assert st.shape == s.shape
        return -(s - 1.2) ** 2, s.copy()
    v, x, st = golden_max(fn, np.zeros(3), np.full(3, 2.0), iterations=40, state=np.zeros(3))
    assert np.array_equal(st, x) and np.allclose(x, 1.2, atol=1e-7)


def test_grid_max_refines_between_grid_points_and_never_goes_below_the_grid():
    grid = np.linspace(0, 1, 11)
    f = lambda s: -(s - 0.537) ** 2  # noqa: E731
    v, x = grid_max(f, grid, f(grid))
    assert abs(x - 0.537) < 1e-7 and v >= f(grid).max()
    # limits: the maximum of the first half only (grid indices 0 .. 4): 0.4 or inside (0.3, 0.5)
    v, x = grid_max(f, grid, f(grid), 0, 5)
    assert 0.3 <= x <= 0.5 and v >= f(0.4)
    # batched rows, each its own peak
    peaks = np.array([0.11, 0.5, 0.93])
    G = np.broadcast_to(grid, (3, 11))
    v, x = grid_max(lambda s: -np.abs(s - peaks), G, -np.abs(G - peaks[:, None]))
    assert np.allclose(x, peaks, atol=1e-9)


def test_first_sign_change_brackets_the_first_root():
    x = np.linspace(0, 10, 101)
    rows = np.stack([np.sin(x), np.cos(x), np.ones_like(x)])
    found, k = first_sign_change(rows)
    assert list(found) == [True, True, False]
    assert x[k[0]] < math.pi <= x[k[0] + 1] and x[k[1]] < math.pi / 2 <= x[k[1] + 1]


def test_illinois_converges_superlinearly_inside_the_bracket():
    c = np.array([2.0, 3.0, 10.0])
    g = lambda s: s**3 - c  # noqa: E731
    a, b = np.zeros(3), np.full(3, 4.0)
    root, gr = illinois(g, a, g(a), b, g(b), iterations=60, ftol=1e-14)
    assert np.allclose(root, np.cbrt(c), rtol=1e-13) and np.all(np.abs(gr) <= 1e-12)
    steps = []
    illinois(lambda s: steps.append(1) or g(s), a, g(a), b, g(b), iterations=200, ftol=1e-13)
    assert len(steps) < 30                   # bisection would take ~45 steps to 1e-13
    cc, fc, flip = illinois_step(g, a, g(a), b, g(b))
    assert np.all((cc >= a) & (cc <= b)) and np.array_equal(fc, g(cc))


def test_illinois_ascending_solves_a_rising_function_with_a_warm_state():
    target = np.array([0.3, 0.7, 1.1])
    hi = np.full(3, 2.0)
    f = lambda s, st: (np.tanh(s - target), s)  # noqa: E731
    s, fs, st = illinois_ascending(f, np.zeros(3), hi, np.tanh(-target), np.tanh(hi - target), 60, 1e-14, 1e-15,
                                   state=np.zeros(3))
    assert np.allclose(s, target, atol=1e-12) and np.array_equal(st, s)
