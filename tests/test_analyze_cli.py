"""`acl analyze`: JSON contract, requires evaluation and exit codes, --at, bad options."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

PAIR = textwrap.dedent("""\
    import stdlib.media
    import stdlib.capsules
    import stdlib.beams
    import stdlib.transducers
    use medium media.pbs
    use transducer transducers.contact_piezo
    param gap = 40 um
    beam la like beams.cantilever50 { clamp = (0, 0, 50 um) }
    beam ra like beams.cantilever50 { clamp = (gap + 54 um, 0, 50 um) }
    capsule left like capsules.design1 { }
    capsule right like capsules.design1 { orifice jet { radius = 10 um, normal = -x } }
    mount left on la.tip
    mount right on ra.tip
    require resonance(left) in 115 kHz .. 130 kHz
    require separation(left, right) >= 20 kHz
    program ramp {
      drive 125 kHz @ 2 V for 200 ms
    }
    """)

ONE = PAIR[:PAIR.index("param gap")] + textwrap.dedent("""\
    beam la like beams.cantilever50 { clamp = (0, 0, 50 um) }
    capsule left like capsules.design1 { }
    mount left on la.tip
    """)


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.fixture(scope="module")
def pair_json(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    (d / "pair.acl").write_text(PAIR)
    r = run("analyze", str(d / "pair.acl"), "--json", "--at", "125 kHz @ 1 V")
    return r, json.loads(r.stdout)


def test_json_has_the_documented_keys(pair_json):
    _, out = pair_json
    for key in ("capsules", "pairs", "latches", "requires", "selectivity", "equilibrium"):
        assert key in out
    mode = out["capsules"][0]["modes"][0]
    assert set(mode) >= {"frequency_hz", "q", "dominant_orifice", "share"}
    pair = out["pairs"][0]
    assert set(pair) >= {"a", "b", "frequency_hz", "force_n", "attract", "phase_difference_deg",
                         "critical_distance_m", "snap_in_voltage_v"}


def test_identical_facing_capsules_attract_in_phase(pair_json):
    _, out = pair_json
    p = out["pairs"][0]
    assert p["attract"] and abs(p["phase_difference_deg"]) < 1.0


def test_snap_in_voltage_is_reported_for_a_close_pair(pair_json):
    _, out = pair_json
    v = out["pairs"][0]["snap_in_voltage_v"]
    assert v is not None and 0 < v < 20


def test_equilibrium_below_snap_in_closes_the_gap_symmetrically(pair_json):
    _, out = pair_json
    eq = out["equilibrium"]
    assert eq["status"] == "ok"
    dl, dr = (c["displacement_m"][0] for c in eq["capsules"])
    assert dl > 0 and dr < 0 and dl == pytest.approx(-dr, rel=1e-6)
    assert eq["gaps"][0]["gap_m"] < 40e-6


def test_failed_require_exits_1_and_is_reported(pair_json):
    r, out = pair_json
    oks = {q["kind"]: q["ok"] for q in out["requires"]}
    assert oks == {"resonance": True, "separation": False}   # identical capsules: no separation
    assert r.returncode == 1


def test_identical_capsules_are_not_crosstalk(pair_json):
    _, out = pair_json
    assert not any(s["crosstalk"] for s in out["selectivity"])


def test_bad_at_drive_is_a_usage_error_without_traceback(tmp_path):
    (tmp_path / "p.acl").write_text(PAIR)
    r = run("analyze", str(tmp_path / "p.acl"), "--at", "125 kHz @ 3 um")
    assert r.returncode == 2 and "E301" in r.stderr and "Traceback" not in r.stderr


def test_at_drive_outside_band_is_rejected(tmp_path):
    (tmp_path / "p.acl").write_text(PAIR)
    r = run("analyze", str(tmp_path / "p.acl"), "--at", "500 kHz @ 3 V")
    assert r.returncode == 2 and "E501" in r.stderr


def test_plot_writes_pngs(tmp_path):
    (tmp_path / "p.acl").write_text(PAIR)
    out = tmp_path / "figs"
    r = run("analyze", str(tmp_path / "p.acl"), "--plot", str(out), "--no-snap")
    assert r.returncode in (0, 1), r.stderr
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "modal_response.png" in pngs and "pair_left_right.png" in pngs
    assert all((out / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_one_capsule_warning_says_what_its_drive_is(tmp_path):
    """A design with one capsule has no pair: its eps/R warning for a frequency's largest program drive said
    "pair analysis" (examples/fig2_vertical_cantilever.acl, 125 kHz @ 8 V).  It now names the drive's basis,
    also in the JSON (`basis`); a pair's drive keeps "pair analysis"."""
    import os

    ex = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
    r = run("analyze", os.path.join(ex, "fig2_vertical_cantilever.acl"), "--no-snap")
    assert r.returncode == 0, r.stderr
    text = r.stdout + r.stderr
    assert "pair" not in text.lower(), text
    assert ("warning[W-ACOUSTIC-AMPLITUDE]: the largest amplitude the programs apply at this frequency: 125 kHz @ 8 V drives act.jet"
            in " ".join(text.split()))
    j = json.loads(run("analyze", os.path.join(ex, "fig2_vertical_cantilever.acl"), "--no-snap",
                       "--output-format", "json").stdout)
    free = {d["drive"]: d["basis"] for d in j["drives"] if d["program"] is None}
    # 125 kHz: the ramp's 8 V; the sweep's ends (100, 150 kHz): the 1 V reference (the sweep step itself is below)
    assert free == {"100 kHz @ 1 V": "reference", "125 kHz @ 8 V": "largest_program_amplitude",
                    "150 kHz @ 1 V": "reference"}
    assert {d["basis"] for d in j["drives"] if d["program"] is not None} == {"step"}
    # no program: the capsule's first mode at the 1 V reference
    (tmp_path / "bare.acl").write_text(ONE)
    j = json.loads(run("analyze", str(tmp_path / "bare.acl"), "--no-snap", "--output-format", "json").stdout)
    assert [d["basis"] for d in j["drives"]] == ["reference"] and j["drives"][0]["drive"].endswith("@ 1 V")
    # a pair's drive at each program frequency is the pair table's
    r = run("analyze", os.path.join(ex, "fig4_facing_pair.acl"), "--no-snap")
    assert "warning[W-ACOUSTIC-AMPLITUDE]: pair analysis: 125 kHz @ 15 V" in " ".join((r.stdout + r.stderr).split())


SWEEP = ONE + "program scan {\n  sweep 100 kHz to 150 kHz @ V_SWEEP in 2 s\n}\n"


def test_a_sweep_step_is_checked_at_its_worst_frequency(tmp_path):
    """A sweep step had no linear-regime check in `acl analyze` (only drive and goal steps): a sweep through
    the capsule's resonance at 15 V (eps/R ~ 0.69 there, as `acl lint` ACL105 finds) gave no warning."""
    from acl.analysis.interfaces import interface_amplitudes
    from acl.design.model import Drive, Tone
    import acl

    (tmp_path / "s.acl").write_text(SWEEP.replace("V_SWEEP", "15 V"))
    j = json.loads(run("analyze", str(tmp_path / "s.acl"), "--no-snap", "--output-format", "json").stdout)
    (entry,) = [d for d in j["drives"] if d["program"] == "scan"]
    assert entry["step"] == 1 and entry["line"] == SWEEP.count("\n") - 1 and not entry["linear"]
    f = float(entry["drive"].split(" kHz")[0]) * 1e3
    assert 100e3 < f < 150e3
    d = acl.load(str(tmp_path / "s.acl"))
    # the worst frequency is a maximum: no point of a fine grid across the sweep beats it
    grid = [max(interface_amplitudes(d, Drive(tones=(Tone(frequency=x, amplitude=15.0),))).values())
            for x in __import__("numpy").linspace(100e3, 150e3, 2001)]
    assert entry["max_amplitude_over_radius"] >= max(grid) * (1 - 1e-9)
    r = run("analyze", str(tmp_path / "s.acl"), "--no-snap")
    assert f"program scan step 1 (line {SWEEP.count(chr(10)) - 1})" in " ".join((r.stdout + r.stderr).split())
