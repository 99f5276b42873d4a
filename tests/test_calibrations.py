"""The paper's cited parameter set (stdlib/calibrations.acl, the *_measured materials) and the examples that use it.

Each comparison states its tolerance and source: the issue 24 targets (Fig. 4 snap-in within 10 % of paper Eq. (3)
with the paper's constants on the example's beams; Fig. 5b beta within 20 %; Table S2's experimental switching
forces within 15 %). These agree by construction (calibrations), which the examples and docs label as such.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import acl
from example_designs import load_first_principles

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"
ALPHA, GAMMA, BETA = 174.5e-21, 0.027e-9, 745.6e-21     # paper Eq. (3) at 125 kHz (Fig. 4e); Suppl. Note 3 (Fig. 5b)


def _pair(design, snap=True):
    return [p for p in acl.analyze(design, snap_in=snap).as_dict()["pairs"] if p["frequency_hz"] == 125e3]


def _eq3_snap(design):
    from acl.analysis import mechanics as M
    from acl.design.model import Drive, Tone

    return M.sweep_voltage(design, Drive(tones=(Tone(frequency=125e3, amplitude=1.0),)), 20.0,
                           M.reduced_eq3_force_model(ALPHA, GAMMA)).snap_voltage


@pytest.mark.parametrize("gap", [20, 30, 40, 50])
def test_fig4_snap_in_within_10_percent_of_eq3(gap):
    d = acl.load(str(EX / "fig4_facing_pair.acl"), overrides={"gap": f"{gap} um"})
    v = _pair(d)[0]["snap_in_voltage_v"]
    assert v == pytest.approx(_eq3_snap(d), rel=0.10)
    # without the calibration the first-principles pair is 74-92 % above Eq. (3): the calibration is what lands it
    fp = _pair(load_first_principles("fig4_facing_pair", overrides={"gap": f"{gap} um"}))[0]["snap_in_voltage_v"]
    assert fp > 1.5 * _eq3_snap(d)


def test_fig5b_beta_within_20_percent():
    ps = _pair(acl.load(str(EX / "fig5a_gripper.acl")), snap=False)
    p = max(ps, key=lambda p: p["force_n"])
    beta = p["force_n"] * p["gap_m"] ** 2 / p["voltage_v"] ** 2
    assert beta == pytest.approx(BETA, rel=0.20)


@pytest.mark.parametrize("angle, measured", [(30, 1.09e-9), (45, 8.95e-9), (60, 16.92e-9)])
def test_table_s2_switching_force_within_15_percent(angle, measured):
    from acl.physics import latch as L

    d = acl.loads(f"import stdlib.materials\nmaterial m like materials.tpeta_latch{angle}_measured {{ }}\n")
    e = d.materials[0].youngs_modulus
    f = L.latch_landscape(np.radians(angle), 50e-6, 1.0e-6, 1.7e-6, e).switching_force   # the examples' latch geometry
    assert f == pytest.approx(measured, rel=0.15)


def test_every_calibration_is_labelled_with_its_source():
    text = (ROOT / "stdlib" / "calibrations.acl").read_text()
    blocks = re.split(r"\n\s*\n", text)
    for block in blocks:
        if re.search(r"(?m)^param ", block):
            comment = " ".join(l for l in block.splitlines() if l.startswith("#"))
            assert re.search(r"Eq\. \(3\)|Fig\. \w+|Table S2|Suppl", comment), block
    for ex in ("fig4_facing_pair", "fig5a_gripper"):
        src = (EX / f"{ex}.acl").read_text()
        line = next(l for l in src.splitlines() if l.startswith("effect bjerknes_scale"))
        assert "CALIBRATION" in line and "calibrations." in src


def test_analyze_says_calibration():
    a = acl.analyze(acl.load(str(EX / "fig4_facing_pair.acl")), snap_in=False)
    assert any("bjerknes_scale" in n and "calibration" in n for n in a.as_dict()["notes"])


def _gap_misfit(load):
    """(RMS, max) m of acl's equilibrium gap minus paper Eq. (3)'s (paper constants, same beams), at 20 / 30 / 40 /
    50 um, 40 voltages up to 95 % of the lower snap-in voltage of the two (the Fig. 4e / S5 curves)."""
    from acl.analysis import acoustics as A, mechanics as M
    from acl.design.model import Drive, Tone

    dr = Drive(tones=(Tone(frequency=125e3, amplitude=1.0),))

    def curve(d, fm):
        s = M.sweep_voltage(d, dr, 20.0, fm)
        return s.voltage, s.positions["right"][:, 0] - s.positions["left"][:, 0], s.snap_voltage

    errs = []
    for g in (20, 30, 40, 50):
        d = load(g)
        ve, ge, se = curve(d, M.reduced_eq3_force_model(ALPHA, GAMMA))
        va, ga, sa = curve(d, A.force_model_for(d))
        vv = np.linspace(0.0, 0.95 * min(se, sa), 40)
        errs.append(np.interp(vv, va, ga) - np.interp(vv, ve, ge))
    e = np.concatenate(errs)
    return float(np.sqrt(np.mean(e * e))), float(np.max(np.abs(e)))


def test_calibrated_pair_law_represents_eq3_gap_curves():
    """The shaped pair law follows Eq. (3)'s whole gap-vs-voltage curves, not only the snap-in points it was fitted on:
    0.35 um RMS (1.8 um max, next to snap-in) where first principles miss by 1.7 um RMS (5.9 um max)."""
    cal = _gap_misfit(lambda g: acl.load(str(EX / "fig4_facing_pair.acl"), overrides={"gap": f"{g} um"}))
    fp = _gap_misfit(lambda g: load_first_principles("fig4_facing_pair", overrides={"gap": f"{g} um"}))
    assert cal[0] < 0.5e-6 and cal[1] < 2.5e-6
    assert fp[0] > 3 * cal[0]
