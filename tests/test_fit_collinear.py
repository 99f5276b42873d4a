"""A collinear group (the Fig. 4e facing pair: every orifice, capsule centre and normal on one line) takes its Newton
steps on the coordinates along the line and evaluates the Jacobian's columns across it once, at each row's solution,
for its stability (acl.fit.group._collinear_columns): 3 copies of each row per iteration where the full Jacobian takes 5.
Against the full Jacobian's solve: the same predictions, snap-ins and Jacobians at the solutions."""
from __future__ import annotations

import os

import numpy as np

from acl.fit.synth import Experiment, generate

HERE = os.path.dirname(__file__)
PAIR = os.path.join(HERE, "..", "samples", "fit_pair.acl")
# gaps 20-60 um to 4 V at three tones: rows at rest, bent and past their snap-in
EX = Experiment(frequencies=(120e3, 125e3, 130e3), voltages=tuple(np.linspace(0, 4, 9)),
                sets={"gap": ["20 um", "40 um", "60 um"]})


def _predictions(monkeypatch, reduced: bool):
    import acl.fit.group as G
    from acl.fit.forward import predict

    seen = []
    with monkeypatch.context() as mp:
        if not reduced:
            mp.setattr(G, "_collinear_columns", lambda *a, **k: (None, None))
        plain = G._predict_block

        def spy(P, blk, items):
            seen.append(blk)
            return plain(P, blk, items)

        mp.setattr(G, "_predict_block", spy)
        _, P = generate(PAIR, EX)
        # cold, an optimizer step (warm: chord steps from the kept Jacobians), a Jacobian column's 1e-6 step
        ys = np.array([predict(P, {"alpha": P.alpha0 * s}, {}) for s in (1.0, 1.03, 1.03 * (1 + 1e-6))])
    return ys, seen[-1].__dict__["jcache"]


def test_collinear_pair_matches_the_full_jacobian_solve(monkeypatch):
    y_full, j_full = _predictions(monkeypatch, reduced=False)
    y_red, j_red = _predictions(monkeypatch, reduced=True)
    assert np.any(y_full == 0.0) and np.any(y_full[0] != 0.0)       # snapped rows and rows in equilibrium
    np.testing.assert_array_equal(y_red == 0.0, y_full == 0.0)
    np.testing.assert_allclose(y_red, y_full, rtol=0, atol=1e-13)   # m; the Newton tolerance is ~1e-14 m
    # the Jacobian kept at each row's equilibrium (the next warm start, and its determinant the stability test)
    # holds the columns across the line, not a placeholder
    kept = np.isfinite(j_full).all(axis=(1, 2))
    np.testing.assert_array_equal(np.isfinite(j_red).all(axis=(1, 2)), kept)
    # (a row polished by a Newton step after its chord steps: its columns across at the polished point, one tolerance
    # from where the full solve takes them; a 1e-9 finite difference)
    np.testing.assert_allclose(j_red[kept], j_full[kept], rtol=1e-6, atol=1e-12)
    loaded = kept & (np.abs(j_full - np.eye(4)).max(axis=(1, 2)) > 0)          # rows under a drive
    across = j_red[loaded][:, [0, 2]][:, :, [0, 2]]
    assert loaded.sum() > 10 and np.all(np.abs(across - np.eye(2)).max(axis=(1, 2)) > 1e-6)  # not the placeholder


def test_collinear_columns_are_found_only_on_one_line():
    from acl.fit.group import _collinear_columns
    from acl.fit.group_block import LAW

    pts = np.array([[27e-6, 0, 68.6e-6], [67e-6, 0, 68.6e-6], [0, 0, 68.6e-6], [94e-6, 0, 68.6e-6]])
    normals = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    bases = [np.array([[0, -1.0], [-1.0, 0], [0, 0]])] * 2                 # (3, k): across (y), along (x)
    beams = np.array([LAW["beam"]] * 2)
    side, along = _collinear_columns(pts, normals, bases, beams, [])
    assert side.tolist() == [0, 2] and along.tolist() == [1, 3]
    off_line = pts.copy()
    off_line[1, 1] = 16.7e-6                                                  # a three-orifice capsule's orifice
    assert _collinear_columns(off_line, normals, bases, beams, []) == (None, None)
    tilted = np.array([[1.0, 0, 0], [-0.5, 0.866, 0]])
    assert _collinear_columns(pts, tilted, bases, beams, []) == (None, None)
    assert _collinear_columns(pts, normals, bases, beams, [np.array([1.0, 1.0, 0])]) == (None, None)
    assert _collinear_columns(pts, normals, bases, beams, [np.array([2.0, 0, 0])])[0].tolist() == [0, 2]
    assert _collinear_columns(pts, normals, bases, np.array([LAW["latch"], LAW["beam"]]), []) == (None, None)
    oblique = [np.array([[0.6, -1.0], [0.8, 0], [0, 0]])] * 2
    assert _collinear_columns(pts, normals, oblique, beams, []) == (None, None)
