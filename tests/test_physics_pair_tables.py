"""The pair table's geometry kept per configuration (acl.physics.forces.interface_pairs): capsule_pair_forces and
dominant_pair_phase give bit for bit the same numbers with it as without it, and both agree with a brute-force loop
over capsule pairs written from the docstrings (1e-12 relative)."""
from __future__ import annotations

import numpy as np
import pytest

from acl.physics.forces import capsule_pair_forces, dominant_pair_phase, interface_pairs
from acl.physics.ties import first_max


def _config(per_capsule, tones: int, seed: int = 3):
    rng = np.random.default_rng(seed)
    body = np.repeat(np.arange(len(per_capsule)), per_capsule)
    points = rng.normal(0.0, 1e-4, (body.size, 3))
    att = rng.normal(0.0, 1e-9, (body.size, body.size))
    att = (att + att.T) * (body[:, None] != body[None, :])
    vol = rng.normal(size=(tones, body.size)) + 1j * rng.normal(size=(tones, body.size))
    return body, points, att, vol


def _brute(body, points, att, vol, ncap):
    fa, dphi, gap = [], [], []
    for a in range(ncap):
        for b in range(a + 1, ncap):
            ia, ib = np.flatnonzero(body == a), np.flatnonzero(body == b)
            f = np.zeros(3)
            for i in ia:
                for j in ib:
                    s = points[j] - points[i]
                    f += att[i, j] * s / np.linalg.norm(s)
            fa.append(f)
            peak = [np.abs(vol[t, ia]).max() * np.abs(vol[t, ib]).max() for t in range(vol.shape[0])]
            t = first_max(np.array(peak))
            ja, jb = ia[first_max(np.abs(vol[t, ia]))], ib[first_max(np.abs(vol[t, ib]))]
            dphi.append(np.angle(vol[t, ja] * np.conj(vol[t, jb])))
            gap.append(np.linalg.norm(points[jb] - points[ja]))
    return np.array(fa), np.array(dphi), np.array(gap)


@pytest.mark.parametrize("per_capsule,tones", [([1] * 9, 1), ([1] * 9, 3), ([2, 1, 3, 1], 2), ([1, 1, 2], 1)])
def test_pair_geometry_kept_gives_the_same_pair_table(per_capsule, tones):
    body, points, att, vol = _config(per_capsule, tones)
    ncap = len(per_capsule)
    pairs = interface_pairs(points, body, ncap)
    assert pairs[5] == all(k == 1 for k in per_capsule)
    dist = np.full(ncap * (ncap - 1) // 2, 7.0)
    fa0, fa1 = capsule_pair_forces(points, att, body, ncap), capsule_pair_forces(points, att, body, ncap, pairs)
    (d0, g0), (d1, g1) = dominant_pair_phase(vol, points, body, ncap, dist), \
        dominant_pair_phase(vol, points, body, ncap, dist, pairs)
    for x, y in ((fa0, fa1), (d0, d1), (g0, g1)):
        assert np.array_equal(x, y) and np.array_equal(np.signbit(x), np.signbit(y))
    fa, dphi, gap = _brute(body, points, att, vol, ncap)
    np.testing.assert_allclose(fa1, fa, rtol=1e-12, atol=1e-12 * np.abs(fa).max())
    np.testing.assert_allclose(d1, dphi, rtol=1e-12)
    np.testing.assert_allclose(g1, gap, rtol=1e-12)
