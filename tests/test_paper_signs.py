"""Issue 24: signs with their probability, d_c with its model-form interval, against the paper.

Sources: paper Fig. 4h (an unequal pair attracts at 85 kHz and repels at 125 kHz), Fig. S6b-c (at 125 kHz
both pairs of the flextensional mechanism close; at 85 kHz the top pair opens and the bottom pair closes),
the text at Fig. 4 (d_c = 50 um measured for the Fig. 4 pair).  A sign counts as reproduced when acl gives
the paper's sign a probability of at least 0.95 under the example's declared uncertainty (Q, orifice radius,
gap; 200 draws, `acl analyze`'s P(other sign)); the signs acl does not reproduce are strict xfails, so a
model change that reproduces them makes the test fail until it is moved.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
H4 = "examples/fig4h_unequal_pair.acl"
S6 = "examples/figS6_flextensional.acl"
FIG4 = "examples/fig4_facing_pair.acl"
REPRODUCED = 0.95      # P(the paper's sign) for a sign to count as reproduced


def run(*args):
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=ROOT, timeout=300)


_CACHE: dict = {}


def analyze(path):
    if path not in _CACHE:
        r = run("analyze", path, "--no-snap", "--output-format", "json")
        assert r.returncode == 0, r.stderr
        _CACHE[path] = json.loads(r.stdout)
    return _CACHE[path]


def pair(path, a, b, khz):
    return next(p for p in analyze(path)["pairs"] if (p["a"], p["b"]) == (a, b) and p["frequency_hz"] == khz * 1e3)


def p_paper_sign(p, paper_attracts: bool) -> float:
    assert p["sign_draws"] == 200 and p["p_other_sign"] is not None
    return 1 - p["p_other_sign"] if p["attract"] == paper_attracts else p["p_other_sign"]


def codes(p):
    return [n["code"] for n in p["notes"]]


# ---- reproduced signs

@pytest.mark.parametrize("path, a, b, khz, attracts", [
    (H4, "big", "small", 85, True),                      # Fig. 4h, left
    (S6, "b_left", "b_right", 125, True),                 # Fig. S6b
    (S6, "t_left", "t_right", 125, True),                 # Fig. S6b
    (S6, "b_left", "b_right", 85, True),                  # Fig. S6c: the bottom pair closes
])
def test_paper_sign_reproduced_with_its_probability(path, a, b, khz, attracts):
    p = pair(path, a, b, khz)
    assert p["attract"] is attracts
    assert p_paper_sign(p, attracts) >= REPRODUCED


# ---- signs not reproduced: reported with their probability and a located note

@pytest.mark.parametrize("path, a, b, khz, line_of", [
    (H4, "big", "small", 125, "capsule big like"),         # Fig. 4h, right: repel
    (S6, "t_left", "t_right", 85, "capsule t_left"),       # Fig. S6c: the top pair opens
])
def test_paper_repulsion_needs_q_outside_plausible_range_located(path, a, b, khz, line_of):
    p = pair(path, a, b, khz)
    assert 0.0 <= p["p_other_sign"] <= 1.0
    note = next(n for n in p["notes"] if n["code"] == "N-PAIR-SIGN")
    lines = (ROOT / path).read_text().splitlines()
    assert note["file"].endswith(path) and lines[note["line"] - 1].startswith(line_of)
    assert "plausible Q <=" in note["message"]


@pytest.mark.xfail(strict=True, reason="open (issue 24): acl gives the paper's repulsion less than even odds; "
                                       "Fig. 4h at 125 kHz only with the radius held, Fig. S6c in no plausible Q")
@pytest.mark.parametrize("path, a, b, khz", [(H4, "big", "small", 125), (S6, "t_left", "t_right", 85)])
def test_paper_repulsion_more_likely_than_not(path, a, b, khz):
    assert p_paper_sign(pair(path, a, b, khz), False) >= 0.5


def test_identical_pair_draws_nothing_without_declared_uncertainty():
    p = pair(FIG4, "left", "right", 125)
    assert p["p_other_sign"] is None and p["sign_draws"] == 0


# ---- d_c with the calibration: an interval from the drag law, and the disagreement with the measured 50 um

def test_fig4_calibrated_dc_interval_and_note():
    p = pair(FIG4, "left", "right", 125)
    lo, hi = sorted((p["critical_distance_paper_drag_m"], p["critical_distance_m"]))
    # one thrust of drag (Eq. 3's F_d = F_AS) pushes harder than the laminar jet (<= 1): a smaller d_c
    assert p["critical_distance_paper_drag_m"] < p["critical_distance_m"]
    # measured 50 um (text at Fig. 4) lies below the whole interval: open, +10 % at least (documented)
    assert lo > 1.10 * 50e-6 and hi < 1.35 * 50e-6
    note = next(n for n in p["notes"] if n["code"] == "N-PAIR-DC")
    assert f"{hi * 1e6:.1f} um" in note["message"] and f"{lo * 1e6:.1f} um" in note["message"]
    text = (ROOT / FIG4).read_text()
    assert text.splitlines()[note["line"] - 1].startswith("capsule right")
    assert f"{hi * 1e6:.1f} um" in text and f"{lo * 1e6:.1f} um" in text      # the example's comment says the same


def test_fig4_dc_of_50um_needs_drag_beyond_the_jets_momentum_flux():
    import acl
    from acl.analysis.pairs import closing_force
    from acl.design.model import Drive, Tone

    d = acl.load(str(ROOT / FIG4))
    dr = Drive(tones=(Tone(frequency=125e3, amplitude=1.0),))
    (g,), (c0,) = closing_force(d, dr, "left", "right", [10e-6], 0.0)
    _, (c1,) = closing_force(d, dr, "left", "right", [10e-6], 1.0)
    assert g == pytest.approx(50e-6, abs=1e-9)
    assert c0 / (c0 - c1) > 1.0          # drag fraction that would make 50 um the d_c: above the cap of jet_drag


# ---- the physics pieces

def test_jet_drag_fraction_override():
    from acl.physics.forces import PAPER_DRAG_FRACTION, jet_drag

    J, x, a = 2e-9, np.array([40e-6, 200e-6]), 27e-6
    law = jet_drag(J, x, 1.0, a)
    assert law == pytest.approx([J * min(1.0, 9 * a / (4 * 40e-6)), J * 9 * a / (4 * 200e-6)])
    assert jet_drag(J, x, np.array([1.0, 0.5]), a, PAPER_DRAG_FRACTION) == pytest.approx([J, J * 0.25])
    assert jet_drag(J, x, -1.0, a, 1.0) == pytest.approx([0.0, 0.0])


def test_plausible_quality_bound_is_twice_viscous_and_radiation_q():
    from acl.physics import resonance as R
    from acl.physics.constants import WATER_20C as W

    v, r, rth = np.pi * 25e-6**2 * 33.15e-6, np.array([10e-6]), 3 * 33.15e-6 * 25e-6 / (2 * 25e-6 + 2 * 33.15e-6)
    args = (v, r, W.density, W.surface_tension, W.ambient_pressure, 1.0, W.viscosity, W.sound_speed, rth)
    full = R.capsule_modes(*args)
    vr = R.capsule_modes(*args, thermal=False)
    assert vr.omega == pytest.approx(full.omega) and vr.quality[0] > full.quality[0]
    assert R.plausible_quality_bound(vr.quality[0]) == pytest.approx(2 * vr.quality[0])
    assert 12 < R.plausible_quality_bound(vr.quality[0]) < 16     # design 1: 2 x 7.1


def test_sign_draws_negative_is_a_located_usage_error():
    r = run("analyze", H4, "--no-snap", "--sign-draws", "-1")
    assert r.returncode == 2 and "E-USAGE" in (r.stdout + r.stderr) and "<--sign-draws>" in (r.stdout + r.stderr)
    assert "Traceback" not in r.stderr


def test_baffled_mutual_mass_would_steepen_the_gap_dependence():
    """docs/physics.md part A section 11 (4): a b = 2 mutual mass lowers the coupled / uncoupled force of an identical
    pair (h / (1 - w^2 rho h b g), tests/test_physics_coupling.py) more at 20 um than at 80 um, so the paper's alpha /
    acl ratio (largest at 20 um, Fig. 4e) would grow steeper: the evidence against making that term half-space."""
    from acl.physics.constants import WATER_20C as W
    from acl.physics.resonance import capsule_modes, volume_response

    m = capsule_modes(6.51e-14, np.array([10e-6]), W.density, W.surface_tension, W.ambient_pressure,
                      W.polytropic_index, W.viscosity, W.sound_speed, 7e-6)
    f = 125e3
    w, h = 2 * np.pi * f, volume_response(m, [f])[0, 0]

    def ratio(d, b):
        return abs(1 / (1 - b * w**2 * W.density * h / (4 * np.pi * d))) ** 2

    loss_20, loss_80 = ratio(20e-6, 1) / ratio(20e-6, 2), ratio(80e-6, 1) / ratio(80e-6, 2)
    assert loss_20 > 1.5 * loss_80 > 1.5
