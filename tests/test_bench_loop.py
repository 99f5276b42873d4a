"""The whole bench loop on a synthetic run: compile -> play --dry-run -> (the run) -> track -> fit.

The truth is the design with its thrust planted at 0.8x (gamma 0.0216 instead of 0.027 nN/V^2);
`acl synth` plays the compiled schedule on it, a video of those displacements is rendered (no
motion blur: the capsule settles within a frame), `acl track --schedule` measures it, and `acl fit
--free gamma` must recover the planted thrust within its 95 % interval.
"""
from __future__ import annotations

import json
import os
import shutil

import pytest

from acl.cli import main

DATA = os.path.join(os.path.dirname(__file__), "..", "samples", "bench")


def test_fit_of_the_tracked_video_recovers_the_planted_thrust(tmp_path, capsys, monkeypatch):
    pytest.importorskip("imageio_ffmpeg")
    from acl.bench.loop import video_of_waypoints

    monkeypatch.chdir(tmp_path)
    shutil.copy(os.path.join(DATA, "loop.acl"), "loop.acl")
    src = open("loop.acl").read()
    open("truth.acl", "w").write(src.replace("param gamma = 0.027 nN/V^2", "param gamma = 0.0216 nN/V^2"))
    assert main(["compile", "loop.acl", "--program", "ramp", "-o", "out", "-q"]) == 0
    assert main(["play", "out/schedule.json", "--dry-run"]) == 0
    stream = capsys.readouterr().out
    assert "SOUR1:AMP 0.3" in stream and "SOUR1:AMP 0.5" in stream    # 3 V and 5 V peak / 20 x 2
    assert main(["synth", "truth.acl", "--schedule", "out/schedule.json", "-o", "truth.csv", "-q"]) == 0
    true_x, _ = video_of_waypoints("truth.csv", "module", "run.avi", fps=100.0, frames=50, scale_um=0.65)
    assert true_x.min() < -8          # 5.3 um at 5 V: 8 px
    assert main(["track", "run.avi", "-o", "tracked.csv", "--scale", "0.65", "--roi", "50,42,40,40",
                 "--name", "module", "--schedule", "out/schedule.json", "-q"]) == 0
    rows = open("tracked.csv").read().splitlines()
    assert any(",125 kHz @ 5 V," in r for r in rows) and rows[2].startswith("module_x,0,um,,0,")
    capsys.readouterr()
    assert main(["fit", "loop.acl", "tracked.csv", "--free", "gamma", "--output-format", "json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    g = fit["final"]["parameters"][0]
    assert g["name"] == "gamma" and not fit["effects_selected"]
    truth = g["initial"] * 0.0216 / 0.027      # the fit's gamma is at f_ref; `initial` is the design's 0.027 there
    lo, hi = g["ci95"]
    assert lo <= truth <= hi, (truth, lo, hi)
    assert (hi - lo) / truth < 0.01
    assert fit["final"]["per_observable"]["module_x"]["redchi"] < 2      # the tracker's sigma is honest
