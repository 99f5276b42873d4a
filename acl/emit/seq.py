"""Constant drives as short looped segments: the compact sequence export (`acl compile --format seq`).

A schedule is a list of constant-drive segments, each a sum of a few tones.  Consecutive segments
with the same tones are one *drive*.  A drive whose tones are whole multiples of a common frequency
``g`` (integer hertz here) repeats exactly every ``1/g`` seconds, so an instrument's sequence mode
plays it as one short segment of ``1/g`` seconds looped ``duration * g`` times (docs/bench.md).
Pure numpy, no instrument: ``acl play`` (acl/bench) builds its command stream from the same drives.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import reduce

SEQ_VERSION = "1"


@dataclass(frozen=True)
class Drive:
    """One constant drive: ``tones`` are (frequency Hz, amplitude V peak, phase rad) at the transducer."""

    start_s: float
    duration_s: float
    tones: tuple[tuple[float, float, float], ...]
    swept: bool = False          # a tone sweeps its frequency: no short loop repeats it


def merge(segments) -> list[Drive]:
    """Runs of consecutive segments with identical tones -> drives. ``segments``: (start, end, tones, swept)."""
    out: list[Drive] = []
    for start, end, tones, swept in segments:
        tones = tuple((float(f), float(a), float(p)) for f, a, p in tones)
        if out and out[-1].tones == tones and not swept and not out[-1].swept \
                and abs(out[-1].start_s + out[-1].duration_s - start) < 1e-9:
            last = out[-1]
            out[-1] = Drive(last.start_s, end - last.start_s, tones)
        else:
            out.append(Drive(float(start), float(end) - float(start), tones, bool(swept)))
    return out


def drives_of_schedule(schedule) -> list[Drive]:
    """The drives of an :class:`acl.schedule.model.Schedule`."""
    return merge((s.start_s, s.end_s, [(t.frequency_hz, t.amplitude_v, t.phase_rad) for t in s.tones],
                  any(t.sweep for t in s.tones)) for s in schedule.segments)


def common_frequency(freqs) -> int | None:
    """The largest whole-hertz frequency every tone is a multiple of (the loop repeats at it), or
    None when a tone is not a whole number of hertz (then no short loop is exact)."""
    ints = []
    for f in freqs:
        n = round(f)
        if n <= 0 or abs(f - n) > 1e-6 * max(1.0, f):
            return None
        ints.append(int(n))
    return reduce(math.gcd, ints) if ints else None


def loop_rate(drives: list[Drive], fmax_rate: float, oversample: float = 8.0) -> float | None:
    """One sample rate at which every drive's loop (1/g) is a whole number of samples and the highest
    tone has at least ``oversample`` samples per period; None if none up to ``fmax_rate``."""
    gs = [common_frequency(f for f, _, _ in d.tones) for d in drives if d.tones]
    if not gs:
        return None
    if any(g is None for g in gs):
        return None
    step = reduce(lambda a, b: a * b // math.gcd(a, b), gs)
    fmax = max(f for d in drives for f, _, _ in d.tones)
    rate = step * max(1, math.ceil(oversample * fmax / step))
    return float(rate) if rate <= fmax_rate else None


def loop_samples(tones, rate: float, points: int):
    """Volts of one loop of ``points`` samples at ``rate`` (sum of the tones, sine convention of render)."""
    import numpy as np

    t = np.arange(points) / rate
    v = np.zeros(points)
    for f, a, p in tones:
        v += a * np.sin(2 * math.pi * f * t + p)
    return v


def write_seq(path: str, drives: list[Drive], meta: dict) -> int:
    """The compact sequence file: one line per drive (start, duration, loop period, repeats, tones).

    Every tone is ``FREQUENCY_HZ:AMPLITUDE_V:PHASE_RAD`` (peak volts at the transducer input); a drive's
    loop period is 1 / the common frequency of its tones (empty when a tone is swept or not whole
    hertz: such a drive does not loop exactly).  Returns the number of drives written.
    """
    lines = [f"# acl sequence {SEQ_VERSION}: one looped segment per constant drive (docs/bench.md)"]
    for k, v in meta.items():
        lines.append(f"# {k}: {v}")
    lines.append("drive,start_s,duration_s,period_s,repeats,tones")
    for i, d in enumerate(drives, 1):
        g = None if d.swept else common_frequency(f for f, _, _ in d.tones)
        period = f"{1.0 / g:.12g}" if g else ""
        repeats = str(max(1, round(d.duration_s * g))) if g else ""
        tones = ";".join(f"{f:.9g}:{a:.9g}:{p:.9g}" for f, a, p in d.tones)
        lines.append(f"{i},{d.start_s:.9g},{d.duration_s:.9g},{period},{repeats},{tones}")
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
    return len(drives)
