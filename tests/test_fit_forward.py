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
    from acl.fit.eq3 import _pair_equilibrium

    L, l, EI = 50e-6, 18.6e-6, 1.02e-17
    cd, ct = B.stiffness_integrals(L, l, EI)
    alpha, gamma = 1.745e-19, 2.7e-11
    d0 = np.array([30e-6, 45e-6, 60e-6, 80e-6])
    V = np.array([0.8, 1.5, 3.0, 3.0])

    def law(load):
        return B.eq1_deflection(load, l, cd, ct)

    da, db = _pair_equilibrium(law, law, alpha * V**2, 2 * gamma * V**2, d0)
    d = d0 - da - db
    force = pair_law_force(alpha, gamma, d, V)            # attraction-positive, paper Eq. (3)
    np.testing.assert_allclose(PB.eq1_force(da, L, l, EI), force, rtol=1e-6, atol=1e-15)
    assert np.all((d < d0) == (d0 < np.sqrt(alpha / (2 * gamma))))   # attract below d_c, repel above


def test_vectorized_pair_agrees_with_the_mechanics_analysis_layer():
    """Same design, same Eq. (3) law: acl.fit.forward vs acl.analysis.mechanics.equilibrium (continuation)."""
    import os

    import acl
    from acl.analysis.mechanics import equilibrium, reduced_eq3_force_model
    from acl.design.model import Drive, Tone
    from acl.fit.data import Dataset
    from acl.fit.forward import predict, prepare
    from acl.fit.mechanism import build_instance

    path = os.path.join(os.path.dirname(__file__), "..", "samples", "fit_pair.acl")
    alpha, gamma = 1.745e-19, 2.7e-11
    cases = [("35 um", 0.8), ("45 um", 1.5), ("70 um", 2.5)]
    n = len(cases)
    data = Dataset(np.array(["distance"] * n, dtype=object), np.zeros(n), np.full(n, np.nan), np.full(n, np.nan),
                   [((125e3, v),) for _, v in cases], {"gap": np.array([g for g, _ in cases], dtype=object)}, {},
                   [None] * n, np.array(["um"] * n, dtype=object))
    P = prepare(data, lambda key: build_instance(acl.load(path, overrides=dict(key)), "eq3"))
    ours = predict(P, {"alpha": alpha, "gamma": gamma}, {})
    for i, ((gap, v), mine) in enumerate(zip(cases, ours)):
        design = acl.load(path, overrides={"gap": gap})
        # the forward model scales gamma and alpha per configuration by the coupled bubbles' response at
        # rest relative to the first row's (acl.physics.coupling: a neighbour's distance changes both);
        # the continuation gets the same per-configuration law
        state = equilibrium(design, Drive(tones=(Tone(frequency=125e3, amplitude=v),)),
                            reduced_eq3_force_model(alpha * P.arel[i, 0], gamma * P.tau[0, i, 0]))
        assert state.status == "ok"
        pa = np.asarray(design.capsule("a").orifices[0].center) + state.displacements["a"]
        pb = np.asarray(design.capsule("b").orifices[0].center) + state.displacements["b"]
        assert mine == pytest.approx(float(np.linalg.norm(pb - pa)), rel=1e-6)


def test_displacement_and_position_observables_of_one_actuator_are_consistent():
    """examples/fig2: `delta` = displacement(arm, -x) and `act_x` = position(act, x) see the same motion."""
    import os

    import acl
    from acl.fit.synth import Experiment, generate

    path = os.path.join(os.path.dirname(__file__), "..", "examples", "fig2_vertical_cantilever.acl")
    design = acl.load(path)
    data, _ = generate(path, Experiment(frequencies=(125e3,), voltages=(0.0, 3.0, 6.0)))
    delta = data.value[data.observable == "delta"]
    x = data.value[data.observable == "act_x"]
    # the jet leaves along the orifice normal (+x) and pushes the actuator towards -x (acl.physics.forces)
    assert delta[0] == 0 and np.all(np.diff(delta) > 0)
    np.testing.assert_allclose(x - design.capsule("act").center[0], -delta, rtol=1e-12, atol=1e-18)
