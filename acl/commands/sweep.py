"""`acl sweep DESIGN [--vary NAME=LO..HI:N]... [--tolerance "NAME=normal(0, 150 nm)"]... [--samples N]
[--seed S] [--scheduler local|tcp://HOST:PORT] -o TABLE.csv|TABLE.parquet`: grids and print-tolerance
Monte Carlo, one row per point, the yield on the summary line (docs/sweep.md)."""
from __future__ import annotations

import json
import os
import sys

from acl.commands._common import (add_design_options, add_output_format, load_or_report, plotting_missing, report, seconds,
                                  seed)
from acl.diagnostics import DiagnosticError, Span, error


def _samples(text: str) -> int:
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: the number of samples is an integer >= 1")
    return value


def add_parser(p) -> None:
    p.add_argument("file", metavar="DESIGN", help="design file (.acl), or a folder holding one design")
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO..HI:N",
                   help="grid of a parameter: NAME=LO..HI:N, NAME=LO..HI:N:log, NAME=V1,V2,... (repeatable: a full grid)")
    p.add_argument("--tolerance", action="append", default=[], metavar="NAME=SPREAD",
                   help="print spread of a parameter: 'NAME=normal(0, 150 nm)', 'NAME=uniform(-0.2um, 0.2um)', "
                        "NAME=3%% (relative), NAME=150nm (standard deviation); repeatable")
    p.add_argument("--samples", type=_samples, metavar="N",
                   help="Monte Carlo samples per grid point (default 1000 when spreads are sampled); "
                        "with no --tolerance, samples the spreads the design declares")
    p.add_argument("--seed", type=seed, default=0, metavar="S", help="random seed (default 0): same seed, same rows")
    p.add_argument("--scheduler", metavar="local|tcp://HOST:PORT", default=None,
                   help="where chunks run: this machine (default) or a dask.distributed scheduler (acl[scale])")
    p.add_argument("-o", "--output", required=True, metavar="TABLE.csv|TABLE.parquet",
                   help="the table: one row per point (Parquet needs pyarrow, the acl[scale] extra)")
    p.add_argument("--quantity", action="append", default=None, metavar="NAME",
                   help="only these columns (repeatable; default every quantity the design offers, docs/sweep.md)")
    p.add_argument("--at", metavar="DRIVE", help='drive for tip deflections, e.g. --at "125 kHz @ 6 V"')
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR (histograms, yield, pass/fail map)")
    p.add_argument("--tolerance-scales", metavar="S1,S2,...",
                   help="also the yield with every spread scaled by each factor (yield vs tolerance; e.g. 0.5,1,2)")
    p.add_argument("--timeout", type=seconds, default=None, metavar="SECONDS",
                   help="on a cluster: how long to wait when it has no worker left before giving up (E-CLUSTER; default 60)")
    add_output_format(p)
    add_design_options(p)


def _scales(text: str) -> list[float]:
    import math

    out = []
    col = 1
    for item in text.split(","):
        try:
            v = float(item)
        except ValueError:
            v = float("nan")
        if not (math.isfinite(v) and v >= 0):
            raise DiagnosticError([error("E-USAGE", f"--tolerance-scales: {item.strip()!r} is not a number >= 0",
                                         Span(file="<--tolerance-scales>", line=1, column=col))])
        out.append(v)
        col += len(item) + 1
    return out


def run(args) -> int:
    fmt = args.output_format
    as_json = fmt == "json"
    quiet = args.quiet or as_json
    try:
        from acl.sweep.run import scheduler_kind
        from acl.sweep.table import check_output

        check_output(args.output)
        if args.plot is not None and not args.plot.strip():     # "" is no folder, not "no figures"
            raise DiagnosticError([error("E-USAGE", f"--plot {args.plot!r}: an empty path", Span(file="<--plot>", line=1, column=1),
                                         "give a folder, or leave the option out")])
        scheduler_kind(args.scheduler)
        scales = _scales(args.tolerance_scales) if args.tolerance_scales is not None else None
        if args.at is not None:
            from acl.design.drives import drive_from_text

            drive_from_text(args.at, "<--at>")
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    if args.plot and plotting_missing("--plot", fmt):
        return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    from acl._files import input_named

    hit = input_named(args.output, [*design.sources, design.file])
    if hit:                    # a CSV the design reads (a gain table) would be replaced by the table
        report([error("E-USAGE", f"--output {args.output}: names the input {hit}; writing would destroy it",
                      Span(file="<--output>", line=1, column=1), "give another path")], fmt)
        return 2
    from acl.commands._common import parse_sets
    from acl.sweep.driver import run_sweep, yield_vs_tolerance
    from acl.sweep.spec import build_spec

    overrides, _ = parse_sets(args.set or [])
    try:
        spec = build_spec(design, args.vary, args.tolerance, args.samples, args.seed)
        if scales is not None and not spec.tolerances:
            raise DiagnosticError([error("E-USAGE", "--tolerance-scales needs spreads to scale (--tolerance, or the design's)",
                                         Span(file="<--tolerance-scales>", line=1, column=1))])
        table = _run(run_sweep, design, spec, args, overrides, quiet)
        curve = yield_vs_tolerance(design, spec, scales, args.quantity, args.at, args.scheduler, overrides, args.path) if scales else None
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    if args.verbose:
        fm = table.field_map
        sys.stderr.write(f"acl sweep: {spec.n_points} points in {spec.n_chunks} chunk(s) of {spec.chunk_size}; fields following "
                         f"{', '.join(spec.names)}: {len(fm.linear) - len(fm.proportional)} affine, {len(fm.proportional)} "
                         f"proportional, {len(fm.derived)} recomputed volume(s), {len(fm.exact)} resolved exactly\n")
    from acl.sweep.table import write_table

    # figures first, into a temporary folder beside --plot: a figure that cannot be written leaves neither
    # the table nor part of the figures (before, the table was written and then the figures failed: exit 2
    # with the table left behind)
    import shutil

    written, tmp = [], None
    if args.plot:
        import tempfile

        from acl.sweep.figures import plot_yield_vs_tolerance, write_figures

        try:
            parent = os.path.dirname(os.path.abspath(args.plot))
            if os.path.lexists(args.plot) and not os.path.isdir(args.plot):
                raise NotADirectoryError(20, "exists and is not a folder")
            tmp = tempfile.mkdtemp(prefix=".acl-sweep-plots-", dir=parent)
            names = [os.path.basename(f) for f in write_figures(table, tmp)]
            if curve:
                names.append(os.path.basename(plot_yield_vs_tolerance(curve, tmp)))
        except OSError as exc:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
            report([error("E601", f"cannot write figures to `{args.plot}`: {exc.strerror or exc}",
                          Span(file="<--plot>", line=1, column=1))], fmt)
            return 2
    try:
        write_table(table, args.output)
    except OSError as exc:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
        report([error("E601", f"cannot write `{args.output}`: {exc.strerror or exc}", Span(file=args.output, line=1, column=1))], fmt)
        return 2
    if tmp:
        try:
            os.makedirs(args.plot, exist_ok=True)
            for n in names:
                os.replace(os.path.join(tmp, n), os.path.join(args.plot, n))
                written.append(os.path.join(args.plot, n))
        except OSError as exc:
            report([error("E601", f"cannot write figures to `{args.plot}`: {exc.strerror or exc}",
                          Span(file="<--plot>", line=1, column=1))], fmt)
            return 2
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    if as_json:
        out = {"design": design.file, "output": args.output, "summary": table.summary_line(), **table.summary()}
        if curve:
            out["yield_vs_tolerance"] = curve
        if args.plot:
            out["figures"] = written
        sys.stdout.write(json.dumps(out, indent=2, default=float) + "\n")
        return 0
    _print(table, args, curve, written, design)
    return 0


def _note(text: str, console=None) -> None:
    """A note on stderr while the sweep runs (through the progress bar's console when there is one)."""
    if console is not None:
        console.print(f"[yellow]note:[/yellow] {text}")
    else:
        sys.stderr.write(f"acl sweep: note: {text}\n")
        sys.stderr.flush()


def _run(run_sweep, design, spec, args, overrides, quiet):
    kw = dict(quantities=args.quantity, at=args.at, scheduler=args.scheduler, overrides=overrides, search_paths=args.path,
              timeout=args.timeout)
    if quiet or spec.n_chunks < 2:
        return run_sweep(design, spec, notify=_note, **kw)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from acl._console import make_console

    with Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TextColumn("chunks"), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=make_console(stderr=True), transient=True) as prog:
        bar = prog.add_task("sweep", total=spec.n_chunks)
        return run_sweep(design, spec, progress=lambda done, total: prog.update(bar, completed=done),
                         notify=lambda text: _note(text, prog.console), **kw)


GRID_ROWS = 50          # grid points listed one per line; the rest are in the JSON summary and the table


def _print(table, args, curve, written, design) -> None:
    from acl._console import make_console

    from acl.sweep.table import Yield

    con = make_console()
    if not args.quiet:
        for n in table.notes:
            con.print(f"[yellow]note:[/yellow] {n}")
    y = table.yields()
    con.print(f"{args.output}: {len(table)} points; {table.summary_line()}")
    if args.quiet:
        return
    for key, v in y.items():
        if key.startswith("require_"):
            i = int(key.split("_")[1])
            verdict = v.text() if table.spec.montecarlo else f"{v.passed} of {v.total} points"
            con.print(f"  {key} `{design.requires[i - 1].text}`: {verdict}")
    rows = table.grid_yields()
    if rows:
        # the pooled yield hides the grid (issue 28: 0.60 over radii whose yields are 0.02 ... 0.09)
        con.print(f"  yield per grid point ({table.spec.samples} samples each):")
        for label, v in rows[:GRID_ROWS]:
            con.print(f"    {label}: {v.text()}")
        if len(rows) > GRID_ROWS:
            con.print(f"    ... {len(rows) - GRID_ROWS} more grid points: --output-format json (grid_yield) or -o table")
    if curve:
        for r in curve:
            # the same text as every other yield: bounds rounded outwards (was to nearest: 0.467 shown as 0.47)
            y = Yield(int(r["passed"]), int(r["total"]), float(r["lower"]), float(r["upper"]))
            con.print(f"  tolerance x{r['scale']:g}: yield {y.text()}")
    if written:
        con.print(f"wrote {len(written)} figure(s) to {args.plot}")

