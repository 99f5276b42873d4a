"""acl.physics.roots.brentq: Brent's method (Brent 1973, ch. 4) without importing scipy.optimize."""
import math

import numpy as np
import pytest

from acl.physics.roots import brentq

FUNCTIONS = [lambda x: x**3 - 2 * x - 5, lambda x: math.cos(x) - x, lambda x: math.exp(x) - 10,
             lambda x: (x - 1.3) ** 5, lambda x: 1e-9 * math.atan(x - 0.7),
             lambda x: x - 0.25 if x < 0.5 else x - 0.25 + 1e3 * (x - 0.5)]


@pytest.mark.parametrize("k", range(len(FUNCTIONS)))
def test_brentq_returns_scipys_root_to_the_last_bit(k):
    # Same iteration as scipy.optimize.brentq: identical floats over random brackets and tolerances.
    scipy_brentq = pytest.importorskip("scipy.optimize").brentq
    f = FUNCTIONS[k]
    rng = np.random.default_rng(k)
    for _ in range(60):
        a, b = rng.uniform(-3, 1), rng.uniform(1.5, 5)
        xtol, rtol = 10 ** rng.uniform(-15, -3), 10 ** rng.uniform(-15.3, -6)
        try:
            expect = scipy_brentq(f, a, b, xtol=xtol, rtol=rtol)
        except (ValueError, RuntimeError):
            with pytest.raises((ValueError, RuntimeError)):
                brentq(f, a, b, xtol=xtol, rtol=rtol)
            continue
        assert brentq(f, a, b, xtol=xtol, rtol=rtol) == expect


def test_brentq_meets_its_tolerance_and_rejects_a_bad_bracket():
    root = brentq(lambda x: x * x - 2, 0.0, 2.0, xtol=1e-14)
    assert abs(root - math.sqrt(2)) <= 1e-14 + 4 * 2.22e-16 * math.sqrt(2)
    with pytest.raises(ValueError):
        brentq(lambda x: x * x + 1, -1.0, 1.0)
    with pytest.raises(ValueError):
        brentq(lambda x: float("nan"), 0.0, 1.0)
