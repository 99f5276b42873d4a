"""Coupled bubbles (acl.physics.coupling): two-oscillator analytic checks, far-field limits, wall images."""
from __future__ import annotations

import math

import numpy as np
import pytest

from acl.physics.coupling import build_system, coupled_modes, coupled_response, green_matrix, prepared_response
from acl.physics.resonance import capsule_modes, volume_response

RHO, SIGMA, P0, MU, C = 998.2, 0.0728, 101325.0, 1.002e-3, 1482.0
V1, R1 = 6.51e-14, 10e-6            # paper Table S1, design 1


def single(volume=V1, radius=R1, n_modes=3, q=None):
    return capsule_modes(volume, [radius], RHO, SIGMA, P0, 1.0, MU, C, 7e-6, quality_override=q,
                         n_modes=n_modes)


def pair(d, n_modes=1, z=1.0, q=None):
    m = single(n_modes=n_modes, q=q)
    return build_system([m, m], [[[0.0, 0.0, z]], [[d, 0.0, z]]], [[R1], [R1]]), m


@pytest.mark.parametrize("d", [20e-6, 40e-6, 80e-6])
def test_two_identical_bubbles_have_the_two_oscillator_in_phase_and_anti_phase_modes(d):
    # Two identical one-mode oscillators (mass m, stiffness k per volume^2, paraboloid interface)
    # with mutual mass m_c = rho/(4 pi d) (Kinsler et al., mutual radiation impedance of two small
    # sources): w_in^2 = k/(m + m_c) (in phase), w_anti^2 = k/(m - m_c).  Tolerance 1e-6 relative.  d is the
    # model's distance law, smoothly floored at contact (acl.physics.coupling.contact_distance; 20 um touches).
    from acl.physics.coupling import contact_distance

    sysm, _ = pair(d)
    cm = coupled_modes(sysm, RHO, C)
    m = 1024 * RHO / (315 * math.pi**2 * R1)
    k = P0 / V1 + 8 * SIGMA / (math.pi * R1**4)
    mc = RHO / (4 * math.pi * float(contact_distance(d, 2 * R1)))
    f_in = math.sqrt(k / (m + mc)) / (2 * math.pi)
    f_anti = math.sqrt(k / (m - mc)) / (2 * math.pi)
    np.testing.assert_allclose(cm.frequency, [f_in, f_anti], rtol=1e-6)
    vin, vanti = cm.volume[:, 0], cm.volume[:, 1]
    assert vin[0] == pytest.approx(vin[1], rel=1e-6)          # in phase
    assert vanti[0] == pytest.approx(-vanti[1], rel=1e-6)     # anti-phase


def test_coupled_response_of_an_identical_pair_is_the_scalar_two_oscillator_response():
    # Symmetric drive of a symmetric pair: U = h / (1 - w^2 rho h exp(-ikd)/(4 pi d)), h the single
    # bubble's response (module doc).  1e-10 relative over 40..250 kHz.
    d = 40e-6
    sysm, m = pair(d, n_modes=3)
    f = np.linspace(40e3, 250e3, 57)
    u = coupled_response(sysm, f, RHO, C)
    h = volume_response(m, f)[:, 0]
    w = 2 * math.pi * f
    from acl.physics.coupling import contact_distance

    dd = float(contact_distance(d, 2 * R1))     # the model's distance law (smooth contact floor; 40 um: +0.05 %)
    expect = h / (1 - w**2 * RHO * h * np.exp(-1j * w / C * dd) / (4 * math.pi * dd))
    np.testing.assert_allclose(u[:, 0], expect, rtol=1e-10)
    np.testing.assert_allclose(u[:, 1], expect, rtol=1e-10)


def test_far_apart_bubbles_and_no_wall_give_the_single_bubble_unchanged():
    # Coupling ~ 1/d: at 100 m the pair responds as one bubble alone to 1e-6 (issue 10: unchanged
    # where coupling vanishes).
    sysm, m = pair(100.0, n_modes=3)
    f = np.linspace(50e3, 200e3, 31)
    np.testing.assert_allclose(coupled_response(sysm, f, RHO, C)[:, 0], volume_response(m, f)[:, 0], rtol=1e-6)
    lone = build_system([m], [[[0.0, 0.0, 0.01]]], [[R1]])
    np.testing.assert_allclose(coupled_response(lone, f, RHO, C, wall_reflection=0.0)[:, 0],
                               volume_response(m, f)[:, 0], rtol=1e-12)
    assert coupled_modes(lone, RHO, C).frequency[0] == pytest.approx(m.frequency[0], rel=1e-12)


def test_rigid_wall_image_is_a_mirrored_twin_bubble():
    # A rigid wall (R = +1) is equivalent to an in-phase twin at the mirror point (Pierce, Acoustics
    # 5.1): one bubble at height z over the wall has the in-phase mode of a free pair at d = 2z.
    z = 30e-6
    m = single(n_modes=1)
    lone = build_system([m], [[[0.0, 0.0, z]]], [[R1]])
    f_wall = coupled_modes(lone, RHO, C, wall_reflection=1.0).frequency[0]
    sysm, _ = pair(2 * z)
    f_twin = coupled_modes(sysm, RHO, C).frequency[0]
    assert f_wall == pytest.approx(f_twin, rel=1e-9)
    assert f_wall < m.frequency[0]                             # the image adds mass


def test_force_between_identical_pair_changes_with_distance_as_coupling_predicts():
    # Bjerknes force ~ |U|^2/d^2 with the coupled U: at a drive below the in-phase resonance the
    # coupling raises |U| (more mass, resonance moves toward the drive), above it lowers it.  The
    # ratio coupled/uncoupled must be |1/(1 - w^2 rho h g(d))|^2 (1e-10) and fade with distance.
    m = single(n_modes=3)
    ratios = {}
    for d in (20e-6, 40e-6, 80e-6):
        sysm = build_system([m, m], [[[0.0, 0.0, 1.0]], [[d, 0.0, 1.0]]], [[R1], [R1]])
        f = np.array([125e3])
        u = coupled_response(sysm, f, RHO, C)[0]
        h = volume_response(m, f)[0, 0]
        w = 2 * math.pi * f[0]
        from acl.physics.coupling import contact_distance

        dd = float(contact_distance(d, 2 * R1))    # the model's distance law (smooth contact floor)
        g = np.exp(-1j * w / C * dd) / (4 * math.pi * dd)
        ratio = abs(u[0]) ** 2 / abs(h) ** 2
        assert ratio == pytest.approx(abs(1 / (1 - w**2 * RHO * h * g)) ** 2, rel=1e-10)
        ratios[d] = ratio
    # 125 kHz is above design 1's uncoupled resonance (~124 kHz): coupling lowers the in-phase
    # resonance, so the force drops, most at 20 um.
    assert ratios[20e-6] < ratios[40e-6] < ratios[80e-6] < 1.0


def test_green_matrix_same_capsule_terms_are_incompressible_and_others_retarded():
    pts = np.array([[0, 0, 1.0], [10e-6, 0, 1.0], [1e-3, 0, 1.0]])
    g = green_matrix(pts, np.array([1e-6] * 3), np.array([0, 0, 1]), np.array([1e5 / C * 2 * math.pi]))[0]
    k = 2 * math.pi * 1e5 / C
    assert g[0, 1] == pytest.approx(1 / (4 * math.pi * 10e-6))                    # same capsule: real
    assert g[0, 2] == pytest.approx(np.exp(-1j * k * 1e-3) / (4 * math.pi * 1e-3))  # other capsule
    assert g[0, 0] == 0


@pytest.mark.parametrize("wall", [0.0, 1.0])
def test_prepared_response_equals_coupled_response(wall):
    # The precomputed evaluator of solver loops (prepared_response) solves the same system as
    # coupled_response: capsules with 1, 3 and 2 orifices (padded layout), displaced configurations,
    # several frequencies; 1e-12 relative.
    three = capsule_modes(V1, [10e-6, 8e-6, 6e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6)
    two = capsule_modes(V1, [9e-6, 12e-6], RHO, SIGMA, P0, 1.0, MU, C, 7e-6)
    pts = [[[0.0, 0.0, 40e-6]], [[60e-6, 0.0, 40e-6], [80e-6, 20e-6, 40e-6], [70e-6, -20e-6, 50e-6]],
           [[0.0, 90e-6, 30e-6], [20e-6, 90e-6, 30e-6]]]
    sysm = build_system([single(), three, two], pts, [[R1], [10e-6, 8e-6, 6e-6], [9e-6, 12e-6]])
    rng = np.random.default_rng(3)
    moved = sysm.points[None] + rng.normal(scale=5e-6, size=(4, sysm.n, 3))
    f = np.array([60e3, 125e3, 240e3])
    expect = coupled_response(sysm, f, RHO, C, wall, points=moved)
    got = prepared_response(sysm, f, RHO, C, wall)(moved)
    np.testing.assert_allclose(got, expect, rtol=1e-12, atol=1e-12 * np.abs(expect).max())
    one = build_system([single(), single()], [[[0.0, 0.0, 40e-6]], [[40e-6, 0.0, 40e-6]]], [[R1], [R1]])
    np.testing.assert_allclose(prepared_response(one, f, RHO, C, wall)(one.points[None])[0],
                               coupled_response(one, f, RHO, C, wall), rtol=1e-12)


@pytest.mark.parametrize("wall", [0.0, 1.0])
def test_prepared_response_of_two_interfaces_closed_form(wall):
    # Two interfaces (a pair of one-orifice capsules) are solved by Cramer's rule: the same volumes as the general
    # solve (coupled_response) to 1e-12 relative, over many configurations from far apart to touching.
    pair = build_system([single(), single(volume=1.12e-13, radius=13e-6)], [[[0.0, 0.0, 40e-6]], [[60e-6, 0.0, 40e-6]]],
                        [[R1], [13e-6]])
    rng = np.random.default_rng(5)
    moved = pair.points[None] + rng.normal(scale=15e-6, size=(64, pair.n, 3))
    moved[:4, 1] = moved[:4, 0] + np.array([[1.0, 0.0, 0.0]]) * np.array([[0.0], [10e-6], [R1 + 13e-6], [30e-6]])
    f = np.array([60e3, 125e3, 240e3])
    expect = coupled_response(pair, f, RHO, C, wall, points=moved)
    got = prepared_response(pair, f, RHO, C, wall)(moved)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, expect, rtol=1e-12, atol=1e-12 * np.abs(expect).max())


def test_modes_up_to_a_frequency_and_a_second_damping_match_the_full_separate_solutions():
    """``max_omega`` keeps a prefix of the full solution and ``also_damping`` gives the Q of a system with
    that damping (a declared Q: same omega and volumes); both to 1e-12 relative."""
    a, b = single(q=12.0), single(volume=1.12e-13, radius=13e-6, q=30.0)
    pts = [[[0.0, 0.0, 40e-6]], [[90e-6, 0.0, 40e-6]], [[0.0, 70e-6, 40e-6]]]
    declared = build_system([a, b, a], pts, [[R1], [13e-6], [R1]])
    bare = build_system([single(), single(volume=1.12e-13, radius=13e-6), single()], pts, [[R1], [13e-6], [R1]])
    full = coupled_modes(declared, RHO, C, 1.0)
    free = coupled_modes(bare, RHO, C, 1.0)
    top = float(np.sort(full.omega)[2]) * 1.01
    part = coupled_modes(declared, RHO, C, 1.0, max_omega=top, also_damping=(bare.damping,))
    assert part.omega.size == 3 < full.omega.size
    np.testing.assert_allclose(part.omega, full.omega[:3], rtol=1e-12)
    np.testing.assert_allclose(part.volume, full.volume[:, :3], rtol=1e-12, atol=1e-12 * np.abs(full.volume).max())
    np.testing.assert_allclose(part.quality, full.quality[:3], rtol=1e-12)
    np.testing.assert_allclose(part.also_quality[0], free.quality[:3], rtol=1e-12)
    assert not np.allclose(part.quality, part.also_quality[0])          # the declared Q does matter
