"""`acl synth TRUTH --schedule schedule.json -o run.csv`: replay a compiled program on any design."""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")


def _acl(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=ROOT)
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=cwd, env=env)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("synth")
    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl", "fig2_stroke_truth.acl"):
        shutil.copy(os.path.join(EX, name), tmp)
    out = _acl("compile", str(tmp / "fig2_stroke.acl"), "--program", "stroke", "-o", str(tmp / "out"),
               "--band-samples", "0", "--waypoint-dt", "0.05")
    assert out.returncode == 0, out.stderr
    return tmp


def test_replay_writes_every_observable_at_every_waypoint(compiled):
    sched = json.loads((compiled / "out" / "schedule.json").read_text())
    n = len(sched["segments"])
    out = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", str(compiled / "out" / "schedule.json"),
               "-o", str(compiled / "run.csv"))
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader(open(compiled / "run.csv")))
    assert len(rows) == 2 * n                                   # observes delta and act_x
    assert {r["observable"] for r in rows} == {"delta", "act_x"}
    times = sorted({float(r["time"]) for r in rows})
    assert times == pytest.approx([s["start_s"] for s in sched["segments"]])
    # played on the design it was compiled for, the stroke is tracked: delta follows the target's -x
    goal = sched["goals"][0]
    target = -np.array(goal["target_um"])[:, 0]
    delta = np.array([float(r["value"]) for r in rows if r["observable"] == "delta"])
    assert np.max(np.abs(delta - target)) < 0.5 * np.ptp(target)
    assert "tracking error on" in out.stderr


def test_replay_on_a_truth_with_an_undeclared_effect_differs(compiled):
    sched = str(compiled / "out" / "schedule.json")
    a = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", sched, "-o", str(compiled / "a.csv"),
             "--observe", "delta")
    b = _acl("synth", str(compiled / "fig2_stroke_truth.acl"), "--schedule", sched, "-o", str(compiled / "b.csv"),
             "--observe", "delta")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    va = np.array([float(r["value"]) for r in csv.DictReader(open(compiled / "a.csv"))])
    vb = np.array([float(r["value"]) for r in csv.DictReader(open(compiled / "b.csv"))])
    assert va.shape == vb.shape and np.max(np.abs(va - vb)) > 0.1


@pytest.mark.parametrize("content, line", [
    ("{not json", 1),
    ('{"version": "1.1", "segments": [{"start_s": 0, "tones": [{"frequency_hz": -5, "amplitude_v": 1}]}]}', 1),
    ('{"version": "2.0", "segments": []}', 1),
])
def test_bad_schedule_is_a_diagnostic_and_writes_nothing(compiled, content, line):
    bad = compiled / "bad.json"
    bad.write_text(content)
    out_csv = compiled / "never.csv"
    out = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", str(bad), "-o", str(out_csv))
    assert out.returncode == 2
    assert "E-SYNTH-SCHEDULE" in out.stderr + out.stdout and "Traceback" not in out.stderr
    assert f"bad.json:{line}:" in out.stderr + out.stdout
    assert not out_csv.exists()


def test_schedule_with_effect_option_is_a_usage_error(compiled):
    out = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", str(compiled / "out" / "schedule.json"),
               "-o", str(compiled / "x.csv"), "--effect", "drive_saturation=v_sat:6V")
    assert out.returncode == 2 and "E-USAGE" in out.stderr + out.stdout
    assert not (compiled / "x.csv").exists()
