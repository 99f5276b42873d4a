"""`acl lint` on large designs (issue 11: a 1,000-line design took ~44 s). What was quadratic or
cubic is now done once: every capsule pair in one array computation per drive
(acl.analysis.acoustics.pair_table), a design's coupled bubble system built once, a step's drives
and forces built once for all rules and beams, a sweep's interface amplitudes in one solve.
Times are printed by benchmarks/lint.py, never asserted; these tests pin the results (equal to
the straightforward loops they replace) and the work done (calls counted)."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis import acoustics as AC
from acl.analysis import interfaces as IF
from acl.design.model import Drive, Tone

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.acl"))


def _generator():
    spec = importlib.util.spec_from_file_location("acl_benchmark_check", ROOT / "benchmarks" / "check.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.generate


def pair_forces_loop(design, drive):
    """The pair loop pair_table replaced (one pair at a time, as before issue 11's fix)."""
    eng = AC._engine(design, drive)
    lay = eng.lay
    centres = AC._centres_array(design, None)
    _, u, thr, att = eng.forces(centres[None], parts=True)
    u, thr, att = u[0], thr[0], att[0]
    pts = lay.points(centres)
    thrust_vec = np.einsum("n,nk,nc->ck", thr, -lay.normals, lay.onehot)
    out = []
    for a in range(len(lay.caps)):
        for b in range(a + 1, len(lay.caps)):
            ia, ib = np.flatnonzero(lay.body == a), np.flatnonzero(lay.body == b)
            sep = pts[ib][None, :, :] - pts[ia][:, None, :]
            dd = np.linalg.norm(sep, axis=-1)
            fa = np.einsum("ij,ijk->k", att[np.ix_(ia, ib)] / dd, sep)
            line = centres[b] - centres[a]
            dist = float(np.linalg.norm(line))
            unit = line / dist if dist > 0 else np.zeros(3)
            attraction = float(fa @ unit)
            if eng.f.size and ia.size and ib.size:
                va, vb = u[:, ia], u[:, ib]
                t = int(np.argmax(np.abs(va).max(axis=1) * np.abs(vb).max(axis=1)))
                ja, jb = int(np.argmax(np.abs(va[t]))), int(np.argmax(np.abs(vb[t])))
                dphi = float(np.angle(va[t, ja] * np.conj(vb[t, jb])))
                gap = float(np.linalg.norm(pts[ib[jb]] - pts[ia[ja]]))
            else:
                dphi, gap = 0.0, dist
            gamma2 = float(thrust_vec[a] @ -unit + thrust_vec[b] @ unit)
            alpha = attraction * gap**2
            dc = math.sqrt(alpha / gamma2) if alpha > 0 and gamma2 > 0 else None
            out.append((lay.caps[a].name, lay.caps[b].name, fa, attraction, dphi, gap, dc))
    return out


DRIVES = [Drive(tones=(Tone(frequency=125e3, amplitude=3.0),)),
          Drive(tones=(Tone(frequency=85e3, amplitude=2.0), Tone(frequency=170e3, amplitude=1.0, phase=0.3)))]


@pytest.mark.parametrize("source", [p.name for p in EXAMPLES] + ["generated-300"])
def test_pair_table_equals_the_pair_loop(source):
    design = acl.loads(_generator()(300), "gen.acl") if source == "generated-300" else acl.load(ROOT / "examples" / source)
    if len(design.capsules) < 2:
        pytest.skip("fewer than two capsules")
    for drive in DRIVES:
        want = pair_forces_loop(design, drive)
        got = AC.pair_forces(design, drive)
        assert len(got) == len(want) == len(design.capsules) * (len(design.capsules) - 1) // 2
        for g, (a, b, fa, attraction, dphi, gap, dc) in zip(got, want):
            assert (g.a, g.b) == (a, b)
            assert np.allclose(g.force_on_a, fa, rtol=1e-12, atol=0) and np.allclose(g.force_on_b, -fa, rtol=1e-12, atol=0)
            assert g.attraction == pytest.approx(attraction, rel=1e-12, abs=0)
            assert g.attract == (attraction > 0)
            assert g.phase_difference == pytest.approx(dphi, rel=0, abs=1e-12)     # rad
            assert g.distance == pytest.approx(gap, rel=1e-12, abs=0)
            assert (g.critical_distance is None) == (dc is None)
            if dc is not None:
                assert g.critical_distance == pytest.approx(dc, rel=1e-12, abs=0)


def test_sweep_amplitudes_equal_each_tone_alone():
    design = acl.load(ROOT / "examples" / "fig4_facing_pair.acl")
    freqs = np.linspace(60e3, 180e3, 7)
    eps = IF.sweep_interface_amplitudes(design, freqs, 2.5)
    for j, f in enumerate(freqs):
        one = IF.interface_amplitudes(design, Drive(tones=(Tone(frequency=float(f), amplitude=2.5),)))
        assert np.allclose(eps[j], list(one.values()), rtol=1e-10, atol=0)


def test_linting_a_generated_design_builds_each_thing_once(monkeypatch, tmp_path):
    """The coupled system of the whole design is built once per damping model (it was rebuilt for
    every solve: 2,447 times on 1,000 lines), each step's drives once (26,623 times)."""
    from acl.lint import LintConfig, lint_file
    from acl.lint.context import Context

    path = tmp_path / "gen.acl"
    path.write_text(_generator()(300))
    design = acl.load(path)
    builds, drives = [], []
    real_build, real_drives = AC._build_system, Context._step_drives
    monkeypatch.setattr(AC, "_build_system", lambda d, caps, pred: builds.append(caps) or real_build(d, caps, pred))
    monkeypatch.setattr(Context, "_step_drives", lambda self, st: drives.append(st) or real_drives(self, st))
    report = lint_file(str(path), LintConfig())
    assert report.findings                        # the rules did run (the grid has findings)
    whole = [c for c in builds if c is None]
    assert len(whole) <= 2, f"the whole design's coupled system was built {len(whole)} times"
    steps = [st for p in design.programs for st in p.steps]
    assert len(drives) <= len(steps) and len({id(s) for s in drives}) == len(drives)
