"""`acl fit DESIGN DATA... [--free NAMES] [--model eq3|coupled] [--report DIR]`: fit, find missing effects, report before/after."""
from __future__ import annotations

import os
import sys

from acl.commands._common import add_output_format, exit_code, jobs, one_design, plotting_missing, report, seed


def add_parser(p) -> None:
    p.add_argument("design", metavar="DESIGN", help="design file (.acl), or a folder holding one design")
    p.add_argument("data", nargs="+", metavar="DATA", help="measurement CSV files (docs/data.md)")
    p.add_argument("--free", default="", metavar="NAMES",
                   help="comma-separated names to fit besides the design's `free` params: gamma, alpha, E, gain, "
                        "f0, q, f0:CAPSULE, q:CAPSULE or design parameters (docs/data.md)")
    p.add_argument("--report", metavar="DIR", help="write report.json, fit.png, residuals.png to DIR (and the "
                                                     "calibrated design next to DESIGN, see --calibrated); the "
                                                     "figures need the plotting extra, acl[plot]")
    p.add_argument("--calibrated", metavar="PATH", default=None,
                   help="write the calibrated design (extends DESIGN) to PATH; default with --report: "
                        "DESIGN's folder as <stem>.calibrated.acl (loads without --path)")
    p.add_argument("--effects", default=None, metavar="IDS",
                   help="comma-separated effect ids to consider (default: the whole library; `none` for none)")
    p.add_argument("--model", type=_model, default="coupled", metavar="MODEL",
                   help="force model of a simple pair (two single-orifice capsules on their own supports): coupled "
                        "(default: the force model of acl analyze and acl compile, per-orifice thrust, Bjerknes "
                        "force between the orifices, jet drag) or eq3 (paper Eq. 3, a declared reduced model with "
                        "F_AS = F_d; faster; docs/fit.md)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the cross-validation folds (default 0)")
    p.add_argument("--jobs", type=jobs, default=1, metavar="N",
                   help="worker processes that fit the candidate effects of a round at once (default 1; auto: one "
                        "per core); the result is the same, bit for bit")
    add_output_format(p, old=("--json",))
    p.add_argument("--path", action="append", default=[], metavar="DIR", help="extra folder imports may read from")


def _model(text: str) -> str:
    """argparse type of --model: one of acl.fit.mechanism.MODELS (imported only when --model is given)."""
    import argparse

    from acl.diagnostics import suggest
    from acl.fit.mechanism import MODELS

    if text in MODELS:
        return text
    hint = suggest(text, MODELS)
    raise argparse.ArgumentTypeError(f"{text!r} is not a pair model: {' or '.join(MODELS)}"
                                     + (f" ({hint})" if hint else ""))


def run(args) -> int:
    fmt = args.output_format
    from acl.diagnostics import DiagnosticError, Span, error
    from acl.fit.effects import EFFECTS

    free = [s.strip() for s in args.free.split(",") if s.strip()]
    candidates = None
    if args.effects is not None:
        names = [s.strip() for s in args.effects.split(",") if s.strip() and s.strip() != "none"]
        bad = [n for n in names if n not in EFFECTS]
        if bad:
            report([error("E-USAGE", f"--effects: unknown effect `{bad[0]}`", Span(file="<--effects>", line=1, column=1),
                          f"effects: {', '.join(EFFECTS)}")], fmt)
            return 2
        candidates = names
    if args.report and plotting_missing("--report", fmt, instead=(
            "without figures, --calibrated PATH writes the calibrated design alone (the report: --output-format json)")):
        return 2
    if args.calibrated == "-" or args.report == "-":
        option = "--calibrated" if args.calibrated == "-" else "--report"
        report([error("E-USAGE", f"{option} -: standard output cannot hold it (the calibrated design extends DESIGN by "
                      "a relative path; the report is a folder)", Span(file=f"<{option}>", line=1, column=1),
                      "give a path")], fmt)
        return 2
    for option, value in (("--calibrated", args.calibrated), ("--report", args.report)):
        if value is not None and not value.strip():      # "" is a path that cannot be written, not no option
            report([error("E-USAGE", f"{option} {value!r}: an empty path", Span(file=f"<{option}>", line=1, column=1),
                          "give a path, or leave the option out")], fmt)
            return 2
    if args.report is not None:
        from acl.fit.report import report_dir_problem

        why = report_dir_problem(args.report)
        if why:
            report([error("E601", why, Span(file="<--report>", line=1, column=1),
                          "a report folder is new, empty, or holds a previous report and nothing else "
                          "(acl fit replaces it as a whole)")], fmt)
            return 2
    if args.calibrated is not None and os.path.isdir(args.calibrated):
        report([error("E601", f"--calibrated {args.calibrated}: a folder, not a file",
                      Span(file="<--calibrated>", line=1, column=1), "give a file path, e.g. design.calibrated.acl")], fmt)
        return 2
    design = one_design(args.design, fmt)
    if design is None:
        return 2
    args.design = design
    for path in [args.design, *args.data]:
        if not os.path.isfile(path):
            what = ("no such file" if not os.path.lexists(path) else
                    "not a regular file (a folder)" if os.path.isdir(path) else
                    "not a regular file (a pipe, device or socket)")
            report([error("E601", f"{what}: {path}", Span(file=path, line=1, column=1),
                          "give a CSV file; save a pipe's output to a file first" if os.path.lexists(path) else None)], fmt)
            return 2
    for j, path in enumerate(args.data):          # the same rows twice would halve every variance (optimistic)
        earlier = next((q for q in args.data[:j] if os.path.samefile(q, path)), None)
        if earlier is not None:
            report([error("E-USAGE", f"data file {path} is given twice (also as {earlier}): its rows would count "
                          "twice and every interval shrink by sqrt(2)", Span(file=path, line=1, column=1),
                          "give each data file once")], fmt)
            return 2
    from acl.fit import run_fit

    progress = None
    if args.verbose:
        import time

        start = time.perf_counter()

        def progress(msg):
            sys.stderr.write(f"[{time.perf_counter() - start:7.2f} s] {msg}\n")
    try:
        out = run_fit(args.design, args.data, free=free, search_paths=args.path, candidates=candidates,
                      seed=args.seed, progress=progress, calibrated_path=args.calibrated, report_dir=args.report,
                      model=args.model, jobs=args.jobs)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return exit_code(exc.diagnostics)
    if args.report or args.calibrated:         # nothing is written over an input, nor a folder holding one
        from acl._files import input_named, inputs_inside

        inputs = [*getattr(out.problem.design, "sources", ()), args.design, *args.data]
        hit = input_named(out.calibrated_path, inputs)
        inside = inputs_inside(args.report, inputs) if args.report else []
        if hit or inside:
            option = "--calibrated" if hit else "--report"
            report([error("E-USAGE", f"{option} would write over the input {hit or inside[0]}"
                          + ((" (the calibrated design extends the design)" if hit == args.design else "") if hit
                             else " (it replaces the folder)"),
                          Span(file=f"<{option}>", line=1, column=1),
                          "give another path" if hit else "give a new or empty folder")], fmt)
            return 2
    if not out.problem.coefs and not args.quiet:
        _nothing_free(args, candidates)
    if args.verbose:
        for stage, secs in out.report["timing_s"].items():
            sys.stderr.write(f"stage {stage}: {secs:.2f} s\n")
    report_new = bool(args.report) and not os.path.lexists(args.report)
    if args.report:
        from acl.fit.report import dump_json, figures, write_report_dir

        def write(tmp):
            dump_json(out.report, os.path.join(tmp, "report.json"))
            figures(out.problem, out.selection, tmp)

        try:
            write_report_dir(args.report, write)
        except OSError as exc:
            report([error("E601", f"cannot write the report: {exc.strerror or exc}", Span(file=args.report, line=1, column=1))], fmt)
            return 2
    if args.report or args.calibrated:
        try:
            _write_atomic(out.calibrated_path, out.calibrated)
        except OSError as exc:
            if report_new:             # no partial output: the report this run wrote goes too
                import shutil

                shutil.rmtree(args.report, ignore_errors=True)
            report([error("E601", f"cannot write the calibrated design: {exc.strerror or exc}",
                          Span(file=out.calibrated_path, line=1, column=1))], fmt)
            return 2
    if args.output_format == "json":
        import json

        sys.stdout.write(json.dumps(out.report, indent=2) + "\n")
    else:
        from acl.fit.report import render_table

        render_table(out.report)
        if args.report and not args.quiet:
            from acl._console import make_console

            make_console(stderr=True, highlight=False).print(f"report written to {os.path.normpath(args.report)}/")
        if (args.report or args.calibrated) and not args.quiet:
            from acl._console import make_console

            # paths as the user wrote them (as diagnostics show them); report.json keeps absolute ones
            shown = os.path.normpath(args.calibrated if args.calibrated else
                                     os.path.join(os.path.dirname(args.design), os.path.basename(out.calibrated_path)))
            extra = out.report.get("calibrated_needs_path")
            how = f" (load it with --path {os.path.dirname(os.path.normpath(args.design)) or '.'})" if extra else ""
            make_console(stderr=True, highlight=False).print(f"calibrated design written to {shown}{how}")
    return 0


def _nothing_free(args, candidates) -> None:
    """W810 on stderr: no coefficient was free, so the base model was compared with the data, not fitted."""
    from acl.diagnostics import Span, render, warning

    searched = "" if candidates == [] else "; only the effect library was searched on top of the declared model"
    render([warning("W810", f"nothing is free: no --free names and no `free` parameters in the design{searched}",
                    Span(file=args.design, line=1, column=1),
                    "free the coefficients the data should determine, e.g. --free gamma (docs/data.md)")])


def _write_atomic(path: str, text: str) -> None:
    """Write ``text`` to ``path`` in one rename (acl.emit.atomic.write_text_atomic)."""
    from acl.emit.atomic import write_text_atomic

    os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
    write_text_atomic(path, text)
