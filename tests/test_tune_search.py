"""acl.sweep.tune's search and statistics on problems whose answer is known in closed form."""
from __future__ import annotations

import math

import numpy as np
import pytest

from acl.sweep.tune import Estimate, Free, clopper_pearson, maximise, passing, require_margins, rounded


class _Req:
    def __init__(self, lower=None, upper=None):
        self.lower, self.upper = lower, upper


def _window_problem(n: int = 2000, sd: float = 0.3, seed: int = 1):
    """Two dimensions x1, x2 printed with N(0, sd) errors (common random numbers): x1 + e1 must lie in
    2 .. 8 and (x2 + e2) - (x1 + e1) must be >= 3. Best: x1 well inside its window, x2 >= x1 + 3 + margin."""
    z = np.random.default_rng(seed).normal(0.0, sd, (n, 2))
    reqs = [_Req(2.0, 8.0), _Req(3.0, None)]

    def evaluate(x):
        v1 = x[0] + z[:, 0]
        v2 = (x[1] + z[:, 1]) - v1
        return require_margins(reqs, [v1, v2])

    return evaluate


FREE = (Free("x1", "", 0.0, 10.0, 2.2), Free("x2", "", 0.0, 10.0, 5.3))


def test_clopper_pearson_matches_the_beta_quantiles_and_brackets_the_estimate():
    lo, hi = clopper_pearson(93, 100)
    assert 0.86 < lo < 0.93 < hi < 0.975
    # exact interval of k = 0: upper bound 1 - (alpha/2)^(1/n)
    assert clopper_pearson(0, 50) == (0.0, pytest.approx(1 - 0.025 ** (1 / 50)))
    assert clopper_pearson(50, 50)[1] == 1.0
    assert Estimate(93, 100).text() == f"0.930 [{lo:.3f}, {hi:.3f}]"


def test_margins_are_value_minus_the_nearer_bound_and_nan_fails():
    m = require_margins([_Req(1.0, 3.0), _Req(None, 5.0)], [np.array([2.5, 0.5, np.nan]), np.array([4.0, 6.0, 1.0])])
    assert np.allclose(m[:2], [[0.5, 1.0], [-0.5, -1.0]]) and np.isnan(m[2, 0])
    assert passing(m).tolist() == [True, False, False]


@pytest.mark.parametrize("method", ["nelder-mead", "powell", "differential-evolution"])
def test_search_raises_the_yield_of_a_known_problem_to_nearly_one(method):
    evaluate = _window_problem()
    start = passing(evaluate(np.array([f.start for f in FREE]))).mean()
    found = maximise(evaluate, FREE, method=method, max_evals=150)
    after = passing(evaluate(found.x)).mean()
    assert start < 0.5 and after > 0.995, (start, after, found.x)
    assert found.evaluations <= 150
    x1, x2 = found.x
    assert 2.9 < x1 < 7.1 and x2 - x1 > 3.9            # > 3 sd (0.42 for the difference) inside both limits


def test_worst_case_margin_objective_centres_the_window():
    evaluate = _window_problem(n=500)
    found = maximise(evaluate, FREE, objective="margin", max_evals=200)
    worst = evaluate(found.x).min(axis=0)
    # x1's window is 6 wide: the worst case is best with x1 near the centre (x2 has room above)
    assert 4.0 < found.x[0] < 6.5 and worst.min() > 1.0


def test_progress_reports_every_trial_with_the_best_yield_so_far():
    evaluate = _window_problem(n=300)
    calls = []
    found = maximise(evaluate, FREE, max_evals=30, progress=lambda d, t, best: calls.append((d, t, best)))
    assert [c[0] for c in calls] == list(range(1, found.evaluations + 1)) and {c[1] for c in calls} == {30}
    bests = [c[2] for c in calls]
    assert bests == sorted(bests) and 0 <= bests[0] <= bests[-1] <= 1


def test_search_never_returns_worse_than_the_start():
    evaluate = _window_problem()
    good = (Free("x1", "", 0.0, 10.0, 5.0), Free("x2", "", 0.0, 10.0, 9.5))
    found = maximise(evaluate, good, max_evals=20)
    assert passing(evaluate(found.x)).mean() >= passing(evaluate(np.array([5.0, 9.5]))).mean()


def test_values_are_rounded_as_written():
    assert rounded(np.array([1.23456789e-5]))[0] == 1.23457e-5
    assert math.isclose(float(f"{rounded(np.array([13.08712345e-6]))[0] * 1e6:.6g}"), 13.0871)
