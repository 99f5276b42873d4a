"""The fit's vectorized forward model agrees with the physics layer it stands in for."""
from __future__ import annotations

import numpy as np
import pytest

from acl.fit import beam as B
from acl.physics import beams as PB
from acl.physics.forces import pair_law_force


def test_uniform_stiffness_integrals_reproduce_paper_eq1():
    L, l, EI = 50e-6, 18.6e-6, 1.02e-17
    P = np.linspace(0, 3e-9, 7)
    cd, ct = B.stiffness_integrals(np.full(7, L), np.full(7, l), np.full(7, EI))
    np.testing.assert_allclose(B.eq1_deflection(P, l, cd, ct), PB.eq1_deflection(P, L, l, EI), rtol=1e-10)


def test_stiffer_top_makes_a_cantilever_more_compliant_than_a_stiffer_root_would():
    cd_top, _ = B.stiffness_integrals(50e-6, 18e-6, 1e-17, gradient=1.0)
    cd_root, _ = B.stiffness_integrals(50e-6, 18e-6, 1e-17, gradient=-1.0)
    assert cd_top > cd_root       # the root carries the largest moment


@pytest.mark.parametrize("lam,p", [(0.0, 0.7), (0.37, 2.0), (0.8, 5.0)])
def test_elastica_table_matches_the_physics_bvp(lam, p):
    ref = PB.elastica(p, 1.0, lam, 1.0).deflection[0]
    assert B.elastica_deflection(p, 1.0, lam, 1.0) == pytest.approx(ref, rel=2e-3)


def test_pair_equilibrium_balances_eq3_against_eq1():
    from acl.fit.forward import _pair_equilibrium

    L, l, EI = 50e-6, 18.6e-6, 1.02e-17
    cd, ct = B.stiffness_integrals(L, l, EI)
    alpha, gamma = 1.745e-19, 2.7e-11
    d0 = np.array([30e-6, 45e-6, 60e-6, 80e-6])
    V = np.array([0.8, 1.5, 3.0, 3.0])

    def law(c, load):
        return B.eq1_deflection(load, l, cd, ct)

    da, db = _pair_equilibrium(law, alpha * V**2, 2 * gamma * V**2, d0)
    d = d0 - da - db
    force = pair_law_force(alpha, gamma, d, V)            # attraction-positive, paper Eq. (3)
    np.testing.assert_allclose(PB.eq1_force(da, L, l, EI), force, rtol=1e-6, atol=1e-15)
    assert np.all((d < d0) == (d0 < np.sqrt(alpha / (2 * gamma))))   # attract below d_c, repel above
