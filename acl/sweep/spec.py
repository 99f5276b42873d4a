"""What a sweep varies: grids (``--vary``) and spreads (``--tolerance``, or declared ``param x = v +- ...``).

Units at the edge, SI inside.  Every problem is a located diagnostic (``<--vary>:1:COL``,
``<--tolerance>:1:COL``) raised as :class:`~acl.diagnostics.DiagnosticError`; nothing is printed
here.  The grid syntax::

    NAME=LO..HI:N          N points, evenly spaced (N >= 2, or LO == HI)
    NAME=LO..HI:N:log      N points, evenly spaced in log (LO, HI > 0)
    NAME=V1,V2,V3          a list
    NAME=V                 one value

and a spread is written as in the language after ``+-`` (acl.design.spread): ``normal(0, 150 nm)``,
``uniform(-0.2 um, 0.2 um)``, ``3 %``, ``150 nm`` (a standard deviation); a leading ``+-`` is allowed.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from acl.design.model import Design, Spread
from acl.diagnostics import Diagnostic, DiagnosticError, Span, error, suggest
from acl.units import Quantity, UnitError, describe, parse_unit

MAX_POINTS = 100_000_000       # rows of one sweep: the table is held in memory (~10 GB at 100 million rows)
DEFAULT_SAMPLES = 1000         # Monte Carlo samples per grid point when --samples is not given
CHUNK_SIZE = 65_536            # points per task: fixed, so any scheduler gives the same chunks

_NAME = re.compile(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*=")
_NUMBER = re.compile(r"\s*([+-]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$", re.S)


@dataclass(frozen=True)
class Axis:
    """One ``--vary`` grid: SI values of one parameter."""

    name: str
    values: np.ndarray
    unit: str                      # SI unit of the values
    log: bool = False


@dataclass(frozen=True)
class Tolerance:
    """A spread on one parameter, from the design (``+- ...``) or from ``--tolerance``."""

    name: str
    spread: Spread
    unit: str
    source: str                    # "design" or "--tolerance"


@dataclass(frozen=True)
class SweepSpec:
    """Points of a sweep: the full grid of ``axes`` (first axis slowest), ``samples`` Monte Carlo
    draws of ``tolerances`` at each grid point (point k = grid g * samples + s), seeded by ``seed``."""

    axes: tuple[Axis, ...]
    tolerances: tuple[Tolerance, ...]
    samples: int
    seed: int
    nominal: dict[str, float]              # every varied or sampled parameter -> its value (SI)
    units: dict[str, str]
    correlation: np.ndarray | None = None  # between tolerances (from the design's `correlation(a, b)`)
    montecarlo: bool = False
    chunk_size: int = CHUNK_SIZE
    notes: tuple[str, ...] = field(default=())

    @property
    def names(self) -> tuple[str, ...]:
        """The parameters that vary, axes first, each once."""
        return tuple(dict.fromkeys([a.name for a in self.axes] + [t.name for t in self.tolerances]))

    @property
    def grid_shape(self) -> tuple[int, ...]:
        return tuple(len(a.values) for a in self.axes)

    @property
    def n_grid(self) -> int:
        return math.prod(self.grid_shape)

    @property
    def n_points(self) -> int:
        return self.n_grid * self.samples

    @property
    def n_chunks(self) -> int:
        return max(1, -(-self.n_points // self.chunk_size))

    def box(self) -> dict[str, tuple[float, float]]:
        """Range each parameter takes (grid bounds widened by 4 standard deviations, or a uniform's
        bounds): where the design's map from parameters to fields is checked (acl.sweep.perturb)."""
        out = {n: (v, v) for n, v in self.nominal.items()}
        for a in self.axes:
            out[a.name] = (float(np.min(a.values)), float(np.max(a.values)))
        for t in self.tolerances:
            lo, hi = out[t.name]
            s = t.spread
            d_lo, d_hi = (s.a - 4 * s.b, s.a + 4 * s.b) if s.kind == "normal" else (s.a, s.b)
            ends = [v + d * (abs(v) if s.relative else 1.0) for v in (lo, hi) for d in (d_lo, d_hi)]
            out[t.name] = (min(ends), max(ends))
        return out


# ------------------------------------------------------------------------------------------------
# Quantities written on the command line
# ------------------------------------------------------------------------------------------------

def _quantity(text: str, col: int, where: str, name: str, unit: str) -> float:
    """``8um``, ``8 um``, ``1e-6``: SI value; its dimension must be the parameter's (E301)."""
    span = Span(file=where, line=1, column=col + 1 + (len(text) - len(text.lstrip())))
    m = _NUMBER.fullmatch(text)
    if not m or not text.strip():
        raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: expected a number with a unit, found {text.strip()!r}",
                                     span, f"e.g. {_example(unit)}")])
    number, u = m.groups()
    try:
        factor, dims = parse_unit(u) if u else (1.0, (0,) * 7)
    except UnitError as exc:
        raise DiagnosticError([error("E302", f"{where[1:-1]} {name}: {exc}", span, exc.hint)]) from None
    want = parse_unit(unit)[1]
    value = float(number) * factor
    if tuple(dims) != tuple(want) and not (value == 0 and not u):
        raise DiagnosticError([error("E301", f"{where[1:-1]} {name}: expected {describe(tuple(want))} like the parameter, "
                                     f"found {describe(tuple(dims))}", span, f"e.g. {_example(unit)}")])
    if not math.isfinite(value):
        raise DiagnosticError([error("E305", f"{where[1:-1]} {name}: value is not finite", span)])
    return value


def _example(unit: str) -> str:
    from acl.design.core import UNIT_EXAMPLES

    return UNIT_EXAMPLES.get(unit, f"1 {unit}".strip()).replace(" ", "")


def _split_name(text: str, where: str, design: Design, what: str) -> tuple[str, int]:
    """``NAME=...`` -> (NAME, offset of what follows '='); the name must be a parameter (E211)."""
    m = _NAME.match(text)
    if not m:
        raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {text!r}: expected NAME={what}", Span(file=where, line=1, column=1),
                                     f"e.g. {where[1:-1]} " + ("radius=8um..12um:41" if what != "SPREAD" else "'radius=normal(0, 150 nm)'"))])
    name = m.group(1)
    names = [p.name for p in design.params]
    if name not in names:
        raise DiagnosticError([error("E211", f"{where[1:-1]} {name}: the design has no parameter `{name}`",
                                     Span(file=where, line=1, column=m.start(1) + 1),
                                     suggest(name, names) or ("parameters: " + ", ".join(names) if names else
                                                              "declare one in the design: `param NAME = value`, and use it"))])
    return name, m.end()


# ------------------------------------------------------------------------------------------------
# --vary
# ------------------------------------------------------------------------------------------------

def parse_vary(text: str, design: Design, where: str = "<--vary>") -> Axis:
    """``NAME=LO..HI:N[:log]``, ``NAME=V1,V2,...`` or ``NAME=V`` -> an :class:`Axis` (SI)."""
    name, off = _split_name(text, where, design, "LO..HI:N")
    unit = design.param(name).unit
    body = text[off:]
    if not body.strip():
        raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: no values after '='", Span(file=where, line=1, column=off + 1),
                                     f"e.g. {name}={_example(unit)}..{_example(unit)}:11")])
    if ".." in body:
        rng, _, rest = body.partition(":")
        lo_t, _, hi_t = rng.partition("..")
        lo = _quantity(lo_t, off, where, name, unit)
        hi = _quantity(hi_t, off + len(lo_t) + 2, where, name, unit)
        parts = rest.split(":") if rest else []
        col = off + len(rng) + 1
        if not parts or not parts[0].strip():
            raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: give the number of points, LO..HI:N",
                                         Span(file=where, line=1, column=col + 1), f"e.g. {name}={rng.strip()}:11")])
        try:
            n = int(parts[0])
        except ValueError:
            n = None
        if n is None or n < 1:
            raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: the number of points must be an integer >= 1, "
                                         f"found {parts[0].strip()!r}", Span(file=where, line=1, column=col + 1))])
        if n > MAX_POINTS:     # before the grid is allocated (1e20 points: numpy's "Maximum allowed size exceeded")
            raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: {n:.3g} points is more than one sweep holds "
                                         f"in memory ({MAX_POINTS:.0e})", Span(file=where, line=1, column=col + 1))])
        log = False
        if len(parts) > 1:
            flag = parts[1].strip()
            if flag != "log" or len(parts) > 2:
                raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: after LO..HI:N only `:log` may follow, found "
                                             f"{':'.join(parts[1:])!r}", Span(file=where, line=1, column=col + len(parts[0]) + 2))])
            log = True
        if n == 1 and lo != hi:
            raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: a range needs at least 2 points",
                                         Span(file=where, line=1, column=col + 1), f"e.g. {name}={rng.strip()}:11")])
        if log:
            if not (lo > 0 and hi > 0):
                raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: a log grid needs LO and HI > 0",
                                             Span(file=where, line=1, column=off + 1))])
            values = np.geomspace(lo, hi, n)
        else:
            values = np.linspace(lo, hi, n)
        values[0], values[-1] = lo, hi      # exact ends
        return Axis(name, values, unit, log)
    values, col = [], off
    for item in body.split(","):
        if not item.strip():
            raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: empty item in the list", Span(file=where, line=1, column=col + 1))])
        values.append(_quantity(item, col, where, name, unit))
        col += len(item) + 1
    return Axis(name, np.array(values, float), unit)


# ------------------------------------------------------------------------------------------------
# --tolerance
# ------------------------------------------------------------------------------------------------

_PREFIX = "param __t = 1 +- "


def parse_spread(text: str, value: Quantity, name: str, where: str, offset: int = 0) -> Spread:
    """A spread as the language writes it after ``+-`` (acl.design.spread), columns in ``where``."""
    from acl.design.spread import SpreadError, spread_of
    from acl.syntax import ast as A
    from acl.syntax.parser import parse_module

    body = text
    stripped = body.lstrip()
    for pm in ("+-", "±"):
        if stripped.startswith(pm):
            offset += len(body) - len(stripped) + len(pm)
            body = stripped[len(pm):]
            break
    shift = offset - len(_PREFIX)

    def moved(span):
        return Span(file=where, line=1, column=max(1, span.column + shift)) if span is not None else Span(file=where, line=1, column=1)

    if not body.strip() or "\n" in body:
        raise DiagnosticError([error("E-USAGE", f"{where[1:-1]} {name}: expected a spread, e.g. normal(0, 150 nm), uniform(lo, hi) or 3 %",
                                     Span(file=where, line=1, column=offset + 1))])
    try:
        mod = parse_module(f"{_PREFIX}{body}\n", where)
        decl = mod.statements[0]
        expr = decl.stddev
        if len(mod.statements) != 1 or expr is None or decl.free:
            raise DiagnosticError([error("E111", "expected a spread, e.g. normal(0, 150 nm)", Span(file=where, line=1, column=1))])
    except DiagnosticError as exc:
        raise DiagnosticError([Diagnostic(d.code, d.severity, f"{where[1:-1]} {name}: {d.message}", moved(d.span), d.hint)
                               for d in exc.diagnostics]) from None
    found: list[Diagnostic] = []

    def evaluate(e):
        sign = 1.0
        while isinstance(e, A.Neg):
            sign, e = -sign, e.operand
        if isinstance(e, A.Num):
            return Quantity(sign * e.value)
        if isinstance(e, A.Qty):
            try:
                factor, dims = parse_unit(e.unit)
            except UnitError as exc:
                found.append(error("E302", f"{where[1:-1]} {name}: {exc}", moved(e.span), exc.hint))
                raise SpreadError() from None
            return Quantity(sign * e.value * factor, dims)
        found.append(error("E304", f"{where[1:-1]} {name}: write numbers with units here, e.g. normal(0, 150 nm)", moved(e.span)))
        raise SpreadError()

    def report(code, msg, span, hint):
        found.append(error(code, f"{where[1:-1]} {msg}", moved(span), hint))

    try:
        sd, spread = spread_of(expr, value, name, evaluate, report)
    except SpreadError:
        raise DiagnosticError(found) from None
    return spread if spread is not None else Spread(kind="normal", a=0.0, b=sd)   # `+- s`: a normal of mean 0


def parse_tolerance(text: str, design: Design, where: str = "<--tolerance>") -> Tolerance:
    """``NAME=SPREAD`` -> a :class:`Tolerance` (``--tolerance "radius=normal(0, 150 nm)"``)."""
    name, off = _split_name(text, where, design, "SPREAD")
    p = design.param(name)
    spread = parse_spread(text[off:], Quantity(p.value, parse_unit(p.unit)[1]), name, where, off)
    return Tolerance(name, spread, p.unit, "--tolerance")


# ------------------------------------------------------------------------------------------------
# The whole specification
# ------------------------------------------------------------------------------------------------

def _items(x, where: str) -> list[str]:
    """Options as a list of ``NAME=...`` strings; the Python API may pass a dict {name: text or values}."""
    if x is None:
        return []
    if isinstance(x, str):
        return [x]
    if isinstance(x, dict):
        out = []
        for k, v in x.items():
            out.append((k, v) if not isinstance(v, str) else f"{k}={v}")
        return out
    return list(x)


def build_spec(design: Design, vary=None, tolerance=None, samples: int | None = None, seed: int = 0,
               chunk_size: int = CHUNK_SIZE) -> SweepSpec:
    """Parse and check everything a sweep varies; raises DiagnosticError with every problem found.

    ``vary``: ``["r=8um..12um:41", ...]`` or ``{"r": "8um..12um:41"}`` or ``{"r": SI values}``;
    ``tolerance``: ``["r=normal(0, 150 nm)", ...]`` or ``{"r": "normal(0, 150 nm)"}``.  Monte Carlo
    is on when a tolerance or ``samples`` is given; it then also samples the spreads the design
    declares (``param x = v +- ...``), with their correlations.
    """
    diags: list[Diagnostic] = []
    axes: list[Axis] = []
    tols: dict[str, Tolerance] = {}
    for item in _items(vary, "<--vary>"):
        try:
            if isinstance(item, tuple):
                axes.append(_axis_from_values(design, *item))
            else:
                axes.append(parse_vary(str(item), design))
        except DiagnosticError as exc:
            diags += exc.diagnostics
    for item in _items(tolerance, "<--tolerance>"):
        try:
            if isinstance(item, tuple):
                raise DiagnosticError([error("E-USAGE", f"tolerance {item[0]}: write the spread as text, e.g. 'normal(0, 150 nm)'",
                                             Span(file="<--tolerance>", line=1, column=1))])
            t = parse_tolerance(str(item), design)
            if t.name in tols:
                raise DiagnosticError([error("E-USAGE", f"--tolerance {t.name} given twice", Span(file="<--tolerance>", line=1, column=1))])
            tols[t.name] = t
        except DiagnosticError as exc:
            diags += exc.diagnostics
    seen = set()
    for a in axes:
        if a.name in seen:
            diags.append(error("E-USAGE", f"--vary {a.name} given twice", Span(file="<--vary>", line=1, column=1)))
        seen.add(a.name)
    if samples is not None and (isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1):
        diags.append(error("E-USAGE", f"--samples {samples!r}: a number of samples is an integer >= 1", Span(file="<--samples>", line=1, column=1)))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        diags.append(error("E-USAGE", f"--seed {seed!r}: a seed is a non-negative integer", Span(file="<--seed>", line=1, column=1)))
    if not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        diags.append(error("E-USAGE", f"chunk size {chunk_size!r}: an integer >= 1", Span(file="<chunk_size>", line=1, column=1)))
    if diags:
        raise DiagnosticError(diags)
    montecarlo = bool(tols) or samples is not None
    notes = []
    if montecarlo:
        for p in design.params:
            sp = p.distribution()
            if sp is not None and p.name in design.lognormal:     # `lognormal(p)`: the same mean and sd, positive
                sp = Spread(kind="lognormal", a=0.0, b=p.stddev / p.value, relative=True)
            if sp is None:
                continue
            if p.name in tols:
                notes.append(f"--tolerance {p.name} replaces the spread the design declares")
            else:
                tols[p.name] = Tolerance(p.name, sp, p.unit, "design")
        if not tols:
            raise DiagnosticError([error("E-USAGE", "--samples: nothing to sample: give --tolerance NAME=SPREAD, or declare "
                                         "`param NAME = value +- SPREAD` in the design", Span(file="<--samples>", line=1, column=1))])
    if not axes and not tols:
        raise DiagnosticError([error("E-USAGE", "nothing to sweep: give --vary NAME=LO..HI:N or --tolerance NAME=SPREAD",
                                     Span(file="<argv>", line=1, column=1))])
    n_samples = (samples if samples is not None else DEFAULT_SAMPLES) if montecarlo else 1
    spec = SweepSpec(axes=tuple(axes), tolerances=tuple(tols.values()), samples=int(n_samples), seed=int(seed),
                     nominal={}, units={}, montecarlo=montecarlo, chunk_size=int(chunk_size), notes=tuple(notes))
    if spec.n_points > MAX_POINTS:
        raise DiagnosticError([error("E-USAGE", f"{spec.n_points:.3g} points is more than one sweep holds in memory ({MAX_POINTS:.0e})",
                                     Span(file="<argv>", line=1, column=1),
                                     "use fewer grid points or samples, or several runs with different --seed")])
    names = spec.names
    corr = _correlation(design, spec.tolerances)
    return SweepSpec(axes=spec.axes, tolerances=spec.tolerances, samples=spec.samples, seed=spec.seed,
                     nominal={n: design.param(n).value for n in names}, units={n: design.param(n).unit for n in names},
                     correlation=corr, montecarlo=montecarlo, chunk_size=spec.chunk_size, notes=spec.notes)


def _axis_from_values(design: Design, name: str, values) -> Axis:
    """The Python API's ``vary={"r": [8e-6, 9e-6]}``: SI values, checked finite."""
    names = [p.name for p in design.params]
    if name not in names:
        raise DiagnosticError([error("E211", f"vary {name}: the design has no parameter `{name}`", Span(file="<vary>", line=1, column=1),
                                     suggest(name, names))])
    try:
        arr = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise DiagnosticError([error("E-USAGE", f"vary {name}: expected finite SI values or text such as '8um..12um:41'",
                                     Span(file="<vary>", line=1, column=1))])
    return Axis(name, arr, design.param(name).unit)


def _correlation(design: Design, tols) -> np.ndarray | None:
    """Correlation matrix between the design-declared spreads (``correlation(a, b) = r``); None if none."""
    pos = {t.name: i for i, t in enumerate(tols) if t.source == "design"}
    corr = np.eye(len(tols))
    found = False
    for c in design.correlations:
        if c.a in pos and c.b in pos:
            corr[pos[c.a], pos[c.b]] = corr[pos[c.b], pos[c.a]] = c.value
            found = True
    return corr if found else None
