"""Mechanics analysis of designs: DOFs from joints, equilibrium, snap-in sweeps, latch margins."""
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from acl.analysis import mechanics as M
from acl.design.model import (Beam, Capsule, Cavity, Design, Drive, Fix, Latch, Link, Mount,
                              Orifice, Section, Spring, Tone, Truss)
from acl.diagnostics import DiagnosticError, Span
from acl.physics import beams

SP = Span(file="test.acl", line=1, column=1)
ALPHA, GAMMA = 174.5e-9 * 1e-12, 0.027e-9        # paper Eq. (3) fit at 125 kHz (nN um^2 V^-2, nN V^-2)
EQ3 = M.reduced_eq3_force_model(ALPHA, GAMMA)
UNIT_DRIVE = Drive(tones=(Tone(frequency=125e3, amplitude=1.0),))
# Fig. 2 cantilever: 50 um long, 2 um diameter, E = 13 MPa; Design 1 capsule (Table S1): cylinder
# radius 25 um, height 33 um (6.5e4 um^3); rigid half-length l = 25 um (cylinder axis horizontal).
L, DIAM, E, R_CAP, H_CAP, WALL = 50e-6, 2e-6, 13e6, 25e-6, 33e-6, 2e-6
L_RIGID = R_CAP


def capsule(name, x_face, facing):
    """Design 1 capsule whose orifice (radius 10 um) at x = x_face faces direction ``facing`` (+1/-1)."""
    z = L + L_RIGID
    cx = x_face - facing * (H_CAP / 2 + WALL)
    cav = Cavity(shape="cylinder", volume=np.pi * R_CAP**2 * H_CAP, radius=R_CAP, height=H_CAP,
                 axis=(1.0, 0.0, 0.0))
    ori = Orifice(name="jet", radius=10e-6, normal=(float(facing), 0.0, 0.0), center=(x_face, 0.0, z), span=SP)
    return Capsule(name=name, cavity=cav, orifices=(ori,), center=(cx, 0.0, z), span=SP)


def cantilever(name, x):
    return Beam(name=name, length=L, section=Section(shape="circle", diameter=DIAM), material="tpeta",
                youngs_modulus=E, clamp=(x, 0.0, 0.0), axis=(0.0, 0.0, 1.0), tip=(x, 0.0, L),
                rigid_length=L_RIGID, span=SP)


def fig2_pair(gap):
    a, b = capsule("a", -gap / 2, +1), capsule("b", gap / 2, -1)
    return Design(file="pair.acl", capsules=(a, b),
                  beams=(cantilever("ba", a.center[0]), cantilever("bb", b.center[0])),
                  joints=(Mount(capsule="a", target="ba", target_kind="beam", span=SP),
                          Mount(capsule="b", target="bb", target_kind="beam", span=SP)))


def spring_pair(gap, k=0.7563e-3):
    """Paper Fig. 5c: capsule `top` fixed, `bottom` on a spring along x (0.7563 nN/um)."""
    top, bottom = capsule("top", gap / 2, -1), capsule("bottom", -gap / 2, +1)
    return Design(file="spring.acl", capsules=(top, bottom),
                  springs=(Spring(name="s", stiffness=k, axis=(1.0, 0.0, 0.0), span=SP),),
                  joints=(Fix(capsule="top", span=SP),
                          Mount(capsule="bottom", target="s", target_kind="spring", span=SP)))


EI = E * np.pi * DIAM**4 / 64


def independent_snap_voltage(gap):
    """1-D check: along the symmetric branch V^2(d) = P_eq1((d0 - d)/2) / (alpha/d^2 - 2 gamma); snap-in at its maximum."""
    def minus_v2(d):
        return -beams.eq1_force((gap - d) / 2, L, L_RIGID, EI) / (ALPHA / d**2 - 2 * GAMMA)

    res = minimize_scalar(minus_v2, bounds=(0.05 * gap, gap * (1 - 1e-9)), method="bounded",
                          options={"xatol": 1e-14})
    return float(np.sqrt(-res.fun)), float(res.x)


@pytest.fixture(scope="module")
def fig2_sweeps():
    return {g: M.sweep_voltage(fig2_pair(g * 1e-6), UNIT_DRIVE, 20.0, EQ3) for g in (20, 30, 40, 50)}


def test_fig2_pair_snaps_in_at_every_gap(fig2_sweeps):
    assert all(s.status == "snap_in" for s in fig2_sweeps.values())


def test_fig2_pair_snap_in_voltage_grows_with_gap(fig2_sweeps):
    v = [fig2_sweeps[g].snap_voltage for g in (20, 30, 40, 50)]
    assert all(x < y for x, y in zip(v, v[1:]))


@pytest.mark.parametrize("gap", [20, 30, 40, 50])
def test_fig2_pair_snap_in_matches_independent_1d_computation(fig2_sweeps, gap):
    # Self-consistency: 2-cantilever, 4-DOF continuation vs 1-D maximisation; tolerance 1e-4.
    v_ref, d_ref = independent_snap_voltage(gap * 1e-6)
    sweep = fig2_sweeps[gap]
    assert sweep.snap_voltage == pytest.approx(v_ref, rel=1e-4)
    pa, pb = sweep.snap_positions["a"], sweep.snap_positions["b"]
    d = (pb[0] - pa[0]) - (2 * (H_CAP / 2 + WALL))
    assert d == pytest.approx(d_ref, rel=1e-3)


def test_fig2_pair_moves_symmetrically_along_the_line_of_centres(fig2_sweeps):
    s = fig2_sweeps[30]
    assert np.allclose(s.positions["a"][:, 0] - s.positions["a"][0, 0],
                       -(s.positions["b"][:, 0] - s.positions["b"][0, 0]), rtol=1e-6, atol=1e-15)
    assert np.allclose(s.positions["a"][:, 1:], s.positions["a"][0, 1:], atol=1e-15)


def test_fig2_pair_beyond_critical_distance_repels():
    # With thrust, d_c = sqrt(alpha / (2 gamma)) = 56.8 um for Eq. (3): at 70 um the beams bend apart.
    state = M.equilibrium(fig2_pair(70e-6), Drive(tones=(Tone(frequency=125e3, amplitude=3.0),)), EQ3)
    assert state.status == "ok" and state.stable
    assert state.displacements["a"][0] < 0 < state.displacements["b"][0]


def test_spring_pair_snaps_at_two_thirds_gap_without_thrust():
    # Paper Fig. 5c mechanism, thrust off: gap at snap-in = 2/3 of the initial gap (tolerance 0.1%).
    model = M.reduced_eq3_force_model(ALPHA, 0.0)
    sweep = M.sweep_voltage(spring_pair(30e-6), UNIT_DRIVE, 50.0, model)
    assert sweep.status == "snap_in"
    assert sweep.snap_gap(spring_pair(30e-6), "top", "bottom") / 30e-6 == pytest.approx(2 / 3, rel=1e-3)


def test_equilibrium_reports_spring_extension_and_small_residual():
    state = M.equilibrium(spring_pair(40e-6), UNIT_DRIVE, EQ3)
    assert state.status == "ok" and state.stable
    d = state.positions["top"][0] - state.positions["bottom"][0] - 2 * (H_CAP / 2 + WALL)
    force = (ALPHA / d**2 - 2 * GAMMA)
    assert state.deflections["s"] * 0.7563e-3 == pytest.approx(force, rel=1e-8)


def test_truss_link_moves_capsules_together():
    d = fig2_pair(30e-6)
    d = d.model_copy(update={
        "trusses": (Truss(name="t", span=SP),),
        "joints": d.joints + (Link(a="a", b="b", element="t", element_kind="truss", span=SP),)})
    state = M.equilibrium(d, UNIT_DRIVE, EQ3)
    assert state.status == "ok"
    assert np.allclose(state.displacements["a"], state.displacements["b"], atol=1e-18)


def test_link_to_an_unknown_element_is_a_diagnostic():
    d = fig2_pair(30e-6)
    d = d.model_copy(update={"joints": d.joints + (Link(a="a", b="ground", element="nope",
                                                        element_kind="spring", span=SP),)})
    with pytest.raises(DiagnosticError) as err:
        M.build_mechanism(d)
    assert err.value.diagnostics[0].code == "E-MECH-002"


def test_large_deflection_warns_that_eq1_is_out_of_range():
    def push(design, positions, drive):
        V2 = sum(t.amplitude**2 for t in drive.tones)
        return {"a": np.array([-V2 * 2e-9, 0, 0]), "b": np.array([V2 * 2e-9, 0, 0])}

    state = M.equilibrium(fig2_pair(30e-6), UNIT_DRIVE, push)
    assert state.status == "ok"
    assert any(dg.code == "W-MECH-001" for dg in state.diagnostics)
    large = M.equilibrium(fig2_pair(30e-6), UNIT_DRIVE, push, mode="large")
    assert large.status == "ok" and not large.diagnostics
    assert abs(large.displacements["a"][0]) < abs(state.displacements["a"][0])
    # a voltage sweep reports the same warning at its last point (computed when first read), and
    # none while the deflection stays small
    assert any(dg.code == "W-MECH-001" for dg in M.sweep_voltage(fig2_pair(30e-6), UNIT_DRIVE, 1.0, push).diagnostics)
    assert not M.sweep_voltage(fig2_pair(30e-6), UNIT_DRIVE, 0.1, push).diagnostics


def _latched(state, push_nN):
    lt = Latch(name="l", angle=np.radians(45), length=50e-6, width=1e-6, thickness=1.7e-6,
               material="tpeta", youngs_modulus=E, anchor=(0.0, 0.0, 0.0), axis=(1.0, 0.0, 0.0),
               state=state, span=SP)
    cap = capsule("c", 0.0, -1)
    d = Design(file="latch.acl", capsules=(cap,), latches=(lt,),
               joints=(Mount(capsule="c", target="l", target_kind="latch", span=SP),))

    def push(design, positions, drive):
        return {"c": np.array([push_nN * 1e-9 * drive.tones[0].amplitude**2, 0.0, 0.0])}

    return d, push


def test_latch_margin_compares_push_with_switching_force():
    d, push = _latched("a", 50.0)
    m = M.latch_margins(d, UNIT_DRIVE, push)["l"]
    assert m.bistable and m.margin == pytest.approx(50e-9 / m.switching_force, rel=1e-12)
    assert m.margin > 1          # 50 nN > ~41 nN switching force at 45 degrees


def test_latch_switches_when_pushed_beyond_its_switching_force():
    d, push = _latched("a", 1.0)
    sweep = M.sweep_voltage(d, UNIT_DRIVE, 10.0, push)
    assert sweep.status == "snap_in"
    m = M.latch_margins(d, UNIT_DRIVE, push)["l"]
    assert sweep.snap_voltage**2 * 1e-9 == pytest.approx(m.switching_force, rel=1e-3)


def test_truss_between_two_supported_capsules_keeps_their_distance_only():
    # Paper Fig. 5a: a moving capsule tied by a truss to an anchored one can still move across the tie.
    d = fig2_pair(30e-6)
    d = d.model_copy(update={
        "trusses": (Truss(name="t", span=SP),),
        "joints": (d.joints[0], Fix(capsule="b", span=SP),
                   Link(a="a", b="b", element="t", element_kind="truss", span=SP))})

    def sideways(design, positions, drive):
        return {"a": np.array([1e-10, 2e-10, 0.0]), "b": np.zeros(3)}

    state = M.equilibrium(d, UNIT_DRIVE, sideways)
    assert state.status == "ok"
    assert abs(state.displacements["a"][0]) < 1e-18        # along the tie: held
    assert state.displacements["a"][1] > 1e-7               # across the tie: free to bend


def test_drive_above_snap_in_reports_snap_not_an_equilibrium():
    v = independent_snap_voltage(30e-6)[0]
    state = M.equilibrium(fig2_pair(30e-6), Drive(tones=(Tone(frequency=125e3, amplitude=1.01 * v),)), EQ3)
    assert state.status == "snap_in" and not state.stable


def test_direct_solve_from_a_start_matches_continuation():
    drive = Drive(tones=(Tone(frequency=125e3, amplitude=0.8),))
    design = fig2_pair(30e-6)
    cont = M.equilibrium(design, drive, EQ3)
    direct = M.equilibrium(design, drive, EQ3, start={c.name: c.center for c in design.capsules})
    assert direct.status == "ok" and direct.stable
    assert np.allclose(direct.positions["a"], cont.positions["a"], rtol=0, atol=1e-12)


def test_latch_resting_in_state_b_is_force_free_and_needs_the_release_force_back():
    d, push = _latched("b", -30.0)       # pushes along -axis, back towards state a
    state = M.equilibrium(d, Drive(tones=(Tone(frequency=125e3, amplitude=0.0),)), push)
    assert state.status == "ok" and np.allclose(state.displacements["c"], 0.0)
    m = M.latch_margins(d, UNIT_DRIVE, push)["l"]
    assert m.required == pytest.approx(m.release_force) and m.margin == pytest.approx(30e-9 / m.release_force)


@pytest.mark.parametrize("name, khz, tol", [("fig4_facing_pair", 125, 1e-6), ("fig5c_linear_spring", 125, 1e-6),
                                            ("figS6_flextensional", 125, 1e-6), ("fig6e_reversible_latch", 85, 1e-5),
                                            ("fig6f_control_module", 85, 1e-5)])
def test_snap_in_voltage_of_the_examples_is_bracketed_by_the_dynamics(name, khz, tol):
    # Accuracy of the reported snap-in voltage (acl analyze's sweep), checked by where the mechanism
    # goes (acl.physics.equilibrium.settle, overdamped flow from the snap state): just below it rests
    # next to the snap state, just above it runs away (contact or the latch's far state).  Smooth
    # folds (Fig. 4, 5c, S6): 1e-6 relative; the latches' kink limits (Fig. 6e, 6f: buckling onset
    # of the tabulated post-buckling law, located by natural-parameter steps of 1e-6 V): 1e-5.
    from pathlib import Path

    import acl
    from acl.analysis import acoustics as AC
    from acl.physics.equilibrium import settle
    d = acl.load(str(Path(__file__).resolve().parents[1] / "examples" / f"{name}.acl"))
    drive = Drive(tones=(Tone(frequency=khz * 1e3, amplitude=1.0),))
    fm = AC.force_model_for(d)
    sweep = M.sweep_voltage(d, drive, d.transducer.max_voltage if d.transducer else 20.0, fm)
    assert sweep.status == "snap_in"
    mech = M.build_mechanism(d)
    rest, ext, adm = M._restoring(mech), M._external(d, mech, drive, fm), M._admissible(d, mech)
    z = mech.Z.T @ np.concatenate([mech.bases[g].T @ (sweep.snap_positions[grp[0]] - np.asarray(d.capsule(grp[0]).center))
                                   for g, grp in enumerate(mech.groups)])
    size = np.linalg.norm(z)
    below = settle(rest, ext, z, sweep.snap_voltage * (1 - tol), admissible=adm, length_scale=M.LENGTH_SCALE)
    assert below.status == "ok" and below.stable and np.linalg.norm(below.q - z) < 0.05 * size
    above = settle(rest, ext, z, sweep.snap_voltage * (1 + tol), admissible=adm, length_scale=M.LENGTH_SCALE)
    assert above.status == "inadmissible" or np.linalg.norm(above.q - z) > 0.5 * size
