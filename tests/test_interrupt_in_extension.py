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
import time
import weakref

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


def _interrupt_in_a_callback(exc):
    """What CI hit: an interrupt raised inside a weakref callback, which Python cannot raise from, so it hands
    it to sys.unraisablehook (from C, as it does for the import system's callbacks)."""
    class Held:
        pass

    def callback(ref):
        raise exc

    held = Held()
    ref = weakref.ref(held, callback)
    del held
    return ref


@pytest.mark.parametrize("exc, code", [(KeyboardInterrupt(), 130),
                                       (cli.Terminated(int(signal.SIGTERM)), 128 + int(signal.SIGTERM))])
def test_an_interrupt_lost_in_a_callback_stops_the_command(monkeypatch, capsys, exc, code):
    # Found by the signal fuzz in CI: the hook sent the signal again from inside itself, its handler raised
    # there, and Python printed "Exception ignored in sys.unraisablehook" with a traceback and lost the signal.
    def run(argv):
        _interrupt_in_a_callback(exc)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:        # a long command: the signal must come back and stop it
            pass
        raise AssertionError("the signal was lost")
    monkeypatch.setattr(cli, "_main", run)
    assert cli.main(["check", "x.acl"]) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err


def test_an_interrupt_lost_in_a_callback_of_a_command_that_ends_is_reported(monkeypatch, capsys):
    def run(argv):
        _interrupt_in_a_callback(KeyboardInterrupt())
        return 0                                   # ends before the signal is sent again
    monkeypatch.setattr(cli, "_main", run)
    assert cli.main(["check", "x.acl"]) == 130
    err = capsys.readouterr().err
    assert "acl: interrupted" in err and "Traceback" not in err
    time.sleep(0.1)                                # the helper thread sends nothing once main() has returned
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_signal_wrapped_in_an_ordinary_error_is_an_interrupt(monkeypatch, capsys):
    # Found by the signal fuzz in CI: SIGINT 0.2 s into `acl synth` landed while pydantic-core built a validator,
    # which wrapped the KeyboardInterrupt in its SchemaError (an Exception): acl printed E-INTERNAL.
    import acl.commands.check as check

    def run(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):
                pass
        except KeyboardInterrupt as exc:
            raise RuntimeError("Error building \"model\" validator") from exc
        raise AssertionError("the signal did not arrive")
    monkeypatch.setattr(check, "run", run)
    assert cli.main(["check", "x.acl"]) == 130
    err = capsys.readouterr().err
    assert "E-INTERNAL" not in err and "acl: interrupted" in err
