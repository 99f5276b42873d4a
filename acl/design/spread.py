"""A parameter's spread, ``param x = v +- SPREAD``: one syntax for the language and the command line.

``+- s`` (normal, standard deviation s, in the value's unit), ``+- normal(mean, sd)``,
``+- uniform(lo, hi)`` (offsets from the value) and ``+- 3 %`` (relative: a normal of standard
deviation 3 % of the value; ``%`` also works inside ``normal``/``uniform``).  The resolver
(:mod:`acl.design.assemble`) and ``acl sweep --tolerance`` (:mod:`acl.sweep.spec`) both call
:func:`spread_of` with their own evaluator, so the two cannot drift.  No numpy: ``acl check`` stays
light.
"""
from __future__ import annotations

import math
from typing import Callable

from acl.design.model import Spread
from acl.syntax import ast as A
from acl.units import Quantity, describe, si_unit

KINDS = ("normal", "uniform")
_ARGS = {"normal": ("mean", "sd"), "uniform": ("lo", "hi")}


class SpreadError(Exception):
    """A bad spread; already reported through the ``report`` callback."""


def _is_percent(e: A.Expr) -> bool:
    while isinstance(e, A.Neg):
        e = e.operand
    return isinstance(e, A.Qty) and e.unit.strip() == "%"


def _is_zero(e: A.Expr) -> bool:
    while isinstance(e, A.Neg):
        e = e.operand
    return isinstance(e, A.Num) and e.value == 0


def spread_of(expr: A.Expr, value: Quantity, name: str, evaluate: Callable[[A.Expr], object],
              report: Callable[[str, str, object, str | None], None]) -> tuple[float, Spread | None]:
    """(standard deviation in SI at ``value``, the Spread or None for a plain ``+- s``).

    ``evaluate(expr)`` returns a value (:class:`~acl.units.Quantity` for numbers) or raises;
    ``report(code, message, span, hint)`` records a diagnostic.  Raises :class:`SpreadError` after
    reporting: E320 negative, E321 wrong dimension, E305 not finite, E322 unknown distribution or
    wrong arguments.
    """
    sd, sp = _spread_of(expr, value, name, evaluate, report)
    if not math.isfinite(sd * sd) or not math.isfinite(abs(value.value) + MAX_SIGMAS * sd):
        report("E305", f"uncertainty of `{name}` is too large to compute with ({sd:g} {si_unit(value.dims)}: its "
               f"variance, or the value {MAX_SIGMAS:g} standard deviations away, is not a finite number)".replace(" :", ":"),
               expr.span, "give the standard deviation the data support")
        raise SpreadError()
    return sd, sp


MAX_SIGMAS = 10.0     # draws of a declared uncertainty stay within this many standard deviations of the value


def _spread_of(expr, value: Quantity, name: str, evaluate, report) -> tuple[float, Spread | None]:
    unit = si_unit(value.dims)
    example = f"{abs(value.value) * 0.01:.3g} {unit}".strip() if value.value else f"1 {unit}".strip()
    if isinstance(expr, A.Call):
        return _call(expr, value, name, evaluate, report, example)
    if isinstance(expr, A.Ref) and expr.dotted in KINDS:
        report("E322", f"spread of `{name}`: `{expr.dotted}` needs its arguments", expr.span,
               f"e.g. `+- {expr.dotted}({'0, ' + example if expr.dotted == 'normal' else '-' + example + ', ' + example})`")
        raise SpreadError()
    if _is_percent(expr):
        frac = _number(expr, evaluate)
        _check_sd(frac, name, expr.span, report, "%")
        sp = Spread(kind="normal", a=0.0, b=frac, relative=True)
        _check_relative_of_zero(sp, value, name, expr.span, report, example)
        return sp.stddev(value.value), sp
    sd = _quantity(expr, value, name, evaluate, report, example)
    _check_sd(sd, name, expr.span, report, unit)
    return sd, None


def _number(e: A.Expr, evaluate) -> float:
    q = evaluate(e)
    return float(q.value)


def _check_sd(sd: float, name: str, span, report, unit: str) -> None:
    if not math.isfinite(sd):
        report("E305", f"uncertainty of `{name}` is not finite", span, "give a finite standard deviation")
        raise SpreadError()
    if sd < 0:
        shown = sd * 100 if unit == "%" else sd     # a relative spread is held as a fraction, written in %
        report("E320", f"uncertainty of `{name}` is negative ({shown:g} {unit})".replace(" )", ")"), span,
               "a standard deviation is >= 0: write `+- s` with s positive")
        raise SpreadError()


def _quantity(e: A.Expr, value: Quantity, name: str, evaluate, report, example: str) -> float:
    q = evaluate(e)
    if _is_zero(e):
        return 0.0
    if not isinstance(q, Quantity) or q.dims != value.dims:
        found = describe(q.dims) if isinstance(q, Quantity) else "not a quantity"
        report("E321", f"uncertainty of `{name}` must be {describe(value.dims)} like its value, found {found}",
               e.span, f"write it in the value's unit, e.g. `+- {example}`, or relative: `+- 3 %`")
        raise SpreadError()
    if not math.isfinite(q.value):
        report("E305", f"uncertainty of `{name}` is not finite", e.span, "give a finite value")
        raise SpreadError()
    return float(q.value)


def _call(e: A.Call, value: Quantity, name: str, evaluate, report, example: str) -> tuple[float, Spread]:
    if e.name not in KINDS:
        from acl.diagnostics import suggest

        report("E322", f"spread of `{name}`: unknown distribution `{e.name}`", e.span,
               suggest(e.name, KINDS) or "distributions: normal(mean, sd), uniform(lo, hi), or `+- 3 %`")
        raise SpreadError()
    keys = _ARGS[e.name]
    args = list(e.args)
    for k, v in e.kwargs:
        if k not in keys:
            report("E322", f"{e.name}(...) has no argument `{k}`", v.span, f"{e.name}({', '.join(keys)})")
            raise SpreadError()
        args.append(v)
    if len(args) != 2 or len(e.kwargs) and [k for k, _ in e.kwargs] != list(keys[len(e.args):]):
        report("E322", f"{e.name} takes two arguments, {e.name}({', '.join(keys)})", e.span,
               f"e.g. `+- {e.name}({'0, ' + example if e.name == 'normal' else '-' + example + ', ' + example})`")
        raise SpreadError()
    relative = any(_is_percent(a) for a in args)
    if relative:
        bad = [a for a in args if not (_is_percent(a) or _is_zero(a))]
        if bad:
            report("E321", f"spread of `{name}`: write both arguments of {e.name}(...) in % or both in the value's unit",
                   bad[0].span, f"e.g. `{e.name}({'0, 3 %' if e.name == 'normal' else '-3 %, 3 %'})`")
            raise SpreadError()
        a, b = (0.0 if _is_zero(x) else _number(x, evaluate) for x in args)
        unit = "%"
    else:
        a, b = (_quantity(x, value, name, evaluate, report, example) for x in args)
        unit = si_unit(value.dims)
    for x, ex in zip((a, b), args):
        if not math.isfinite(x):
            report("E305", f"spread of `{name}`: argument is not finite", ex.span, None)
            raise SpreadError()
    if e.name == "normal":
        _check_sd(b, name, args[1].span, report, unit)
    elif b < a:
        report("E322", f"spread of `{name}`: uniform(lo, hi) needs lo <= hi", e.span,
               "the bounds are offsets from the value, e.g. `uniform(-200 nm, 200 nm)`")
        raise SpreadError()
    sp = Spread(kind=e.name, a=a, b=b, relative=relative)
    _check_relative_of_zero(sp, value, name, e.span, report, example)
    return sp.stddev(value.value), sp


def _check_relative_of_zero(sp: Spread, value: Quantity, name: str, span, report, example: str) -> None:
    """A relative spread (`%`) of a value that is zero is no spread at all: E322, not a silent zero uncertainty."""
    if value.value == 0 and (sp.a or sp.b):
        report("E322", f"spread of `{name}`: a relative spread (%) of a zero value is zero: `{name}` would have no "
               "uncertainty", span, "give an absolute spread in the value's unit: `+- s`")
        raise SpreadError()
