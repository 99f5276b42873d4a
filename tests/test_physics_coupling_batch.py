"""The one coupled law over a batch axis (acl.physics.coupling.coupled_volumes / coupled_mode_batch) against an
independent computation: a brute-force loop over batch rows, frequencies and interface pairs written from the module
doc's equations (dense Green matrix entry by entry, the generalized eigenproblem by scipy, the radiation resistance as
a double sum), and the two-identical-bubble closed form per batch row.  Three capsules with 2, 1 and 1 orifices near
a wall, each batch row with its own positions and medium.  Tolerances 1e-9 relative (rounding of different summation
orders and LAPACK paths)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from acl.physics.coupling import (build_system, contact_distance, coupled_mode_batch, coupled_modes, coupled_response,
                                  coupled_volumes, uncoupled_blocks)
from acl.physics.resonance import capsule_modes

RHO, SIGMA, P0, MU, C = 998.2, 0.0728, 101325.0, 1.002e-3, 1482.0
WALL = 0.7


def _capsules():
    two = capsule_modes(6.51e-14, [10e-6, 8e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=2)
    one = capsule_modes(6.51e-14, [10e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=2)
    big = capsule_modes(9.0e-14, [12e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=2)
    pts = [[[0.0, 0.0, 30e-6], [0.0, 25e-6, 30e-6]], [[45e-6, 5e-6, 28e-6]], [[-20e-6, 60e-6, 35e-6]]]
    radii = [[10e-6, 8e-6], [10e-6], [12e-6]]
    return [two, one, big], pts, radii


def _batch():
    """Three rows: displaced interface positions (B, n, 3), each row with its own density and sound speed."""
    modes, pts, radii = _capsules()
    sysm = build_system(modes, pts, radii)
    rng = np.random.default_rng(7)
    points = sysm.points[None] + rng.normal(0.0, 4e-6, (3, sysm.n, 3))
    points[..., 2] = np.abs(points[..., 2]) + 12e-6
    return modes, sysm, points, np.array([998.2, 1010.0, 990.0]), np.array([1482.0, 1500.0, 1450.0])


def _dense_phi(modes):
    """Phi (n, M) over all capsules' modes and their omega, damping (block diagonal)."""
    n = sum(m.orifice_volume.shape[0] for m in modes)
    mt = sum(m.omega.size for m in modes)
    phi, om, dmp, body = np.zeros((n, mt)), [], [], []
    i = k = 0
    for c, m in enumerate(modes):
        p, nm = m.orifice_volume.shape
        phi[i:i + p, k:k + nm] = m.orifice_volume
        om += list(m.omega)
        dmp += list(m.omega / m.quality)
        body += [c] * p
        i, k = i + p, k + nm
    return phi, np.array(om), np.array(dmp), np.array(body)


def _green(points, radii, body, k, wall, static=False):
    """g_ij entry by entry (module doc): retarded between capsules, incompressible within one, wall images for all."""
    n = len(radii)
    g = np.zeros((n, n), complex)
    for i in range(n):
        for j in range(n):
            floor = radii[i] + radii[j]
            if i != j:
                d = float(contact_distance(np.linalg.norm(points[i] - points[j]), floor))
                retard = 0.0 if static or body[i] == body[j] else k * d
                g[i, j] += np.exp(-1j * retard) / (4 * math.pi * d)
            image = points[j] * np.array([1.0, 1.0, -1.0])
            di = float(contact_distance(np.linalg.norm(points[i] - image), floor))
            g[i, j] += wall * np.exp(-1j * (0.0 if static else k * di)) / (4 * math.pi * di)
    return g


def test_coupled_volumes_over_a_batch_equal_a_brute_force_loop():
    modes, sysm, points, rho, c = _batch()
    phi, om, dmp, body = _dense_phi(modes)
    f = np.linspace(60e3, 240e3, 7)
    w = 2 * math.pi * f
    blocks = uncoupled_blocks(sysm, w)
    got = coupled_volumes(blocks, sysm.slot, points, sysm.radii, f, rho, c, WALL)          # (B, F, n)
    assert got.shape == (3, f.size, sysm.n)
    for b in range(3):
        for fi, wf in enumerate(w):
            h0 = np.zeros((sysm.n, sysm.n), complex)
            for i in range(sysm.n):
                for j in range(sysm.n):
                    if body[i] == body[j]:
                        h0[i, j] = sum(phi[i, m] * phi[j, m] / (om[m]**2 - wf**2 + 1j * wf * dmp[m])
                                       for m in range(om.size))
            g = _green(points[b], sysm.radii, body, wf / c[b], WALL)
            u = np.linalg.solve(np.eye(sysm.n) - wf**2 * rho[b] * h0 @ g, h0 @ np.ones(sysm.n))
            np.testing.assert_allclose(got[b, fi], u, rtol=1e-9)
    # the scalar API is the same law at batch size 1
    one = coupled_response(sysm, f, rho[1], c[1], WALL, points=points[1:2])[0]
    np.testing.assert_allclose(one, got[1], rtol=1e-12)


def test_coupled_mode_batch_equals_the_generalized_eigenproblem_and_a_double_sum():
    modes, sysm, points, rho, c = _batch()
    phi, om, dmp, body = _dense_phi(modes)
    w, vol, q, (q_bare,) = coupled_mode_batch(np.broadcast_to(phi, (3,) + phi.shape), om, dmp, points, sysm.radii,
                                              body, rho, c, WALL, also_damping=[0.5 * dmp])
    for b in range(3):
        g0 = _green(points[b], sysm.radii, body, 0.0, WALL, static=True).real
        mass = np.eye(om.size) + rho[b] * phi.T @ g0 @ phi
        w2, vec = scipy.linalg.eigh(np.diag(om**2), mass)          # q^T M q = I
        np.testing.assert_allclose(w[b], np.sqrt(w2), rtol=1e-9)
        v = phi @ vec
        np.testing.assert_allclose(np.abs(vol[b]), np.abs(v), rtol=1e-7, atol=1e-9 * np.abs(v).max())
        for n_ in range(om.size):
            k = np.sqrt(w2[n_]) / c[b]
            rad = 0.0
            for i in range(sysm.n):
                for j in range(sysm.n):
                    floor = sysm.radii[i] + sysm.radii[j]
                    if body[i] != body[j]:
                        d = float(contact_distance(np.linalg.norm(points[b, i] - points[b, j]), floor))
                        rad += v[i, n_] * v[j, n_] * math.sin(k * d) / (k * d)
                    image = points[b, j] * np.array([1.0, 1.0, -1.0])
                    di = float(contact_distance(np.linalg.norm(points[b, i] - image), floor))
                    rad += WALL * v[i, n_] * v[j, n_] * math.sin(k * di) / (k * di)
            rad *= rho[b] * w2[n_] / (4 * math.pi * c[b])
            own = (dmp * vec[:, n_] ** 2).sum()
            assert q[b, n_] == pytest.approx(np.sqrt(w2[n_]) / (own + rad), rel=1e-9)
            assert q_bare[b, n_] == pytest.approx(np.sqrt(w2[n_]) / (0.5 * own + rad), rel=1e-9)


def test_scalar_coupled_modes_is_the_batch_at_size_one():
    modes, sysm, _, _, _ = _batch()
    phi, om, dmp, body = _dense_phi(modes)
    cm = coupled_modes(sysm, RHO, C, WALL)
    w, vol, q, _ = coupled_mode_batch(phi[None], om[None], dmp[None], sysm.points[None], sysm.radii, body, RHO, C, WALL)
    np.testing.assert_allclose(cm.omega, w[0], rtol=1e-12)
    np.testing.assert_allclose(cm.quality, q[0], rtol=1e-12)
    top = float(cm.omega[2])
    part = coupled_modes(sysm, RHO, C, WALL, max_omega=top)
    assert part.omega.size == 3
    np.testing.assert_allclose(part.quality, cm.quality[:3], rtol=1e-12)


@pytest.mark.parametrize("wall", [0.0, 1.0])
def test_two_identical_bubbles_closed_form_per_batch_row(wall):
    # Two identical one-mode bubbles at the same height z, distance d: the in-phase / anti-phase modes
    # w^2 = w0^2 / (1 + rho v^2 (m_img +- m_c)), m_c = 1/(4 pi d) + R/(4 pi d'), m_img = R/(8 pi z) (module doc:
    # mutual mass and the wall images), one batch row per distance.  1e-9 relative.
    m = capsule_modes(6.51e-14, [10e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=1)
    v, w0 = float(m.orifice_volume[0, 0]), float(m.omega[0])
    z = 30e-6
    dists = np.array([25e-6, 40e-6, 80e-6, 160e-6])
    pts = np.zeros((dists.size, 2, 3))
    pts[:, :, 2] = z
    pts[:, 1, 0] = dists
    radii = np.array([10e-6, 10e-6])
    phi = np.broadcast_to(np.diag([v, v]), (dists.size, 2, 2))
    om = np.full((dists.size, 2), w0)
    w, _, _, _ = coupled_mode_batch(phi, om, om / 50.0, pts, radii, np.array([0, 1]), RHO, C, wall)
    d = contact_distance(dists, 20e-6)
    dimg = contact_distance(np.hypot(dists, 2 * z), 20e-6)
    m_img = wall / (4 * math.pi * float(contact_distance(2 * z, 20e-6)))
    mc = 1 / (4 * math.pi * d) + wall / (4 * math.pi * dimg)
    expect = np.sort(np.stack([w0 / np.sqrt(1 + RHO * v * v * (m_img + mc)),
                               w0 / np.sqrt(1 + RHO * v * v * (m_img - mc))], axis=1), axis=1)
    np.testing.assert_allclose(w, expect, rtol=1e-9)


@pytest.mark.parametrize("capsules", [1, 2])
@pytest.mark.parametrize("batched", [False, True])
def test_three_orifice_capsules_equal_a_brute_force_loop(batched, capsules):
    # One or two capsules of three orifices each (the Fig. 3 capsule's layout): the per-capsule blocks go through
    # the einsum path, whose result may have any memory layout.  Brute force as above, 1e-9 relative.
    m3 = capsule_modes(6.51e-14, [10e-6, 8e-6, 6e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=3)
    pts = [[[0.0, 0.0, 30e-6], [0.0, 25e-6, 30e-6], [20e-6, 10e-6, 40e-6]],
           [[60e-6, 0.0, 30e-6], [60e-6, 25e-6, 30e-6], [80e-6, 10e-6, 40e-6]]]
    sysm = build_system([m3] * capsules, pts[:capsules], [[10e-6, 8e-6, 6e-6]] * capsules)
    phi, om, dmp, body = _dense_phi([m3] * capsules)
    f = np.array([40e3, 95e3, 160e3])
    w = 2 * math.pi * f
    points = sysm.points[None] + (np.array([0.0, 2e-6])[:, None, None] if batched else 0.0)
    got = coupled_response(sysm, f, RHO, C, WALL, points=points)
    for b in range(points.shape[0]):
        for fi, wf in enumerate(w):
            h0 = (phi / (om**2 - wf**2 + 1j * wf * dmp)) @ phi.T * (body[:, None] == body[None, :])
            g = _green(points[b], sysm.radii, body, wf / C, WALL)
            u = np.linalg.solve(np.eye(sysm.n) - wf**2 * RHO * h0 @ g, h0 @ np.ones(sysm.n))
            np.testing.assert_allclose(got[b, fi], u, rtol=1e-9)



def _array_of_capsules(rows: int = 3, cols: int = 5, pitch: float = 100e-6):
    """A regular array of one-orifice capsules of two kinds, as large designs are laid out."""
    kinds = [capsule_modes(6.51e-14, [r], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=2) for r in (10e-6, 12e-6)]
    modes, pts, radii = [], [], []
    for r in range(rows):
        for q in range(cols):
            modes.append(kinds[(r + q) % 2])
            pts.append([[q * pitch, r * pitch, 60e-6]])
            radii.append([(10e-6, 12e-6)[(r + q) % 2]])
    return modes, build_system(modes, pts, radii)


def test_coupled_volumes_of_an_array_gather_the_same_green_matrix_bit_for_bit(monkeypatch):
    """The distinct-pair table (DISTINCT_PAIRS) gives exactly the numbers of the pair-by-pair Green matrix, and both
    the brute-force loop's to 1e-9."""
    import acl.physics.coupling as CP

    modes, sysm = _array_of_capsules()
    phi, om, dmp, body = _dense_phi(modes)
    f = np.linspace(60e3, 240e3, CP.TABLE_MIN_EVALUATIONS)
    blocks = uncoupled_blocks(sysm, 2 * math.pi * f)
    args = (blocks, sysm.slot, sysm.points, sysm.radii, f, RHO, C, WALL)
    terms = []
    green = CP._green_terms
    monkeypatch.setattr(CP, "_green_terms", lambda k, t, r, *a: terms.append(t[0].shape[-1]) or green(k, t, r, *a))
    table = coupled_volumes(*args)
    pairs = sysm.n * (sysm.n + 1) // 2
    assert terms and max(terms) < pairs / 4                 # the array repeats its distances: the table path ran
    monkeypatch.setattr(CP, "DISTINCT_PAIRS", 0.0)          # pair by pair
    terms.clear()
    pairwise = coupled_volumes(*args)
    assert terms and min(terms) == pairs
    assert np.array_equal(table, pairwise)
    for fi, wf in enumerate(2 * math.pi * f):
        h0 = np.zeros((sysm.n, sysm.n), complex)
        for i in range(sysm.n):
            for j in range(sysm.n):
                if body[i] == body[j]:
                    h0[i, j] = sum(phi[i, m] * phi[j, m] / (om[m]**2 - wf**2 + 1j * wf * dmp[m]) for m in range(om.size))
        g = _green(sysm.points, sysm.radii, body, wf / C, WALL)
        u = np.linalg.solve(np.eye(sysm.n) - wf**2 * RHO * h0 @ g, h0 @ np.ones(sysm.n))
        np.testing.assert_allclose(table[fi], u, rtol=1e-9)


def test_mutual_resistance_of_an_array_is_the_pair_by_pair_sum_bit_for_bit(monkeypatch):
    """sin(kd)/d once per distinct distance (DISTINCT_PAIRS) gives exactly the pair-by-pair sums, and both the
    double sum over interfaces and images of the module doc (1e-9)."""
    import acl.physics.coupling as CP

    modes, sysm = _array_of_capsules()
    phi, om, dmp, body = _dense_phi(modes)
    vol = phi @ np.random.default_rng(5).normal(size=(om.size, 8))             # eight collective shapes
    k = np.linspace(200.0, 900.0, 8)                                          # rad/m
    distinct = []
    unique = np.unique
    monkeypatch.setattr(CP.np, "unique", lambda *a, **kw: distinct.append(unique(*a, **kw)) or distinct[-1])
    table = CP.mutual_resistance(vol, sysm.points, sysm.radii, body, k, WALL)
    monkeypatch.setattr(CP.np, "unique", unique)
    assert distinct and distinct[-1][0].size < np.size(distinct[-1][1]) / 4     # the table path ran
    monkeypatch.setattr(CP, "DISTINCT_PAIRS", 0.0)
    assert np.array_equal(table, CP.mutual_resistance(vol, sysm.points, sysm.radii, body, k, WALL))
    for n_ in range(k.size):
        s = 0.0
        for i in range(sysm.n):
            for j in range(sysm.n):
                floor = sysm.radii[i] + sysm.radii[j]
                if body[i] != body[j]:
                    d = float(contact_distance(np.linalg.norm(sysm.points[i] - sysm.points[j]), floor))
                    s += vol[i, n_] * vol[j, n_] * math.sin(k[n_] * d) / (k[n_] * d)
                di = float(contact_distance(np.linalg.norm(sysm.points[i] - sysm.points[j] * [1.0, 1.0, -1.0]), floor))
                s += WALL * vol[i, n_] * vol[j, n_] * math.sin(k[n_] * di) / (k[n_] * di)
        assert table[n_] == pytest.approx(s, rel=1e-9)


def test_coupled_volumes_of_an_array_with_batched_blocks_equal_each_row(monkeypatch):
    """The gathered Green matrix broadcast over a batch of uncoupled responses (one configuration): each row as
    solved alone, bit for bit."""
    import acl.physics.coupling as CP
    from acl.physics.coupling import uncoupled_response

    modes, sysm = _array_of_capsules()
    f = np.linspace(80e3, 200e3, CP.TABLE_MIN_EVALUATIONS)
    w = 2 * math.pi * f
    terms = []
    green = CP._green_terms
    monkeypatch.setattr(CP, "_green_terms", lambda k, t, r, *a: terms.append(t[0].shape[-1]) or green(k, t, r, *a))

    blocks = np.stack([np.moveaxis(uncoupled_response(sysm.phi, sysm.omega, s * sysm.damping, w), -3, 0)
                       for s in (1.0, 1.7)])                                              # (2, F, C, P, P)
    both = coupled_volumes(blocks, sysm.slot, sysm.points, sysm.radii, f, RHO, C, WALL)
    assert both.shape == (2, f.size, sysm.n)
    for b in range(2):
        assert np.array_equal(both[b], coupled_volumes(blocks[b], sysm.slot, sysm.points, sysm.radii, f, RHO, C, WALL))
    assert not np.allclose(both[0], both[1], rtol=1e-3, atol=0.0)                     # the rows differ
    assert terms and max(terms) < sysm.n * (sysm.n + 1) // 8                           # the table path ran


@pytest.mark.parametrize("capsules", [1, 2])
def test_same_capsule_pairs_skip_the_phase_bit_for_bit(capsules):
    """coupled_volumes' Green terms without cosines and sines for same-capsule pairs (phase exactly 1) are the
    numbers of the full retarded formula, for one capsule (no pair between capsules) and two (mixed); and the
    layout's index arrays are built once per layout."""
    import acl.physics.coupling as CP

    m3 = capsule_modes(6.51e-14, [10e-6, 8e-6, 6e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, n_modes=3)
    pts = [[[0.0, 0.0, 30e-6], [0.0, 25e-6, 30e-6], [20e-6, 10e-6, 40e-6]],
           [[60e-6, 0.0, 30e-6], [60e-6, 25e-6, 30e-6], [80e-6, 10e-6, 40e-6]]]
    sysm = build_system([m3] * capsules, pts[:capsules], [[10e-6, 8e-6, 6e-6]] * capsules)
    lay = CP._pad_layout(capsules, 3, sysm.slot)
    assert CP._pad_layout(capsules, 3, np.array(sysm.slot)) is lay
    assert lay.other_at.size == (0 if capsules == 1 else 9)
    points = sysm.points[None] + np.random.default_rng(4).normal(0.0, 2e-6, (5, sysm.n, 3))
    d, di = CP._pair_distances(points, sysm.radii[None], lay.iu, lay.ju, True)
    terms = [np.where(lay.other, d, 0.0)[:, None], np.where(lay.offdiag, 1 / (4 * np.pi * d), 0.0)[:, None],
             di[:, None], WALL / (4 * np.pi * di)[:, None]]
    k = (2 * np.pi * np.array([60e3, 150e3]) / C)[None, :, None]
    skip = CP._green_terms(k, terms, WALL, lay.other_at)
    full = CP._green_terms(k, terms, WALL)
    assert np.array_equal(skip, full) and np.array_equal(np.signbit(skip.imag), np.signbit(full.imag))
    # the distances are _distances' (the full matrices) on the upper triangle, bit for bit
    assert np.array_equal(d, CP._distances(points, sysm.radii, False)[:, lay.iu, lay.ju])
    assert np.array_equal(di, CP._distances(points, sysm.radii, True)[:, lay.iu, lay.ju])
