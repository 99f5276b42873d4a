"""Interruptions and sizes (issue 29, item 3).

Before: SIGTERM (what `timeout` and batch schedulers send) killed `acl compile` at once and left
`.acl-compile-*/` beside the output with 1-2 GB of half-written waveform.npy, and `acl sweep -o`
left `.acl-*.tmp.csv`; only SIGINT cleaned up.  A 2,000 s drive with `--format npy` was accepted
as a 10 GB file.  Now SIGTERM and SIGHUP unwind like Ctrl-C (exit 128 + signal, every temporary
removed), and a waveform beyond `--max-output-size` (default 4 GiB) or the free disk space is
refused before anything is written.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
DATA = os.path.join(ROOT, "samples")

LONG = 'extends "fig2_vertical_cantilever.acl"\nprogram long {\n  drive 125 kHz @ 1 V for 2000 s\n}\n'


@pytest.fixture
def long_design(tmp_path):
    shutil.copy(os.path.join(EX, "fig2_vertical_cantilever.acl"), tmp_path)
    (tmp_path / "long.acl").write_text(LONG)
    return tmp_path


def _leftovers(folder):
    return sorted(n for n in os.listdir(folder) if n.startswith(".acl-") or n == "out")


def test_a_ten_gigabyte_waveform_is_refused_before_writing(long_design, capsys):
    rc = main(["compile", str(long_design / "long.acl"), "--program", "long", "--format", "npy",
               "-o", str(long_design / "out"), "-q"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "<--max-output-size>:1:1: error[E-EMIT-SIZE]" in err and "9.31 GiB" in err, err
    assert _leftovers(long_design) == []


def test_the_free_disk_space_is_checked(long_design, capsys, monkeypatch):
    import acl.emit.output as output

    monkeypatch.setattr(output, "free_bytes", lambda out_dir: 100 * 2 ** 20)    # a nearly full disk
    rc = main(["compile", str(long_design / "long.acl"), "--program", "long", "--format", "npy",
               "-o", str(long_design / "out"), "-q", "--max-output-size", "20GiB"])
    err = capsys.readouterr().err
    assert rc == 2 and "<--output>:1:1: error[E-EMIT-SIZE]" in err and "free" in err, err
    assert _leftovers(long_design) == []


@pytest.mark.parametrize("bad", ["bogus", "-1GB", "0", "1 parsec", "nan", "1e999"])
def test_a_bad_size_limit_is_a_usage_error(long_design, capsys, bad):
    rc = main(["compile", str(long_design / "long.acl"), "--program", "long", "-o", str(long_design / "out"),
               f"--max-output-size={bad}"])
    err = capsys.readouterr().err
    assert rc == 2 and "<--max-output-size>:1:1: error[E-USAGE]" in err and "not a size" in err, err
    assert "Traceback" not in err


def _run_then_signal(argv, cwd, ready, sig=signal.SIGTERM, timeout=120):
    """Start acl, wait until ``ready()`` is true (the work has begun writing), send ``sig``; (rc, stderr)."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "acl", *argv], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + timeout
    try:
        while not ready() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "acl finished before it could be interrupted: " + proc.stderr.read()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=["TERM", "HUP", "INT"])
def test_a_signal_while_compile_writes_leaves_nothing(long_design, sig):
    folder = str(long_design)

    def writing():
        return any(n.startswith(".acl-compile-") for n in os.listdir(folder))

    rc, err = _run_then_signal(["compile", "long.acl", "--program", "long", "--format", "npy", "-o", "out",
                                "--max-output-size", "20GiB", "-q"], folder, writing, sig)
    assert rc == (130 if sig == signal.SIGINT else 128 + sig), err
    assert "Traceback" not in err
    assert _leftovers(folder) == []


def test_sigterm_while_sweep_writes_leaves_nothing(tmp_path):
    folder = str(tmp_path)
    shutil.copy(os.path.join(DATA, "sweep_cantilever.acl"), folder)

    def started():          # the sweep is under way (its progress) or writing its table
        return any(n.startswith(".acl-") for n in os.listdir(folder)) or time.monotonic() > t0 + 3

    t0 = time.monotonic()
    rc, err = _run_then_signal(["sweep", "sweep_cantilever.acl", "--vary", "radius=9um..11um:200000", "-o", "t.csv",
                                "-q"], folder, started)
    assert rc == 128 + signal.SIGTERM, err
    assert "Traceback" not in err
    assert sorted(os.listdir(folder)) == ["sweep_cantilever.acl"]
