"""The batched engine (issue 23): Newton over rows, forces under per-row drives, equilibria of many rows at once.

Each batched function is compared with an independent computation: a closed form, or a loop of the public
one-drive functions (acoustics.force_model, mechanics.equilibrium) on a small case.
"""
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis import acoustics, equilibria, interfaces, mechanics, tones
from acl.design.model import Drive, Tone
from acl.physics.equilibrium import solve_equilibrium_batch
from acl.schedule import bands, gains

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
FIG3_TONES = [72500.0, 128500.0, 178500.0]


@pytest.fixture(scope="module")
def fig3():
    return acl.load(str(EXAMPLES / "fig3_three_orifice.acl"))


def _drive(freqs, amps):
    return Drive(tones=tuple(Tone(frequency=float(f), amplitude=float(a)) for f, a in zip(freqs, amps)))


def test_newton_rows_find_the_cubic_spring_roots_of_each_row():
    # k q + c q^3 = F_b: one real root per row (k, c > 0), the closed form of Cardano's depressed cubic
    k, c = 2.0, 5.0
    force = np.array([0.0, 0.3, -1.7, 12.0, 250.0])

    def rt(q, rows):
        f = force[rows][:, None]
        return k * q + c * q**3 - f, (k + 3 * c * q**2)[:, :, None], np.maximum(np.abs(k * q + c * q**3), np.abs(f))[:, 0]

    out = solve_equilibrium_batch(rt, np.zeros((force.size, 1)))
    p, qq = k / c, -force / c
    disc = np.sqrt(qq**2 / 4 + p**3 / 27)
    exact = np.cbrt(-qq / 2 + disc) + np.cbrt(-qq / 2 - disc)
    assert list(out.status) == ["ok"] * force.size
    assert np.all(out.stable)
    np.testing.assert_allclose(out.q[:, 0], exact, rtol=1e-9, atol=1e-15)
    # rows leave the batch when they converge: the force-free row needs no step, the largest force the most
    assert out.iterations[0] == 1 and out.iterations[-1] == out.iterations.max()


def test_newton_rows_report_each_rows_failure_on_its_own():
    # row 0 converges; row 1 has a non-finite force; row 2's only root lies outside the admissible set (q < 1)
    def rt(q, rows):
        R = q - np.array([0.5, np.nan, 3.0])[rows][:, None]
        return R, np.ones((q.shape[0], 1, 1)), np.ones(q.shape[0])

    out = solve_equilibrium_batch(rt, np.zeros((3, 1)), admissible=lambda q: q[:, 0] < 1.0)
    assert out.status[0] == "ok" and out.q[0, 0] == pytest.approx(0.5)
    assert out.status[1] == "no_convergence" and out.message[1] == "non-finite force"
    assert out.status[2] == "no_convergence" and "line search" in out.message[2]


def test_forces_under_per_row_drives_equal_one_drive_at_a_time(fig3):
    # force_batch_tones (rows: own amplitudes, own gain-table draw) against force_model of each drive on each design
    draws = [fig3] + [d for _, d in bands.sample_designs(fig3, 3, seed=4)]
    rng = np.random.default_rng(1)
    centres = np.array([c.center for c in fig3.capsules])[None] + rng.normal(0, 2e-6, (len(draws), 1, 3))
    amps = rng.uniform(0, 6, (len(draws), 3))
    factors = [tones.drive_factors(d, FIG3_TONES) for d in draws]
    got = tones.force_batch_tones(fig3, centres, FIG3_TONES, amps, np.array([g for g, _ in factors]),
                                      np.array([s for _, s in factors]))
    for b, d in enumerate(draws):
        fm = acoustics.force_model(d, {"m": centres[b, 0]}, _drive(FIG3_TONES, amps[b]))
        np.testing.assert_allclose(got[b, 0], fm["m"], rtol=1e-12, atol=0)


@pytest.mark.parametrize("name", ["fig4_facing_pair", "fig6f_control_module"])
def test_each_tone_alone_equals_its_single_tone_force_model(name):
    design = acl.load(str(EXAMPLES / f"{name}.acl"))
    freqs = np.array([60e3, 85e3, 125e3, 170e3])
    got = tones.tone_forces(design, freqs)
    for k, f in enumerate(freqs):
        fm = acoustics.force_model(design, None, _drive([f], [1.0]))
        want = np.array([fm[c.name] for c in design.capsules])
        np.testing.assert_allclose(got[k], want, rtol=1e-11, atol=1e-12 * np.abs(want).max())


def _scalar_forward(design, u):
    """The re-simulation written out with the one-drive engine: each waypoint warm-started from the last, the first
    continued from rest (mechanics.equilibrium)."""
    fm = acoustics.force_model_for(design)
    out, prev = [], None
    for row in u:
        eq = mechanics.equilibrium(design, _drive(FIG3_TONES, np.sqrt(row)), fm, start=prev)
        assert eq.status == "ok"
        out.append(np.asarray(eq.displacements["m"], float)[:2])
        prev = eq.positions
    return np.array(out)


def test_resimulation_batch_of_draws_equals_a_loop_of_one_drive_solves(fig3):
    a = np.linspace(0, 2 * np.pi, 6)
    u = np.column_stack([40 + 25 * np.cos(a), 40 + 25 * np.sin(a), 30 + 10 * np.cos(2 * a)])    # V^2 per tone
    draws = [fig3] + [d for _, d in bands.sample_designs(fig3, 3, seed=2)]
    got = gains.model_forward_many(draws, "m", FIG3_TONES, u)
    for d, pred in zip(draws, got):
        want = _scalar_forward(d, u)
        np.testing.assert_allclose(pred, want, rtol=1e-7, atol=1e-15)
    # the draws differ (30 % gain uncertainty): the batch did not give every row the nominal answer
    assert np.max(np.abs(got[1] - got[0])) > 1e-3 * np.max(np.abs(got[0]))


def test_equilibria_from_rest_match_the_continuation_and_leave_a_snap_in_to_the_caller():
    pair = acl.load(str(EXAMPLES / "fig4_facing_pair.acl"))
    f = 125e3
    sweep = mechanics.sweep_voltage(pair, _drive([f], [1.0]), 60.0, acoustics.force_model_for(pair))
    assert sweep.snap_voltage is not None
    # below the fold, near it, and beyond it (no equilibrium near rest: the pair snaps in)
    volts = np.array([0.3, 0.8, 1.2]) * float(sweep.snap_voltage)

    def rows(c, r, s):
        return tones.force_batch_tones(pair, c, [f], (volts[r] * s)[:, None])

    got = equilibria.equilibria_from_rest(pair, rows, volts.size)
    assert list(got.found) == [True, True, False]
    for k in range(2):
        eq = mechanics.equilibrium(pair, _drive([f], [volts[k]]), acoustics.force_model_for(pair))
        for i, c in enumerate(pair.capsules):
            np.testing.assert_allclose(got.displacements[k, i], eq.displacements[c.name], rtol=1e-7, atol=1e-15)


def test_band_of_batched_draws_equals_the_band_of_one_draw_at_a_time(fig3):
    a = np.linspace(0, 2 * np.pi, 5)
    u = np.column_stack([40 + 25 * np.cos(a), 40 + 25 * np.sin(a), 30 + 10 * np.cos(2 * a)]).T     # (K, M) V^2
    targets = np.column_stack([np.cos(a), np.sin(a)]) * 2e-6

    def one(d):
        return gains.model_forward(d, "m", FIG3_TONES)[0]

    loop = bands.error_band(fig3, one, u, targets, samples=4, seed=3)
    batch = bands.error_band(fig3, one, u, targets, samples=4, seed=3,
                             forward_many=lambda ds: gains.model_forward_many(ds, "m", FIG3_TONES, u.T))
    assert batch.samples == loop.samples == 4 and batch.failed == loop.failed == 0
    np.testing.assert_allclose(batch.rms_m, loop.rms_m, rtol=1e-9)
    np.testing.assert_allclose(batch.max_m, loop.max_m, rtol=1e-9)


def test_a_failing_model_fails_its_own_entry_of_the_batch(fig3):
    u = np.full((2, 3), 20.0)
    got = gains.model_forward_many([fig3, fig3], "no_such_capsule", FIG3_TONES, u)
    assert all(isinstance(g, ValueError) for g in got)
    with pytest.raises(ValueError):
        gains.model_forward(fig3, "no_such_capsule", FIG3_TONES)[0](u)


def test_interface_amplitudes_of_many_drives_equal_one_drive_at_a_time(fig3):
    amps = np.array([[0.0, 1.0, 2.0], [5.0, 0.5, 0.0], [3.0, 3.0, 3.0]])
    got = interfaces.interface_amplitudes_batch(fig3, FIG3_TONES, amps)
    labels = acoustics.interface_labels(fig3)
    for row, a in zip(got, amps):
        one = interfaces.interface_amplitudes(fig3, _drive(FIG3_TONES, a))
        np.testing.assert_allclose(row, [one[k] for k in labels], rtol=1e-13)
    # eps/R is linear in the summed tone amplitudes (linear acoustics, no saturation declared)
    np.testing.assert_allclose(interfaces.interface_amplitudes_batch(fig3, FIG3_TONES, 2 * amps), 2 * got, rtol=1e-13)
