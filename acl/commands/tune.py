"""`acl tune DESIGN`: choose the design's `free` parameters to maximise the yield of its `require`s
under the declared tolerances; print the chosen values and the yield before and after; write a tuned
design that `extends` the original (acl.sweep.tune)."""
from __future__ import annotations

import os
import sys

from acl.commands._common import add_output_format, exit_code, one_design, report, seconds, seed


def add_parser(p) -> None:
    from acl.sweep.tune import METHODS, OBJECTIVES

    p.add_argument("design", metavar="DESIGN", help="design file (.acl) with `free` parameters, `require`s and "
                                                     "tolerances, or a folder holding one design")
    p.add_argument("--tolerance", action="append", default=[], metavar="NAME=SPREAD",
                   help="a print tolerance, as in acl sweep: 'r1=normal(0, 150 nm)', 'r1=uniform(-0.2um, 0.2um)', "
                        "'r1=3 %%' (repeatable; replaces the spread the design declares for NAME)")
    p.add_argument("--objective", choices=OBJECTIVES, default="yield",
                   help="yield: the fraction of samples meeting every require (default); margin: the worst-case "
                        "margin over the samples (each require's margin in units of its spread)")
    p.add_argument("--samples", type=_count, default=2000, metavar="N",
                   help="samples the search averages over, the same at every trial (default 2000)")
    p.add_argument("--validate", type=_count, default=None, metavar="N",
                   help="fresh samples the yield before and after is reported on (default: as --samples)")
    p.add_argument("--seed", type=seed, default=0, help="random seed of the samples (default 0)")
    p.add_argument("--method", choices=METHODS, default="nelder-mead",
                   help="search: nelder-mead (default, after a Latin hypercube scan), powell, differential-evolution")
    p.add_argument("--max-evals", type=_count, default=200, metavar="N",
                   help="most trial points the search evaluates (default 200)")
    p.add_argument("--scheduler", metavar="local|tcp://HOST:PORT", default=None,
                   help="where trials run: this machine (default) or a dask.distributed scheduler (acl[scale]); "
                        "the tuned values are the same on either")
    p.add_argument("--target", type=_fraction, default=None, metavar="YIELD",
                   help="required yield, e.g. 0.95: unless the validated yield's 95%% interval lies at or above it, "
                        "exit 1 (E876) and write nothing")
    p.add_argument("-o", "--output", metavar="PATH", default=None,
                   help="where to write the tuned design (default: <stem>.tuned.acl next to DESIGN)")
    p.add_argument("--no-write", action="store_true", help="report only; write no tuned design")
    p.add_argument("--timeout", type=seconds, default=None, metavar="SECONDS",
                   help="on a cluster: how long to wait when it has no worker left before giving up (E-CLUSTER; default 60)")
    add_output_format(p)
    p.add_argument("--path", action="append", default=[], metavar="DIR", help="extra folder imports may read from")


def _count(text: str) -> int:
    import argparse

    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give an integer >= 1")
    return v


def _fraction(text: str) -> float:
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and 0 < v <= 1):
        raise argparse.ArgumentTypeError(f"{text!r}: a yield is a fraction in (0, 1], e.g. 0.95")
    return v


def run(args) -> int:
    from acl.commands._common import check_paths
    from acl.diagnostics import DiagnosticError, Span, error

    fmt = args.output_format
    design = one_design(args.design, fmt)
    if design is None:
        return 2
    diags = check_paths(args.path)
    if args.output is not None and not args.output.strip():     # "" is no path, not the default one
        diags.append(error("E-USAGE", f"--output {args.output!r}: an empty path", Span(file="<--output>", line=1, column=1),
                           "give a path, or leave the option out (the default is next to DESIGN)"))
    elif args.output is not None and args.no_write:
        diags.append(error("E-USAGE", "--output and --no-write contradict each other: --no-write writes nothing",
                           Span(file="<--output>", line=1, column=1), "drop one of them"))
    if args.output == "-":
        diags.append(error("E-USAGE", "--output -: standard output cannot hold the tuned design (it extends DESIGN by a "
                           "relative path)", Span(file="<--output>", line=1, column=1), "give a path, or --no-write"))
    folder_out = bool(args.output and args.output.strip() and args.output != "-"
                      and (args.output.endswith(("/", os.sep)) or os.path.isdir(args.output)))
    if args.output and args.output.strip() and not folder_out and not args.output.endswith(".acl") and args.output != "-":
        diags.append(error("E-USAGE", f"--output {args.output!r}: a design file ends in .acl",
                           Span(file="<--output>", line=1, column=1), "e.g. -o tuned.acl"))
    from acl.sweep.run import scheduler_kind

    try:
        scheduler_kind(args.scheduler)
    except DiagnosticError as exc:
        diags += exc.diagnostics
    if diags:
        report(diags, fmt)
        return 2
    from acl.sweep import tune as T

    out_path = os.path.abspath(args.output) if args.output else T.default_path(design)
    if folder_out:                  # -o FOLDER/: <stem>.tuned.acl in it
        out_path = os.path.join(os.path.abspath(args.output), os.path.basename(T.default_path(design)))
    if not args.no_write:
        folder = os.path.dirname(out_path)
        if not os.path.isdir(folder):
            report([error("E601", f"cannot write the tuned design: no such folder {folder}",
                          Span(file="<--output>", line=1, column=1))], fmt)
            return 2
        if not T.reaches(folder, design, args.path):
            # `extends` reads only the tuned file's folder and below, and --path folders (E210 otherwise)
            report([error("E-USAGE", f"--output {args.output}: the tuned design extends {design}, which a design in "
                          f"{folder} may not read (acl check would refuse it: E210)", Span(file="<--output>", line=1, column=1),
                          f"write it in {os.path.dirname(os.path.abspath(design)) or '.'} or a folder above it (the default "
                          "is beside DESIGN), or pass --path with DESIGN's folder here and to acl check/compile")], fmt)
            return 2
        if os.path.abspath(design) == out_path:
            report([error("E-USAGE", "--output names DESIGN itself; the tuned design extends it",
                          Span(file="<--output>", line=1, column=1), "give another path")], fmt)
            return 2
    import time

    t0 = time.perf_counter()
    try:
        problem = T.prepare(design, tolerance=args.tolerance, samples=args.samples, validate=args.validate,
                            seed=args.seed, search_paths=args.path)
        prepared = time.perf_counter() - t0
        if not args.no_write:      # the tuned design must not replace a file the design reads (a base it extends)
            from acl._files import input_named

            hit = input_named(out_path, getattr(problem.design, "sources", ()))
            if hit:
                report([error("E-USAGE", f"--output names {hit}, which the design reads; the tuned design would "
                              "replace it", Span(file="<--output>", line=1, column=1), "give another path")], fmt)
                return 2
        result = _search(T, problem, args)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        # a problem in an option's text (`<--tolerance>:1:12`) is a usage error, exit 2 as in `acl sweep`
        options = any(d.span is not None and d.span.file.startswith("<--") for d in exc.diagnostics)
        return 2 if options else exit_code(exc.diagnostics)
    if args.verbose:
        for stage, secs in {"prepare": prepared, **result.timing_s}.items():
            sys.stderr.write(f"stage {stage}: {secs:.2f} s\n")
        sys.stderr.write(f"trials: {result.search.evaluations}\n")
    written = None
    missed = args.target is not None and result.after.interval[0] < args.target
    if not args.no_write and not missed:
        text = T.tuned_text(result, out_path, command=_command_line(args))
        try:
            _write_atomic(out_path, text)
        except OSError as exc:
            report([error("E601", f"cannot write the tuned design: {exc.strerror or exc}",
                          Span(file=out_path, line=1, column=1))], fmt)
            return 2
        written = out_path
    if fmt == "json":
        import json

        doc = result.to_json()
        doc["tuned_design"] = written
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
    else:
        _render(result, written, args.quiet)
    if missed:
        lo, hi = result.after.interval
        report([error("E876", f"yield target {args.target:g} not met: the validated yield is {result.after.text()} "
                      f"(95% interval lower end {lo:.4g}); no tuned design written",
                      Span(file="<--target>", line=1, column=1),
                      "widen the free ranges, tighten the tolerances, or give more --samples/--validate (a narrower "
                      "interval)")], "text")
        return 1
    return 0


def _search(T, problem, args):
    from acl._console import make_console

    console = make_console(stderr=True, highlight=False)

    def note(text: str) -> None:
        console.print(f"[yellow]note:[/yellow] {text}")

    if args.quiet or not console.is_terminal:
        return T.tune(problem, objective=args.objective, method=args.method, max_evals=args.max_evals,
                      scheduler=args.scheduler, timeout=args.timeout, notify=note)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("tuning"), BarColumn(), MofNCompleteColumn(), TextColumn("best yield {task.fields[best]}"),
                  TimeElapsedColumn(), console=console, transient=True) as bar:
        task = bar.add_task("tune", total=args.max_evals, best="-")
        return T.tune(problem, objective=args.objective, method=args.method, max_evals=args.max_evals,
                      progress=lambda done, total, best: bar.update(task, completed=done, best=f"{best:.3f}"),
                      scheduler=args.scheduler, timeout=args.timeout, notify=lambda text: bar.console.print(f"note: {text}"))


def _command_line(args) -> str:
    parts = ["acl tune", os.path.basename(args.design)]
    parts += [f"--tolerance '{t}'" for t in args.tolerance]
    if args.objective != "yield":
        parts.append(f"--objective {args.objective}")
    parts += [f"--samples {args.samples}", f"--seed {args.seed}"]
    return " ".join(parts)


def _render(result, written, quiet) -> None:
    from rich.table import Table

    from acl._console import make_console
    from acl.sweep.tune import literal

    console = make_console()
    p = result.problem
    summary = (f"yield before {result.before.text()}, after {result.after.text()} "
               f"({result.objective}, {result.search.evaluations} trials on {p.samples} samples, seed {p.seed})")
    if quiet:                       # -q: the one line, as acl sweep -q
        print(summary)
        return
    t = Table(title="Free parameters")
    for col in ("parameter", "start", "chosen", "range"):
        t.add_column(col)
    for f, s, c in zip(p.free, result.start, result.chosen):
        t.add_row(f.name, literal(s, f.unit), literal(c, f.unit), f"{literal(f.lower, f.unit)} .. {literal(f.upper, f.unit)}")
    console.print(t)
    r = Table(title=f"Yield on {p.validate} fresh samples (95% Clopper-Pearson interval)")
    for col in ("requirement", "line", "before", "after", "worst margin after"):
        r.add_column(col)
    for q in result.per_require:
        worst = q["worst_after"]
        shown = literal(worst, q["unit"], 4) if abs(worst) != float("inf") else "invalid points"
        r.add_row(q["text"], str(q["line"]), q["before"].text(), q["after"].text(), shown)
    r.add_row("all together", "", result.before.text(), result.after.text(), "")
    console.print(r)
    print(summary)
    if written:
        here = os.path.relpath(written)
        shown = here if not here.startswith("..") else written
        make_console(stderr=True, highlight=False).print(f"tuned design written to {shown}")


def _write_atomic(path: str, text: str) -> None:
    """Write ``text`` to ``path`` in one rename (acl.emit.atomic.write_text_atomic)."""
    from acl.emit.atomic import write_text_atomic

    write_text_atomic(path, text)

