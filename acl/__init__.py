"""acl: a language and compiler for acoustically programmable soft micro-mechanisms.

Python API (docs/python.md).  Every function imports what it needs when called, so ``import acl``
stays cheap (no numpy, scipy, cvxpy, matplotlib or pygls)::

    import acl
    design = acl.load("examples/fig2_vertical_cantilever.acl")
    report = acl.analyze(design)          # typed, shows as a table in notebooks, report.plot()
    report.resonance("act")               # Hz

Results (:mod:`acl.notebook`) hold the same data as the commands' JSON outputs (``as_dict()``),
display as compact HTML tables in notebooks and draw with ``.plot(ax=None)`` without changing the
matplotlib backend.  Errors in a design raise :class:`acl.diagnostics.DiagnosticError` carrying
every diagnostic (code, file:line:column, hint).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

__version__ = "0.1.0"

__all__ = ["load", "loads", "analyze", "compile", "lint", "fit", "sweep", "tune", "__version__"]

if TYPE_CHECKING:  # pragma: no cover
    from acl.design.model import Design
    from acl.notebook import Analysis, Compiled, FitReport, LintResult
    from acl.sweep.table import SweepTable
    from acl.sweep.tune import Tuned


def load(path, overrides=None, search_paths=()) -> "Design":
    """Parse, resolve and check a design file; return the resolved, immutable design (SI floats).

    ``overrides`` maps parameter names to values as written in the language (like ``--set``);
    ``search_paths`` are extra folders imports may read from (like ``--path``).  Raises
    :class:`acl.diagnostics.DiagnosticError` with every diagnostic if the design has errors.

    >>> import acl
    >>> d = acl.load("examples/fig2_vertical_cantilever.acl", overrides={"dwell": "100 ms"})
    >>> d.capsule("act").orifices[0].radius * 1e6       # SI inside: metres
    10.0
    """
    from acl.design.resolve import load_design

    return load_design(path, overrides=overrides or {}, search_paths=search_paths)


def loads(text, filename="<string>", overrides=None, search_paths=()) -> "Design":
    """Like :func:`load`, from source text; ``filename`` is used in diagnostics and to find imports.

    >>> import acl
    >>> d = acl.loads("import stdlib.capsules\\ncapsule c like capsules.design1 { center = (0, 0, 100 um) }\\n")
    >>> round(d.capsule("c").cavity.volume * 1e18)
    65090
    """
    from acl.design.resolve import load_text

    return load_text(text, filename=filename, overrides=overrides or {}, search_paths=search_paths)


def _design(design, search_paths=()):
    from acl.design.model import Design

    return design if isinstance(design, Design) else load(design, search_paths=search_paths)


def analyze(design, at=None, snap_in=True) -> "Analysis":
    """Predict modes, selectivity, pair forces, latch margins and `require`s (as `acl analyze --output-format json`).

    ``design``: a :class:`~acl.design.model.Design` or a path.  ``at``: a drive such as
    ``"125 kHz @ 6 V"`` for the equilibrium under it.  ``snap_in=False`` skips the snap-in voltage
    sweeps (faster).  Returns an :class:`acl.notebook.Analysis`.

    >>> import acl
    >>> a = acl.analyze("examples/fig2_vertical_cantilever.acl")
    >>> abs(a.resonance("act") / 122e3 - 1) < 0.03     # paper Table S1, design 1: 122 kHz (3 %)
    True
    """
    from acl.analysis.report import analyze as _analyze
    from acl.notebook import Analysis

    d = _design(design)
    drive = None
    if at is not None:
        from acl.design.drives import drive_from_text

        drive = drive_from_text(at, "<at>") if isinstance(at, str) else at
    from acl.sweep.signs import annotate_pairs

    rep = _analyze(d, drive, snap_in=snap_in)
    annotate_pairs(d, rep.pairs)          # P(other sign) of each pair, as `acl analyze`
    return Analysis.from_report(rep)


def compile(design, program=None, sample_rate_hz=None, ramp_s=1e-3, tolerance_m=0.5e-6, calibration=None,  # noqa: A001
            allow_nonlinear=False) -> "Compiled":
    """Compile a program of ``design`` into a drive schedule (as `acl compile`, without writing files).

    ``program`` may be omitted when the design has one.  ``calibration``: path of a measured sweep
    CSV (like ``--calibration``).  ``allow_nonlinear`` plans drives past the hemisphere (eps/R > 1)
    (like ``--allow-nonlinear``; docs/physics.md).  Raises :class:`acl.diagnostics.DiagnosticError`
    when the program cannot be compiled.  Returns an :class:`acl.notebook.Compiled`.

    >>> import acl
    >>> s = acl.compile("examples/fig2_vertical_cantilever.acl", "ramp")  # the paper's 8 V: warned (W-ACOUSTIC-AMPLITUDE), not refused
    >>> round(s.duration_s, 3), len(s.segments)
    (3.4, 9)
    """
    from acl.diagnostics import DiagnosticError, Span, error, suggest
    from acl.notebook import Compiled
    from acl.schedule.compile import CompileOptions, compile_program

    d = _design(design)
    names = [p.name for p in d.programs]
    where = Span(file=d.file, line=1, column=1)
    if program is None:
        if len(names) != 1:
            raise DiagnosticError([error("E-COMPILE-PROGRAM", f"the design has {len(names)} programs; choose one",
                                         where, "programs: " + (", ".join(names) or "none"))])
        program = names[0]
    if program not in names:
        raise DiagnosticError([error("E-COMPILE-PROGRAM", f"no program named {program!r}", where,
                                     suggest(program, names) or "programs: " + (", ".join(names) or "none"))])
    cal = None
    if calibration is not None:
        from acl.schedule.calibration import read_sweep_csv

        t = d.transducer
        cal = read_sweep_csv(str(calibration), t.band if t is not None else None, t.name if t else "")
    opts = CompileOptions(sample_rate_hz=sample_rate_hz, ramp_s=ramp_s, tolerance_m=tolerance_m, calibration=cal,
                          allow_nonlinear=allow_nonlinear)
    return Compiled.from_schedule(compile_program(d, program, opts))


def _lint(path, select=None, ignore=None, config=None) -> "LintResult":
    """Run the design rules on a file (as `acl lint --output-format json PATH`).

    ``select``/``ignore``: rule codes or prefixes; ``config``: a configuration file (default: the
    nearest acl.toml or pyproject.toml).  Returns an :class:`acl.notebook.LintResult`.

    >>> import acl
    >>> acl.lint("examples/fig2_vertical_cantilever.acl").ok
    True
    """
    import io
    import json

    from acl.lint import find_config, lint_file, load_config, load_rules
    from acl.lint.formats import rule_name, write_json
    from acl.lint.registry import match_codes
    from acl.notebook import Finding, LintResult

    path = str(getattr(path, "file", path))
    rules = load_rules()
    cfg = load_config(str(config) if config else find_config(path), rules)
    if select:
        cfg.select = tuple(c for p in select for c in match_codes(p, rules))
    if ignore:
        cfg.ignore = tuple(dict.fromkeys(tuple(cfg.ignore) + tuple(c for p in ignore for c in match_codes(p, rules))))
    rep = lint_file(path, cfg)
    buf = io.StringIO()
    write_json([rep], buf)
    findings = [Finding(d.code, rule_name(d.code), d.severity.value, d.message, d.span.file if d.span else None,
                        d.span.line if d.span else None, d.span.column if d.span else None, d.hint)
                for d in rep.findings]
    return LintResult(path, findings, list(rep.notes), json.loads(buf.getvalue()))


def _fit(design, data, free=(), effects=None, seed=0, search_paths=(), model="coupled") -> "FitReport":
    """Fit the model to measured data and search for missing effects (as `acl fit --output-format json`).

    ``design``: path of the design; ``data``: a CSV path or a list of them (docs/data.md);
    ``free``: names to fit besides the design's `free` params (gamma, alpha, E, gain, params);
    ``effects``: effect ids to consider (None: the whole library); ``model``: a simple pair's force
    model, "coupled" (the analysis' forces, the default) or "eq3" (paper Eq. 3, as `--model`).  Writes nothing; the calibrated
    design's text is ``result.calibrated_source``.  Returns an :class:`acl.notebook.FitReport`.

    >>> import acl
    >>> r = acl.fit("samples/fit_cantilever.acl", "fit_data.csv", free=["gamma"], effects=[])  # doctest: +SKIP
    >>> r.rmse_after < r.rmse_before                                                              # doctest: +SKIP
    True
    """
    from acl.fit import run_fit
    from acl.notebook import FitReport

    paths = [str(data)] if isinstance(data, (str, bytes)) or hasattr(data, "__fspath__") else [str(p) for p in data]
    out = run_fit(str(getattr(design, "file", design)), paths, free=list(free), search_paths=search_paths,
                  candidates=None if effects is None else list(effects), seed=seed, model=model)
    return FitReport.from_outcome(out)


def _sweep(design, vary=None, tolerance=None, n=None, seed=0, quantities=None, at=None, scheduler=None,
           overrides=None, search_paths=()) -> "SweepTable":
    """Evaluate a design over grids and print tolerances (as `acl sweep`, without writing files; docs/sweep.md).

    ``design``: a path (or a Design loaded from a file); ``vary``: ``{"radius": "8um..12um:41"}``,
    ``{"radius": [8e-6, 9e-6]}`` (SI) or ``["radius=8um..12um:41"]``; ``tolerance``:
    ``{"radius": "normal(0, 150 nm)"}`` (Monte Carlo; the design's own ``+- ...`` spreads are sampled
    too); ``n`` samples per grid point (default 1000 with tolerances); ``seed``; ``quantities``:
    column names (default: every quantity the batched evaluation gives); ``at``: a drive for tip
    deflections; ``scheduler``: None/"local" or "tcp://HOST:PORT" (dask, `acl[scale]`).  Returns an
    :class:`acl.sweep.table.SweepTable`: ``t["resonance_act_1_hz"]``, ``t.yields()["all"]``,
    ``t.to_arrow()``, ``t.to_pandas()``.

    >>> import acl
    >>> t = acl.sweep("samples/sweep_cantilever.acl", vary={"radius": "9um..11um:5"})
    >>> len(t), t.columns[:2]
    (5, ('point', 'radius'))
    """
    from acl.sweep.driver import sweep as _run

    return _run(design, vary=vary, tolerance=tolerance, n=n, seed=seed, quantities=quantities, at=at,
                scheduler=scheduler, overrides=overrides, search_paths=search_paths)


def tune(design, tolerance=None, n=2000, validate=None, seed=0, objective="yield", method="nelder-mead",
         max_evals=200, scheduler=None, search_paths=()) -> "Tuned":
    """Choose the design's `free` parameters for yield under its print tolerances (as `acl tune`, writing
    nothing; docs/tune.md).

    ``design``: a path (or a Design loaded from a file); ``tolerance`` as :func:`sweep`
    (``{"r1": "normal(0, 150 nm)"}`` or ``["r1=normal(0, 150 nm)"]``), replacing a declared spread;
    ``n`` samples searched (``--samples``); ``validate`` fresh samples the yield before and after is
    counted on (default ``n``); ``seed``; ``objective`` "yield" or "margin"; ``method``
    "nelder-mead", "powell" or "differential-evolution"; ``max_evals`` trials; ``scheduler``:
    None/"local" or "tcp://HOST:PORT" (dask, `acl[scale]`), the same result on either.  Returns an
    :class:`acl.sweep.tune.Tuned`: ``.values`` ({name: SI value}), ``.before``/``.after`` (yields
    with ``.interval``), ``.to_json()`` (as `--output-format json`), ``.write(path)`` (the tuned
    design).  Raises :class:`acl.diagnostics.DiagnosticError` (E870-E875) when it cannot tune.

    >>> import acl
    >>> r = acl.tune("examples/fig3_robust_radii.acl", n=300, max_evals=40)   # doctest: +SKIP
    >>> r.after.value > r.before.value                                         # doctest: +SKIP
    True
    """
    from acl.sweep import tune as T

    if isinstance(tolerance, dict):
        tolerance = [f"{k}={v}" for k, v in tolerance.items()]
    elif isinstance(tolerance, str):
        tolerance = [tolerance]
    path = str(getattr(design, "file", design))
    problem = T.prepare(path, tolerance=list(tolerance or ()), samples=n, validate=validate, seed=seed,
                        search_paths=search_paths)
    return T.tune(problem, objective=objective, method=method, max_evals=max_evals, scheduler=scheduler)


# `acl.lint` and `acl.fit` are also subpackages: once imported they replace these attributes with
# modules that are callable with the same arguments (acl/_callable.py), so both spellings work.
lint = _lint
fit = _fit
sweep = _sweep
