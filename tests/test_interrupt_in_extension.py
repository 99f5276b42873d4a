"""Ctrl-C that lands inside a compiled extension's import.

Found by the signal fuzz (tests/test_fuzz_hostile.py) on a loaded CI machine: SIGINT 0.2 s after start arrived
while pydantic_core imported `datetime`; pyo3 turned the KeyboardInterrupt into its own PanicException (a
BaseException that is not KeyboardInterrupt), and `acl synth` ended in a traceback.  The timing cannot be made
deterministic in a subprocess, so these tests raise such an exception from inside the command, after a real
signal, and check that main() reports the interrupt (exit 130 or 128 + signal, no traceback), and that the same
exception without a signal is not swallowed.
"""
from __future__ import annotations

import os
import signal

import pytest

import acl.cli as cli


class PanicException(BaseException):
    """Stands for pyo3_runtime.PanicException: what a Rust extension raises when an import inside it fails."""


def _signal_inside_extension(signum):
    def run(argv):
        try:
            os.kill(os.getpid(), signum)
            for _ in range(1000):        # the handler runs at the next bytecode boundary
                pass
        except KeyboardInterrupt as exc:
            raise PanicException("failed to import `datetime` C API") from exc
        raise AssertionError("the signal did not arrive")
    return run


def test_sigint_that_surfaces_as_an_extension_error_is_an_interrupt(monkeypatch, capsys):
    monkeypatch.setattr(cli, "_main", _signal_inside_extension(signal.SIGINT))
    assert cli.main(["check", "x.acl"]) == 130
    err = capsys.readouterr().err
    assert "acl: interrupted" in err and "Traceback" not in err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler     # restored


def test_sigterm_that_surfaces_as_an_extension_error_is_a_termination(monkeypatch, capsys):
    monkeypatch.setattr(cli, "_main", _signal_inside_extension(signal.SIGTERM))
    assert cli.main(["check", "x.acl"]) == 128 + signal.SIGTERM
    assert "acl: terminated (SIGTERM)" in capsys.readouterr().err


def test_the_same_error_without_a_signal_is_not_swallowed(monkeypatch):
    def run(argv):
        raise PanicException("a real defect")
    monkeypatch.setattr(cli, "_main", run)
    with pytest.raises(PanicException):
        cli.main(["check", "x.acl"])


def test_a_signal_in_an_earlier_run_does_not_swallow_a_later_error(monkeypatch):
    monkeypatch.setattr(cli, "_main", _signal_inside_extension(signal.SIGINT))
    assert cli.main(["check", "x.acl"]) == 130

    def run(argv):
        raise PanicException("a real defect")
    monkeypatch.setattr(cli, "_main", run)
    with pytest.raises(PanicException):
        cli.main(["check", "x.acl"])
