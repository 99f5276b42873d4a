"""Intervals of a fit stopped at a jump (a snap-in fold), and the bound warning on a log-spaced range.

A pair fit (Fig. 4 pair-hold study, seed 1: 15 rows of a 1..3 V ramp) stopped with gamma where one row's model
value jumps (the pair snaps in between gamma and gamma + the finite-difference step).  That row's slope, a jump over
the step, was the largest row norm, so every other row looked negligible and nothing was set aside: gamma's 95 %
interval came out +-4e-9 relative, and the calibrated design declared it so.  acl.fit.solve now checks rows far above
the median slope at a 100x smaller step.
"""
import numpy as np

from acl.fit import solve

X = np.linspace(1.0, 2.0, 12)
A_TRUE, A_STAR = 2.0, 1.9           # the smooth rows want a = 2; the step row forbids a >= 1.9


def _model(coeffs, _effects):
    a = coeffs["gain"]
    smooth = a * X * 1e-6
    step = np.array([50e-6 if a >= A_STAR else 0.0])     # 50 sigma (unit sigma 1 um) once a reaches the fold
    return np.concatenate([smooth, step])


def _data():
    rng = np.random.default_rng(3)
    y = np.concatenate([A_TRUE * X * 1e-6 + rng.normal(0, 0.05e-6, X.size), [0.0]])
    return y, np.full(y.size, 0.05e-6)


def test_a_jump_inside_the_step_does_not_shrink_the_interval():
    y, sigma = _data()
    coef = solve.Coef("gain", "gain", 1.0, 0.01, 100.0, 1.0)
    r = solve.fit(_model, y, sigma, [coef])
    assert A_STAR - 1e-3 < r.values[0] < A_STAR            # the fit parks at the fold (what the test is about)
    # the interval of the smooth rows alone: sigma / sqrt(sum x^2), scaled by the reduced chi-square
    smooth_se = 0.05e-6 / np.sqrt(np.sum((X * 1e-6) ** 2)) * np.sqrt(r.redchi)
    assert 0.5 < r.stderr[0] / smooth_se < 2.0, (r.stderr[0], smooth_se)
    assert any("nearly singular" in w for w in r.warnings)


def test_bound_warning_is_on_the_log_scale():
    # bounds 1e-3 .. 1e3 of the start: a value at 0.07x the start is far from both ends (it was "at a bound")
    y = 0.07 * X * 1e-6
    coef = solve.Coef("gain", "gain", 1.0, 1e-3, 1e3, 1.0)
    r = solve.fit(lambda c, e: c["gain"] * X * 1e-6, y, np.full(X.size, 0.01e-6), [coef])
    assert abs(r.values[0] - 0.07) < 1e-6
    assert not any("at a bound" in w for w in r.warnings), r.warnings
    # and a value that does sit at its lower bound is still said
    y = 1e-3 * X * 1e-6 - 1e-9
    r = solve.fit(lambda c, e: c["gain"] * X * 1e-6, y, np.full(X.size, 0.01e-6), [solve.Coef("gain", "gain", 1.0, 1e-3, 1e3, 1.0)])
    assert any("at a bound" in w for w in r.warnings), r.warnings
