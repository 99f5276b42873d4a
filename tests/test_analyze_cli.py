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
