"""`acl track VIDEO -o CSV --scale UM_PER_PX [--roi X,Y,W,H] [--name NAME] [--fps F]`.

Thin: parse the options, call :func:`acl.bench.track.track_video`, write the data format `acl fit`
reads (docs/data.md) atomically.  Exit codes: 0 written; 2 bad options or an unreadable video
(nothing written).  docs/bench.md.
"""
from __future__ import annotations

import math
import os
import re
import sys

from acl.commands._common import report
from acl.diagnostics import DiagnosticError, Span, error

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def add_parser(p) -> None:
    p.add_argument("video", metavar="VIDEO", help="AVI or MP4 video (through ffmpeg), or a multi-page TIFF stack")
    p.add_argument("-o", "--output", required=True, metavar="CSV", help="output CSV (docs/data.md format)")
    p.add_argument("--scale", required=True, metavar="UM_PER_PX", help="pixel size in micrometres, e.g. 0.65")
    p.add_argument("--roi", metavar="X,Y,W,H", help="the template: a region of the first frame in pixels "
                                                    "(default: the whole first frame)")
    p.add_argument("--name", default="capsule", metavar="NAME",
                   help="observable prefix: rows NAME_x and NAME_y (default capsule)")
    p.add_argument("--fps", metavar="F", help="frames per second, for a TIFF stack that records none")
    p.add_argument("--schedule", metavar="JSON", help="the schedule.json the video recorded: fills each row's "
                                                      "`drive` with the drive playing at that frame")
    p.add_argument("--sync", default="0", metavar="S",
                   help="with --schedule: the video time (s) at which the schedule starts (default 0)")


def _usage(code, option, message, hint=None):
    return error(code, message, Span(file=f"<{option}>", line=1, column=1), hint)


def _positive(text, option, code):
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = float("nan")
    if not (math.isfinite(value) and value > 0 and value < 1e9):
        return None, [_usage(code, option, f"{option} {text!r} must be a positive number")]
    return value, []


def _roi(text):
    if text is None:
        return None, []
    parts = text.split(",")
    try:
        vals = [int(p.strip()) for p in parts]
    except ValueError:
        vals = []
    if len(vals) != 4 or any(v < 0 for v in vals):
        return None, [_usage("E-TRACK-ROI", "--roi", f"--roi {text!r} must be four whole numbers X,Y,W,H >= 0",
                             "e.g. --roi 200,180,64,64")]
    return tuple(vals), []


def _output_ok(path):
    if not path or path == "-" or os.path.isdir(path):
        return [_usage("E-TRACK-OUTPUT", "--output", f"-o {path!r}: give a file path for the CSV")]
    if os.path.lexists(path) and not os.path.isfile(path):
        return [_usage("E-TRACK-OUTPUT", "--output", f"-o {path!r} exists and is not a regular file (a pipe or "
                       "a device): acl writes a CSV only by replacing a regular file")]
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        return [_usage("E-TRACK-OUTPUT", "--output", f"-o {path!r}: no folder {folder!r}")]
    return []


def run(args) -> int:
    diags = []
    scale, more = _positive(args.scale, "--scale", "E-TRACK-SCALE")
    diags += more
    fps = None
    if args.fps is not None:
        fps, more = _positive(args.fps, "--fps", "E-TRACK-FPS")
        diags += more
    roi, more = _roi(args.roi)
    diags += more
    if not _NAME.match(args.name or ""):
        diags.append(_usage("E-USAGE", "--name", f"--name {args.name!r} must be a name (letters, digits, _)"))
    diags += _output_ok(args.output)
    try:
        sync = float(args.sync)
    except ValueError:
        sync = float("nan")
    if not (math.isfinite(sync) and abs(sync) < 1e9):
        diags.append(_usage("E-USAGE", "--sync", f"--sync {args.sync!r} must be a number of seconds"))
    if os.path.abspath(args.output) == os.path.abspath(args.video):
        diags.append(_usage("E-TRACK-OUTPUT", "--output", f"-o {args.output!r} names the video"))
    if diags:
        report(diags)
        return 2
    from acl.bench.track import csv_text, drive_cells, track_video
    from acl.emit.atomic import write_text_atomic

    try:
        drives = None
        if args.schedule is not None:
            from acl.bench.schedule import load

            drives, _ = load(args.schedule)
        track = track_video(args.video, roi, fps)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    cells = drive_cells(track.time, drives, sync) if drives is not None else None
    text = csv_text(track, args.name, scale, os.path.basename(args.video), cells)
    try:
        write_text_atomic(args.output, text)
    except OSError as exc:
        report([_usage("E-TRACK-OUTPUT", "--output", f"cannot write {args.output!r}: {exc.strerror or exc}")])
        return 2
    if not args.quiet:
        sys.stderr.write(f"acl track: {len(track.time)} frames at {track.fps:g} frames/s -> {args.output}; "
                         f"median sigma {float(__import__('numpy').median(track.sigma_x)):.3g} px"
                         + (f"; {track.lost} frames did not converge" if track.lost else "") + "\n")
    return 0
