"""The band's cure closed through the commands a lab runs (issue 28): `acl compile` proposes bench readings for the
README's main job (examples/fig3_three_orifice.acl, program circle) and prints the band it expects after them; a
truth drawn from the declared prior stands in for the device; `acl synth` makes the readings on it with the stated
noise, `acl fit` fits them, `acl compile` recompiles on the calibrated design, and `acl synth --schedule` plays the
new program on the truth.

Three claims, three tests:
* the recompiled design's own 95 % band must cover the error the lab then sees (a band narrower than the error is a
  safety defect).  Before acl.fit.report.tone_gain_stderr added the offset of each tone's gain from the calibrated
  model, the calibrated design declared measured(gain) of 1.5-3 % at the three tones while its gain there was off by
  20-33 %, and the recompiled band was far narrower than the achieved error;
* the error after the readings is within the band compile promised for the readings the loop takes, the first
  goal's (goal 1: its own promise, 0.221 um RMS, 95 %; goal 2: its promise on goal 1's readings, `with_readings_of`,
  0.354 um; its own, on the higher-voltage readings it proposes, is 0.236).  It was not while `acl fit` calibrated
  one gain scale (plus tilt): three single-tone readings left the per-tone gains the prior drew unexplained (rng seed
  28, goal 1 / goal 2 RMS in um: truth 1 0.629 / 0.985, truth 2 1.39 / 2.10; a strict xfail held them).  Now
  acl.fit.report.tone_gains fits the gain at each read tone (kept when it beats the gain model, p < 0.01), the
  calibrated design carries it as `measured(gain) = [(tone, Pa/V, sd)]`, and compile plays the measured tones:
  truth 1 0.0177 / 0.0287, truth 2 0.0469 / 0.0839;
* the cure's mechanism: the calibrated design carries a gain at each read tone, the recompile plays exactly those
  tones, and its band (the measured errors, plus the fit's residual as discrepancy(position)) is close to the
  promised one: truth 1 0.213 / 0.323, truth 2 0.238 / 0.335 um (at most BAND_OVER_PROMISE x the promise).
Over 20 truths (benchmarks/band_cure.py: the same loop; about 20 min on a loaded 2-core machine): every recompile
played the read tones, the recompiled band covered the achieved error on all 40 goals (median band / error 3.3 and
2.9); goal 1's achieved error has median 0.067, 90th percentile 0.173 and maximum 0.222 um, goal 2's median 0.120,
90th percentile 0.272, maximum 0.340.  The promise was the band at the nominal design's Fisher information (0.160 /
0.174, goal 2's on step 2's readings): 17 and 14 of 20 within it.  It now counts the devices the prior allows, each
read with the noise and fitted at its own gain (acl.schedule.experiment.promise; a device with a lower gain moves
less under the proposed voltage and is measured worse): 19 (the worst truth 0.5 % above) and 20 of 20 within it,
the promise 3.3 / 3.0 x the median achieved error (2.4 / 1.5 x before).  Before the readings: median 1.61 / 2.54 um.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG3 = os.path.join(ROOT, "examples", "fig3_three_orifice.acl")
TRUTHS = 2          # truths drawn from the prior (each loop about 15 s of CPU)
TOLERANCE = 1.0     # achieved RMS at most the promise (a 95 % band; these two truths are well inside it)
BAND_OVER_PROMISE = 2.5     # the recompiled band at most this x the promised one (measured: 1.3-1.9x)


def _acl(*args, cwd):
    r = subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=cwd,
                       env={**os.environ, "PYTHONPATH": ROOT, "COLUMNS": "200"}, timeout=300)
    assert r.returncode == 0, (args, r.stdout[-2000:], r.stderr[-2000:])
    return r.stdout + r.stderr


def _truth_text(z) -> str:
    """fig3 with its transducer replaced by one whose gain-table points are the stdlib table's times exp(sd z_j)
    (the prior compile's bands draw: log-normal, independent per point, sd the declared gain_uncertainty)."""
    import acl

    t = acl.load(FIG3).transducer
    table = ", ".join(f"({f / 1e3:g} kHz, {g * np.exp(t.gain_uncertainty * zj):.6g} Pa/V)"
                      for f, g, zj in zip(t.gain_frequencies, t.gain_pa_per_v, z))
    lo, hi = t.band
    src = open(FIG3).read()
    use = "use transducer transducers.contact_piezo\n"
    assert use in src
    return src.replace(use, f"transducer truth_piezo {{\n  max_voltage = {t.max_voltage:g} V\n"
                            f"  band = {lo / 1e3:g} kHz .. {hi / 1e3:g} kHz\n  gain = [{table}]\n}}\n"
                            "use transducer truth_piezo\n")


def _tracking(text: str) -> list[float]:
    """RMS tracking errors (um) per goal from `acl synth --schedule`'s summary lines."""
    return [float(x) for x in re.findall(r"tracking error on \S+ RMS ([0-9.eE+-]+) um", text)]


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """(expected band after the readings per goal, [(before, achieved, recompiled band) per truth]), RMS in um."""
    tmp_path = tmp_path_factory.mktemp("cure")
    work = tmp_path / "examples"
    work.mkdir()
    (work / "fig3_three_orifice.acl").write_text(open(FIG3).read())
    _acl("compile", "examples/fig3_three_orifice.acl", "--program", "circle", "-o", "out0", cwd=tmp_path)
    goals0 = json.loads((tmp_path / "out0" / "schedule.json").read_text())["goals"]
    m = goals0[0]["details"]["band"]["cause"]["measurement"]
    noise_um = m["noise_m"] * 1e6
    expected_um = [_promised_on(g, goals0[0]["name"]) * 1e6 for g in goals0]
    rng = np.random.default_rng(28)
    rows = []
    for k in range(TRUTHS):
        z = rng.standard_normal(8)
        (work / "truth.acl").write_text(_truth_text(z))
        data = []
        for i, r in enumerate(m["readings"]):            # one tone at one voltage each, as compile proposed
            csv = f"reading{k}_{i}.csv"
            v = f"{r['voltage_v']:g}V"
            _acl("synth", "examples/truth.acl", "-o", csv, "--frequencies", f"{r['frequency_hz'] / 1e3:g}kHz",
                 "--voltages", f"{v}..{v}:1", "--noise", f"{noise_um:g}um", "--observe", "mx,my",
                 "--seed", str(100 * k + i), cwd=tmp_path)
            data.append(csv)
        _acl("fit", "examples/fig3_three_orifice.acl", *data, "--free", "gain",
             "--calibrated", f"examples/cal{k}.acl", cwd=tmp_path)
        _acl("compile", f"examples/cal{k}.acl", "--program", "circle", "-o", f"out{k + 1}", cwd=tmp_path)
        goals = json.loads((tmp_path / f"out{k + 1}" / "schedule.json").read_text())["goals"]
        band = [g["rms_error_p95_um"] for g in goals]
        import acl

        cal = acl.load(str(work / f"cal{k}.acl"))
        carried = {m.frequency: (m.gain, m.stddev) for m in cal.measured_gain}
        plays = [(g["frequencies_hz"], g["details"]["band"].get("unmeasured_tones_hz")) for g in goals]
        played = _tracking(_acl("synth", "examples/truth.acl", "--schedule", f"out{k + 1}/schedule.json",
                                "-o", f"play{k}.csv", "--observe", "mx,my", cwd=tmp_path))
        before = _tracking(_acl("synth", "examples/truth.acl", "--schedule", "out0/schedule.json",
                                "-o", f"before{k}.csv", "--observe", "mx,my", cwd=tmp_path))
        rows.append((before, played, band, carried, plays, [float(x) for x in z]))
    return expected_um, rows, [r["frequency_hz"] for r in m["readings"]]


def _promised_on(goal, first: str) -> float:
    """The band (m RMS) compile promises for ``goal`` after the readings the loop takes, the first goal's: its own
    promise for the first goal; for a later one, its promise on the first goal's readings (``with_readings_of``),
    or its own where it proposed the same readings."""
    m = goal["details"]["band"]["cause"]["measurement"]
    if first in (m["readings_of"], m.get("same_readings_as")):
        return m["expected_rms_p95_m"]
    w = m["with_readings_of"]
    assert w["goal"] == first, m
    return w["expected_rms_p95_m"]


@pytest.mark.studies
def test_the_recompiled_band_covers_the_error_the_lab_sees(loop):
    _, rows, _ = loop
    for _, achieved, band, _, _, _ in rows:
        assert len(achieved) == len(band) == 2, rows
        for a, b in zip(achieved, band):
            assert a <= b, rows


@pytest.mark.studies
def test_proposed_readings_through_synth_fit_compile_leave_the_expected_band(loop):
    expected_um, rows, _ = loop
    for _, achieved, _, _, _, _ in rows:
        assert len(achieved) == len(expected_um) == 2, rows
        for a, e in zip(achieved, expected_um):
            assert a <= TOLERANCE * e, (expected_um, rows)


@pytest.mark.studies
def test_the_calibrated_design_carries_the_gain_at_each_read_tone_and_compile_plays_them(loop):
    """The cure's mechanism: `acl fit` wrote the gain it fitted at each read tone (a table point in Pa/V with its
    standard error), the recompile plays exactly those tones, and its band, now the measured errors, is close to
    the promised one (at most BAND_OVER_PROMISE x; it adds the fit's residual as discrepancy(position))."""
    expected_um, rows, tones = loop
    for _, _, band, carried, plays, _ in rows:
        assert sorted(carried) == sorted(tones), carried
        assert all(g is not None and g > 0 and 0 < sd < 0.05 for g, sd in carried.values()), carried
        for freqs, unmeasured in plays:
            assert sorted(freqs) == sorted(tones) and not unmeasured, plays
        for b, e in zip(band, expected_um):
            assert b <= BAND_OVER_PROMISE * e, (band, expected_um)
