"""Drive expressions on their own (`125 kHz @ 6 V + 85 kHz @ 2 V`), as the CLI and data files use them."""
from __future__ import annotations

from acl.design import model as M
from acl.diagnostics import DiagnosticError, Span, error
from acl.syntax import ast as A
from acl.syntax.parser import parse_drive
from acl.units import UnitError, describe, parse_unit, parse_unit_static

_HZ, _V = parse_unit_static("Hz"), parse_unit_static("V")


def drive_from_text(text: str, file: str = "<drive>", line: int = 1, column: int = 1) -> M.Drive:
    """Parse and evaluate a drive; raises DiagnosticError located at file:line:column."""
    if not text.strip():
        return M.Drive(tones=())
    tones = parse_drive(text, file, line, column)
    raw = parse_drive(text, file)  # unshifted sub-expression spans, shifted below
    out = []
    for t, r in zip(tones, raw):
        t = r
        f = _value(t.frequency, _HZ, "frequency", file, line, column)
        v = _value(t.amplitude, _V, "amplitude", file, line, column)
        ph = _value(t.phase, (0,) * 7, "phase", file, line, column) if t.phase is not None else 0.0
        if f <= 0 or v < 0:
            raise DiagnosticError([error("E401", f"drive `{text.strip()}`: frequencies must be positive and amplitudes not negative",
                                         Span(file=file, line=line, column=column))])
        out.append(M.Tone(frequency=f, amplitude=v, phase=ph))
    if len({t.frequency for t in out}) != len(out):
        raise DiagnosticError([error("E504", f"drive `{text.strip()}` lists the same frequency twice", Span(file=file, line=line, column=column))])
    return M.Drive(tones=tuple(out))


def _value(e, dims, what, file, line, column) -> float:
    from acl.diagnostics import Span

    s0 = getattr(e, "span", None)
    span = Span(file=file, line=line, column=column + (s0.column - 1 if s0 else 0))
    sign = 1.0
    while isinstance(e, A.Neg):
        sign, e = -sign, e.operand
    if isinstance(e, A.Qty):
        try:
            factor, d = parse_unit(e.unit)
        except UnitError as exc:
            raise DiagnosticError([error("E302", str(exc), span, exc.hint)]) from None
        value = sign * e.value * factor
    elif isinstance(e, A.Num):
        d, value = (0,) * 7, sign * e.value
    else:
        raise DiagnosticError([error("E304", f"drive {what}: write a number with a unit, e.g. `125 kHz @ 6 V`", span)])
    if tuple(d) != tuple(dims):
        raise DiagnosticError([error("E301", f"drive {what}: expected {describe(tuple(dims))}, found {describe(tuple(d))}", span)])
    return value


def describe_drive(drive: M.Drive) -> str:
    if not drive.tones:
        return "no drive"
    return " + ".join(f"{t.frequency / 1e3:g} kHz @ {t.amplitude:g} V" for t in drive.tones)
