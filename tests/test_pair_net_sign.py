"""Issue 24: a drive step of a first-principles design carries its pairs' net sign over the pair-scale spread, and the
reported d_c is where the beams' equilibrium changes from closing to opening.

Sources: paper Fig. 4h and Fig. S6 (drive-only programs, no goal and so no band); the text at Fig. 4 (d_c: below it
the beams close, above it they open)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis.effects import with_pair_scale
from acl.analysis.pairs import closing_force, net_critical_distance, net_sign_over_pair_scale
from acl.design.model import Drive, Tone
from acl.physics import constants as C

ROOT = Path(__file__).resolve().parents[1]
H4 = ROOT / "examples" / "fig4h_unequal_pair.acl"
FIG4 = ROOT / "examples" / "fig4_facing_pair.acl"


def test_net_force_is_linear_in_the_scale_and_flips_where_stated():
    d = acl.load(str(H4))
    dr = Drive(tones=(Tone(frequency=85e3, amplitude=1.0),))
    r = net_sign_over_pair_scale(d, dr, "big", "small")
    s = r["flip_scale"]
    assert s is not None and 1.0 < s < 1e3          # repels at first principles, attracts past s*
    assert r["attract"] is False
    for k in (0.5, 3.0, 30.0):                        # the closing force through the language, scale by scale
        _, (c,) = closing_force(with_pair_scale(d, k), dr, "big", "small", [0.0])
        _, (c0,) = closing_force(with_pair_scale(d, 0.0), dr, "big", "small", [0.0])
        assert c == pytest.approx(c0 + k * (r["closing_n"] - c0), rel=1e-6, abs=1e-18)
    signs = [closing_force(with_pair_scale(d, f * s), dr, "big", "small", [0.0])[1][0] > 0 for f in (0.99, 1.01)]
    assert signs == [False, True]
    # P(other sign): the spread's mass above s*, against draws of the spread (4000: 3 sigma of a binomial)
    draws = C.pair_scale_from_uniform(np.random.default_rng(4).random(4000))
    p = float(np.mean(draws > s))
    assert r["p_other_sign"] == pytest.approx(1 - C.pair_scale_cdf(s), rel=1e-12)
    assert abs(r["p_other_sign"] - p) < 3 * np.sqrt(p * (1 - p) / 4000)


def test_a_drive_step_gets_a_located_note_with_the_net_sign_and_its_probability():
    from acl.schedule.compile import CompileOptions, compile_program

    d = acl.load(str(H4))
    s = compile_program(d, "attract", CompileOptions(band_samples=0))
    (note,) = [w for w in s.warnings if w.code == "N-PAIR-SCALE"]
    line = next(i for i, t in enumerate(H4.read_text().splitlines(), 1) if t.strip().startswith("drive 85 kHz"))
    assert (note.span.line, note.span.column) == (line, 3)
    r = net_sign_over_pair_scale(d, d.programs[0].steps[0].drive, "big", "small")
    assert f"big-small repels at rest, P(attract) = {r['p_other_sign']:.2f}" in note.message
    assert f"attracts above {r['flip_scale']:.3g}x" in note.message
    # a calibrated design gets none (Fig. 4: bjerknes_scale declared)
    cal = compile_program(acl.load(str(FIG4)), "ramp", CompileOptions(band_samples=0))
    assert not [w for w in cal.warnings if w.code == "N-PAIR-SCALE"]


@pytest.mark.parametrize("gap_um, closes", [(58.0, True), (61.0, True), (64.0, False), (67.0, False)])
def test_reported_dc_is_where_the_beams_equilibrium_turns(gap_um, closes):
    """An independent path to d_c: the quasi-static equilibrium of both beams (acl.analysis.mechanics) under a small
    drive at 125 kHz, the example re-declared at each gap; below the reported d_c (62.6 um) the gap closes, above
    it the gap opens."""
    dc = net_critical_distance(acl.load(str(FIG4)), Drive(tones=(Tone(frequency=125e3, amplitude=1.0),)),
                               "left", "right")
    assert 60e-6 < dc < 64e-6
    assert (gap_um * 1e-6 < dc) is closes
    d = acl.load(str(FIG4), overrides={"gap": f"{gap_um} um"})
    rep = acl.analyze(d, at=Drive(tones=(Tone(frequency=125e3, amplitude=0.3),)), snap_in=False).as_dict()
    (g,) = rep["equilibrium"]["gaps"]
    assert (g["gap_m"] < gap_um * 1e-6) is closes


@pytest.mark.parametrize("name", ["fig2_vertical_cantilever", "fig4_facing_pair"])
def test_every_validity_warning_of_analyze_is_located(name):
    """The drives analyze checks that are no program step (the pair table's, a frequency's largest program amplitude)
    were printed without a location; they are now located at the capsule of the largest interface amplitude."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "acl", "analyze", f"examples/{name}.acl", "--no-snap"],
                       capture_output=True, text=True, cwd=ROOT, timeout=300, env={**__import__("os").environ,
                                                                                   "COLUMNS": "400"})
    assert r.returncode == 0, r.stderr
    lines = [x for x in (r.stdout + r.stderr).splitlines() if "warning[W-" in x]
    assert any("pair analysis" in x or "largest amplitude" in x for x in lines)
    for x in lines:
        assert x.startswith(f"examples/{name}.acl:"), x


def test_a_step_that_drives_nothing_states_no_sign():
    from acl.schedule.compile import CompileOptions, compile_program

    text = H4.read_text().replace("drive 85 kHz @ volts for 1 s", "drive 85 kHz @ 0 V for 1 s")
    s = compile_program(acl.loads(text, filename=str(H4)), "attract", CompileOptions(band_samples=0))
    assert not [w for w in s.warnings if w.code == "N-PAIR-SCALE"]
