"""Acoustic forces (acl.physics.forces) and drive pressure (acl.physics.transducer)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from acl.physics.forces import (
    bjerknes_attraction,
    bjerknes_vectors,
    boundary_layer,
    critical_distance,
    law_critical_distance,
    streaming_constant_from_critical_distance,
    jet_drag,
    pair_law_force,
    thrust_magnitude,
)
from acl.physics.transducer import drive_pressure, pressure_per_volt

RHO = 998.2
OMEGA = 2 * math.pi * 125e3

# Paper Eq. (3) fit at 125 kHz: alpha = 174.5 nN um^2 V^-2 (printed unit corrected), gamma = 0.027 nN V^-2.
ALPHA = 174.5e-9 * 1e-12
GAMMA = 0.027e-9

phases = st.floats(min_value=0.0, max_value=2 * math.pi, allow_nan=False)
amplitudes = st.floats(min_value=1e-20, max_value=1e-14)


@given(phase=phases, a=amplitudes, b=amplitudes)
def test_bjerknes_attracts_within_a_quarter_period_and_repels_beyond(phase, a, b):
    # Paper text at Fig. 4f: attraction for |dphi| < 90 deg, repulsion for 90 < dphi < 270 deg.
    f = bjerknes_attraction(OMEGA, a, b * np.exp(1j * phase), 20e-6, RHO)
    c = math.cos(phase)
    if abs(c) > 1e-9:
        assert np.sign(f) == np.sign(c)


@pytest.mark.parametrize("deg, sign", [(89.0, 1), (91.0, -1), (269.0, -1), (271.0, 1)])
def test_bjerknes_sign_changes_at_90_and_270_degrees(deg, sign):
    f = bjerknes_attraction(OMEGA, 1e-16, 1e-16 * np.exp(1j * math.radians(deg)), 20e-6, RHO)
    assert np.sign(f) == sign


def test_bjerknes_equals_time_average_of_volume_velocity_product():
    # F = -rho/(4 pi d^2) <dV1/dt dV2/dt>, averaged numerically over one period (attraction positive).
    v1, v2, d = 3e-16, 2e-16 * np.exp(1j * 0.7), 30e-6
    t = np.linspace(0, 2 * math.pi / OMEGA, 20001)[:-1]
    dv1 = np.real(1j * OMEGA * v1 * np.exp(1j * OMEGA * t))
    dv2 = np.real(1j * OMEGA * v2 * np.exp(1j * OMEGA * t))
    expected = RHO / (4 * math.pi * d**2) * np.mean(dv1 * dv2)
    assert bjerknes_attraction(OMEGA, v1, v2, d, RHO) == pytest.approx(expected, rel=1e-9)


@settings(max_examples=50)
@given(phase=phases,
       pa=st.tuples(*[st.floats(-1e-4, 1e-4)] * 3),
       pb=st.tuples(*[st.floats(-1e-4, 1e-4)] * 3))
def test_bjerknes_pair_forces_are_equal_and_opposite_along_the_line(phase, pa, pb):
    sep = np.subtract(pb, pa)
    if np.linalg.norm(sep) < 1e-6:
        return
    on_a, on_b = bjerknes_vectors(OMEGA, 1e-16, pa, 1e-16 * np.exp(1j * phase), pb, RHO)
    np.testing.assert_allclose(on_a, -on_b)
    assert np.linalg.norm(np.cross(on_a, sep)) <= 1e-9 * np.linalg.norm(on_a) * np.linalg.norm(sep) + 1e-30


def test_critical_distance_of_paper_eq3_is_56p85_um():
    # d_c = sqrt(alpha / (2 gamma)) with the paper's Eq. (3) fit; tolerance 0.01 um.
    assert critical_distance(ALPHA, GAMMA) == pytest.approx(56.85e-6, abs=0.01e-6)


def test_reduced_pair_law_attracts_inside_and_repels_outside_critical_distance():
    dc = critical_distance(ALPHA, GAMMA)
    assert pair_law_force(ALPHA, GAMMA, 0.9 * dc, 5.0) > 0
    assert pair_law_force(ALPHA, GAMMA, 1.1 * dc, 5.0) < 0
    assert pair_law_force(ALPHA, GAMMA, dc, 5.0) == pytest.approx(0.0, abs=1e-20)


def test_law_critical_distance_balances_bjerknes_against_two_thrusts():
    # Identical in-phase interfaces: rho w^2 |dV|^2/(8 pi d_c^2) = 2 x thrust (Crum 1975 + the
    # Stokes-regime streaming law, Stuart 1966).  The closed form must be that balance (1e-12 rel.),
    # for any amplitude, radius, frequency and constant.
    mu = 1.002e-3
    for dv, r, f, cs in [(1e-16, 10e-6, 125e3, 8e-3), (3e-17, 6e-6, 80e3, 0.2), (5e-16, 15e-6, 200e3, 1e-3)]:
        w = 2 * math.pi * f
        dc = law_critical_distance(r, w, RHO, mu, cs)
        bj = bjerknes_attraction(w, dv, dv, dc, RHO)
        assert bj == pytest.approx(2 * thrust_magnitude(dv, r, w, mu, cs), rel=1e-12)
        assert streaming_constant_from_critical_distance(dc, r, w, RHO, mu) == pytest.approx(cs, rel=1e-12)


def test_thrust_is_quadratic_in_amplitude_and_linear_in_frequency_and_viscosity():
    # F = C_s 6 pi mu omega eps^2 (Stokes outer flow driven by a slip ~ omega eps^2 / R; Riley 2001):
    # quadratic in eps (paper Eq. 3's gamma V^2), independent of R at fixed eps.  1e-12 rel.
    r, cs, mu = 10e-6, 8e-3, 1e-3
    f1 = thrust_magnitude(1e-16, r, OMEGA, mu, cs)
    assert thrust_magnitude(2e-16, r, OMEGA, mu, cs) == pytest.approx(4 * f1, rel=1e-12)
    assert thrust_magnitude(1e-16, r, 2 * OMEGA, mu, cs) == pytest.approx(2 * f1, rel=1e-12)
    assert thrust_magnitude(1e-16, r, OMEGA, 2 * mu, cs) == pytest.approx(2 * f1, rel=1e-12)
    # same centre amplitude on a twice larger orifice (4x the volume) gives the same thrust
    assert thrust_magnitude(4e-16, 2 * r, OMEGA, mu, cs) == pytest.approx(f1, rel=1e-12)


def test_boundary_layer_of_water_at_125_khz_is_1p6_um():
    # delta = sqrt(2 nu / omega) (Landau & Lifshitz section 24): water, 125 kHz -> 1.60 um (0.5 %).
    assert boundary_layer(2 * math.pi * 125e3, 998.2, 1.002e-3) == pytest.approx(1.60e-6, rel=5e-3)


def test_jet_drag_vanishes_behind_the_orifice_and_never_exceeds_the_jet_flux():
    assert jet_drag(1e-9, 50e-6, -0.5, 25e-6) == 0.0
    assert jet_drag(1e-9, 1e-6, 1.0, 25e-6) == pytest.approx(1e-9)
    assert jet_drag(1e-9, 200e-6, 1.0, 25e-6) < 1e-9


# --- drive pressure -----------------------------------------------------------------------------

TABLE_F = (50e3, 100e3, 150e3)
TABLE_G = (200.0, 400.0, 100.0)


def test_gain_is_interpolated_linearly_inside_the_table():
    g, outside = pressure_per_volt([75e3, 125e3], TABLE_F, TABLE_G)
    np.testing.assert_allclose(g, [300.0, 250.0])
    assert not outside.any()


def test_gain_is_held_flat_and_flagged_outside_the_table():
    g, outside = pressure_per_volt([10e3, 200e3, 100e3], TABLE_F, TABLE_G)
    np.testing.assert_allclose(g, [200.0, 100.0, 400.0])
    assert outside.tolist() == [True, True, False]


def test_drive_pressure_is_linear_in_voltage():
    p1, _ = drive_pressure(120e3, 1.0, TABLE_F, TABLE_G)
    p7, _ = drive_pressure(120e3, 7.0, TABLE_F, TABLE_G)
    assert p7 == pytest.approx(7 * p1)


def test_unsorted_gain_table_is_rejected():
    with pytest.raises(ValueError):
        pressure_per_volt(1e5, (2e5, 1e5), (1.0, 2.0))


@pytest.mark.parametrize("capsules", [1, 2])
def test_capsule_forces_of_one_capsule_are_its_thrust_alone(capsules):
    """One capsule has no pair of interfaces on different capsules and no jet reaching another capsule: its force is
    the thrust sum_o -|F_o| n_o alone (the Bjerknes and drag terms are skipped, not computed as zeros); two capsules
    get both terms (their sum differs from the thrust)."""
    from acl.physics.forces import capsule_forces, force_constants

    rng = np.random.default_rng(9)
    body = np.repeat(np.arange(capsules), 3)
    n = body.size
    offsets = rng.normal(0.0, 20e-6, (n, 3))
    normals = offsets / np.linalg.norm(offsets, axis=1, keepdims=True)
    onehot = (body[:, None] == np.arange(capsules)[None, :]).astype(float)
    centres = np.array([[0.0, 0.0, 60e-6], [90e-6, 0.0, 60e-6]])[None, :capsules] + rng.normal(0, 1e-6, (4, capsules, 3))
    radii = np.full(n, 8e-6)
    w = 2 * math.pi * np.array([80e3, 125e3])
    k = force_constants(w, radii, body, capsules, 1.0e-3, RHO, 0.5, np.array([1e3, 2e3]), np.ones(capsules),
                        np.ones((capsules, capsules)))
    resp = (rng.normal(size=(4, 2, n)) + 1j * rng.normal(size=(4, 2, n))) * 1e-16
    total, _, thr, att = capsule_forces(centres, body, offsets, normals, onehot, np.full(capsules, 30e-6), resp, k)
    expect_thr = ((resp.real ** 2 + resp.imag ** 2) * k["thrust"]).sum(axis=1)
    np.testing.assert_allclose(thr, expect_thr, rtol=1e-14)
    thrust_only = np.einsum("nc,bnk->bck", onehot, -thr[:, :, None] * normals)
    if capsules == 1:
        np.testing.assert_allclose(total, thrust_only, rtol=1e-14, atol=0.0)
        assert not att.any()
    else:
        assert att.any() and not np.allclose(total, thrust_only, rtol=1e-6, atol=0.0)
