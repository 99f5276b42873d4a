"""`acl compile --reading-noise`: the assumed noise of the bench readings the band's cure proposes (acl.schedule.
experiment), carried into the printed cure, schedule.json and the band expected after those readings."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

import acl
from acl.schedule.compile import CompileOptions, compile_program
from acl.schedule.experiment import READING_NOISE_M

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG3 = os.path.join(ROOT, "examples", "fig3_three_orifice.acl")


def _compile(*extra, out):
    return subprocess.run([sys.executable, "-m", "acl", "compile", FIG3, "--program", "circle", "-o", str(out),
                           "--band-samples", "2", *extra], capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": ROOT, "COLUMNS": "200"})


@pytest.mark.parametrize("value, says", [
    ("-0.1um", "must be a positive length"),
    ("0um", "must be a positive length"),
    ("nan um", "must be a positive length"),
    ("inf um", "must be a positive length"),
    ("1V", "is a voltage"),
    ("0.1", "is a plain number"),
])
def test_bad_reading_noise_is_a_located_usage_error(tmp_path, value, says):
    out = tmp_path / "out"
    r = _compile(f"--reading-noise={value}", out=out)
    text = r.stdout + r.stderr
    assert r.returncode == 2, text
    assert "<--reading-noise>:1:1" in text and "E-COMPILE-OPTION" in text and says in text
    assert "Traceback" not in text and "E-INTERNAL" not in text
    assert not out.exists()          # nothing written


def test_reading_noise_is_printed_and_written(tmp_path):
    out = tmp_path / "out"
    r = _compile("--reading-noise", "0.5um", out=out)
    assert r.returncode == 0, r.stderr
    assert "(assumed noise 0.5 um per axis)" in r.stdout + r.stderr
    cause = json.loads((out / "schedule.json").read_text())["goals"][0]["details"]["band"]["cause"]
    assert cause["reading_noise_m"] == pytest.approx(0.5e-6)
    assert cause["measurement"]["noise_m"] == pytest.approx(0.5e-6)


def test_noisier_readings_leave_a_wider_expected_band():
    d = acl.load(FIG3)
    bands = []
    for noise in (READING_NOISE_M, 10 * READING_NOISE_M):
        s = compile_program(d, "circle", CompileOptions(band_samples=2, resim_points=20, reading_noise_m=noise))
        cause = s.goals[0].details["band"]["cause"]
        assert cause["reading_noise_m"] == noise
        bands.append(cause["measurement"]["expected_rms_p95_m"])
    # the same prior, a 10x noisier reading: less is learnt, the band after the readings is wider
    assert bands[1] > 1.2 * bands[0], bands
