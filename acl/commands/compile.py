"""`acl compile FILE -o OUT/`: a program -> schedule.json, waveform files, segment table (and plots).

Thin: parse options, call :func:`acl.schedule.compile.compile_program` and
:func:`acl.emit.output.emit`, render diagnostics and a summary.  Exit codes: 0 written; 1 the design
or a goal is infeasible / has errors; 2 bad options or input files.  OUT is only touched on success.
"""
from __future__ import annotations

import math
import re
import sys

from acl.commands._common import (add_design_options, add_output_format, load_or_report,
                                  plotting_missing, report, seed)
from acl.diagnostics import DiagnosticError, Span, error, suggest

_RATE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(hz|khz|mhz|k|m|ms/s|ks/s)?\s*$", re.I)
_RATE_UNITS = {None: 1.0, "hz": 1.0, "khz": 1e3, "k": 1e3, "ks/s": 1e3, "mhz": 1e6, "m": 1e6, "ms/s": 1e6}


def add_parser(p) -> None:
    p.add_argument("file", metavar="FILE", help="design file (.acl), or a folder holding one design")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output directory: new, empty, or holding a previous compile (replaced)")
    p.add_argument("--program", metavar="NAME", help="program to compile (default: the only one)")
    p.add_argument("--format", action="append", default=[], metavar="FMT",
                   help="waveform formats, comma separated: wav, npy, csv (raw samples, "
                        "waveform-samples.csv; large), seq (sequence.seq: one looped segment per "
                        "constant drive, docs/bench.md) (default wav)")
    p.add_argument("--sample-rate", metavar="HZ",
                   help="samples per second, e.g. 2e6 or 2MHz (default: >= 10x the highest tone)")
    p.add_argument("--full-scale", metavar="V",
                   help="voltage of WAV sample +-1.0, e.g. 10V (default: the transducer's max voltage)")
    p.add_argument("--calibration", metavar="CSV",
                   help="measured frequency sweep (frequency, dx, dy) used instead of the model gains")
    p.add_argument("--waypoint-dt", default="0.01", metavar="S",
                   help="time between path waypoints in seconds (default 0.01)")
    p.add_argument("--tolerance", default="0.5", metavar="UM",
                   help="path tracking tolerance in micrometres (default 0.5)")
    p.add_argument("--ramp", default="1e-3", metavar="S",
                   help="raised-cosine crossfade between segments in seconds (default 0.001)")
    p.add_argument("--robust", nargs="?", const="mean", default=None, choices=("mean", "worst"),
                   help="plan paths with the declared uncertainty: `mean` (default) the least expected squared "
                        "error, `worst` the least worst case over its 1-sigma ellipsoid (docs/schedule.md)")
    p.add_argument("--band-samples", type=int, default=20, metavar="N",
                   help="draws of the declared uncertainty for each goal's 95 %% error band (default 20; 0: none)")
    p.add_argument("--band-seed", type=seed, default=0, metavar="N", help="seed of those draws (default 0)")
    p.add_argument("--reading-noise", default="0.1um", metavar="SIGMA",
                   help="noise of one bench reading the band's cure proposes (a length per axis, e.g. 0.5um; "
                        "default 0.1um): it sets the band expected after those readings")
    p.add_argument("--nonlinear-passes", type=int, default=0, metavar="N",
                   help="re-plan paths N times against the design's nonlinear model (saturation, stiffening, "
                        "declared effects); default 0")
    p.add_argument("--plot", action="store_true", help="write a PNG per path goal")
    p.add_argument("--max-output-size", default="4GiB", metavar="SIZE",
                   help="refuse waveform files larger than this, e.g. 500MB, 20GiB (default 4GiB); the free "
                        "disk space is checked too")
    p.add_argument("--allow-nonlinear", action="store_true",
                   help="plan drives past the hemisphere, where the bubble model has no meaning (interface amplitude "
                        "eps/R > 1; between 0.25 and 1 compile warns and widens its bands; docs/physics.md)")
    add_output_format(p, old=("--diagnostics",))
    add_design_options(p)


def _usage(code: str, message: str, hint: str | None = None, option: str = "command line"):
    return error(code, message, Span(file=f"<{option}>", line=1, column=1), hint)


def _formats(items: list[str]):
    from acl.emit.writers import FORMATS

    out, diags = [], []
    for item in items or ["wav"]:
        for f in (x.strip().lower() for x in item.split(",")):
            if not f:
                continue
            if f not in FORMATS:
                diags.append(_usage("E-COMPILE-FORMAT", f"unknown waveform format {f!r}",
                                    suggest(f, FORMATS) or f"choose from {', '.join(FORMATS)}", "--format"))
            elif f not in out:
                out.append(f)
    if not out and not diags:
        diags.append(_usage("E-COMPILE-FORMAT", f"--format {','.join(items)!r} names no waveform format",
                            f"choose from {', '.join(FORMATS)}", "--format"))
    return out, diags


MAX_SAMPLE_RATE = 1e9


def _rate(text: str | None):
    if text is None:
        return None, []
    m = _RATE.match(text)
    if not m:
        return None, [_usage("E-COMPILE-RATE", f"cannot read sample rate {text!r}", "e.g. 2e6 or 2MHz",
                             "--sample-rate")]
    value = float(m.group(1)) * _RATE_UNITS[m.group(2).lower() if m.group(2) else None]
    if not (math.isfinite(value) and 0 < value <= MAX_SAMPLE_RATE):
        return None, [_usage("E-COMPILE-RATE", f"the sample rate {text!r} must be positive and at most "
                             f"{MAX_SAMPLE_RATE:g} S/s", "e.g. 2e6 or 2MHz", "--sample-rate")]
    return value, []


_VOLTS = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(mv|v|kv)?\s*$", re.I)


def _full_scale(text: str | None):
    if text is None:
        return None, []
    m = _VOLTS.match(text)
    value = float(m.group(1)) * {"mv": 1e-3, "v": 1.0, "kv": 1e3}[(m.group(2) or "v").lower()] if m else None
    if value is None or not (math.isfinite(value) and 1e-3 <= value <= 1e4):
        return None, [_usage("E-COMPILE-OPTION", f"cannot use full scale {text!r}: a voltage from 1 mV "
                             "to 10 kV", "e.g. --full-scale 10V", "--full-scale")]
    return value, []


# (option, attribute, smallest allowed value, largest allowed value, unit)
_NUMBERS = (("--waypoint-dt", "waypoint_dt", 1e-6, 10.0, "s"),
            ("--tolerance", "tolerance", 1e-6, 1e3, "um"),
            ("--ramp", "ramp", 0.0, 10.0, "s"))


def _numbers(args):
    out, diags = {}, []
    for option, attr, lo, hi, unit in _NUMBERS:
        text = str(getattr(args, attr))
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (math.isfinite(value) and lo <= value <= hi) or (lo == 0.0 and value < 0):
            diags.append(_usage("E-COMPILE-OPTION", f"{option} {text!r} must be a number from {lo:g} "
                                f"to {hi:g} {unit}", None, option))
        out[attr] = value
    return out, diags


def _reading_noise(text: str):
    """``--reading-noise`` in metres: a positive, finite length."""
    from acl.commands._common import quantity_text
    from acl.fit.data import parse_quantity
    from acl.units import DIMENSIONLESS, UnitError, describe, parse_unit_static

    bad = [_usage("E-COMPILE-OPTION", f"--reading-noise {text!r} must be a positive length",
                  "e.g. --reading-noise 0.1um", "--reading-noise")]
    try:
        value, dims = parse_quantity(quantity_text(str(text)))
    except (ValueError, UnitError):
        return None, bad
    if dims != parse_unit_static("m"):
        got = "a plain number" if dims == DIMENSIONLESS else f"a {describe(dims)}"
        return None, [_usage("E-COMPILE-OPTION", f"--reading-noise {text!r} is {got}, not a length",
                             "e.g. --reading-noise 0.1um", "--reading-noise")]
    if not (math.isfinite(value) and value > 0):
        return None, bad
    return value, []


def run(args) -> int:
    fmt = args.output_format
    formats, diags = _formats(args.format)
    rate, more = _rate(args.sample_rate)
    diags += more
    full_scale, more = _full_scale(args.full_scale)
    diags += more
    numbers, more = _numbers(args)
    diags += more
    reading_noise, more = _reading_noise(args.reading_noise)
    diags += more
    try:
        _size(args.max_output_size)
    except DiagnosticError as exc:
        diags += exc.diagnostics
    if args.output == "-":   # it made a folder named `-`
        diags.append(_usage("E-EMIT-OUTPUT", "-o -: standard output cannot hold a compile (schedule.json and "
                            "waveform files)", "give a folder, e.g. -o out/", "--output"))
    for option, value, hi in (("--band-samples", args.band_samples, 10_000),
                              ("--nonlinear-passes", args.nonlinear_passes, 100)):
        if not 0 <= value <= hi:
            diags.append(_usage("E-COMPILE-OPTION", f"{option} {value} must be a whole number from 0 to {hi}",
                                None, option))
    if diags:
        report(diags, fmt)
        return 2
    if args.plot and plotting_missing("--plot", fmt):
        return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    names = [p.name for p in design.programs]
    if not names:                  # "the design has 0 programs; choose one with --program" sent the user nowhere
        from acl.diagnostics import Span, error

        report([error("E-COMPILE-PROGRAM", f"{design.file} declares no program: nothing to compile",
                      Span(file=design.file, line=1, column=1),
                      "add one, e.g. `program ramp { drive 125 kHz @ 2 V for 500 ms }`")], fmt)
        return 1
    if args.program is None and len(names) != 1:
        report([_usage("E-COMPILE-PROGRAM", f"the design has {len(names)} programs; choose one with --program",
                       "programs: " + (", ".join(names) or "none"), "--program")], fmt)
        return 2
    program = args.program if args.program is not None else names[0]     # `--program ""` names no program
    if program not in names:
        report([_usage("E-COMPILE-PROGRAM", f"no program named {program!r}",
                       suggest(program, names) or ("programs: " + (", ".join(names) or "none")),
                       "--program")], fmt)
        return 2

    from acl.schedule.compile import CompileOptions, compile_program

    calibration = None
    try:
        if args.calibration is not None:      # `--calibration ""` is a path that cannot be read, not no option
            from acl.schedule.calibration import read_sweep_csv

            t = design.transducer
            calibration = read_sweep_csv(args.calibration, t.band if t is not None else None, t.name if t else "")
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    opts = CompileOptions(sample_rate_hz=rate, waypoint_dt_s=numbers["waypoint_dt"],
                          tolerance_m=numbers["tolerance"] * 1e-6, ramp_s=numbers["ramp"],
                          calibration=calibration, full_scale_v=full_scale,
                          robust=args.robust is not None, robust_mode=args.robust or "mean",
                          band_samples=args.band_samples, band_seed=args.band_seed,
                          nonlinear_passes=args.nonlinear_passes, reload=_reloader(args, design.file),
                          allow_nonlinear=bool(getattr(args, "allow_nonlinear", False)),
                          reading_noise_m=reading_noise)
    try:
        schedule = compile_program(design, program, opts)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 1
    return _emit(schedule, args, formats, rate, fmt)


_SIZE_UNITS = {"": 1, "b": 1, "kb": 1e3, "mb": 1e6, "gb": 1e9, "tb": 1e12,
               "kib": 2 ** 10, "mib": 2 ** 20, "gib": 2 ** 30, "tib": 2 ** 40}


def _size(text: str) -> float:
    """Bytes of ``--max-output-size`` (``500MB``, ``20GiB``, ``1e9``); E-USAGE otherwise."""
    import math
    import re

    m = re.fullmatch(r"\s*([0-9][0-9_.]*(?:[eE][+-]?[0-9]+)?)\s*([A-Za-z]*)\s*", str(text))
    value = None
    if m and m.group(2).lower() in _SIZE_UNITS:
        try:
            value = float(m.group(1)) * _SIZE_UNITS[m.group(2).lower()]
        except ValueError:
            value = None
    if value is None or not math.isfinite(value) or value <= 0:
        raise DiagnosticError([_usage("E-USAGE", f"--max-output-size {text!r}: not a size",
                                      "e.g. 500MB, 4GiB or 1e9 (bytes)", "--max-output-size")])
    return value


def _reloader(args, path):
    """{param: "v unit"} -> the design resolved again with those values (for the uncertainty draws)."""
    from acl.commands._common import parse_sets

    sets, _ = parse_sets(getattr(args, "set", []) or [])
    paths = getattr(args, "path", []) or []

    def reload(overrides):
        import acl

        return acl.load(path, overrides={**sets, **overrides}, search_paths=paths)

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
    from acl.emit.output import check_output_dir, check_size

    try:
        max_bytes = _size(args.max_output_size)
        check_output_dir(args.output)
        check_size(schedule, formats, fs, args.output, max_bytes)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    from acl._console import make_console

    console = make_console(stderr=True, highlight=False)
    n = total_samples(schedule, fs)
    try:
        if n > 4_000_000 and console.is_terminal and not args.quiet:
            from rich.progress import BarColumn, Progress, TimeRemainingColumn

            with Progress("rendering", BarColumn(), "{task.percentage:>3.0f}%", TimeRemainingColumn(),
                          console=console, transient=True) as bar:
                task = bar.add_task("render", total=n)
                result = emit(schedule, args.output, formats, fs, args.plot,
                              progress=lambda done, total: bar.update(task, completed=done), max_bytes=max_bytes)
        else:
            result = emit(schedule, args.output, formats, fs, args.plot, max_bytes=max_bytes)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    except OSError as exc:
        report([_usage("E-COMPILE-IO", f"cannot write {args.output!r}: {exc.strerror or exc}",
                       "check the path and free space; nothing was written", "--output")], fmt)
        return 2
    warnings = list(result.warnings) + list(schedule.warnings)     # the schedule's: located at their goal
    if fmt == "json":
        import json

        sys.stdout.write(json.dumps({"diagnostics": [d.as_dict() for d in warnings],
                                     "output": args.output, "files": result.files,
                                     "removed": result.removed}, indent=2) + "\n")
    else:
        if warnings:
            report(warnings, fmt)
        if not args.quiet:
            _summary(console, schedule, result)
    return 0


def _summary(console, schedule, result) -> None:
    from acl._console import table as Table

    table = Table(title=f"acl compile: program `{schedule.program}` -> {result.out_dir}", title_justify="left")
    for col in ("goal", "time (s)", "tones (kHz)", "predicted error RMS / max (um)",
                "95 % band RMS / max (um)", "model"):
        table.add_column(col)
    for g in schedule.goals:
        err = ("-" if g.rms_error_m is None else f"{g.rms_error_m * 1e6:.3g} / {g.max_error_m * 1e6:.3g}")
        band = ("-" if g.rms_error_p95_m is None else f"{g.rms_error_p95_m * 1e6:.3g} / {g.max_error_p95_m * 1e6:.3g}")
        mb = (g.details or {}).get("band") or {}
        if g.rms_error_p95_m is None and "margin_p05" in mb:       # a hold or switch: its margin's 5th percentile
            band = f"margin p05 {mb['margin_p05']:.3g}"
        table.add_row(g.name, f"{g.start_s:.3g}-{g.end_s:.3g}",
                      ", ".join(f"{f / 1e3:g}" for f in g.frequencies_hz), err, band, g.model or "-")
    console.print(table)
    located = {f"warning: {w.message}" for w in schedule.warnings}     # reported above with their location
    for note in schedule.notes:
        if note not in located:
            console.print(note if note.startswith("warning:") else f"note: {note}")
    s = result.stats
    tones = ", ".join(f"{f / 1e3:g}" for f in schedule.frequencies_hz())
    analog = max((g.peak_v or 0.0 for g in schedule.segments), default=0.0)
    console.print(f"duration {schedule.duration_s:.4g} s, {len(schedule.segments)} segments, tones {tones} kHz; "
                  f"peak {analog:.4g} V analog ({s.peak_v:.4g} V sampled; limit {schedule.max_voltage_v:g} V), "
                  f"RMS {s.rms_v:.4g} V; {result.sample_rate_hz:g} S/s; "
                  f"WAV full scale {schedule.full_scale_v:g} V ({schedule.full_scale_source}); "
                  f"files: {', '.join(result.files.values())}"
                  + (f"; replaced the previous compile's {', '.join(result.removed)}" if result.removed else ""))
