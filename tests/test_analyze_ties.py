"""Ties in "which is largest" are decided by declaration order, not by rounding (acl.physics.ties), and
`acl analyze` imports no scipy (symmetric_eigh, complete_elliptic replace scipy.linalg.eigh and
scipy.special.ellipk/ellipe)."""
from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

ROOT = os.path.join(os.path.dirname(__file__), "..")
PAIR = os.path.join(ROOT, "examples", "fig4_facing_pair.acl")


def test_first_max_takes_the_first_of_values_equal_to_rounding():
    from acl.physics.ties import first_max, first_max_item

    assert first_max([0.5, 0.5 + 1e-15]) == 0                  # a rounding difference is a tie
    assert first_max([0.5 + 1e-15, 0.5]) == 0
    assert first_max([0.5, 0.5 + 1e-6]) == 1                   # a real difference is not
    assert first_max([np.nan, 0.2, 0.1]) == 1                  # NaN is never the largest
    assert first_max([1.0, np.inf, np.inf]) == 1
    assert first_max([0.0, 0.0]) == 0
    a = np.array([[1.0, 1.0 + 1e-14, 0.2], [0.1, 0.3, 0.3 * (1 - 1e-14)]])
    assert first_max(a, axis=1).tolist() == [0, 1]
    assert first_max(a.T, axis=0).tolist() == [0, 1]
    assert first_max_item({"a.jet": 0.25, "b.jet": 0.25 * (1 + 1e-15)}) == ("a.jet", 0.25)
    assert first_max_item({}) == ("", 0.0)


@pytest.mark.parametrize("favour", [0, 1])
def test_a_symmetric_pair_names_the_first_declared_interface_whichever_way_rounding_leans(monkeypatch, favour):
    """The facing pair's coupled modes are 50/50; before the tie rule the (anti) mark and the dominant
    interface followed the last bit of the eigensolver (scipy's eigh named right.jet, numpy's left.jet)."""
    import acl
    from acl.analysis import acoustics as AC

    real = AC._physics_coupled_modes

    def leaning(*args, **kwargs):          # as another BLAS could round: interface `favour` larger by 1e-13
        cm = real(*args, **kwargs)
        vol = np.array(cm.volume)
        if vol.shape[0] > 1:
            vol[favour] *= 1 + 1e-13
        return replace(cm, volume=vol)

    monkeypatch.setattr(AC, "_physics_coupled_modes", leaning)
    design = acl.load(PAIR)
    modes = AC.coupled_modes(design)
    assert len(modes) == 2
    for m in modes:
        assert m.shares["left.jet"] == pytest.approx(0.5, abs=1e-9)
        assert m.dominant_orifice == "left.jet"
        assert m.phases["left.jet"] == 0.0
    assert [m.phases["right.jet"] for m in modes] == [0.0, 180.0]          # in phase, then anti-phase


def test_analyze_imports_no_scipy():
    """`acl analyze` of the latch example (elliptic integrals, snap-in sweeps) and the pair (coupled modes)."""
    code = ("import sys\nfrom acl.cli import main\n"
            "rc = [main(['analyze', p, '-q']) for p in sys.argv[1:]]\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'cvxpy', 'matplotlib'))\n"
            "sys.stderr.write('HEAVY=' + ','.join(heavy) + ' RC=' + str(rc))\n")
    files = [PAIR, os.path.join(ROOT, "examples", "fig6_bistable_latch.acl")]
    r = subprocess.run([sys.executable, "-c", code, *files], capture_output=True, text=True, timeout=300,
                       cwd=ROOT, env={**os.environ, "PYTHONPATH": ROOT})
    assert "HEAVY= RC=[0, 0]" in r.stderr, r.stderr[-2000:]


def test_symmetric_eigh_is_scipys_generalized_eigh():
    scipy_linalg = pytest.importorskip("scipy.linalg")
    from acl.physics.resonance import symmetric_eigh

    rng = np.random.default_rng(3)
    for n in (1, 3, 9):
        a = rng.normal(size=(n, n))
        b = rng.normal(size=(n, n))
        k, m = a @ a.T + n * np.eye(n), b @ b.T + n * np.eye(n)
        w2, x = symmetric_eigh(k, m)
        w2s, xs = scipy_linalg.eigh(k, m)
        np.testing.assert_allclose(w2, w2s, rtol=1e-12)
        np.testing.assert_allclose(x.T @ m @ x, np.eye(n), atol=1e-12)          # mass-normalised
        np.testing.assert_allclose(np.abs(x), np.abs(xs), rtol=1e-9, atol=1e-12)  # up to each vector's sign


def test_complete_elliptic_is_scipys():
    special = pytest.importorskip("scipy.special")
    from acl.physics.latch import complete_elliptic

    m = np.concatenate([[0.0], np.geomspace(1e-12, 0.999, 500)])
    K, E = complete_elliptic(m)
    np.testing.assert_allclose(K, special.ellipk(m), rtol=2e-15)
    np.testing.assert_allclose(E, special.ellipe(m), rtol=2e-15)
    assert K[0] == pytest.approx(np.pi / 2, rel=1e-15) and E[0] == pytest.approx(np.pi / 2, rel=1e-15)
