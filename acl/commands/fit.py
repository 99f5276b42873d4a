"""`acl fit DESIGN DATA... [--free NAMES] [--report DIR]`: fit, find missing effects, report before/after."""
from __future__ import annotations

import os
import sys

from acl.commands._common import exit_code, report


def add_parser(p) -> None:
    p.add_argument("design", metavar="DESIGN", help="design file (.acl)")
    p.add_argument("data", nargs="+", metavar="DATA", help="measurement CSV files (docs/data.md)")
    p.add_argument("--free", default="", metavar="NAMES",
                   help="comma-separated names to fit besides the design's `free` params: gamma, alpha, E, gain, "
                        "f0, q, f0:CAPSULE, q:CAPSULE or design parameters (docs/data.md)")
    p.add_argument("--report", metavar="DIR", help="write report.json, fit.png, residuals.png to DIR (and the "
                                                     "calibrated design next to DESIGN, see --calibrated)")
    p.add_argument("--calibrated", metavar="PATH", default=None,
                   help="write the calibrated design (extends DESIGN) to PATH; default with --report: "
                        "DESIGN's folder as <stem>.calibrated.acl (loads without --path)")
    p.add_argument("--effects", default=None, metavar="IDS",
                   help="comma-separated effect ids to consider (default: the whole library; `none` for none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the cross-validation folds (default 0)")
    p.add_argument("--json", action="store_true", help="print report.json to stdout instead of the tables")
    p.add_argument("--verbose", action="store_true", help="print each stage and effect trial with its time (stderr)")
    p.add_argument("--path", action="append", default=[], metavar="DIR", help="extra folder imports may read from")


def run(args) -> int:
    from acl.diagnostics import DiagnosticError, Span, error
    from acl.fit.effects import EFFECTS

    free = [s.strip() for s in args.free.split(",") if s.strip()]
    candidates = None
    if args.effects is not None:
        names = [s.strip() for s in args.effects.split(",") if s.strip() and s.strip() != "none"]
        bad = [n for n in names if n not in EFFECTS]
        if bad:
            report([error("E-USAGE", f"--effects: unknown effect `{bad[0]}`", Span(file="<--effects>", line=1, column=1),
                          f"effects: {', '.join(EFFECTS)}")])
            return 2
        candidates = names
    for path in [args.design, *args.data]:
        if not os.path.isfile(path):
            report([error("E601", f"no such file: {path}", Span(file=path, line=1, column=1))])
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
                      seed=args.seed, progress=progress, calibrated_path=args.calibrated, report_dir=args.report)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return exit_code(exc.diagnostics)
    if args.verbose:
        for stage, secs in out.report["timing_s"].items():
            sys.stderr.write(f"stage {stage}: {secs:.2f} s\n")
    if args.report:
        from acl.fit.report import dump_json, figures, write_report_dir

        def write(tmp):
            dump_json(out.report, os.path.join(tmp, "report.json"))
            figures(out.problem, out.selection, tmp)

        try:
            write_report_dir(args.report, write)
        except OSError as exc:
            report([error("E601", f"cannot write the report: {exc.strerror or exc}", Span(file=args.report, line=1, column=1))])
            return 2
    if args.report or args.calibrated:
        try:
            _write_atomic(out.calibrated_path, out.calibrated)
        except OSError as exc:
            report([error("E601", f"cannot write the calibrated design: {exc.strerror or exc}",
                          Span(file=out.calibrated_path, line=1, column=1))])
            return 2
    if args.json:
        import json

        sys.stdout.write(json.dumps(out.report, indent=2) + "\n")
    else:
        from acl.fit.report import render_table

        render_table(out.report)
        if args.report:
            from rich.console import Console

            Console(stderr=True, highlight=False).print(f"report written to {args.report}/")
        if args.report or args.calibrated:
            from rich.console import Console

            extra = out.report.get("calibrated_needs_path")
            how = f" (load it with --path {extra})" if extra else ""
            Console(stderr=True, highlight=False).print(f"calibrated design written to {out.calibrated_path}{how}")
    return 0


def _write_atomic(path: str, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file in the same folder and os.replace."""
    import tempfile

    folder = os.path.dirname(os.path.abspath(path)) or "."
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".acl-calibrated-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
