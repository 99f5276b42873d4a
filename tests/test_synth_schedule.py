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


def test_replay_summary_is_not_wrapped_when_piped(compiled):
    # the tracking-error line runs past 80 columns; piped into a log it must stay one line
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    env["PYTHONPATH"] = ROOT
    out = subprocess.run([sys.executable, "-m", "acl", "synth", str(compiled / "fig2_stroke_truth.acl"), "--schedule",
                          str(compiled / "out" / "schedule.json"), "-o", str(compiled / "w.csv"), "--observe", "delta"],
                         capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    line = next(x for x in out.stderr.splitlines() if "tracking error on" in x)
    assert len(line) > 80 and "over" in line and "waypoints" in line


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


# -- issue 11: a replay is capped (a 200,000-segment schedule replayed for minutes) ------------------

_SEG = '{"start_s": %d, "duration_s": 0.5, "tones": [{"frequency_hz": 125e3, "amplitude_v": %.2f}]}'
CANTILEVER = os.path.join(ROOT, "samples", "fit_cantilever.acl")


def _schedule(path, n, bad_at=None):
    segs = [_SEG % (i, 1 + (i % 5) / 2) for i in range(n)]
    if bad_at is not None:
        segs[bad_at] = '{"start_s": "soon", "tones": []}'
    path.write_text('{"version": "1.1",\n "segments": [\n  ' + ",\n  ".join(segs) + "\n]}\n")
    return str(path)


def test_a_200000_segment_schedule_is_refused_at_the_first_segment_beyond_the_cap(tmp_path):
    sched = _schedule(tmp_path / "long.json", 200_000)
    out = tmp_path / "r.csv"
    r = _acl("synth", CANTILEVER, "--schedule", sched, "-o", str(out))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    # segment k sits on line k + 3, after two spaces
    assert f"{sched}:20003:3: error[E-SYNTH-SCHEDULE]: segments[20000]: more than 20,000 constant-drive segments" \
        in r.stderr, r.stderr
    assert "--max-segments" in r.stderr and not out.exists()


def test_max_segments_sets_the_cap(tmp_path):
    sched = _schedule(tmp_path / "s.json", 30)
    r = _acl("synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "a.csv"), "--max-segments", "29")
    assert r.returncode == 2 and f"{sched}:32:3: error[E-SYNTH-SCHEDULE]: segments[29]" in r.stderr, r.stderr
    assert not (tmp_path / "a.csv").exists()
    r = _acl("synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "b.csv"), "--max-segments", "30")
    assert r.returncode == 0, r.stderr
    assert len(list(csv.DictReader(open(tmp_path / "b.csv")))) == 30


@pytest.mark.parametrize("value", ["0", "-3", "x", "200001", "1e3"])
def test_max_segments_out_of_range_is_a_usage_error(tmp_path, value):
    sched = _schedule(tmp_path / "s.json", 3)
    r = _acl("synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "a.csv"), "--max-segments", value)
    assert r.returncode == 2 and "<--max-segments>:1:1: error[E-USAGE]" in r.stderr, r.stderr


def test_max_segments_without_schedule_is_a_usage_error(tmp_path):
    r = _acl("synth", CANTILEVER, "-o", str(tmp_path / "a.csv"), "--max-segments", "5")
    assert r.returncode == 2 and "error[E-USAGE]: --max-segments applies to --schedule only" in r.stderr


def test_a_malformed_segment_is_located_at_its_line(tmp_path):
    sched = _schedule(tmp_path / "s.json", 10, bad_at=6)
    r = _acl("synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "a.csv"))
    assert r.returncode == 2 and f"{sched}:9:3: error[E-SYNTH-SCHEDULE]: segments[6]: malformed segment" in r.stderr, r.stderr


def test_a_schedule_over_the_size_limit_is_refused_before_parsing(tmp_path, monkeypatch, capsys):
    from acl.cli import main
    from acl.fit import synth

    sched = _schedule(tmp_path / "s.json", 50)
    monkeypatch.setattr(synth, "MAX_SCHEDULE_BYTES", os.path.getsize(sched) - 1)
    monkeypatch.setattr(json, "loads", lambda *a, **k: pytest.fail("parsed a schedule over the limit"))
    assert main(["synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "a.csv")]) == 2
    assert "E-SYNTH-SCHEDULE" in capsys.readouterr().err and not (tmp_path / "a.csv").exists()


def test_segment_positions_follow_the_json_not_the_text():
    from acl.fit.synth import _segment_position

    text = '{"goals": [{"segments": [1, 2]}], "segments" : [ {"a": "[,]"} ,\n {"b": 2}, 3 ]}'
    assert _segment_position(text, 0) == (1, 50)
    assert _segment_position(text, 1) == (2, 2)
    assert _segment_position(text, 2) == (2, 12)
    assert _segment_position("[]", 0) == (1, 1) and _segment_position('{"x": 1}', 0) == (1, 1)


def test_the_documented_replay_limits_are_the_code_s():
    from acl.fit import synth

    text = open(os.path.join(ROOT, "docs", "fit.md")).read()
    assert f"more than {synth.MAX_REPLAY_SEGMENTS:,} constant-drive segments" in text
    assert f"at most {synth.MAX_REPLAY_LIMIT:,})" in text and f"over {synth.MAX_SCHEDULE_BYTES // 2**20} MB" in text


@pytest.mark.parametrize("segment, words", [
    ('"soon"', 'a segment is an object, not "soon"'),                  # was "'str' object has no attribute 'get'"
    ('{"start_s": 1}', "no tones"),                                       # was replayed as a pause
    ('{"tones": []}', "no start_s"),
    ('{"start_s": 1, "tones": ["x"]}', 'tones[0] is "x", not an object'),  # was "string indices must be integers"
    ('{"start_s": 1, "tones": [{"frequency_hz": 125e3}]}', "tones[0] has no amplitude_v"),   # was "('amplitude_v')"
])
def test_a_malformed_segment_says_what_is_wrong_in_the_schedule_s_terms(tmp_path, capsys, segment, words):
    from acl.cli import main

    sched = tmp_path / "s.json"
    good = _SEG % (0, 1.0)
    sched.write_text('{"version": "1.1",\n "segments": [\n  ' + good + ",\n  " + segment + "\n]}\n")
    out = tmp_path / "a.csv"
    assert main(["synth", CANTILEVER, "--schedule", str(sched), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{sched}:4:3: error[E-SYNTH-SCHEDULE]: segments[1]: malformed segment ({words}" in err, err
    assert "object has no attribute" not in err and "string indices" not in err and not out.exists()


def _follow_schedule(path, targets):
    segs = ",\n  ".join('{"start_s": %d, "end_s": %d, "goal": "g", "tones": [{"frequency_hz": 125e3, "amplitude_v": %d}]}'
                        % (i, i + 1, 1 + i) for i in range(3))
    path.write_text('{"version": "1.1",\n "segments": [\n  ' + segs + '\n ],\n "goals": [\n  {"name": "g", "kind": '
                    '"follow", "capsule": "act", "target_um": ' + json.dumps(targets) + '}\n ]}\n')
    return str(path)


@pytest.mark.parametrize("targets, words", [
    ([], "0 target points for 3 constant-drive segments"),             # was E-INTERNAL (max of an empty array)
    ([[-1, 0]], "1 target point for 3 constant-drive segments"),       # was an error over 1 of 3 waypoints, exit 0
    ([[-1, 0]] * 4, "4 target points for 3 constant-drive segments"),
])
def test_follow_targets_that_do_not_match_the_goal_s_waypoints_are_refused(tmp_path, capsys, targets, words):
    from acl.cli import main

    sched = _follow_schedule(tmp_path / "s.json", targets)
    out = tmp_path / "a.csv"
    assert main(["synth", CANTILEVER, "--schedule", sched, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{sched}:8:3: error[E-SYNTH-SCHEDULE]: goals[0] `g`: {words}" in err, err
    assert "E-INTERNAL" not in err and not out.exists()


def test_follow_targets_one_per_waypoint_are_replayed(tmp_path, capsys):
    from acl.cli import main

    sched = _follow_schedule(tmp_path / "s.json", [[-0.1, 0], [-0.4, 0], [-1, 0]])
    assert main(["synth", CANTILEVER, "--schedule", sched, "-o", str(tmp_path / "a.csv")]) == 0
    err = capsys.readouterr().err
    assert "g: tracking error on" in err and "over 3 waypoints" in err, err


@pytest.mark.parametrize("field, value", [("capsule", 5), ("capsule", ["act"]), ("name", 7)])
def test_a_goal_field_of_the_wrong_type_is_malformed_not_another_design(tmp_path, capsys, field, value):
    """`"capsule": 5` was exit 1 with "follows capsule `5`, which the truth does not have"."""
    from acl.cli import main

    sched = tmp_path / "s.json"
    text = open(_follow_schedule(tmp_path / "t.json", [[-1, 0]] * 3)).read()
    doc = json.loads(text)
    doc["goals"][0][field] = value
    sched.write_text(json.dumps(doc))
    assert main(["synth", CANTILEVER, "--schedule", str(sched), "-o", str(tmp_path / "a.csv")]) == 2
    err = capsys.readouterr().err
    assert f"error[E-SYNTH-SCHEDULE]: goals[0].{field} is {json.dumps(value)}, not a string" in err, err


def test_a_segment_repeating_a_frequency_is_malformed(tmp_path, capsys):
    """Its rows were written as `125 kHz @ 1 V + 125 kHz @ 2 V`, which `acl fit` refuses (E802)."""
    from acl.cli import main

    sched = tmp_path / "s.json"
    sched.write_text('{"version": "1.1",\n "segments": [\n  {"start_s": 0, "tones": [{"frequency_hz": 125e3, '
                     '"amplitude_v": 1}, {"frequency_hz": 125e3, "amplitude_v": 2}]}\n]}\n')
    assert main(["synth", CANTILEVER, "--schedule", str(sched), "-o", str(tmp_path / "a.csv")]) == 2
    err = capsys.readouterr().err
    assert f"{sched}:3:3: error[E-SYNTH-SCHEDULE]: segments[0]: malformed segment (tones[1] repeats frequency_hz 125000)" \
        in err, err


def test_quiet_replay_prints_nothing_but_writes_the_rows(compiled):
    """`-q` is diagnostics only: the replay printed "wrote N rows" and the tracking errors anyway (newcomer
    review); the CSV is the same as without it."""
    sched = str(compiled / "out" / "schedule.json")
    loud = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", sched, "-o", str(compiled / "l.csv"))
    quiet = _acl("synth", str(compiled / "fig2_stroke.acl"), "--schedule", sched, "-o", str(compiled / "q.csv"), "-q")
    assert loud.returncode == quiet.returncode == 0, loud.stderr + quiet.stderr
    assert "wrote" in loud.stderr and quiet.stderr == "" and quiet.stdout == ""
    assert (compiled / "l.csv").read_text() == (compiled / "q.csv").read_text()
