"""Sending a :class:`acl.bench.plan.Plan` to an instrument through PyVISA, every setting read back.

The output is off before the first setting and after the last, and on any error, Ctrl-C or SIGTERM
(the stop step is sent whatever happened; its own failures are reported, never hidden).
Diagnostics: E-PLAY-RESOURCE (bad VISA address), E-PLAY-CONNECT (no instrument there),
E-PLAY-READBACK (an answer differing from the setting), E-PLAY-IO (the instrument stopped
answering), E-PLAY-INSTRUMENT (not the instrument the plan is for), E-PLAY-INTERRUPTED.
"""
from __future__ import annotations

import math
import signal
import time
from dataclasses import dataclass, field

from acl.bench.plan import Plan, Setting
from acl.diagnostics import DiagnosticError, Span, error

WHERE = Span(file="<--resource>", line=1, column=1)


@dataclass
class PlayResult:
    sent: list[str] = field(default_factory=list)        # every message, queries included
    readbacks: list[tuple[str, str, object]] = field(default_factory=list)   # (query, answer, expected)
    late_s: float = 0.0                                   # worst lateness of a host-timed step


class _Stop(Exception):
    pass


def check_address(resource: str) -> None:
    """E-PLAY-RESOURCE unless ``resource`` is a VISA resource name (``USB0::...::INSTR``, ``TCPIP::...``)."""
    try:
        from pyvisa import rname
    except ImportError:
        raise DiagnosticError([error("E-PLAY-CONNECT", "talking to an instrument needs PyVISA: "
                                     "pip install 'acl[bench]' (from a checkout: pip install '.[bench]'; --dry-run needs nothing)", WHERE)]) from None
    try:
        rname.parse_resource_name(resource)
    except Exception as exc:     # pyvisa raises InvalidResourceName (a ValueError) with its reason
        raise DiagnosticError([error("E-PLAY-RESOURCE", f"{resource!r} is not a VISA resource address: "
                                     f"{str(exc).splitlines()[0]}", WHERE,
                                     "e.g. USB0::0x2184::0x0049::GEQ000001::INSTR or TCPIP0::192.168.1.5::INSTR")]) \
            from None


def open_resource(resource: str, backend: str = ""):
    """The opened instrument (PyVISA); E-PLAY-CONNECT if nothing answers there."""
    import pyvisa

    check_address(resource)
    try:
        rm = pyvisa.ResourceManager(backend) if backend else pyvisa.ResourceManager()
    except Exception as exc:
        raise DiagnosticError([error("E-PLAY-CONNECT", f"no VISA library: {str(exc).splitlines()[0]}", WHERE,
                                     "install a VISA backend (pyvisa-py, or the vendor's VISA)")]) from None
    try:
        inst = rm.open_resource(resource)
        inst.timeout = 5000
        inst.write_termination = "\n"
        inst.read_termination = "\n"
    except Exception as exc:
        raise DiagnosticError([error("E-PLAY-CONNECT", f"cannot open {resource!r}: {str(exc).splitlines()[0]}",
                                     WHERE, "check the address (`python -m pyvisa info`), the cable and that "
                                     "no other program holds the instrument")]) from None
    return inst


def agrees(answer: str, s: Setting) -> bool:
    if isinstance(s.expect, float):
        try:
            value = float(answer.strip().strip('"'))
        except ValueError:
            return False
        return math.isfinite(value) and abs(value - s.expect) <= s.tol
    a = answer.strip().strip('"').upper()
    e = str(s.expect).upper()
    if e == "INF":                          # high impedance: INF, or the Keysight's 9.9E+37
        try:
            return a == "INF" or float(a) >= 9e37
        except ValueError:
            return False
    if e in ("ON", "OFF"):
        return a in ((e, "1") if e == "ON" else (e, "0"))
    return a == e or a.endswith("\\" + e + ".SEQ") or a.endswith("\\" + e + ".ARB")


def _send(inst, s: Setting, result: PlayResult) -> None:
    try:
        inst.write(s.command)
        result.sent.append(s.command)
        if s.query:
            answer = inst.query(s.query)
            result.sent.append(s.query)
            result.readbacks.append((s.query, answer, s.expect))
    except Exception as exc:
        raise DiagnosticError([error("E-PLAY-IO", f"the instrument did not take `{s.command[:60]}`: "
                                     f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", WHERE,
                                     "the output was switched off")]) from None
    if s.query and not agrees(answer, s):
        raise DiagnosticError([error("E-PLAY-READBACK", f"`{s.query}` answered {answer.strip()[:60]!r} after "
                                     f"`{s.command[:60]}`: the instrument does not hold what was set", WHERE,
                                     "the output was switched off; check the instrument model (--instrument)")])


def identify(inst) -> str:
    """The *IDN? answer; E-PLAY-CONNECT when nothing (or nothing readable) answers."""
    try:
        answer = inst.query("*IDN?").strip()
    except Exception as exc:
        answer, why = "", str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    else:
        why = "an empty answer"
    if not answer:
        raise DiagnosticError([error("E-PLAY-CONNECT", f"no instrument answers *IDN? at {inst.resource_name}: {why}",
                                     WHERE, "check the address (`python -m pyvisa info`) and the cable")])
    return answer


def _errors(inst, result: PlayResult) -> None:
    """The instrument's error queue must be empty (a command it refused without a read-back)."""
    answer = inst.query("SYST:ERR?")
    result.sent.append("SYST:ERR?")
    code = answer.strip().split(",")[0].strip()
    try:
        ok = int(float(code)) == 0
    except ValueError:
        ok = False
    if not ok:
        raise DiagnosticError([error("E-PLAY-READBACK", f"the instrument reports an error: {answer.strip()[:80]!r}",
                                     WHERE, "the output was switched off")])


def play(plan: Plan, inst, clock=time.monotonic, sleep=time.sleep) -> PlayResult:
    """Send ``plan`` to ``inst``; the stop step runs whatever happens (also on SIGTERM)."""
    result = PlayResult()

    def on_term(signum, frame):
        raise _Stop()

    old = None
    try:
        old = signal.signal(signal.SIGTERM, on_term)
    except ValueError:           # not the main thread: Ctrl-C/SIGTERM are the caller's
        old = None
    failure = None
    try:
        for s in plan.setup.settings:
            _send(inst, s, result)
        _errors(inst, result)
        t0 = clock()
        for step in plan.steps:
            wait = t0 + step.at_s - clock()
            if wait > 0:
                sleep(wait)
            else:
                result.late_s = max(result.late_s, -wait)
            for s in step.settings:
                _send(inst, s, result)
        wait = t0 + plan.duration_s - clock()
        if wait > 0:
            sleep(wait)
        _errors(inst, result)
    except (KeyboardInterrupt, _Stop):
        failure = DiagnosticError([error("E-PLAY-INTERRUPTED", "interrupted: the output was switched off", WHERE)])
    except DiagnosticError as exc:
        failure = exc
    finally:
        stop_failure = None
        for s in plan.stop.settings:          # every one tried, even after one fails
            try:
                _send(inst, s, result)
            except DiagnosticError as exc:
                stop_failure = stop_failure or exc
        if old is not None:
            signal.signal(signal.SIGTERM, old)
    if failure is not None:
        raise failure
    if stop_failure is not None:
        raise stop_failure
    return result
