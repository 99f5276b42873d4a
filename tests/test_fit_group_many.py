"""Several predictions of a group's rows in one batched solve (acl.fit.forward.predict_many and
acl.fit.group.predict_many): a Jacobian's columns, a grid's points, the fold probes.

Each stacked prediction must give the numbers that the same prediction made alone gives, to the solver's tolerance
(its rows converge to 1e-9 of the group's smallest rest distance: far below 1e-9 m), the same rows snapped (contact,
exactly 0), while the block's state of the last evaluation (the optimizer's warm start) is read and not replaced.
The reference is a fresh data set per prediction (a cold start: continuation from rest), so that it does not share the
warm start it is checked against.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
PAIR = os.path.join(ROOT, "samples", "fit_pair.acl")
GROUP3 = os.path.join(ROOT, "samples", "fit_group3.acl")
TOL = 1e-9          # m: the brief's bound on a prediction's change


def _prepared(path, ex, tmp, name):
    from acl.fit.problem import load_problem
    from acl.fit.synth import generate, write_csv

    data, _ = generate(path, ex)
    csv = os.path.join(tmp, f"{name}.csv")
    write_csv(data, csv)
    return csv, (lambda: load_problem(path, [csv]).prepared)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from acl.fit.synth import Experiment

    # 25 um gap: rows past snap-in at the top voltages; 45 um: rows on the branch
    ex = Experiment(frequencies=(120e3, 125e3), voltages=(0.0, 1.0, 2.0, 2.5, 3.0, 3.5),
                    sets={"gap": ["25 um", "45 um"]})
    return _prepared(PAIR, ex, str(tmp_path_factory.mktemp("many")), "pair")[1]


ITEMS = [   # (coeffs, effects): the base point, a Jacobian column of each kind of coefficient, two 1 % steps
    ({}, {}),
    ({"alpha": 1.745e-19 * (1 + 1e-6)}, {}),
    ({"gamma": 0.027e-9 * (1 + 1e-6)}, {}),
    ({}, {"bjerknes_scale": {"factor": 1.01}}),
    ({}, {"stiffness_scale": {"e_scale": 0.99}}),
    ({}, {"neighbour_drag": {"inv_plateau": 1 / 40e-6}}),
    ({}, {"large_deflection": {"elastica_weight": 0.5}}),
    ({}, {"bjerknes_shape": {"gap_exponent": 0.3}}),
    ({}, {"substrate_proximity": {"h_substrate": 30e-6}}),
    ({}, {"drive_saturation": {"inv_vsat2": 1 / 9.0}}),
]


def _no_memo(P):
    import dataclasses

    P.options = dataclasses.replace(P.options, memo=0)
    return P


def _alone(make, items):
    from acl.fit.forward import predict

    return [predict(make(), c, e) for c, e in items]


def test_stacked_predictions_of_a_pair_are_the_predictions_alone(pair):
    from acl.fit.forward import predict, predict_many

    P = _no_memo(pair())
    base = predict(P, {}, {})          # the optimizer's point: its state is what the stacked columns start from
    red = P.groups[0].__dict__.get(("distinct", False))
    blk = P.groups[0] if red is None else red[0]       # the block solved (repeated rows once)
    state = (blk.cache.copy(), blk.closing.copy(), blk.fold[0].copy())
    got = predict_many(P, ITEMS)
    ref = _alone(pair, ITEMS)
    assert np.array_equal(got[0] == 0.0, base == 0.0)
    for k, (g, r) in enumerate(zip(got, ref)):
        assert np.array_equal(g == 0.0, r == 0.0), ITEMS[k]          # the same rows in contact
        assert np.max(np.abs(g - r)) < TOL, (ITEMS[k], np.max(np.abs(g - r)))
    assert (ref[0] == 0.0).any() and (ref[0] != 0.0).sum() > 10      # both kinds of row are checked
    # the block's state is read, not replaced
    assert np.array_equal(blk.cache, state[0]) and np.array_equal(blk.closing, state[1])
    assert np.array_equal(blk.fold[0], state[2])


def test_the_items_are_solved_in_one_call(pair, monkeypatch):
    """One batched solve of the block for all items (the point of stacking), not one per item."""
    from acl.fit import group as G
    from acl.fit.forward import predict, predict_many

    P = _no_memo(pair())
    predict(P, {}, {})
    calls = []
    real = G._predict_block
    monkeypatch.setattr(G, "_predict_block", lambda P_, blk, items: calls.append(len(items)) or real(P_, blk, items))
    predict_many(P, ITEMS[:4])
    assert calls == [4]


def test_a_jacobian_of_stacked_columns_is_the_jacobian_of_single_ones(pair):
    """Forward differences at a 1e-6 step from the stacked columns agree with those of the columns alone (the warm
    start of the base point either way) to 1e-3 relative: the columns are smooth in the coefficient."""
    from acl.fit.forward import predict, predict_many

    P = _no_memo(pair())
    a0 = 1.745e-19
    cols = [({"alpha": a0 * (1 + 1e-6)}, {}), ({"alpha": a0, "gamma": 0.027e-9 * (1 + 1e-6)}, {})]
    f0 = predict(P, {"alpha": a0}, {})
    many = predict_many(P, cols)
    alone = []
    for c, e in cols:
        predict(P, {"alpha": a0}, {})                     # the same warm start for each column
        alone.append(predict(P, c, e))
    for m_, a_ in zip(many, alone):
        dm, da = m_ - f0, a_ - f0
        assert np.max(np.abs(dm - da)) <= 1e-3 * np.max(np.abs(da)) + 1e-15


def test_three_capsule_group_stacked(tmp_path):
    from acl.fit.forward import predict_many
    from acl.fit.synth import Experiment

    ex = Experiment(frequencies=(125e3,), voltages=(0.0, 1.0, 2.0, 3.0))
    _, make = _prepared(GROUP3, ex, str(tmp_path), "group3")
    items = [({}, {}), ({"gamma": 1.2 * 0.027e-9}, {}), ({}, {"bjerknes_scale": {"factor": 0.7}}),
             ({}, {"neighbour_drag": {"inv_plateau": 1 / 40e-6}})]
    P = make()
    assert P.groups
    got = predict_many(P, items)
    ref = _alone(make, items)
    for k, (g, r) in enumerate(zip(got, ref)):
        assert np.array_equal(g == 0.0, r == 0.0)
        assert np.max(np.abs(g - r)) < TOL, (items[k], np.max(np.abs(g - r)))
