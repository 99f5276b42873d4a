"""`acl lint` on one design shares one analysis (acl.analysis.cache, issue 23): the coupled bubble
system at rest is solved once per frequency and the rules read forces, pair tables and thrust from
it.  These tests check the shared results against independent computations (the Green matrix of
acl.physics.coupling.green_matrix solved directly; each frequency alone; the beam rule's worst load
by a plain loop over programs, steps and drives) and that each frequency is solved once."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis import acoustics as AC
from acl.analysis.selectivity import selectivity
from acl.analysis.cache import analysis_for
from acl.physics import constants as C
from acl.physics import coupling as PC

ROOT = Path(__file__).resolve().parents[1]


def _generate(lines: int) -> str:
    spec = importlib.util.spec_from_file_location("acl_benchmark_check", ROOT / "benchmarks" / "check.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.generate(lines)


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    path = tmp_path_factory.mktemp("gen") / "gen.acl"
    path.write_text(_generate(400))
    return path, acl.load(path)


def _direct_response(design, f: float) -> np.ndarray:
    """(I - w^2 rho H0 g) U = H0 1 with g from green_matrix (exp(-ikd)), one frequency, numpy.linalg.solve."""
    sysm = AC._system(design)
    med = AC.medium_constants(design)
    w = 2 * np.pi * f
    ncap, p, _ = sysm.phi.shape
    assert p * ncap == sysm.n            # the generated capsules: one orifice each, no padding
    h0 = PC.uncoupled_blocks(sysm, w)[0]                                           # (C, P, P)
    g = PC.green_matrix(sysm.points, sysm.radii, np.repeat(np.arange(ncap), p), np.array([w / med.sound_speed]),
                        C.SUBSTRATE_REFLECTION)[0]
    H = np.zeros((sysm.n, sysm.n), complex)
    for c in range(ncap):
        H[c * p:(c + 1) * p, c * p:(c + 1) * p] = h0[c]
    a = np.eye(sysm.n) - w**2 * med.density * H @ g
    return np.linalg.solve(a, H.sum(axis=1))


def test_rest_response_equals_the_green_matrix_solved_directly(generated):
    _, design = generated
    assert len(design.capsules) >= 20
    freqs = np.array([85e3, 125e3, 170e3, 131.7e3])
    got = AC.rest_response(design, freqs)
    for j, f in enumerate(freqs):
        want = _direct_response(design, float(f))
        assert np.allclose(got[j], want, rtol=1e-10, atol=1e-10 * np.abs(want).max())


def test_thrust_per_frequency_equals_each_frequency_alone(generated):
    """The shared analysis answers a batch from per-frequency caches: equal to selectivity of each tone alone
    (a fresh design object: nothing cached)."""
    path, design = generated
    fresh = acl.load(path)
    freqs = np.geomspace(60e3, 200e3, 9)
    batch = analysis_for(design).thrust_per_v2(freqs)
    assert batch.shape == (len(design.capsules), freqs.size)
    for j, f in enumerate(freqs):
        alone = selectivity(fresh, [f]).thrust_per_v2[:, 0]
        assert np.allclose(batch[:, j], alone, rtol=1e-12, atol=0)
    assert analysis_for(design) is analysis_for(design)


def test_lint_solves_each_frequency_once(generated, monkeypatch):
    from acl.lint import LintConfig, lint_file

    path, _ = generated
    solved = []
    real = PC.coupled_response
    monkeypatch.setattr(AC, "_physics_coupled", lambda system, f, *a, **k: solved.append(np.atleast_1d(f).copy())
                        or real(system, f, *a, **k))
    report = lint_file(str(path), LintConfig())
    assert report.resolved and report.findings
    rest = np.concatenate([f for f in solved]) if solved else np.zeros(0)
    assert rest.size == np.unique(rest).size, "a frequency was solved twice at rest"
    assert len(solved) <= 4, f"{len(solved)} separate coupled solves (the rules' frequencies are batched)"


def test_beam_strain_findings_equal_a_plain_loop(generated):
    """ACL401 on the generated grid against the straightforward computation: for every beam and program,
    the largest load perpendicular to the beam over every drive of every step (force_model at rest),
    strain = P (L + l) c / EI; the limit set at the median strain so that about half are flagged."""
    from acl.lint import LintConfig, lint_file
    from acl.lint.context import Context

    path, design = generated
    ctx = Context(design, LintConfig(), None)
    strains, forces = {}, {}

    def force(drive, cap):
        key = tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones)
        if key not in forces:
            forces[key] = AC.force_model(design, None, drive)
        return np.asarray(forces[key][cap], float)

    for beam in design.beams:
        cap = next(j.capsule for j in design.joints if j.kind == "mount" and j.target == beam.name)
        axis = np.asarray(beam.axis, float)
        s = beam.section
        c = s.diameter / 2 if s.shape == "circle" else min(s.width, s.thickness) / 2
        for p in design.programs:
            loads = [np.linalg.norm(F - (F @ axis) * axis) for st in p.steps for d in ctx.step_drives(st)
                     for F in [force(d, cap)]]
            if loads:
                strains[(beam.name, p.name)] = max(loads) * (beam.length + beam.rigid_length) * c / beam.bending_stiffness
    limit = float(np.median(list(strains.values())))
    want = {k for k, v in strains.items() if v > limit}
    assert 0 < len(want) < len(strains)
    report = lint_file(str(path), LintConfig(thresholds={"strain_limit": limit}))
    got = {(f.message.split("`")[3], f.message.split("`")[1]) for f in report.findings if f.code == "ACL401"}
    assert got == want
