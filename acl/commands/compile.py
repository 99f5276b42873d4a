"""`acl compile FILE -o OUT/`: a program -> schedule.json, waveform files, segment table (and plots).

Thin: parse options, call :func:`acl.schedule.compile.compile_program` and
:func:`acl.emit.output.emit`, render diagnostics and a summary.  Exit codes: 0 written; 1 the design
or a goal is infeasible / has errors; 2 bad options or input files.  OUT is only touched on success.
"""
from __future__ import annotations

import re
import sys

from acl.commands._common import add_design_options, load_or_report, report
from acl.diagnostics import DiagnosticError, Span, error, suggest

_RATE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(hz|khz|mhz|k|m|ms/s|ks/s)?\s*$", re.I)
_RATE_UNITS = {None: 1.0, "hz": 1.0, "khz": 1e3, "k": 1e3, "ks/s": 1e3, "mhz": 1e6, "m": 1e6, "ms/s": 1e6}


def add_parser(p) -> None:
    p.add_argument("file", metavar="FILE", help="design file (.acl)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output directory")
    p.add_argument("--program", metavar="NAME", help="program to compile (default: the only one)")
    p.add_argument("--format", action="append", default=[], metavar="FMT",
                   help="waveform formats, comma separated: wav, csv, npy (default wav)")
    p.add_argument("--sample-rate", metavar="HZ",
                   help="samples per second, e.g. 2e6 or 2MHz (default: >= 10x the highest tone)")
    p.add_argument("--calibration", metavar="CSV",
                   help="measured frequency sweep (frequency, dx, dy) used instead of the model gains")
    p.add_argument("--waypoint-dt", type=float, default=0.01, metavar="S",
                   help="time between path waypoints in seconds (default 0.01)")
    p.add_argument("--tolerance", type=float, default=0.5, metavar="UM",
                   help="path tracking tolerance in micrometres (default 0.5)")
    p.add_argument("--ramp", type=float, default=1e-3, metavar="S",
                   help="raised-cosine crossfade between segments in seconds (default 0.001)")
    p.add_argument("--robust", action="store_true",
                   help="plan paths for the least expected error over the declared uncertainty (docs/schedule.md)")
    p.add_argument("--band-samples", type=int, default=20, metavar="N",
                   help="draws of the declared uncertainty for each goal's 95 %% error band (default 20; 0: none)")
    p.add_argument("--band-seed", type=int, default=0, metavar="N", help="seed of those draws (default 0)")
    p.add_argument("--nonlinear-passes", type=int, default=0, metavar="N",
                   help="re-plan paths N times against the design's nonlinear model (saturation, stiffening, "
                        "declared effects); default 0")
    p.add_argument("--plot", action="store_true", help="write a PNG per path goal")
    p.add_argument("--diagnostics", choices=["text", "json"], default="text",
                   help="diagnostics as text (default) or JSON on stdout")
    add_design_options(p)


def _usage(code: str, message: str, hint: str | None = None):
    return error(code, message, Span(file="<command line>", line=1, column=1), hint)


def _formats(items: list[str]):
    from acl.emit.writers import FORMATS

    out, diags = [], []
    for item in items or ["wav"]:
        for f in (x.strip().lower() for x in item.split(",")):
            if not f:
                continue
            if f not in FORMATS:
                diags.append(_usage("E-COMPILE-FORMAT", f"unknown waveform format {f!r}",
                                    suggest(f, FORMATS) or f"choose from {', '.join(FORMATS)}"))
            elif f not in out:
                out.append(f)
    return out, diags


def _rate(text: str | None):
    if text is None:
        return None, []
    m = _RATE.match(text)
    if not m:
        return None, [_usage("E-COMPILE-RATE", f"cannot read sample rate {text!r}", "e.g. 2e6 or 2MHz")]
    value = float(m.group(1)) * _RATE_UNITS[m.group(2).lower() if m.group(2) else None]
    if value <= 0:
        return None, [_usage("E-COMPILE-RATE", "the sample rate must be positive")]
    return value, []


def run(args) -> int:
    fmt = args.diagnostics
    formats, diags = _formats(args.format)
    rate, more = _rate(args.sample_rate)
    diags += more
    for name, val in (("--waypoint-dt", args.waypoint_dt), ("--tolerance", args.tolerance)):
        if not val > 0:
            diags.append(_usage("E-COMPILE-OPTION", f"{name} must be positive"))
    if not args.ramp >= 0:
        diags.append(_usage("E-COMPILE-OPTION", "--ramp must not be negative"))
    if args.band_samples < 0:
        diags.append(_usage("E-COMPILE-OPTION", "--band-samples must not be negative"))
    if args.nonlinear_passes < 0:
        diags.append(_usage("E-COMPILE-OPTION", "--nonlinear-passes must not be negative"))
    if diags:
        report(diags, fmt)
        return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    names = [p.name for p in design.programs]
    if args.program is None and len(names) != 1:
        report([_usage("E-COMPILE-PROGRAM", f"the design has {len(names)} programs; choose one with --program",
                       "programs: " + (", ".join(names) or "none"))], fmt)
        return 2
    program = args.program or names[0]
    if program not in names:
        report([_usage("E-COMPILE-PROGRAM", f"no program named {program!r}",
                       suggest(program, names) or ("programs: " + (", ".join(names) or "none")))], fmt)
        return 2

    from acl.schedule.compile import CompileOptions, compile_program

    calibration = None
    try:
        if args.calibration:
            from acl.schedule.calibration import read_sweep_csv

            calibration = read_sweep_csv(args.calibration)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    opts = CompileOptions(sample_rate_hz=rate, waypoint_dt_s=args.waypoint_dt,
                          tolerance_m=args.tolerance * 1e-6, ramp_s=args.ramp, calibration=calibration,
                          robust=args.robust, band_samples=args.band_samples, band_seed=args.band_seed,
                          nonlinear_passes=args.nonlinear_passes,
                          reload=_reloader(args))
    try:
        schedule = compile_program(design, program, opts)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 1
    return _emit(schedule, args, formats, rate, fmt)


def _reloader(args):
    """{param: "v unit"} -> the design resolved again with those values (for the uncertainty draws)."""
    from acl.commands._common import parse_sets

    sets, _ = parse_sets(getattr(args, "set", []) or [])
    paths = getattr(args, "path", []) or []

    def reload(overrides):
        import acl

        return acl.load(args.file, overrides={**sets, **overrides}, search_paths=paths)

    return reload


def _emit(schedule, args, formats, rate, fmt) -> int:
    from acl.emit.output import check_options, emit
    from acl.emit.render import total_samples

    fs = rate or schedule.sample_rate_hz
    try:
        check_options(schedule, formats, fs)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    from rich.console import Console

    console = Console(stderr=True, highlight=False)
    n = total_samples(schedule, fs)
    try:
        if n > 4_000_000 and console.is_terminal:
            from rich.progress import BarColumn, Progress, TimeRemainingColumn

            with Progress("rendering", BarColumn(), "{task.percentage:>3.0f}%", TimeRemainingColumn(),
                          console=console, transient=True) as bar:
                task = bar.add_task("render", total=n)
                result = emit(schedule, args.output, formats, fs, args.plot,
                              progress=lambda done, total: bar.update(task, completed=done))
        else:
            result = emit(schedule, args.output, formats, fs, args.plot)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    except OSError as exc:
        report([_usage("E-COMPILE-IO", f"cannot write {args.output!r}: {exc.strerror or exc}",
                       "check the path and free space; nothing was written")], fmt)
        return 2
    if fmt == "json":
        import json

        sys.stdout.write(json.dumps({"diagnostics": [], "output": args.output,
                                     "files": result.files}, indent=2) + "\n")
    else:
        _summary(console, schedule, result)
    return 0


def _summary(console, schedule, result) -> None:
    from rich.table import Table

    table = Table(title=f"acl compile: program `{schedule.program}` -> {result.out_dir}", title_justify="left")
    for col in ("goal", "time (s)", "tones (kHz)", "predicted error RMS / max (um)",
                "95 % band RMS / max (um)", "model"):
        table.add_column(col)
    for g in schedule.goals:
        err = ("-" if g.rms_error_m is None else f"{g.rms_error_m * 1e6:.3g} / {g.max_error_m * 1e6:.3g}")
        band = ("-" if g.rms_error_p95_m is None else f"{g.rms_error_p95_m * 1e6:.3g} / {g.max_error_p95_m * 1e6:.3g}")
        table.add_row(g.name, f"{g.start_s:.3g}-{g.end_s:.3g}",
                      ", ".join(f"{f / 1e3:g}" for f in g.frequencies_hz), err, band, g.model or "-")
    console.print(table)
    for note in schedule.notes:
        console.print(note if note.startswith("warning:") else f"note: {note}")
    s = result.stats
    tones = ", ".join(f"{f / 1e3:g}" for f in schedule.frequencies_hz())
    console.print(f"duration {schedule.duration_s:.4g} s, {len(schedule.segments)} segments, tones {tones} kHz; "
                  f"peak {s.peak_v:.4g} V (limit {schedule.max_voltage_v:g} V), RMS {s.rms_v:.4g} V; "
                  f"{result.sample_rate_hz:g} S/s; files: {', '.join(result.files.values())}")
