"""acl.physics.batch: each vectorised function equals its scalar twin in acl.physics, point by point."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from acl.physics import batch as PB
from acl.physics import coupling as CP
from acl.physics import latch as LT
from acl.physics import resonance as R
from acl.physics.beams import eq1_force
from acl.physics.constants import WATER_20C as W

ROOT = Path(__file__).resolve().parents[1]


def _scalar_modes(vol, radii, rth, q=None):
    return R.capsule_modes(vol, radii, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity,
                           W.sound_speed, rth, quality_override=q)


@pytest.mark.parametrize("n_orifices", [1, 2, 3])
def test_capsule_modes_equal_scalar_over_a_wide_range(n_orifices):
    rng = np.random.default_rng(n_orifices)
    n = 40
    vol = 6.5e-14 * np.exp(1.2 * rng.standard_normal(n))          # a factor ~10 either way
    radii = 10e-6 * np.exp(0.5 * rng.standard_normal((n, n_orifices)))
    rth = 1e-5 * np.exp(0.3 * rng.standard_normal(n))
    om, q, v = PB.capsule_modes(vol, radii, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity,
                                W.sound_speed, rth)
    for i in range(n):
        m = _scalar_modes(vol[i], radii[i], rth[i])
        np.testing.assert_allclose(om[i], m.omega, rtol=1e-11)
        np.testing.assert_allclose(q[i], m.quality, rtol=1e-11)
        # eigenvector signs are arbitrary: compare magnitudes (the physics uses products and |.|); near-degenerate
        # membrane overtones of similar orifices mix at ~1e-9 of the largest volume
        np.testing.assert_allclose(np.abs(v[i]), np.abs(m.orifice_volume), rtol=1e-9, atol=1e-8 * np.abs(v[i]).max())


def test_declared_quality_overrides_per_point():
    vol = np.array([6.5e-14, 6.5e-14])
    radii = np.array([[10e-6], [10e-6]])
    _, q, _ = PB.capsule_modes(vol, radii, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity,
                               W.sound_speed, 1e-5, quality_override=np.array([np.nan, 12.0]))
    assert np.all(q[1] == 12.0)
    np.testing.assert_allclose(q[0], _scalar_modes(6.5e-14, [10e-6], 1e-5).quality, rtol=1e-11)


def test_rank_one_eigenpairs_fall_back_to_lapack_near_a_pole():
    """A vanishing gas spring puts the roots on the poles of the rank-one update: the rows go to LAPACK and stay right."""
    vol = np.array([1e-3, 6.5e-14])                                # a huge volume: gas spring ~ 0
    radii = np.array([[10e-6], [10e-6]])
    om, q, _ = PB.capsule_modes(vol, radii, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity,
                                W.sound_speed, 1e-5)
    m = _scalar_modes(vol[0], radii[0], 1e-5)
    np.testing.assert_allclose(om[0], m.omega, rtol=1e-9)


def test_coupled_modes_and_response_equal_scalar():
    rng = np.random.default_rng(2)
    n = 6
    vol = 6.5e-14 * (1 + 0.2 * rng.standard_normal((n, 2)))
    radii = 10e-6 * (1 + 0.1 * rng.standard_normal((n, 2)))
    pts = np.zeros((n, 2, 3))
    pts[:, 0, 2] = 50e-6 + 10e-6 * rng.random(n)
    pts[:, 1] = pts[:, 0] + np.array([90e-6, 0, 0]) + 5e-6 * rng.standard_normal((n, 3))
    body = np.array([0, 1])
    bare = [PB.capsule_modes(vol[:, c], radii[:, c:c + 1], W.density, W.surface_tension, W.ambient_pressure, 1.0,
                             W.viscosity, W.sound_speed, 1e-5) for c in range(2)]
    phi = np.zeros((n, 2, 6))
    phi[:, 0, :3], phi[:, 1, 3:] = bare[0][2][:, 0], bare[1][2][:, 0]
    om = np.concatenate([bare[0][0], bare[1][0]], axis=1)
    dmp = np.concatenate([bare[0][0] / bare[0][1], bare[1][0] / bare[1][1]], axis=1)
    w, vv, qq = PB.coupled_modes(phi, om, dmp, pts, radii, body, W.density, W.sound_speed, 1.0)
    f = np.array([100e3, 125e3])
    h0 = CP.uncoupled_response(phi, om, dmp, 2 * np.pi * f[None, :], body)
    u = PB.coupled_response(h0, pts, radii, body, f[None, :], W.density, W.sound_speed, 1.0)
    for i in range(n):
        ms = [R.BubbleModes(omega=bare[c][0][i], quality=bare[c][1][i], orifice_volume=bare[c][2][i]) for c in range(2)]
        sysm = CP.build_system(ms, [pts[i, :1], pts[i, 1:]], [radii[i, :1], radii[i, 1:]])
        cm = CP.coupled_modes(sysm, W.density, W.sound_speed, 1.0)
        np.testing.assert_allclose(w[i], cm.omega, rtol=1e-11)
        np.testing.assert_allclose(qq[i], cm.quality, rtol=1e-9)
        np.testing.assert_allclose(u[i], CP.coupled_response(sysm, f, W.density, W.sound_speed, 1.0), rtol=1e-11)


def test_lowest_single_interface_mode_equals_the_full_eigenproblem():
    rng = np.random.default_rng(5)
    n = 30
    vol = 6.5e-14 * np.exp(0.8 * rng.standard_normal(n))
    radii = 10e-6 * np.exp(0.3 * rng.standard_normal((n, 1)))
    om, q, v = PB.capsule_modes(vol, radii, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity,
                                W.sound_speed, 1e-5)
    pts = np.zeros((n, 1, 3))
    pts[:, 0, 2] = 60e-6 * np.exp(rng.standard_normal(n))          # including heights below 2R (floored)
    w0, _, q0 = PB.lowest_single_interface_mode(v[:, 0], om, om / q, pts[:, 0], radii[:, 0], W.density, W.sound_speed, 1.0)
    w, _, qq = PB.coupled_modes(v, om, om / q, pts, radii, np.zeros(1, int), W.density, W.sound_speed, 1.0)
    np.testing.assert_allclose(w0, w[:, 0], rtol=1e-12)
    np.testing.assert_allclose(q0, qq[:, 0], rtol=1e-10)


def test_eq1_force_with_array_geometry_equals_scalar():
    rng = np.random.default_rng(1)
    L = 50e-6 * (1 + 0.2 * rng.random(8))
    l = 27e-6 * rng.random(8)
    EI = 13e6 * np.pi * (2e-6) ** 4 / 64 * (1 + rng.random(8))
    delta = 1e-5 * rng.standard_normal(8)
    got = PB.eq1_force(delta, L, l, EI)
    for i in range(8):
        assert got[i] == pytest.approx(float(eq1_force(delta[i], L[i], l[i], EI[i])), rel=1e-12)


def test_latch_forces_and_switching_force_equal_scalar():
    rng = np.random.default_rng(0)
    n = 6
    theta = np.deg2rad(rng.uniform(20, 65, n))
    L = 50e-6 * (1 + 0.1 * rng.standard_normal(n))
    w = 1e-6 * (1 + 0.1 * rng.standard_normal(n))
    t = np.full(n, 1.7e-6)
    E = np.full(n, 13e6)
    u = np.linspace(0, 60e-6, 300)
    c = np.linspace(0, 0.2, 500)
    for i in range(n):
        np.testing.assert_allclose(LT.axial_force(c, np.full(c.shape, w[i] / L[i])), LT.axial_force(c, w[i] / L[i]), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(PB.latch_force(u, theta[i], L[i], w[i], t[i], E[i]),
                                   LT.latch_force(u, theta[i], L[i], w[i], t[i], E[i]), rtol=1e-10, atol=1e-22)
    fs, rel, bi = PB.latch_switching_force(theta, L, w, t, E)
    assert bi.any()
    for i in range(n):
        land = LT.latch_landscape(theta[i], L[i], w[i], t[i], E[i])
        assert bi[i] == land.bistable
        u = np.linspace(0.0, land.unstable if land.bistable else 2.6 * L[i] * np.sin(theta[i]), 200001)
        dense = LT.latch_force(u, theta[i], L[i], w[i], t[i], E[i]).max()
        # fs is a value of the force (golden section evaluates it), so it cannot exceed the true maximum; a
        # dense scan can only approach it from below
        assert dense * (1 - 1e-12) <= fs[i] <= dense * (1 + 1e-5)
        # the scalar extremes are over a 2001-point grid: never above the refined ones, within 1e-3
        assert land.switching_force * (1 - 1e-12) <= fs[i] <= land.switching_force * (1 + 1e-3)
        if land.bistable:
            assert land.release_force * (1 - 1e-12) <= rel[i] <= land.release_force * (1 + 5e-3)
            u = np.linspace(land.unstable, land.state_b, 200001)         # a dense scan: the refined value is the model's
            dense = -LT.latch_force(u, theta[i], L[i], w[i], t[i], E[i]).min()
            assert dense * (1 - 1e-12) <= rel[i] <= dense * (1 + 1e-5)
        else:
            assert np.isnan(rel[i])


def test_physics_batch_imports_no_design_sweep_or_cli():
    tree = ast.parse((ROOT / "acl" / "physics" / "batch.py").read_text())
    mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)} | \
        {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert all(m in ("numpy", "functools", "__future__") or m.startswith("acl.physics") for m in mods), mods


def test_latch_state_b_equals_the_landscape():
    """Second stable state per point (batched grid crossing + bisection) vs latch.latch_landscape (Brent): 1e-12 of L."""
    rng = np.random.default_rng(4)
    n = 30
    theta = np.deg2rad(rng.uniform(10, 70, n))
    L = 50e-6 * (1 + 0.1 * rng.standard_normal(n))
    w = 1e-6 * (1 + 0.3 * rng.standard_normal(n))
    t = np.full(n, 1.7e-6)
    E = np.full(n, 13e6)
    ub = PB.latch_state_b(theta, L, w, t, E, block=7)
    mono = 0
    for i in range(n):
        land = LT.latch_landscape(float(theta[i]), float(L[i]), float(w[i]), float(t[i]), float(E[i]))
        if land.bistable:
            assert abs(ub[i] - land.state_b) <= 1e-12 * L[i]
        else:
            mono += 1
            assert ub[i] == 0.0
    assert mono < n
