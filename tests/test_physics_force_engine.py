"""acl.physics.forces.capsule_forces (the batched force engine) against a plain loop over capsules, interfaces and
tones written with the one-pair laws (thrust_magnitude, bjerknes_attraction, jet_drag), and the pair helpers."""
import numpy as np

from acl.physics.forces import (bjerknes_attraction, capsule_forces, capsule_pair_forces, force_constants,
                                jet_drag, neighbour_drag, thrust_magnitude)

MU, RHO, CS = 1.0e-3, 998.0, 0.37


def _case(seed=0):
    rng = np.random.default_rng(seed)
    body = np.array([0, 0, 1, 2, 2])                     # 3 capsules, 5 interfaces
    n, ncap, nt, nb = body.size, 3, 2, 4
    offsets = rng.normal(0, 10e-6, (n, 3))
    normals = rng.normal(0, 1, (n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    onehot = np.eye(ncap)[body]
    radii = rng.uniform(5e-6, 15e-6, n)
    outer = rng.uniform(20e-6, 40e-6, ncap)
    centres = rng.normal(0, 80e-6, (nb, ncap, 3))
    resp = (rng.normal(0, 1e-19, (nb, nt, n)) + 1j * rng.normal(0, 1e-19, (nb, nt, n)))
    f = np.array([90e3, 130e3])
    pressure = np.array([3e4, 5e4])
    scale = rng.uniform(0.5, 1.5, ncap)
    pair = rng.uniform(0.5, 1.5, (ncap, ncap))
    pair = (pair + pair.T) / 2
    return body, offsets, normals, onehot, radii, outer, centres, resp, f, pressure, scale, pair


def _loop(body, offsets, normals, radii, outer, centres, resp, f, pressure, scale, pair):
    nb, ncap = centres.shape[:2]
    out = np.zeros((nb, ncap, 3))
    for b in range(nb):
        pts = centres[b, body] + offsets
        vol = resp[b] * pressure[:, None]                               # (T, n) m^3
        thr = np.array([sum(thrust_magnitude(vol[t, i], radii[i], 2 * np.pi * f[t], MU, CS) for t in range(f.size))
                        * scale[body[i]] for i in range(body.size)])
        for i in range(body.size):
            out[b, body[i]] -= thr[i] * normals[i]
            for j in range(body.size):
                if body[j] == body[i]:
                    continue
                sep = pts[j] - pts[i]
                d = np.linalg.norm(sep)
                att = sum(bjerknes_attraction(2 * np.pi * f[t], vol[t, i], vol[t, j], d, RHO) for t in range(f.size))
                out[b, body[i]] += att * pair[body[i], body[j]] * sep / d
            for c in range(ncap):
                if c == body[i]:
                    continue
                x = centres[b, c] - pts[i]
                r = np.linalg.norm(x)
                out[b, c] += jet_drag(thr[i], r, x @ normals[i] / r, outer[c]) * normals[i]
    return out


def test_capsule_forces_equals_the_loop_over_pairs_with_the_one_pair_laws():
    body, offsets, normals, onehot, radii, outer, centres, resp, f, pressure, scale, pair = _case()
    k = force_constants(2 * np.pi * f, radii, body, 3, MU, RHO, CS, pressure, scale, pair)
    total, pts, thr, att = capsule_forces(centres, body, offsets, normals, onehot, outer, resp, k)
    expect = _loop(body, offsets, normals, radii, outer, centres, resp, f, pressure, scale, pair)
    assert np.allclose(total, expect, rtol=1e-10, atol=1e-12 * np.abs(expect).max())
    assert np.abs(total).max() > 0 and np.allclose(pts, centres[:, body] + offsets)
    # the pair helper sums the same Bjerknes attraction into the force on capsule a of each pair a < b
    fa = capsule_pair_forces(pts[0], att[0], body, 3)
    p0 = pts[0]
    want = np.zeros((3, 3))
    for k_, (a, b) in enumerate(zip(*np.triu_indices(3, 1))):
        for i in np.flatnonzero(body == a):
            for j in np.flatnonzero(body == b):
                sep = p0[j] - p0[i]
                want[k_] += att[0, i, j] * sep / np.linalg.norm(sep)
    assert np.allclose(fa, want, rtol=1e-12)


def test_neighbour_drag_weakens_only_the_capsules_with_a_neighbour():
    total = np.ones((2, 3, 3))
    rest = np.zeros((3, 3))
    centres = np.zeros((2, 3, 3))
    centres[1, :, 0] = [1e-6, 2e-6, 3e-6]
    out = neighbour_drag(total, centres, rest, [True, False, True], 1e5)    # delta_p = 10 um
    assert np.array_equal(out[0], total[0])
    assert np.allclose(out[1, :, 0], [0.9, 1.0, 0.7])
