"""Writing a schedule to an output directory: atomically, streamed, validated first.

:func:`emit` renders into a temporary directory beside ``out_dir`` and moves the files in only
when everything succeeded; on any error (or KeyboardInterrupt) the temporary directory is
removed and ``out_dir`` is left as it was.  Bad options are diagnostics raised before anything
is written; each names the command-line option it comes from.

An output directory holds one compile and nothing else: files a previous compile listed in its
``schedule.json`` (``files``) are replaced or removed; a directory holding anything acl did not
write there is refused (E-EMIT-OUTPUT), so no user file is ever deleted or left beside a schedule
it does not belong to.
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from typing import Callable

from acl.diagnostics import Diagnostic, DiagnosticError, Span, error, warning
from acl.emit.render import RenderStats, render_chunks, total_samples
from acl.emit.schedule_json import schedule_dict, write_schedule_json, write_segments_csv
from acl.emit.writers import CSV_BYTES_PER_SAMPLE, FORMATS, WRITERS
from acl.schedule.model import Schedule

# names acl writes into an output directory (and only these may ever be removed from one)
_ACL_NAME = re.compile(r"^(schedule\.json|segments\.csv|sequence\.seq|waveform(-samples)?\.(wav|npy|csv)|goal-step[0-9]+\.png)$")
CSV_WARN_BYTES = 100 * 2 ** 20
MAX_SAMPLES = 1 << 36              # 64 Gi samples: 256 GiB of float32 in any format
DEFAULT_MAX_OUTPUT_BYTES = 4 * 2 ** 30   # waveform files larger than this need --max-output-size
_BYTES_PER_SAMPLE = {"wav": 4, "npy": 4}


def option_span(option: str) -> Span:
    """Location of a command-line option in diagnostics (``<--sample-rate>:1:1``)."""
    return Span(file=f"<{option}>", line=1, column=1)


@dataclass
class EmitResult:
    out_dir: str
    files: dict[str, str] = field(default_factory=dict)
    stats: RenderStats = field(default_factory=RenderStats)
    sample_rate_hz: float = 0.0
    warnings: list[Diagnostic] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)      # stale files of a previous compile


def check_options(schedule: Schedule, formats, sample_rate: float) -> list[Diagnostic]:
    """Raise DiagnosticError (E-EMIT-*) for unknown formats, a sample rate below Nyquist, a size
    no file can hold or a peak beyond the WAV full scale; return warnings (W-EMIT-*)."""
    diags, warns = [], []
    for f in formats:
        if f not in FORMATS:
            diags.append(error("E-EMIT-FORMAT", f"unknown output format {f!r}", option_span("--format"),
                               f"choose from {', '.join(FORMATS)}"))
    fmax = schedule.max_frequency_hz
    rate = option_span("--sample-rate")
    if not (math.isfinite(sample_rate) and sample_rate > 0) or sample_rate < 2 * fmax:
        diags.append(error("E-EMIT-RATE", f"sample rate {sample_rate:g} Hz is below twice the highest "
                           f"tone ({fmax:g} Hz)" if math.isfinite(sample_rate) and sample_rate > 0
                           else f"sample rate {sample_rate:g} Hz is not a positive finite number", rate,
                           f"use at least {2 * fmax:g} Hz; the default is 10x the highest tone"))
    elif "wav" in formats and int(sample_rate) != sample_rate:
        diags.append(error("E-EMIT-RATE", "a WAV sample rate must be a whole number of Hz", rate))
    elif total_samples(schedule, sample_rate) > MAX_SAMPLES:
        diags.append(error("E-EMIT-SIZE", f"{schedule.duration_s:g} s at {sample_rate:g} S/s is "
                           f"{total_samples(schedule, sample_rate):.3g} samples, more than the "
                           f"{MAX_SAMPLES:.3g} acl writes", rate, "lower the sample rate or split the program"))
    elif "wav" in formats and 4 * total_samples(schedule, sample_rate) + 64 >= 2 ** 32:
        diags.append(error("E-EMIT-SIZE", f"{schedule.duration_s:g} s at {sample_rate:g} S/s exceeds the "
                           "4 GiB limit of a WAV file", option_span("--format"),
                           "use --format npy, or a lower sample rate"))
    else:
        if fmax > 0 and sample_rate < 4 * fmax:
            warns.append(warning("W-EMIT-RATE", f"sample rate {sample_rate:g} Hz is under 4x the highest "
                                 f"tone ({fmax:g} Hz): the samples miss the crests by up to "
                                 f"{100 * (1 - math.cos(math.pi * fmax / sample_rate)):.0f} % and the "
                                 "instrument's reconstruction filter decides the waveform", rate,
                                 f"use at least {4 * fmax:g} Hz (the default is 10x)"))
        if fmax > 0 and len(schedule.segments) > 1 and schedule.ramp_s < 10.0 / fmax:
            warns.append(warning("W-EMIT-RAMP", f"crossfades of {schedule.ramp_s:g} s are shorter than 10 "
                                 f"periods of the highest tone ({10.0 / fmax:.3g} s): segment boundaries "
                                 "are near-hard switches, and the instrument's reconstruction filter can "
                                 "ring above the peak the compiler checked", option_span("--ramp"),
                                 f"use --ramp {10.0 / fmax:.2g} or longer (default 0.001)"))
        size = CSV_BYTES_PER_SAMPLE * total_samples(schedule, sample_rate)
        if "csv" in formats and size > CSV_WARN_BYTES:
            warns.append(warning("W-EMIT-SIZE", f"waveform-samples.csv holds one row per sample: about "
                                 f"{size / 2 ** 20:.0f} MiB", option_span("--format"),
                                 "segments.csv (always written) lists the same schedule as tones; "
                                 "use npy for raw samples"))
    gen = (getattr(schedule, "chain", None) or {}).get("generator") or {}
    if gen.get("sample_rate") and math.isfinite(sample_rate) and sample_rate > gen["sample_rate"] * (1 + 1e-9):
        diags.append(error("E-EMIT-RATE", f"sample rate {sample_rate:g} S/s is above the {gen['sample_rate']:g} S/s "
                           f"of generator `{gen.get('name', '?')}` (use generator)", rate,
                           f"use at most {gen['sample_rate']:g} S/s"))
    elif gen.get("memory") and not diags and total_samples(schedule, sample_rate) > gen["memory"]:
        warns.append(warning("W-EMIT-MEMORY", f"the waveform's {total_samples(schedule, sample_rate):,} samples do "
                             f"not fit the {gen['memory']:,.0f} points of generator `{gen.get('name', '?')}`",
                             option_span("--format"), "play schedule.json with `acl play` (one looped segment per "
                             "constant drive, or steps; docs/bench.md) or load sequence.seq (--format seq)"))
    peak = max((s.peak_v or 0.0 for s in schedule.segments), default=0.0)
    if peak > schedule.full_scale_v * (1 + 1e-9):
        diags.append(error("E-EMIT-FULLSCALE", f"the schedule's peak {peak:.4g} V exceeds the WAV full "
                           f"scale {schedule.full_scale_v:g} V", option_span("--full-scale"),
                           "raise --full-scale (the instrument's +-1.0 must mean at least the peak)"))
    if diags:
        raise DiagnosticError(diags)
    return warns


def output_bytes(schedule: Schedule, formats, sample_rate: float) -> int:
    """Bytes the waveform files of ``formats`` will take (the CSV of samples at its typical row size)."""
    n = total_samples(schedule, sample_rate)
    return sum(_BYTES_PER_SAMPLE.get(f, CSV_BYTES_PER_SAMPLE) * n for f in dict.fromkeys(formats))


def free_bytes(out_dir: str) -> int | None:
    """Free space (bytes) of the filesystem that will hold ``out_dir`` (its nearest existing folder), or None."""
    folder = os.path.abspath(out_dir)
    while folder and not os.path.isdir(folder):
        parent = os.path.dirname(folder)
        if parent == folder:
            break
        folder = parent
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


def check_size(schedule: Schedule, formats, sample_rate: float, out_dir: str,
               max_bytes: float | None = DEFAULT_MAX_OUTPUT_BYTES) -> None:
    """E-EMIT-SIZE before anything is written: waveform files beyond ``max_bytes`` (a sane default, raised
    with --max-output-size) or beyond the free space where they go.  A 2,000 s drive with --format npy was
    accepted as a 10 GB file; interrupted, it left gigabytes of half-written samples."""
    need = output_bytes(schedule, formats, sample_rate)
    gib = need / 2 ** 30
    if max_bytes is not None and need > max_bytes:
        raise DiagnosticError([error(
            "E-EMIT-SIZE", f"the waveform files would take {gib:.3g} GiB ({schedule.duration_s:g} s at "
            f"{sample_rate:g} S/s, {', '.join(dict.fromkeys(formats))}), more than the "
            f"{max_bytes / 2 ** 30:.3g} GiB limit", option_span("--max-output-size"),
            "raise the limit (--max-output-size 20GiB) if you mean it; segments.csv lists the same schedule "
            "as tones in a few kB; or lower the sample rate")])
    free = free_bytes(out_dir)
    if free is not None and need + (1 << 20) > free:
        raise DiagnosticError([error(
            "E-EMIT-SIZE", f"the waveform files would take {gib:.3g} GiB, and the disk holding {out_dir!r} "
            f"has {free / 2 ** 30:.3g} GiB free", option_span("--output"),
            "free some space or write elsewhere; nothing was written")])


def previous_compile(out_dir: str) -> set[str] | None:
    """Names a previous acl compile wrote into ``out_dir`` (its schedule.json's ``files``), or None."""
    path = os.path.join(out_dir, "schedule.json")
    if not os.path.isfile(path) or os.path.islink(path):
        return None
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except (OSError, ValueError, UnicodeDecodeError, RecursionError):   # not ours (or hostile): refused later
        return None
    if not isinstance(data, dict) or not str(data.get("generator", "")).startswith("acl "):
        return None
    files = data.get("files")
    names = {"schedule.json"}
    if isinstance(files, dict):
        names |= {v for v in files.values() if isinstance(v, str) and _ACL_NAME.match(v)}
    return names


def check_output_dir(out_dir: str) -> set[str]:
    """The files of a previous compile in ``out_dir`` (to replace); E-EMIT-OUTPUT if it holds others."""
    where = option_span("--output")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise DiagnosticError([error("E-EMIT-OUTPUT", f"output {out_dir!r} exists and is not a directory",
                                     where, "give a directory path with -o")])
    if not os.path.isdir(out_dir):
        return set()
    try:
        entries = os.listdir(out_dir)
    except OSError as exc:
        raise DiagnosticError([error("E-EMIT-OUTPUT", f"cannot list {out_dir!r}: {exc.strerror or exc}",
                                     where)]) from None
    ours = previous_compile(out_dir) or set()
    foreign = sorted(n for n in entries if n not in ours or os.path.islink(os.path.join(out_dir, n))
                     or not os.path.isfile(os.path.join(out_dir, n)))
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise DiagnosticError([error(
            "E-EMIT-OUTPUT", f"output folder {out_dir!r} holds files acl did not write there: {shown}",
            where, "an output folder holds one compile and nothing else: choose a new or empty folder "
                   "(acl replaces only the files of its own previous compile)")])
    return set(entries)


def emit(schedule: Schedule, out_dir: str, formats=("wav",), sample_rate: float | None = None,
         plot: bool = False, progress: Callable[[int, int], None] | None = None,
         max_bytes: float | None = DEFAULT_MAX_OUTPUT_BYTES) -> EmitResult:
    fs = float(sample_rate or schedule.sample_rate_hz)
    formats = tuple(dict.fromkeys(formats))
    warns = check_options(schedule, formats, fs)
    stale = check_output_dir(out_dir)
    check_size(schedule, formats, fs, out_dir, max_bytes)
    parent = os.path.dirname(os.path.abspath(out_dir)) or "."
    os.makedirs(parent, exist_ok=True)
    from acl._files import as_umask, deferred_signals

    tmp = None
    result = EmitResult(out_dir=out_dir, sample_rate_hz=fs, warnings=warns)
    try:
        with deferred_signals():
            tmp = tempfile.mkdtemp(prefix=".acl-compile-", dir=parent)
        as_umask(tmp, directory=True)
        n = total_samples(schedule, fs)
        writers = []
        try:
            for f in formats:
                if f == "seq":          # tones, not samples: written below
                    continue
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
        if "seq" in formats:
            from acl.emit.seq import drives_of_schedule, write_seq

            write_seq(os.path.join(tmp, "sequence.seq"), drives_of_schedule(schedule),
                      {"program": schedule.program, "source": schedule.source,
                       "amplitudes": "peak volts at the transducer input"})
            result.files["seq"] = "sequence.seq"
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
        result.removed = _publish(tmp, out_dir, stale)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    return result


def _publish(tmp: str, out_dir: str, stale: set[str]) -> list[str]:
    """Move the finished files into ``out_dir`` (a rename of the whole directory when it is new),
    then remove the previous compile's files the new one did not replace; returns those names."""
    if not os.path.exists(out_dir):
        os.replace(tmp, out_dir)
        return []
    if not os.path.isdir(out_dir):
        raise NotADirectoryError(out_dir)
    new = set(os.listdir(tmp))
    for name in new:
        os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    os.rmdir(tmp)
    removed = []
    for name in sorted(stale - new):
        path = os.path.join(out_dir, name)
        if _ACL_NAME.match(name) and os.path.isfile(path) and not os.path.islink(path):
            os.remove(path)
            removed.append(name)
    return removed
