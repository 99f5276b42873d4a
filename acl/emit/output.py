"""Writing a schedule to an output directory: atomically, streamed, validated first.

:func:`emit` renders into a temporary directory beside ``out_dir`` and moves the files in only
when everything succeeded; on any error (or KeyboardInterrupt) the temporary directory is
removed and ``out_dir`` is left as it was.  Bad options are diagnostics raised before anything
is written.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from typing import Callable

from acl.diagnostics import DiagnosticError, error
from acl.emit.render import RenderStats, render_chunks, total_samples
from acl.emit.schedule_json import schedule_dict, write_schedule_json, write_segments_csv
from acl.emit.writers import FORMATS, WRITERS
from acl.schedule.model import Schedule


@dataclass
class EmitResult:
    out_dir: str
    files: dict[str, str] = field(default_factory=dict)
    stats: RenderStats = field(default_factory=RenderStats)
    sample_rate_hz: float = 0.0


def check_options(schedule: Schedule, formats, sample_rate: float) -> None:
    """Raise DiagnosticError (E-EMIT-*) for unknown formats or a sample rate below Nyquist."""
    diags = []
    for f in formats:
        if f not in FORMATS:
            diags.append(error("E-EMIT-FORMAT", f"unknown output format {f!r}", None,
                               f"choose from {', '.join(FORMATS)}"))
    fmax = schedule.max_frequency_hz
    if sample_rate <= 0 or sample_rate < 2 * fmax:
        diags.append(error("E-EMIT-RATE", f"sample rate {sample_rate:g} Hz is below twice the highest "
                           f"tone ({fmax:g} Hz)", None,
                           f"use at least {2 * fmax:g} Hz; the default is 10x the highest tone"))
    elif "wav" in formats and int(sample_rate) != sample_rate:
        diags.append(error("E-EMIT-RATE", "a WAV sample rate must be a whole number of Hz", None))
    elif "wav" in formats and 4 * total_samples(schedule, sample_rate) + 64 >= 2 ** 32:
        diags.append(error("E-EMIT-SIZE", f"{schedule.duration_s:g} s at {sample_rate:g} S/s exceeds the "
                           "4 GiB limit of a WAV file", None, "use --format npy, or a lower sample rate"))
    if diags:
        raise DiagnosticError(diags)


def emit(schedule: Schedule, out_dir: str, formats=("wav",), sample_rate: float | None = None,
         plot: bool = False, progress: Callable[[int, int], None] | None = None) -> EmitResult:
    fs = float(sample_rate or schedule.sample_rate_hz)
    formats = tuple(dict.fromkeys(formats))
    check_options(schedule, formats, fs)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise DiagnosticError([error("E-EMIT-OUTPUT", f"output {out_dir!r} exists and is not a directory",
                                     None, "give a directory path with -o")])
    parent = os.path.dirname(os.path.abspath(out_dir)) or "."
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".acl-compile-", dir=parent)
    from acl._files import as_umask

    as_umask(tmp, directory=True)
    result = EmitResult(out_dir=out_dir, sample_rate_hz=fs)
    try:
        n = total_samples(schedule, fs)
        writers = []
        try:
            for f in formats:
                cls, name = WRITERS[f]
                writers.append(cls(os.path.join(tmp, name), n, fs, schedule.full_scale_v))
                result.files[f] = name
            for n0, chunk in render_chunks(schedule, fs, progress=progress):
                result.stats.update(chunk)
                for w in writers:
                    w.write(n0, chunk)
        finally:
            for w in writers:
                w.close()
        write_segments_csv(os.path.join(tmp, "segments.csv"), schedule)
        result.files["segments"] = "segments.csv"
        if plot:
            from acl.emit.plot import plot_goal

            for g in schedule.goals:
                if g.kind == "follow" and g.target_m is not None:
                    name = f"goal-step{g.step + 1}.png"
                    plot_goal(g, os.path.join(tmp, name))
                    result.files[f"plot step {g.step + 1}"] = name
        result.files["schedule"] = "schedule.json"
        write_schedule_json(os.path.join(tmp, "schedule.json"),
                            schedule_dict(schedule, fs, result.stats, dict(result.files)))
        _publish(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return result


def _publish(tmp: str, out_dir: str) -> None:
    """Move the finished files into ``out_dir`` (a rename of the whole directory when it is new)."""
    if not os.path.exists(out_dir):
        os.replace(tmp, out_dir)
        return
    if not os.path.isdir(out_dir):
        raise NotADirectoryError(out_dir)
    for name in os.listdir(tmp):
        os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    os.rmdir(tmp)
