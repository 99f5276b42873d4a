"""Sampling a schedule into volts, chunk by chunk (memory independent of duration).

Segment ``i`` contributes ``w_i(t) * sum_k A_k sin(phi_k(t))`` where the weights ``w_i`` form a
partition of unity made of raised-cosine crossfades: at the boundary between two segments the
fade lasts ``2 h`` with ``h = min(ramp_s / 2, half of either neighbour)``; the first segment fades
in over ``[0, 2 h]`` and the last fades out over ``[T - 2 h, T]``.  Because the weights are convex
combinations, the peak never exceeds the largest segment peak, and a tone kept with the same
frequency and phase across a boundary simply has its amplitude interpolated (no click).

Constant tones use the global time axis ``phi = 2 pi f t + phase``; when a segment's tones share a
common period of M samples the segment is rendered from a one-period template (fast path).
Chirps (sweep steps) integrate their instantaneous frequency from the segment's start.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from acl.schedule.model import Schedule, Segment
from acl.schedule.phases import common_period_samples

CHUNK = 1 << 18


@dataclass
class RenderStats:
    samples: int = 0
    peak_v: float = 0.0
    sum_sq: float = 0.0
    max_jump_v: float = 0.0
    _last: float | None = field(default=None, repr=False)

    @property
    def rms_v(self) -> float:
        return float(np.sqrt(self.sum_sq / self.samples)) if self.samples else 0.0

    def update(self, x: np.ndarray) -> None:
        if x.size == 0:
            return
        self.peak_v = max(self.peak_v, float(x.max()), -float(x.min()))
        self.sum_sq += float(np.einsum("i,i->", x, x))       # no BLAS threads: predictable
        if x.size > 1:
            d = np.subtract(x[1:], x[:-1])
            self.max_jump_v = max(self.max_jump_v, float(d.max()), -float(d.min()))
        if self._last is not None:
            self.max_jump_v = max(self.max_jump_v, abs(float(x[0]) - self._last))
        self._last = float(x[-1])
        self.samples += x.size


def total_samples(schedule: Schedule, sample_rate: float) -> int:
    return int(round(schedule.duration_s * sample_rate))


def _half_ramps(segments: list[Segment], ramp_s: float) -> np.ndarray:
    """h[i] for boundary i (start of segment i); h[n] for the end. Shape (n + 1,)."""
    d = np.array([s.duration_s for s in segments])
    h = np.empty(len(segments) + 1)
    half = ramp_s / 2
    h[0] = min(half, d[0] / 2)
    h[-1] = min(half, d[-1] / 2)
    if len(segments) > 1:
        h[1:-1] = np.minimum(half, np.minimum(d[:-1], d[1:]) / 2)
    return h


def _rc(x: np.ndarray) -> np.ndarray:
    """Raised cosine from 0 (x <= 0) to 1 (x >= 1)."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))


class _Segments:
    """Per-segment support, weights and (cached) one-period templates."""

    def __init__(self, schedule: Schedule, fs: float):
        self.segs = schedule.segments
        self.fs = fs
        self.h = _half_ramps(self.segs, schedule.ramp_s) if self.segs else np.zeros(1)
        n = len(self.segs)
        starts = np.array([s.start_s for s in self.segs])
        ends = np.array([s.end_s for s in self.segs])
        # time of full weight / support, per segment: fade-in [a0, a1], fade-out [b0, b1]
        self.a0 = starts - self.h[:n]
        self.a1 = starts + self.h[:n]
        self.b0 = ends - self.h[1:]
        self.b1 = ends + self.h[1:]
        self.a0[0], self.a1[0] = starts[0], starts[0] + 2 * self.h[0]
        self.b0[-1], self.b1[-1] = ends[-1] - 2 * self.h[-1], ends[-1]
        self.support_end = np.maximum.accumulate(self.b1)
        self._templates: dict[int, np.ndarray | None] = {}
        self._tiled: dict[int, np.ndarray] = {}
        self._units: dict[tuple, np.ndarray] = {}

    def overlapping(self, t0: float, t1: float) -> range:
        lo = int(np.searchsorted(self.support_end, t0, side="right"))
        hi = int(np.searchsorted(self.a0, t1, side="left"))
        return range(lo, hi)

    def template(self, i: int) -> np.ndarray | None:
        if i not in self._templates:
            seg = self.segs[i]
            tpl = None
            if seg.tones and not any(t.sweep for t in seg.tones):
                m = common_period_samples([t.frequency_hz for t in seg.tones], self.fs,
                                          max_samples=1 << 16)
                if m is not None:
                    tpl = self._template_of(seg, m)
            if len(self._templates) > 64:
                self._templates.clear()
            self._templates[i] = tpl
        return self._templates[i]


    def _template_of(self, seg: Segment, m: int) -> np.ndarray:
        """:func:`_tones_at` of ``seg`` over samples 0 .. m-1 (the same arithmetic, tone by tone), each tone's unit
        sine kept by (frequency, phase, m): a schedule's segments replay a few tones at new amplitudes."""
        if any(t.sweep is not None for t in seg.tones):
            return _tones_at(seg, np.arange(m, dtype=np.int64), self.fs)
        out = np.zeros(m)
        for tone in seg.tones:
            if tone.amplitude_v == 0:
                continue
            key = (tone.frequency_hz, tone.phase_rad, m)
            unit = self._units.get(key)
            if unit is None:
                if len(self._units) >= 16:
                    self._units.clear()
                cyc = np.mod(tone.frequency_hz * np.arange(m, dtype=np.int64).astype(np.float64), self.fs) / self.fs
                unit = self._units[key] = np.sin(2 * np.pi * cyc + tone.phase_rad)
            out += tone.amplitude_v * unit
        return out

    def tiled(self, i: int, tpl: np.ndarray, length: int) -> np.ndarray:
        """The template repeated to cover ``length + period`` samples (long segments: a slice is a copy)."""
        big = self._tiled.get(i)
        if big is None or big.size < length + tpl.size:
            if len(self._tiled) >= 2:
                self._tiled.clear()
            big = np.tile(tpl, (length + 2 * tpl.size - 1) // tpl.size)
            self._tiled[i] = big
        return big


def _tones_at(seg: Segment, n: np.ndarray, fs: float) -> np.ndarray:
    """Sum of a segment's tones at sample indices ``n`` (global), volts."""
    out = np.zeros(n.size)
    t_start = seg.start_s
    for tone in seg.tones:
        if tone.amplitude_v == 0:
            continue
        if tone.sweep is None:
            # exact phase reduction: (f n mod fs) / fs cycles
            cyc = np.mod(tone.frequency_hz * n.astype(np.float64), fs) / fs
            out += tone.amplitude_v * np.sin(2 * np.pi * cyc + tone.phase_rad)
        else:
            tau = n / fs - t_start
            D = max(seg.duration_s, 1e-300)
            f0, f1 = tone.frequency_hz, tone.frequency_end_hz or tone.frequency_hz
            if tone.sweep == "log" and f1 != f0:
                k = np.log(f1 / f0)
                cyc = f0 * D / k * np.expm1(k * tau / D)
            else:
                cyc = f0 * tau + (f1 - f0) * tau ** 2 / (2 * D)
            out += tone.amplitude_v * np.sin(2 * np.pi * cyc + tone.phase_rad)
    return out


def render_chunks(schedule: Schedule, sample_rate: float, chunk: int = CHUNK,
                  progress: Callable[[int, int], None] | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (first sample index, volts float64 array) chunks covering the whole schedule."""
    fs = float(sample_rate)
    total = total_samples(schedule, fs)
    if not schedule.segments or total == 0:
        return
    S = _Segments(schedule, fs)
    for n0 in range(0, total, chunk):
        n1 = min(total, n0 + chunk)
        out = np.zeros(n1 - n0)
        for i in S.overlapping(n0 / fs, n1 / fs):
            seg = S.segs[i]
            if not seg.tones:
                continue
            # A fade shorter than one sample is a step at the middle of its interval; both neighbours
            # compute that middle identically, so each boundary sample goes to exactly one segment.
            fade_in = S.a1[i] - S.a0[i] >= 1.0 / fs
            fade_out = S.b1[i] - S.b0[i] >= 1.0 / fs
            lo = S.a0[i] if fade_in else (S.a0[i] + S.a1[i]) / 2
            hi = S.b1[i] if fade_out else (S.b0[i] + S.b1[i]) / 2
            # samples of this chunk inside the segment's support
            s0 = max(n0, int(np.ceil(lo * fs - 1e-9)))
            s1 = min(n1, int(np.ceil(hi * fs - 1e-9)))
            if s1 <= s0:
                continue
            tpl = S.template(i)
            if tpl is not None and s1 - s0 >= chunk // 2:
                o = s0 % tpl.size
                x = S.tiled(i, tpl, chunk)[o:o + (s1 - s0)]
            elif tpl is not None:
                x = tpl[np.arange(s0, s1, dtype=np.int64) % tpl.size]
            else:
                x = _tones_at(seg, np.arange(s0, s1, dtype=np.int64), fs)
            # weights: only where a fade is active
            # (a step's weight is 1 on the support: a weight computed in seconds could drop a
            # sample that rounding put on the other side)
            if (fade_in and s0 / fs < S.a1[i]) or (fade_out and (s1 - 1) / fs > S.b0[i]):
                # (the raised cosine is exactly 1 outside its fade: evaluated only on the samples inside one)
                t = np.arange(s0, s1, dtype=np.int64) / fs
                w = np.ones(t.size)
                if fade_in:
                    k = int(np.searchsorted(t, S.a1[i], side="left"))          # t[:k] < a1
                    w[:k] *= _rc((t[:k] - S.a0[i]) / (S.a1[i] - S.a0[i]))
                if fade_out:
                    k = int(np.searchsorted(t, S.b0[i], side="right"))         # t[k:] > b0
                    w[k:] *= 1.0 - _rc((t[k:] - S.b0[i]) / (S.b1[i] - S.b0[i]))
                x = w * x
            out[s0 - n0:s1 - n0] += x
        if progress is not None:
            progress(n1, total)
        yield n0, out
