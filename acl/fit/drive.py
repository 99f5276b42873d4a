"""Drive cells of data files: acl drive syntax (`125 kHz @ 6 V + 85 kHz @ 2 V`) evaluated to SI tones."""
from __future__ import annotations

from acl.diagnostics import DiagnosticError, Span, error
from acl.syntax import ast as A

HZ = (0, 0, -1, 0, 0, 0, 0)
VOLT = (2, 1, -3, -1, 0, 0, 0)
DIMENSIONLESS = (0, 0, 0, 0, 0, 0, 0)


def _value(expr, span: Span):
    """(SI value, dims) of a constant expression (numbers, quantities, + - * / ^, negation)."""
    from acl.units import Quantity, UnitError, quantity

    def ev(e):
        if isinstance(e, A.Num):
            return Quantity(float(e.value))
        if isinstance(e, A.Qty):
            return quantity(float(e.value), e.unit)
        if isinstance(e, A.Neg):
            return -ev(e.operand)
        if isinstance(e, A.BinOp):
            a, b = ev(e.left), ev(e.right)
            return {"+": a.__add__, "-": a.__sub__, "*": a.__mul__, "/": a.__truediv__, "^": a.__pow__}[e.op](b)
        raise ValueError("a drive holds numbers with units only (no names or calls)")

    try:
        return ev(expr)
    except UnitError as exc:
        raise DiagnosticError([error("E802", str(exc), span, exc.hint)])
    except (ValueError, ZeroDivisionError) as exc:
        raise DiagnosticError([error("E802", f"drive: {exc}", span)])


def parse_drive_cell(text: str, file: str, line: int, column: int) -> tuple[tuple[float, float], ...]:
    """``((frequency Hz, amplitude V peak), ...)`` of a data-file drive cell; empty text is no drive.

    Raises :class:`DiagnosticError` (code E802) pointing at file:line:column of the cell.
    """
    from acl.syntax.parser import parse_drive

    if not text.strip():
        return ()
    tones = parse_drive(text, file, line, column)
    out = []
    for t in tones:
        f = _value(t.frequency, t.span)
        v = _value(t.amplitude, t.span)
        if f.dims != HZ:
            raise DiagnosticError([error("E802", f"drive frequency must be a frequency, got `{f}`", t.span,
                                         "a tone is `FREQUENCY @ AMPLITUDE`, e.g. `125 kHz @ 6 V`")])
        if v.dims != VOLT:
            raise DiagnosticError([error("E802", f"drive amplitude must be a voltage, got `{v}`", t.span,
                                         "a tone is `FREQUENCY @ AMPLITUDE`, e.g. `125 kHz @ 6 V`")])
        if f.value <= 0 or v.value < 0:
            raise DiagnosticError([error("E802", "drive frequency must be positive and amplitude not negative", t.span)])
        if any(float(f.value) == g for g, _ in out):   # as a design's drive (E504): two tones at one frequency add
            raise DiagnosticError([error("E802", f"drive `{text.strip()}` lists the frequency {f.value / 1e3:g} kHz "
                                         "twice (two tones at one frequency add with their phases: one amplitude)",
                                         t.span, "give each frequency once, with the amplitude measured")])
        out.append((float(f.value), float(v.value)))
    return tuple(out)


def format_drive(tones) -> str:
    """Inverse of :func:`parse_drive_cell` (kHz and V)."""
    return " + ".join(f"{f / 1e3:.6g} kHz @ {v:.6g} V" for f, v in tones)
