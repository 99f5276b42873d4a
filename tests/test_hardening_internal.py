"""Internal errors, unit misreadings and a quadratic cache (issue 29, items 4, 6 and 7).

Each case was an E-INTERNAL (or a traceback, or a silently wrong number) before; each is now a located
diagnostic with a code and a non-zero exit, or the right number.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
DATA = os.path.join(ROOT, "samples")
CANTILEVER = os.path.join(EX, "fig2_vertical_cantilever.acl")


def _clean(text):
    assert "Traceback" not in text and "E-INTERNAL" not in text, text


def _acl(*argv, cwd=None, env=None, **kw):
    e = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "acl", *argv], cwd=cwd, env=e, capture_output=True, text=True,
                          timeout=120, **kw)


# ---- integers beyond Python's 4,300-digit conversion limit -------------------------------------------

def test_an_overlong_integer_in_acl_toml_is_located(tmp_path, capsys):
    shutil.copy(CANTILEVER, tmp_path)
    (tmp_path / "acl.toml").write_text("[lint.thresholds]\n\nsubstrate_clearance = " + "9" * 5000 + "\n")
    rc = main(["lint", str(tmp_path / "fig2_vertical_cantilever.acl")])
    out = capsys.readouterr()
    _clean(out.out + out.err)
    assert rc == 2, out.err
    assert "acl.toml:3:23: error[E-CONFIG]" in out.out + out.err


def test_an_overlong_integer_in_a_schedule_is_located(tmp_path, capsys):
    sched = tmp_path / "s.json"
    sched.write_text('{"version": "1.0",\n "segments": [' + "1" * 5000 + "]}\n")
    rc = main(["synth", os.path.join(EX, "fig2_stroke.acl"), "--schedule", str(sched), "-o", str(tmp_path / "d.csv")])
    out = capsys.readouterr()
    _clean(out.out + out.err)
    assert rc != 0 and "s.json:2:15: error[E-SYNTH-SCHEDULE]" in out.err, out.err
    assert not (tmp_path / "d.csv").exists()


# ---- latch dimensions -------------------------------------------------------------------------------

@pytest.mark.parametrize("key,value", [("width", "1e308 um"), ("length", "1e308 um"), ("thickness", "1e-300 um")])
def test_latch_dimensions_are_range_checked(tmp_path, capsys, key, value):
    src = open(os.path.join(EX, "fig6_bistable_latch.acl")).read()
    old = {"width": "width = 1 um", "length": "length = 50 um", "thickness": "thickness = 1.7 um"}[key]
    assert old in src
    (tmp_path / "l.acl").write_text(src.replace(old, f"{key} = {value}", 1))
    for cmd in (["check"], ["analyze"]):
        rc = main([*cmd, str(tmp_path / "l.acl")])
        out = capsys.readouterr()
        _clean(out.out + out.err)
        assert rc == 1 and "error[E412]" in out.err and f"snap.{key}" in out.err, out.err


# ---- synth --sweep values ---------------------------------------------------------------------------

@pytest.mark.parametrize("value", ["gap*2", "(50um)", "gamma", "50um+1um"])
def test_synth_sweep_takes_values_not_expressions(tmp_path, capsys, value):
    rc = main(["synth", os.path.join(EX, "fig4_facing_pair.acl"), "-o", str(tmp_path / "x.csv"), "--observe", "d",
               "--sweep", f"gap={value}", "--voltages", "0V..3V:4"])
    out = capsys.readouterr()
    _clean(out.out + out.err)
    assert rc == 2 and "<--sweep>:1:1: error[E-USAGE]" in out.err, out.err
    assert not (tmp_path / "x.csv").exists()


# ---- file names that are not UTF-8 ------------------------------------------------------------------

@pytest.fixture
def latin1_name(tmp_path):
    name = os.fsdecode(b"caf\xe9.acl")
    with open(CANTILEVER) as fh:
        (tmp_path / name).write_text(fh.read() + "param bad = 1 blorp\n")     # one error to report
    return tmp_path, name


@pytest.mark.parametrize("fmt", ["sarif", "json", "github", "junit", "full", "concise"])
def test_lint_reports_a_non_utf8_file_name(latin1_name, fmt):
    folder, name = latin1_name
    r = _acl("lint", ".", "--output-format", fmt, cwd=folder)
    _clean(r.stdout + r.stderr)
    assert r.returncode == 1, r.stderr
    if fmt == "sarif":
        doc = json.loads(r.stdout)
        uris = {loc["physicalLocation"]["artifactLocation"]["uri"]
                for res in doc["runs"][0]["results"] for loc in res["locations"]}
        assert uris == {"./caf%E9.acl"}         # the file's bytes, percent-encoded (RFC 3986)
    if fmt == "json":
        json.loads(r.stdout)


@pytest.mark.parametrize("argv", [["check", "--output-format", "json"], ["show", "--output-format", "json"],
                                  ["analyze", "--output-format", "json"], ["show"]])
def test_other_commands_report_a_non_utf8_file_name(latin1_name, argv):
    folder, name = latin1_name
    with open(CANTILEVER) as fh:
        (folder / name).write_text(fh.read())
    r = _acl(argv[0], name, *argv[1:], cwd=folder)
    _clean(r.stdout + r.stderr)
    assert r.returncode == 0, r.stderr
    if "json" in argv:
        json.loads(r.stdout)


# ---- standard streams -------------------------------------------------------------------------------

def _shell(command):
    """Run ``command`` in sh (whose `<&-` and `>&-` really start acl with the descriptor closed)."""
    import shlex

    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(["sh", "-c", f"{shlex.quote(sys.executable)} -m acl {command}"], env=env,
                          capture_output=True, text=True, timeout=60)


def test_closed_stdin():
    r = _shell("check - <&-")
    _clean(r.stdout + r.stderr)
    assert r.returncode == 2 and "<stdin>:1:1: error[E601]" in r.stderr and "closed" in r.stderr, r.stderr


def test_closed_stdout():
    r = _shell(f"show {CANTILEVER} >&-")
    _clean(r.stderr)
    assert r.returncode == 2 and "<stdout>:1:1: error[E601]" in r.stderr, r.stderr


def test_closed_stderr_still_gives_the_exit_code(tmp_path):
    (tmp_path / "bad.acl").write_text("param x = 1 blorp\n")
    r = _shell(f"check {tmp_path / 'bad.acl'} 2>&-")
    assert r.returncode == 1


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full on this system")
def test_a_full_stdout():
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "acl", "show", CANTILEVER], stdout=full, stderr=subprocess.PIPE,
                           env=dict(os.environ, PYTHONPATH=ROOT), text=True, timeout=60)
    _clean(r.stderr)
    assert r.returncode == 2 and "<stdout>:1:1: error[E601]" in r.stderr and "space" in r.stderr, r.stderr
    assert "Exception ignored" not in r.stderr


def test_an_ascii_terminal_gets_the_tables():
    r = _acl("analyze", os.path.join(EX, "fig4_facing_pair.acl"), env={"PYTHONIOENCODING": "ascii", "COLUMNS": "60"})
    _clean(r.stdout + r.stderr)
    assert r.returncode == 0, r.stderr


# ---- the units cache --------------------------------------------------------------------------------

@pytest.mark.parametrize("content", ["[]", '{"kHz": [1, [0, 0, -1, 0, 0, 0, 0]], "furlong": "x"}',
                                     '{"furlong": [NaN, [1, 0, 0, 0, 0, 0, 0]]}', '{"furlong": [1, [1, 2]]}',
                                     '{"furlong": [1e999, [1,0,0,0,0,0,0]]}', "[" * 100000, "9" * 5000,
                                     '{"furlong": [-1, [1, 0, 0, 0, 0, 0, 0]]}', '{"furlong": [1, [true,0,0,0,0,0,0]]}'],
                         ids=["list", "mixed", "nan", "short", "inf", "deep", "bigint", "negative", "bool"])
def test_a_corrupt_units_cache_is_ignored(tmp_path, content):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "units-v2.json").write_text(content)
    (tmp_path / "u.acl").write_text("param x = 2 furlong\n")
    env = {"ACL_CACHE_DIR": str(cache)}
    for _ in range(2):                       # the run that meets it, and every later one
        r = _acl("show", "u.acl", "--output-format", "json", cwd=tmp_path, env=env)
        _clean(r.stdout + r.stderr)
        assert r.returncode == 0, r.stderr
        assert "402.336" in r.stdout          # 2 furlong = 402.336 m, whatever the cache held


def test_new_units_are_saved_once_per_run(tmp_path, monkeypatch):
    """Each new spelling rewrote the whole cache: 3,000 params with distinct units took 84-120 s."""
    import acl.units as U

    monkeypatch.setenv("ACL_CACHE_DIR", str(tmp_path))
    U._disk_cache.cache_clear()
    U.parse_unit.cache_clear()
    saves = []
    real = U._save_disk_cache
    monkeypatch.setattr(U, "_save_disk_cache", lambda c: (saves.append(len(c)), real(c)))
    for i in range(1, 40):
        U.parse_unit(f"furlong^{i % 6 + 1}/fortnight^{i % 5 + 1}")
    assert saves == []
    U.flush_unit_cache()
    assert len(saves) == 1 and saves[0] >= 30
    U._disk_cache.cache_clear()
    U.parse_unit.cache_clear()


# ---- units misread (item 7) ---------------------------------------------------------------------------

@pytest.mark.parametrize("text,why", [("20 degC", "offset"), ("5 degF", "offset"), ("3 dB", "logarithmic"),
                                      ("1 Np", "logarithmic"), ("1 octave", "logarithmic"), ("1 µ", "prefix"),
                                      ("1 μ", "prefix"), ("1 m^9223372036854775808", "exponent"),
                                      ("1 m^9223372036854775807", "exponent"), ("1 s^-99", "exponent")])
def test_units_acl_would_misread_are_refused(tmp_path, capsys, text, why):
    (tmp_path / "u.acl").write_text(f"param x = {text}\n")
    rc = main(["check", str(tmp_path / "u.acl")])
    err = capsys.readouterr().err
    _clean(err)
    assert rc == 1 and "u.acl:1:11: error[E302]" in err and why in err, err


@pytest.mark.parametrize("text,si", [("300 K", 300.0), ("2 mK", 2e-3), ("1 um^3", 1e-18), ("125 kHz", 1.25e5),
                                     ("3 nN*um^2/V^2", 3e-21)])
def test_ordinary_units_still_convert(tmp_path, capsys, text, si):
    (tmp_path / "u.acl").write_text(f"param x = {text}\n")
    assert main(["show", str(tmp_path / "u.acl"), "--output-format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["params"][0]["value"] == pytest.approx(si, rel=1e-12)


# ---- cost on small inputs (item 6) ---------------------------------------------------------------------

def test_a_segment_of_many_tones_is_read_and_checked(tmp_path):
    """A replayed segment's duplicate-frequency check compared every tone with every other: one 50,000-tone
    segment ran past a minute (1.25e9 comparisons; 0.8 s now, measured in the closing note of issue 29).
    Here: 20,000 tones are read whole, and a repeated frequency among them is still found."""
    import acl.fit.synth as S
    from acl.diagnostics import DiagnosticError

    n = 20_000
    tones = [{"frequency_hz": 100e3 + i, "amplitude_v": 1e-6, "phase_rad": 0.0} for i in range(n)]
    doc = {"version": "1.0", "segments": [{"start_s": 0.0, "end_s": 0.01, "goal": "g", "step": 0, "tones": tones}],
           "goals": []}
    path = tmp_path / "s.json"
    path.write_text(json.dumps(doc))
    points, _, _ = S.read_schedule(str(path))
    assert len(points[0].tones) == n
    doc["segments"][0]["tones"] = tones + [dict(tones[n // 2])]
    path.write_text(json.dumps(doc))
    with pytest.raises(DiagnosticError) as e:
        S.read_schedule(str(path))
    assert f"tones[{n}] repeats frequency_hz" in e.value.diagnostics[0].message


def test_an_older_versions_units_cache_is_not_read(tmp_path):
    """units.json of earlier versions cached pint's answer for `dB` (3.78): it must not bring it back."""
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "units.json").write_text('{"dB": [1.2589254117941673, [0, 0, 0, 0, 0, 0, 0]]}')
    (tmp_path / "u.acl").write_text("param x = 3 dB\n")
    r = _acl("check", "u.acl", cwd=tmp_path, env={"ACL_CACHE_DIR": str(cache)})
    assert r.returncode == 1 and "error[E302]" in r.stderr and "logarithmic" in r.stderr, r.stderr
