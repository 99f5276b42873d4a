"""The shortcuts of the fit's forward model against the plain computation (benchmarks/fit.py case 3, issue 9).

The fast paths (acl.fit.forward: each distinct row predicted once, a pair solve reused when its inputs are bitwise the same, the bracket grid read
only up to each row's last cell, predictions memoized; acl.fit.solve.fd_least_squares: the Jacobian's columns made
inside FD_COLUMNS) must give the plain solve's numbers bit for bit.  The opt-in warm start (ForwardOptions.warm) must give
finite-difference columns equal to the plain ones to the solver tolerance.  A small pair + calibration beam data
set, with and without neighbour drag (an iterated deflection law).  These shortcuts belong to the paper's Eq. (3)
pair solve (acl.fit.eq3), the reduced model a user asks for (``model="eq3"``): the data sets are made with it."""
from __future__ import annotations

import os

import numpy as np
import pytest

from acl.fit import eq3 as E3
from acl.fit import forward as F
from acl.fit import solve
from acl.fit.synth import Experiment, generate

HERE = os.path.dirname(__file__)
PAIR_CAL = os.path.join(HERE, "..", "samples", "fit_pair_cal.acl")
EX = [Experiment(frequencies=(120e3, 130e3), voltages=tuple(np.linspace(0, 4, 7)), observables=("distance",),
                 sets={"gap": ["40 um", "60 um"]}, label="pair"),
      Experiment(frequencies=(120e3, 130e3), voltages=tuple(np.linspace(0, 11, 4)), observables=("cal",),
                 label="calibration")]
DRAG = {"neighbour_drag": {"inv_plateau": 1.0 / 8e-6}}


@pytest.fixture(scope="module")
def pair_cal():
    data, P = generate(PAIR_CAL, EX, {"neighbour_drag": {"plateau": 8e-6}}, noise=0.2e-6, seed=3, model="eq3")
    assert np.any(P.pair) and np.any(~P.pair)
    return data, P


def _plain(P, coeffs, effects):
    """The forward model with every shortcut off: no memo, every row solved (no distinct-row reduction), no reused or
    guided pair solve."""
    old = P.options
    P.options = F.ForwardOptions(memo=0, dedup=False, warm=old.warm)
    try:
        P.__dict__.pop("_eq_cache", None)
        return F.predict(P, coeffs, effects)
    finally:
        P.options = old


def _columns(P, coeffs, effects, steps, warm=False):
    """Base prediction, then one prediction per perturbation inside FD_COLUMNS (as the Jacobian makes them)."""
    P.__dict__.pop("_eq_cache", None)
    P.__dict__.pop("_memo", None)
    old = P.options
    P.options = F.ForwardOptions(memo=old.memo, dedup=old.dedup, warm=warm)
    try:
        base = F.predict(P, coeffs, effects)
        out = []
        for co, ef in steps:
            with E3.FD_COLUMNS:
                out.append(F.predict(P, co, ef))
        return base, out
    finally:
        P.options = old


def _steps(P, effects, h=1e-6):
    co = {"gamma": P.gamma0 * 1.3, "alpha": P.alpha0 * 0.8}
    steps = [({**co, "gamma": co["gamma"] * (1 + h)}, effects), ({**co, "alpha": co["alpha"] * (1 + h)}, effects)]
    for e, ps in effects.items():
        for k, v in ps.items():
            steps.append((co, {**effects, e: {**ps, k: v * (1 + h)}}))
    # a parameter that cannot move the pair rows (an offset): the pair solve is reused as it is
    steps.append((co, {**effects, "offset_drift": {"offset": 1e-9, "drift": 0.0}}))
    return co, steps


@pytest.mark.parametrize("effects", [{}, DRAG], ids=["eq1", "drag"])
def test_shortcut_columns_are_the_plain_solve_bit_for_bit(pair_cal, effects):
    _, P = pair_cal
    co, steps = _steps(P, effects)
    base, cols = _columns(P, co, effects, steps)
    np.testing.assert_array_equal(base, _plain(P, co, effects))
    for (c, e), col in zip(steps, cols):
        plain = _plain(P, c, e)
        np.testing.assert_array_equal(col, plain)
        assert np.any(col[P.pair] != base[P.pair]) or "offset_drift" in e     # the columns do move the pair rows


def test_fit_with_shortcuts_equals_the_plain_fit_bit_for_bit(pair_cal, monkeypatch):
    """solve.fit (fd_least_squares, memo, reused and guided pair solves) against the same fit with all of them off and
    scipy's own "2-point" Jacobian."""
    from scipy.optimize import least_squares

    data, P = pair_cal
    coefs = [solve.Coef("gamma", "gamma", P.gamma0, P.gamma0 / 1e3, P.gamma0 * 1e3, P.gamma0),
             solve.Coef("alpha", "alpha", P.alpha0, P.alpha0 / 1e3, P.alpha0 * 1e3, P.alpha0),
             solve.Coef("neighbour_drag.inv_plateau", "effect", 5e4, 0.0, 1e9, 1e5, effect="neighbour_drag",
                        param="inv_plateau")]
    P.__dict__.pop("_eq_cache", None)
    P.__dict__.pop("_memo", None)
    fast = solve.fit(lambda a, b: F.predict(P, a, b), data.value, data.sigma, coefs)

    def plain_lsq(fun, x0, *, bounds, diff_step, **kw):
        return least_squares(fun, x0, bounds=bounds, diff_step=diff_step, **kw)

    monkeypatch.setattr(solve, "fd_least_squares", plain_lsq)
    slow = solve.fit(lambda a, b: _plain(P, a, b), data.value, data.sigma, coefs)
    np.testing.assert_array_equal(fast.values, slow.values)
    np.testing.assert_array_equal(fast.prediction, slow.prediction)
    assert fast.chi2 == slow.chi2 and np.array_equal(fast.stderr, slow.stderr)


@pytest.mark.parametrize("effects", [{}, DRAG], ids=["eq1", "drag"])
def test_warm_start_columns_agree_with_the_plain_solve_to_its_tolerance(pair_cal, effects):
    """ForwardOptions.warm (opt-in): one Newton step from the last root.  The finite difference of each column (prediction
    minus base, ~1e-6 of the deflection) agrees with the plain solve's to 1e-5 of itself (the solve's tolerance is
    1e-12 of the gap); a warm start that kept the old root would give no difference on the pair rows at all."""
    _, P = pair_cal
    co, steps = _steps(P, effects)
    base, cols = _columns(P, co, effects, steps, warm=True)
    plain_base = _plain(P, co, effects)
    pair = P.pair
    for (c, e), col in zip(steps, cols):
        plain = _plain(P, c, e)
        dw, dp = (col - base)[pair], (plain - plain_base)[pair]
        scale = np.max(np.abs(dp))
        if "offset_drift" not in e:
            assert scale > 0
        np.testing.assert_allclose(dw, dp, rtol=0, atol=1e-5 * scale + 1e-20)


@pytest.mark.parametrize("effects", [{}, DRAG], ids=["eq1", "drag"])
def test_guided_and_reused_solves_follow_large_steps_bit_for_bit(pair_cal, effects):
    """Full solves guided by the previous one's bracketing cells (rows whose crossing moved to later cells, and back)
    and repeated points (memo, reuse) give the plain solve's numbers."""
    _, P = pair_cal
    P.__dict__.pop("_eq_cache", None)
    P.__dict__.pop("_memo", None)
    seen_more = []
    orig = E3._scan

    def spy(rows, npts, *a):
        seen_more.append(bool(np.all(npts == E3.N_GRID + 1)))
        return orig(rows, npts, *a)

    E3._scan = spy
    try:
        for gs, al in [(1.0, 1.0), (1.6, 0.7), (0.5, 1.5), (2.5, 1.0), (1.6, 0.7), (1.0, 1.0)]:
            co = {"gamma": P.gamma0 * gs, "alpha": P.alpha0 * al}
            np.testing.assert_array_equal(F.predict(P, co, effects), _plain(P, co, effects))   # (the plain solve leaves
            # its own cache: the next fast solve is guided by this point's cells)
    finally:
        E3._scan = orig
    if effects:            # the iterated law reads the grid from the guess, and past it where the crossing moved on
        assert seen_more and any(seen_more) and not all(seen_more)


REPEATED = [Experiment(frequencies=(120e3, 130e3), voltages=tuple(np.linspace(0, 4, 5)), observables=("distance",),
                       sets={"gap": ["40 um", "60 um"]}, repeats=3, label="pair"),
            Experiment(frequencies=(120e3, 130e3), voltages=tuple(np.linspace(0, 11, 4)), observables=("cal",),
                       repeats=4, label="calibration")]


@pytest.mark.parametrize("effects", [
    {}, DRAG, {"large_deflection": {"elastica_weight": 0.4}, **DRAG},
    {"drive_saturation": {"inv_vsat2": 0.05}, "offset_drift": {"offset": 2e-7, "drift": -3e-9}},
    {"bubble_shrinkage": {"shrink_rate": 2e-3}}, {"stiffness_scale": {"e_scale": 1.2}},
    {"transducer_resonance": {"inv_f_ratio": 0.5, "gain_q": 3.0}}], ids=lambda e: "+".join(e) or "base")
def test_distinct_rows_give_every_row_bit_for_bit(effects):
    """Repeated rows (the same drive, gap and design; times apart) are predicted once (forward._distinct): each row's
    number is the full prediction's, also with an offset drift (added per row after) and bubble shrinkage (which reads
    the time: every timed row is then its own)."""
    data, P = generate(PAIR_CAL, REPEATED, {}, noise=0.2e-6, seed=5, model="eq3")
    red = F._distinct(P, {})
    assert red is not None and red[0].n < P.n / 2            # the repeats are found (the times are ignored)
    co = {"gamma": P.gamma0 * 1.2, "alpha": P.alpha0 * 0.9}
    fast = F.predict(P, co, effects)
    plain = _plain(P, co, effects)
    np.testing.assert_array_equal(fast, plain)
    if "offset_drift" in effects:
        assert np.unique(fast).size > red[0].n                # the drift makes each timed row its own


@pytest.mark.parametrize("effects", [{}, DRAG, {"large_deflection": {"elastica_weight": 0.3}, **DRAG},
                                     {"large_deflection": {"elastica_weight": 0.0}},
                                     {"offset_drift": {"offset": 1e-7, "drift": 1e-9}},
                                     {"bubble_shrinkage": {"shrink_rate": 1e-3}}],
                         ids=["eq1", "drag", "elastica+drag", "elastica-at-null", "offset", "shrinkage"])
@pytest.mark.parametrize("inside", [True, False], ids=["columns", "probes"])
def test_predictions_made_at_once_are_the_one_by_one_predictions_bit_for_bit(effects, inside):
    """forward.predict_many (a Jacobian's columns inside FD_COLUMNS, the fold probes outside it): the pair solves of
    several predictions stacked, each stopped where its own solve stops, against the predictions one by one; with and
    without a kept solve to read (guided or whole grids), columns whose laws differ (an elastica weight stepped off
    its null value: solved apart), a column that leaves the pair rows alone (an offset: the kept solve reused), and
    repeated rows (REPEATED)."""
    data, P = generate(PAIR_CAL, REPEATED, {}, noise=0.2e-6, seed=5, model="eq3")
    rng = np.random.default_rng(4)
    for trial in range(4):
        co = {"gamma": P.gamma0 * rng.uniform(0.6, 1.6), "alpha": P.alpha0 * rng.uniform(0.6, 1.6)}
        for q in (P, *(r[0] for r in P.__dict__.get("_distinct", {}).values() if r)):
            q.__dict__.pop("_eq_cache", None)
            q.__dict__.pop("_memo", None)
        if trial % 2 == 0:
            F.predict(P, co, effects)       # a kept solve at the base point
        items = [({**co, k: co[k] * (1 + 1e-6)}, effects) for k in ("gamma", "alpha")]
        for e, ps in effects.items():
            for k, v in ps.items():
                items.append((co, {**effects, e: {**ps, k: v + 1e-6 * max(1.0, abs(v))}}))
        items.append((co, {**effects, "offset_drift": {"offset": 3e-9, "drift": 0.0}}))
        old = P.options
        P.options = F.ForwardOptions(memo=0, dedup=old.dedup, warm=old.warm)
        try:
            if inside:
                with E3.FD_COLUMNS:
                    many = F.predict_many(P, items)
                    one = [F.predict(P, c, e) for c, e in items]
            else:
                many = F.predict_many(P, items)
                one = [_plain(P, c, e) for c, e in items]
        finally:
            P.options = old
        for a, b in zip(many, one):
            np.testing.assert_array_equal(a, b)


def test_the_fit_makes_the_columns_at_once():
    """solve.fit with a forward.Model evaluates its Jacobians through predict_many (the search's speed, issue 9)."""
    data, P = generate(PAIR_CAL, REPEATED, {}, noise=0.2e-6, seed=5, model="eq3")
    calls = []
    orig = F.predict_many

    def spy(P_, items):
        calls.append(len(items))
        return orig(P_, items)

    coefs = [solve.Coef("gamma", "gamma", P.gamma0, P.gamma0 / 1e3, P.gamma0 * 1e3, P.gamma0),
             solve.Coef("alpha", "alpha", P.alpha0, P.alpha0 / 1e3, P.alpha0 * 1e3, P.alpha0)]
    F.predict_many = spy
    try:
        fast = solve.fit(F.Model(P), data.value, data.sigma, coefs)
    finally:
        F.predict_many = orig
    slow = solve.fit(lambda a, b: _plain(P, a, b), data.value, data.sigma, coefs)
    import inspect

    from scipy.optimize._numdiff import approx_derivative

    if "workers" in inspect.signature(approx_derivative).parameters:      # scipy >= 1.16
        assert 2 in calls           # the two columns of a Jacobian
    np.testing.assert_array_equal(fast.values, slow.values)
    assert fast.chi2 == slow.chi2 and np.array_equal(fast.stderr, slow.stderr)


def test_a_coefficient_given_per_row_is_predicted_on_every_row():
    """A coefficient given per row (acl.fit.report.tone_gain_stderr's ``tone_weight``, one factor per row and tone)
    cannot be predicted on the distinct rows only: predict falls back to every row (with the reduction it raised a
    shape error, which run_fit turned into an empty tone-gain figure)."""
    data, P = generate(PAIR_CAL, REPEATED, {}, noise=0.2e-6, seed=5, model="eq3")
    co = {"gamma": P.gamma0 * 1.2, "alpha": P.alpha0 * 0.9,
          "tone_weight": np.where((P.f == 120e3) & (P.v > 0), np.exp(2e-4), 1.0)}
    np.testing.assert_array_equal(F.predict(P, co, DRAG), _plain(P, co, DRAG))
    with E3.FD_COLUMNS:
        many = F.predict_many(P, [(co, DRAG), ({**co, "gamma": co["gamma"] * (1 + 1e-6)}, DRAG)])
    np.testing.assert_array_equal(many[1], _plain(P, {**co, "gamma": co["gamma"] * (1 + 1e-6)}, DRAG))
