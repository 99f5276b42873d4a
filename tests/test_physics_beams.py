"""Cantilever with rigid actuator (paper Eq. (1), Suppl. Note 2), elastica, validity, flexures."""
import numpy as np
import pytest

from acl.physics import beams, springs

# Fig. 2 cantilever (paper text: 50 um long, 2 um diameter, E = 13 MPa); l = Design 1 radius 25 um.
L, D, E, LR = 50e-6, 2e-6, 13e6, 25e-6
EI = E * np.pi * D**4 / 64


def _eq1_from_note2(P):
    """Suppl. Note 2 rebuilt step by step: cubic (2.4) at x = L, slope (2.5), rigid rotation (2.6)."""
    u = np.polynomial.Polynomial([0, 0, 3 * (LR + L), -1]) * (1.0 / (6 * EI))
    flexible_end = P * u(L)
    slope = P * u.deriv()(L)
    return flexible_end + LR * np.sin(np.arctan(slope))


def test_eq1_matches_supplementary_note_2_to_1e9():
    # Paper Eq. (1) vs Suppl. Eqs. (2.4)-(2.6); tolerance 1e-9 relative (issue 3 acceptance).
    P = np.geomspace(1e-12, 1e-6, 40)
    assert np.allclose(beams.eq1_deflection(P, L, LR, EI), _eq1_from_note2(P), rtol=1e-9, atol=0)


def test_eq1_force_inverts_eq1():
    P = np.concatenate([-np.geomspace(1e-12, 1e-6, 20), np.geomspace(1e-12, 1e-6, 20)])
    d = beams.eq1_deflection(P, L, LR, EI)
    assert np.allclose(beams.eq1_force(d, L, LR, EI), P, rtol=1e-9, atol=0)


def test_eq1_small_force_stiffness_is_the_slope_at_zero():
    P = 1e-15
    slope = P / beams.eq1_deflection(P, L, LR, EI)
    assert slope == pytest.approx(beams.eq1_small_force_stiffness(L, LR, EI), rel=1e-9)
    assert beams.eq1_tangent_stiffness(1e-12, L, LR, EI) == pytest.approx(slope, rel=1e-6)


def test_supplementary_k_overestimates_load_point_stiffness():
    # Suppl. Eq. (2.5) k ignores the rigid part's rotation: stiffer than Eq. (1) at small force.
    assert beams.flexible_part_stiffness(L, LR, EI) > 1.8 * beams.eq1_small_force_stiffness(L, LR, EI)
    assert beams.flexible_part_stiffness(L, 0.0, EI) == pytest.approx(3 * EI / L**3, rel=1e-12)


def test_elastica_dead_load_reproduces_classical_0_3017():
    # Bisshopp & Drucker (1945): delta/L = 0.3017 at P L^2/EI = 1, no rigid tip; tolerance 0.1%.
    sol = beams.elastica(EI / L**2, L, 0.0, EI)
    assert sol.converged[0]
    assert sol.deflection[0] / L == pytest.approx(0.3017, rel=1e-3)


@pytest.mark.parametrize("mode", ["dead", "follower"])
def test_elastica_with_rigid_tip_tends_to_eq1_at_small_load(mode):
    P = 1e-3 * EI / L**2
    sol = beams.elastica(P, L, LR, EI, mode=mode)
    assert sol.deflection[0] == pytest.approx(beams.eq1_deflection(P, L, LR, EI), rel=1e-5)


def test_follower_load_bends_more_than_dead_load():
    P = 1.5 * EI / L**2
    dead = beams.elastica(P, L, LR, EI, mode="dead").deflection[0]
    follower = beams.elastica(P, L, LR, EI, mode="follower").deflection[0]
    assert follower > dead * 1.02


def test_elastica_is_odd_in_load():
    sol = beams.elastica([-0.8 * EI / L**2, 0.8 * EI / L**2], L, LR, EI)
    assert sol.deflection[0] == pytest.approx(-sol.deflection[1], rel=1e-9)


def test_elastica_force_inverts_elastica():
    P = np.array([0.1, 0.7, 2.0]) * EI / L**2
    d = beams.elastica(P, L, LR, EI).deflection
    assert np.allclose(beams.elastica_force(d, L, LR, EI), P, rtol=2e-4)


def test_eq1_validity_limit_near_0_3_L_for_quarter_length_actuator():
    # Issue 3: Eq. (1) flagged beyond ~0.3 L where it departs from the elastica by > 5%.
    limit = beams.eq1_validity_limit(L, L / 4)
    assert 0.27 * L < limit < 0.37 * L


def test_eq1_validity_limit_grows_with_the_rigid_length_above_its_floor():
    # mechanics skips the elastica for deflections below EQ1_LIMIT_FLOOR * L: the floor must stay
    # below the limit for every l/L >= 0.  The limit's minimum is at l = 0 (0.2145 L) and it grows
    # with l/L; checked on a grid of l/L from 0 to 10.
    lam = [0.0, 0.01, 0.03, 0.06, 0.1, 0.2, 0.35, 0.5, 1.0, 2.0, 5.0, 10.0]
    ratio = [beams.eq1_validity_limit(1.0, x) for x in lam]
    assert ratio[0] == pytest.approx(0.2145, abs=5e-4)
    assert all(a < b for a, b in zip(ratio, ratio[1:]))
    assert ratio[0] > beams.EQ1_LIMIT_FLOOR


def test_eq1_departure_crosses_5_percent_at_the_validity_limit():
    limit = beams.eq1_validity_limit(L, LR)
    P_lim = beams.elastica_force(limit, L, LR, EI)
    below, at = beams.eq1_departure([0.8 * P_lim, P_lim], L, LR, EI)
    assert abs(below) < 0.05
    assert abs(at) == pytest.approx(0.05, abs=2e-3)
    assert beams.eq1_is_valid(0.9 * limit, L, LR) and not beams.eq1_is_valid(1.1 * limit, L, LR)


def test_guided_beam_stiffness_matches_beam_equation():
    # Clamped-guided beam, u'''' = 0 with u(0)=u'(0)=u'(Lg)=0 and shear P: solve the 4x4 system.
    Lg, I = 80e-6, springs.rect_second_moment(2e-6, 10e-6)
    P = 1e-9
    # u = a2 x^2 + a3 x^3; u'(Lg) = 0 and EI u'''(Lg) = -P
    a3 = -P / (6 * E * I)
    a2 = -3 * a3 * Lg / 2
    k = P / (a2 * Lg**2 + a3 * Lg**3)
    assert springs.guided_beam_stiffness(E, I, Lg) == pytest.approx(k, rel=1e-12)


def test_springs_combine_in_series_and_parallel():
    assert springs.in_series(2.0, 2.0) == pytest.approx(1.0)
    assert springs.in_parallel(2.0, 3.0) == pytest.approx(5.0)
    assert springs.spring_force(0.7563e-3, 2e-6) == pytest.approx(-1.5126e-9)


def test_elastica_tip_batched_equals_one_load_at_a_time():
    # One shooting solver for every batch shape: a (3, 4) grid of (P L^2/EI, l/L) against one call per entry; 1e-9.
    p, lam = np.array([[0.4], [2.0], [5.0]]), np.array([0.0, 0.2, 0.7, 1.5])
    for mode in ("dead", "follower"):
        grid = beams.elastica_tip(p, lam, mode)
        assert grid[0].shape == (3, 4) and grid[3].all()
        for i in range(3):
            for j in range(4):
                one = beams.elastica_tip(p[i, 0], lam[j], mode)
                assert grid[0][i, j] == pytest.approx(float(one[0]), rel=1e-9)
                assert grid[2][i, j] == pytest.approx(float(one[2]), rel=1e-9)


def test_elastica_table_of_the_fit_is_the_elastica_at_its_nodes():
    # acl.physics.cantilever (the fit's names) reads the one solver's table: exact at the grid nodes (1e-9).
    from acl.physics import cantilever

    p_grid, lam_grid, table = cantilever.elastica_table()
    for i, j in ((6, 0), (30, 9), (60, 20)):
        d = beams.elastica(p_grid[i], 1.0, lam_grid[j], 1.0).deflection[0]
        assert table[i, j] == pytest.approx(d, rel=1e-8)
        assert cantilever.elastica_deflection(p_grid[i], 1.0, lam_grid[j], 1.0) == pytest.approx(d, rel=1e-8)


def _bvp_reference(p, lam, mode):
    """(delta/L, tip angle) of the elastica by scipy's solve_bvp (tol 1e-10, continuation in p): an independent check."""
    from scipy.integrate import solve_bvp

    s = np.linspace(0.0, 1.0, 21)
    y = np.zeros((4, s.size))
    y[2] = s
    sol = None
    for pp in np.linspace(0.0, p, int(np.ceil(p / 0.5)) + 1)[1:]:
        def rhs(_, y, par, pp=pp):
            return np.vstack([y[1], -pp * np.cos(y[0] - (par[0] if mode == "follower" else 0.0)),
                              np.cos(y[0]), np.sin(y[0])])

        def bc(ya, yb, par, pp=pp):
            moment = pp * lam * (1.0 if mode == "follower" else np.cos(par[0]))
            return np.array([ya[0], ya[2], ya[3], yb[0] - par[0], yb[1] - moment])

        sol = solve_bvp(rhs, bc, s if sol is None else sol.x, y if sol is None else sol.y,
                        p=[0.0] if sol is None else sol.p, tol=1e-10, max_nodes=20000)
        assert sol.status == 0
    return sol.y[3, -1] + lam * np.sin(sol.p[0]), sol.p[0]


@pytest.mark.parametrize("mode", ["dead", "follower"])
def test_elastica_tip_agrees_with_an_independent_bvp_solve(mode):
    # docs/explanation/structures.md section 2: the one shooting solver vs solve_bvp (tol 1e-10), p <= 6: deflection to
    # 1e-8 L (the follower's deflection at p = 6, l = L is small: 2e-8 relative), tip angle 1e-9 relative.
    for p, lam in ((0.5, 0.0), (2.0, 0.36), (6.0, 1.0)):
        ref_d, ref_a = _bvp_reference(p, lam, mode)
        d, _, a, ok, _ = beams.elastica_tip(p, lam, mode)
        assert ok and d == pytest.approx(ref_d, rel=0, abs=1e-8) and a == pytest.approx(ref_a, rel=1e-9)
