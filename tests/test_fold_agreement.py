"""Snap-in and the equilibrium walk agree at a fold: an equilibrium exists iff V < the snap-in voltage.

The Fig. 4 pair (examples/fig4_facing_pair.acl) at a gap of 41.294 um puts its fold 0.03 % above a 2 V
drive.  There, `acl analyze` reported a snap-in of 2.000588 V while its equilibrium walk to 2 V ended
as snap-in (a fold refined past the end of the walk was taken for a snap).  The independent check is a
brute-force scan: the pair is mirror-symmetric (each capsule moves by s towards the other), so an
equilibrium at V is a root of V^2 F(s) = P(s), P the load of paper Eq. (1) at deflection s and F the
acoustic force per V^2 at the displaced centres; the fold is the first maximum of P(s) / F(s), found on a
grid refined to 1 nm steps.  Tolerances: the snap-in within 1e-6 relative of the scan's fold; the
deflection at 2 V within 1e-6 relative of the scan's root (interpolated between 1 nm grid points);
equilibria at V = snap-in x (1 - 1e-6) and none at snap-in x (1 + 1e-6); the sweep (acl.sweep) gives the
same deflection and snap-in to 1e-6.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis import acoustics as AC
from acl.analysis import mechanics as ME
from acl.analysis.report import analyze
from acl.design.drives import drive_from_text
from acl.physics import beams as B

EX = Path(__file__).resolve().parents[1] / "examples" / "fig4_facing_pair.acl"
GAP = "41.294 um"


@pytest.fixture(scope="module")
def pair():
    src = EX.read_text()
    assert "param gap = 40 um" in src
    return acl.loads(src.replace("param gap = 40 um", f"param gap = {GAP}"), filename=str(EX))


def _v2_curve(d, s):
    """(V^2(s) holding the mirror-symmetric pair at deflection s, force asymmetry between the two capsules)."""
    rest = np.array([c.center for c in d.capsules], float)
    toward = np.sign(rest[1, 0] - rest[0, 0])
    C = np.repeat(rest[None], s.size, axis=0)
    C[:, 0, 0] += toward * s
    C[:, 1, 0] -= toward * s
    F = AC.force_batch(d, C, drive_from_text("125 kHz @ 1 V", "<at>"))
    f_left, f_right = toward * F[:, 0, 0], -toward * F[:, 1, 0]
    beam = {b.name: b for b in d.beams}["left_arm"]
    P = B.eq1_force(s, beam.length, beam.rigid_length, beam.bending_stiffness)
    return P / f_left, float(np.max(np.abs(f_left - f_right) / np.abs(f_left)))


@pytest.fixture(scope="module")
def scan(pair):
    """Brute force: the first maximum of V^2(s) on a 10 nm grid, then on a 1 nm grid around it."""
    s = np.linspace(0.0, 12e-6, 1201)[1:]
    v2, asym = _v2_curve(pair, s)
    assert asym < 1e-12                               # the mirror symmetry the scan relies on
    k = int(np.argmax(np.diff(v2) < 0))
    assert 0 < k < s.size - 2, "no fold inside the scanned range"
    fine = np.arange(s[k - 1], s[k + 1], 1e-9)
    v2f, _ = _v2_curve(pair, fine)
    j = int(np.argmax(v2f))
    assert 0 < j < fine.size - 1
    # the ascending branch's root of V^2(s) = 4 (2 V), linear between the 1 nm points around it
    lo = np.linspace(0.0, fine[j], 1201)[1:]
    v2l, _ = _v2_curve(pair, lo)
    i = int(np.argmax(v2l >= 4.0))
    sub = np.arange(lo[i - 1], lo[i] + 1e-9, 1e-9)
    v2s, _ = _v2_curve(pair, sub)
    m = int(np.argmax(v2s >= 4.0))
    s2 = sub[m - 1] + (4.0 - v2s[m - 1]) / (v2s[m] - v2s[m - 1]) * (sub[m] - sub[m - 1])
    return {"v_fold": float(np.sqrt(v2f[j])), "s_fold": float(fine[j]), "s_at_2v": float(s2)}


def test_snap_in_is_the_brute_force_fold(pair, scan):
    rep = analyze(pair, at=drive_from_text("125 kHz @ 2 V", "<at>")).as_dict()
    (p,) = [p for p in rep["pairs"] if p["frequency_hz"] == 125e3]
    assert abs(p["snap_in_voltage_v"] - scan["v_fold"]) <= 1e-6 * scan["v_fold"], (p["snap_in_voltage_v"], scan)
    assert 2.0 < scan["v_fold"] < 2.001             # the case: the fold just above the drive


def test_equilibrium_exists_iff_below_the_snap_in(pair, scan):
    rep = analyze(pair, at=drive_from_text("125 kHz @ 2 V", "<at>")).as_dict()
    v_snap = next(p["snap_in_voltage_v"] for p in rep["pairs"] if p["frequency_hz"] == 125e3)
    eq = rep["equilibrium"]
    assert eq["status"] == "ok" and eq["stable"]
    for arm in ("left_arm", "right_arm"):
        got = eq["deflections_m"][arm]
        assert abs(got - scan["s_at_2v"]) <= 1e-6 * scan["s_at_2v"], (arm, got, scan["s_at_2v"])
    fm = AC.force_model_for(pair)
    for rel, exists in ((1e-6, True), (1e-4, True), (-1e-6, False), (-1e-4, False)):
        v = v_snap * (1 - rel)
        st = ME.equilibrium(pair, drive_from_text(f"125 kHz @ {v!r} V", "<at>"), fm)
        assert (st.status == "ok" and st.stable) == exists, (v, st.status)
        if exists:
            assert st.deflections["left_arm"] < scan["s_fold"] * (1 + 1e-6)


def test_sweep_agrees_at_the_fold(pair, scan):
    from acl.sweep.evaluate import evaluate
    from acl.sweep.perturb import FieldBatch

    b = FieldBatch(design=pair, n=1, fields={}, valid=np.ones(1, bool), code=np.full(1, ""))
    cols = evaluate(b, ["tip_deflection_left_arm_m", "equilibrium_ok", "snap_in_left_right_125khz_v"],
                    "125 kHz @ 2 V")
    assert bool(cols["equilibrium_ok"][0])
    assert abs(cols["tip_deflection_left_arm_m"][0] - scan["s_at_2v"]) <= 1e-6 * scan["s_at_2v"]
    assert abs(cols["snap_in_left_right_125khz_v"][0] - scan["v_fold"]) <= 1e-6 * scan["v_fold"]
    assert cols["snap_in_left_right_125khz_v"][0] <= scan["v_fold"] * (1 + 1e-9)
