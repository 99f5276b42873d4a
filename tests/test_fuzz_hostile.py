"""Fuzzing studies (issue 29): generated hostile inputs, never a traceback, hang, warning or partial output.

Run with `python -m pytest -m studies tests/test_fuzz_hostile.py` (CI runs the studies after the fast set).
Generators live in tests/fuzz_generators.py.  Each property runs acl in-process under an alarm (a hang fails
the example instead of stopping the run), or as a subprocess with a timeout and a 2 GB address-space limit.

Accepted outcomes: exit 0, 1 or 2 with every error line located (``FILE:LINE:COLUMN: error[CODE]``); never
a Python traceback, E-INTERNAL, a Python warning, a hang, or an output file left half-written.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fuzz_generators as G
from acl.cli import main

pytestmark = pytest.mark.studies

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
DATA = os.path.join(ROOT, "samples")
LOCATED = re.compile(r"^(?:\S.*):\d+:\d+: (?:error|warning)\[[A-Za-z0-9-]+\]")
STUDY = settings(max_examples=int(os.environ.get("ACL_FUZZ_EXAMPLES", "40")), deadline=None, derandomize=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                        HealthCheck.data_too_large])


class Hang(Exception):
    pass


@contextlib.contextmanager
def alarm(seconds: int):
    def ring(signum, frame):
        raise Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, ring)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def run_in_process(argv, seconds=60):
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err), alarm(seconds):
        warnings.simplefilter("always")
        try:
            code = main(list(map(str, argv)))
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue(), caught


def assert_clean(code, out, err, caught=()):
    text = out + err
    assert code in (0, 1, 2), (code, err[-2000:])
    assert "Traceback" not in text and "E-INTERNAL" not in text, err[-3000:]
    assert "Warning:" not in err, err[-2000:]
    for line in err.splitlines():
        if "error[" in line and not line.startswith(" "):
            assert LOCATED.match(line) or line.startswith("acl: "), line


# ---- designs ------------------------------------------------------------------------------------------

@STUDY
@given(G.mutated_design(), st.sampled_from(["check", "analyze", "lint", "fmt"]))
def test_mutated_designs(tmp_path_factory, text, command):
    folder = tmp_path_factory.mktemp("design")
    for name, src in G.SOURCES.items():                 # `extends` of a sibling example still resolves
        (folder / name).write_text(src, encoding="utf-8")
    f = folder / "mutant.acl"
    f.write_text(text, encoding="utf-8")
    argv = {"check": ["check", f], "analyze": ["analyze", f], "lint": ["lint", f, "--output-format", "sarif"],
            "fmt": ["fmt", "--check", f]}[command]
    assert_clean(*run_in_process(argv))


def test_circular_designs(tmp_path):
    for f in G.circular_designs(tmp_path):
        for argv in (["check", f], ["analyze", f], ["fmt", "--check", f], ["lint", f]):
            code, out, err, caught = run_in_process(argv, 30)
            assert_clean(code, out, err, caught)
            assert code != 0 or argv[0] == "fmt"         # fmt lays the text out; it does not resolve extends


# ---- data files and schedules ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fit_inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fitdata")
    design = os.path.join(DATA, "fit_cantilever.acl")
    assert main(["synth", design, "-o", str(folder / "d.csv"), "--voltages", "0V..2V:6", "--noise", "0.05um",
                 "-q"]) == 0
    return design, (folder / "d.csv").read_text()


@settings(STUDY, max_examples=min(STUDY.max_examples, 30))
@given(st.data())
def test_mutated_data_files(tmp_path_factory, fit_inputs, data):
    design, text = fit_inputs
    folder = tmp_path_factory.mktemp("fit")
    f = folder / "m.csv"
    f.write_text(data.draw(G.mutated_csv(text)), encoding="utf-8", errors="surrogateescape")
    code, out, err, caught = run_in_process(["fit", design, f, "--free", "gamma", "--calibrated", folder / "c.acl",
                                             "-q"], 120)
    assert_clean(code, out, err, caught)
    if code != 0:
        assert not (folder / "c.acl").exists()


@pytest.fixture(scope="module")
def schedule_doc(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sched")
    assert main(["compile", os.path.join(EX, "fig2_stroke.acl"), "--program", "stroke", "-o", str(folder / "o"),
                 "--band-samples", "0", "-q"]) == 0
    return json.loads((folder / "o" / "schedule.json").read_text())


@settings(STUDY, max_examples=min(STUDY.max_examples, 30))
@given(st.data())
def test_mutated_schedules(tmp_path_factory, schedule_doc, data):
    folder = tmp_path_factory.mktemp("replay")
    f = folder / "s.json"
    f.write_text(data.draw(G.mutated_schedule(schedule_doc)))
    code, out, err, caught = run_in_process(["synth", os.path.join(EX, "fig2_stroke.acl"), "--schedule", f,
                                             "-o", folder / "r.csv"], 120)
    assert_clean(code, out, err, caught)
    if code != 0:
        assert not (folder / "r.csv").exists()


# ---- signals at random points ---------------------------------------------------------------------------------

def _limited():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (2 * 2 ** 30, 2 * 2 ** 30))       # never over 2 GB on a small input


JOBS = {
    "compile": (["compile", os.path.join(EX, "fig2_stroke.acl"), "--program", "stroke", "-o", "out"], "out"),
    "sweep": (["sweep", os.path.join(DATA, "sweep_cantilever.acl"), "--vary", "radius=9um..11um:20000", "-o", "t.csv"],
              "t.csv"),
    "synth": (["synth", os.path.join(DATA, "fit_cantilever.acl"), "--voltages", "0V..2V:20000", "-o", "d.csv"], "d.csv"),
}


def _complete(job, path):
    """The finished output is whole: JSON parses, the CSV's last line ends, the WAV holds its declared size."""
    if job == "compile":
        doc = json.loads(open(os.path.join(path, "schedule.json")).read())
        wav = os.path.join(path, "waveform.wav")
        return os.path.getsize(wav) > 44 and doc["files"]
    with open(path, "rb") as fh:
        body = fh.read()
    return body.endswith(b"\n") and body.count(b"\n") > 1


@settings(max_examples=int(os.environ.get("ACL_FUZZ_SIGNALS", "12")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.sampled_from(sorted(JOBS)), st.sampled_from(["INT", "TERM", "KILL"]), st.floats(0.2, 4.0))
def test_signals_at_random_points(tmp_path_factory, job, sig, delay):
    folder = tmp_path_factory.mktemp("signal")
    argv, output = JOBS[job]
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "acl", *argv, "-q"], cwd=folder, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=_limited)
    time.sleep(delay)
    if proc.poll() is None:
        proc.send_signal(getattr(signal, "SIG" + sig))
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail(f"{job} did not stop within 120 s of SIG{sig}")
    err = err.decode(errors="replace")
    assert "Traceback" not in err and "E-INTERNAL" not in err, err[-2000:]
    target = folder / output
    if target.exists():
        assert _complete(job, str(target)), f"{job}: a partial {output} after SIG{sig}"
    leftovers = [n for n in os.listdir(folder) if n.startswith(".acl-")]
    if sig != "KILL":                 # SIGKILL cannot be caught: its temporary files stay, never the output
        assert leftovers == [], (job, sig, leftovers)


# ---- LSP framing --------------------------------------------------------------------------------------------

def _lsp_messages(out: bytes) -> list[dict]:
    msgs = []
    while out:
        head, sep, rest = out.partition(b"\r\n\r\n")
        m = re.search(rb"Content-Length: (\d+)", head)
        if not sep or not m:
            break
        n = int(m.group(1))
        msgs.append(json.loads(rest[:n]))
        out = rest[n:]
    return msgs


@settings(max_examples=int(os.environ.get("ACL_FUZZ_LSP", "25")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(G.broken_frames())
def test_broken_lsp_framing_never_stops_the_server(frames):
    """Broken frames (short, overlong, garbage headers, non-JSON, bad UTF-8, 5,000-digit ids, arrays, negative
    lengths) before a session: the server answers initialize and shutdown after them and exits cleanly.  An
    overlong Content-Length that swallows the next message can cost that message, never the stream: the session
    is sent after a pause-free separator of whole messages, so at most the first reply may be lost."""
    pytest.importorskip("pygls")
    init = G.frame(json.dumps({"jsonrpc": "2.0", "id": 1, "method": "initialize",
                               "params": {"processId": None, "rootUri": None, "capabilities": {}}}).encode())
    session = (G.frame(json.dumps({"jsonrpc": "2.0", "method": "initialized", "params": {}}).encode())
               + G.frame(json.dumps({"jsonrpc": "2.0", "id": 2, "method": "shutdown"}).encode())
               + G.frame(json.dumps({"jsonrpc": "2.0", "method": "exit"}).encode()))
    # a frame whose Content-Length is too long for what follows swallows bytes up to its length: it is sent last
    # among the broken ones, then padding of whole no-op notifications it can swallow, then the session
    pad = G.frame(json.dumps({"jsonrpc": "2.0", "method": "$/noop", "params": {}}).encode()) * 4
    stdin = b"".join(frames) + pad + init + session
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run([sys.executable, "-m", "acl", "lsp"], input=stdin, capture_output=True, timeout=120, env=env,
                       cwd=ROOT, preexec_fn=_limited)
    err = p.stderr.decode(errors="replace")
    assert "Traceback" not in err and "E-INTERNAL" not in err, err[-2000:]
    msgs = _lsp_messages(p.stdout)
    for m in msgs:
        assert "error" not in m or "Traceback" not in json.dumps(m["error"]), m
    shut = [m for m in msgs if m.get("id") == 2]
    assert shut, ("the server stopped answering after broken frames", err[-1500:])
