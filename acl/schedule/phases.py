"""Multi-tone phases with a low crest factor, and the true (analog) peak of a multi-tone.

The peak of ``x(t) = sum_k A_k sin(2 pi f_k t + phi_k)`` never exceeds ``sum_k A_k``; for
incommensurate frequencies it comes arbitrarily close whatever the phases.  When the tones share a
common period ``T = 1 / gcd(f_k)`` (frequencies on a common grid), the phases decide its peak.

The peak that matters is that of the *analog* signal the DAC reconstructs, not of the samples: a
sample grid misses the crest by up to ``1 - cos(pi f / fs)`` (4.9 % at 10 samples per cycle).
:func:`analog_peaks` bounds it rigorously: ``|x''| <= D2 = sum_k A_k (2 pi f_k)^2``, so within
``h / 2`` of the true crest a grid of step ``h`` has a point at most ``D2 h^2 / 8`` below it.  A
grid of 8 points per cycle of the highest tone finds the candidate intervals, each is refined on a
32-point sub-grid, and the bound ``max + D2 h_sub^2 / 8`` (within 2e-4 of ``sum A``) is reported.
The phases minimise the peak on a 16-point-per-cycle grid of one common period (Nelder-Mead from
Schroeder's phases); phases the user gave are kept.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from acl.schedule.model import Schedule, ScheduledTone, Segment


def common_period_samples(frequencies, sample_rate: float, max_samples: int = 1 << 20) -> int | None:
    """Smallest M with f_k * M / fs integer for every tone (frequencies to 1 mHz), or None."""
    fs = Fraction(sample_rate).limit_denominator(1000)
    m = 1
    for f in frequencies:
        r = Fraction(f).limit_denominator(1000) / fs          # cycles per sample
        m = m * r.denominator // math.gcd(m, r.denominator)
        if m > max_samples:
            return None
    return m


def schroeder_phases(amplitudes) -> np.ndarray:
    """Schroeder's low-crest phases for the given amplitudes (power-weighted form)."""
    a = np.asarray(amplitudes, dtype=float)
    p = a ** 2 / max(float(np.sum(a ** 2)), 1e-300)
    K = a.size
    phi = np.zeros(K)
    for k in range(1, K):
        phi[k] = phi[0] - 2 * np.pi * np.sum((k - np.arange(k)) * p[:k])
    return np.mod(phi, 2 * np.pi)


def _basis(frequencies, sample_rate, n):
    t = np.arange(n) / sample_rate
    return 2 * np.pi * np.outer(np.asarray(frequencies, float), t)     # (K, n)


def sampled_peak(frequencies, amplitudes, phases, sample_rate: float, n: int) -> float:
    arg = _basis(frequencies, sample_rate, n) + np.asarray(phases, float)[:, None]
    return float(np.max(np.abs(np.asarray(amplitudes, float) @ np.sin(arg))))


def analog_period(frequencies, max_points: int = 1 << 17, per_cycle: int = 16) -> float | None:
    """Common period 1 / gcd(f_k) (frequencies to 1 mHz) in s, or None if it needs more than
    ``max_points`` grid points at ``per_cycle`` points per cycle of the highest tone."""
    fr = [Fraction(float(f)).limit_denominator(1000) for f in frequencies]
    if not fr or any(f <= 0 for f in fr):
        return None
    g = fr[0]
    for f in fr[1:]:
        g = Fraction(math.gcd(g.numerator * f.denominator, f.numerator * g.denominator),
                     g.denominator * f.denominator)
    period = 1 / float(g)
    if period * float(max(fr)) * per_cycle > max_points:
        return None
    return period


def _grid(frequencies, period: float, per_cycle: int) -> np.ndarray:
    n = max(8, int(np.ceil(period * float(np.max(frequencies)) * per_cycle)))
    return np.arange(n) * (period / n)


def analog_peaks(frequencies, phases, amplitudes, chunk: int | None = None) -> np.ndarray:
    """Upper bound (V, tight to ~1e-4 of sum A) on the analog peak of each row of ``amplitudes`` (N, K).

    Without a common period short enough to scan, the bound is ``sum_k |A_k|`` (reached for
    incommensurate tones)."""
    a = np.atleast_2d(np.abs(np.asarray(amplitudes, float)))
    f = np.asarray(frequencies, float)
    if f.size == 0:
        return np.zeros(a.shape[0])
    if f.size == 1:
        return a[:, 0].copy()
    period = analog_period(f)
    if period is None:
        return a.sum(axis=1)
    phi = np.asarray(phases, float)
    t = _grid(f, period, 8)
    h = t[1] - t[0]
    w = 2 * np.pi * f
    arg0 = np.outer(w, t) + phi[:, None]
    S, Cg = np.sin(arg0), np.cos(arg0)                                 # (K, n)
    chunk = chunk or max(1, (1 << 19) // t.size)                       # rows x grid <= 4 MB (stays in cache)
    d2 = a @ (w ** 2)                                                  # (N,) bound on |x''|
    sub = np.linspace(-0.5, 0.5, 32) * h                               # sub-grid around a point
    # sin(w (t + s) + phi) = sin(w t + phi) cos(w s) + cos(w t + phi) sin(w s): no sin() per candidate
    cs, ss = np.cos(np.outer(w, sub)), np.sin(np.outer(w, sub))        # (K, 32)
    h_sub = h / 31
    out = np.empty(a.shape[0])
    for s0 in range(0, a.shape[0], chunk):
        rows = a[s0:s0 + chunk]
        x = rows[:, :1] * S[0]                                         # (n_rows, n): sum_k A_k sin(...), K small:
        for k in range(1, f.size):                                     # K outer products beat a rank-K matmul
            x += rows[:, k:k + 1] * S[k]
        np.abs(x, out=x)
        m = x.max(axis=1)
        slack = d2[s0:s0 + chunk] * h ** 2 / 8
        r_idx, c_idx = np.nonzero(x >= (m - slack)[:, None])
        best = np.zeros(rows.shape[0])
        for p0 in range(0, r_idx.size, 16384):
            ri, ci = r_idx[p0:p0 + 16384], c_idx[p0:p0 + 16384]
            ra = rows[ri]                                              # (P, K)
            val = np.abs(np.einsum("pk,kj->pj", ra * S[:, ci].T, cs)
                         + np.einsum("pk,kj->pj", ra * Cg[:, ci].T, ss)).max(axis=1)
            np.maximum.at(best, ri, val)
        out[s0:s0 + chunk] = np.maximum(best, m) + d2[s0:s0 + chunk] * h_sub ** 2 / 8
    return np.minimum(out, a.sum(axis=1))


def choose_phases(frequencies, amplitudes, sample_rate: float | None = None, window: int = 4096,
                  iterations: int = 200, fixed=None, start=None) -> tuple[np.ndarray, float]:
    """Phases (K,) rad with a low analog peak, and that peak's bound (V, :func:`analog_peaks`).

    ``fixed`` (K,) bool marks phases the user gave: they keep their value from ``start`` (K,) rad.
    ``sample_rate`` and ``window`` are unused (kept for callers): the analog peak does not depend
    on the sample rate."""
    f = np.asarray(frequencies, float)
    a = np.asarray(amplitudes, float)
    fixed = np.zeros(f.size, bool) if fixed is None else np.asarray(fixed, bool)
    given = np.zeros(f.size) if start is None else np.asarray(start, float)
    free = np.flatnonzero(~fixed & (a != 0))
    if f.size <= 1 or np.count_nonzero(a) <= 1 or free.size == 0 or (free.size == 1 and not fixed.any()):
        phi = np.where(fixed, given, 0.0)
        return phi, float(analog_peaks(f, phi, a[None])[0])
    period = analog_period(f)
    schroeder = schroeder_phases(a)
    phi0 = np.where(fixed, given, schroeder - (schroeder[free[0]] if not fixed.any() else 0.0))
    if not fixed.any():
        free = free[1:]                        # a common time shift: one free phase is redundant
    candidates = [np.mod(phi0, 2 * np.pi)]
    if period is not None and free.size:
        from scipy.optimize import minimize

        t = _grid(f, period, 16)
        base = np.outer(2 * np.pi * f, t)
        sinb, cosb = np.sin(base), np.cos(base)

        def peak(x):
            phi = phi0.copy()
            phi[free] = x
            # sin(x + phi) = sin x cos phi + cos x sin phi, so no new sin() per evaluation
            return float(np.max(np.abs((a * np.cos(phi)) @ sinb + (a * np.sin(phi)) @ cosb)))

        for x0 in (phi0[free], np.zeros(free.size), np.linspace(0.5, 2.5, free.size)):
            r = minimize(peak, x0, method="Nelder-Mead",
                         options={"maxfev": iterations, "xatol": 1e-3, "fatol": 1e-6 * np.abs(a).sum()})
            phi = phi0.copy()
            phi[free] = r.x
            candidates.append(np.mod(phi, 2 * np.pi))
    peaks = np.array([analog_peaks(f, c, a[None])[0] for c in candidates])
    best = int(np.argmin(peaks))
    return candidates[best], float(peaks[best])


def group_peaks(frequencies, phases, amplitudes: np.ndarray, sample_rate: float | None = None,
                window: int = 4096, chunk: int = 512) -> np.ndarray:
    """Analog peak bound (V) of each row of ``amplitudes`` (N, K) with shared tones and phases."""
    return analog_peaks(frequencies, phases, amplitudes)


def choose_all_phases(sched: Schedule, fs: float) -> None:
    """Pick low-peak phases per group of consecutive segments sharing the same frequencies (phases
    the user gave are kept), and record each segment's analog peak bound."""
    segs = sched.segments
    i = 0
    while i < len(segs):
        key = tuple(t.frequency_hz for t in segs[i].tones)
        j = i
        while j + 1 < len(segs) and tuple(t.frequency_hz for t in segs[j + 1].tones) == key \
                and segs[j + 1].goal == segs[i].goal:
            j += 1
        group = segs[i:j + 1]
        amps = np.array([[t.amplitude_v for t in s.tones] for s in group]).reshape(len(group), -1)
        tones0 = group[0].tones
        phases = np.array([t.phase_rad for t in tones0])
        if any(t.sweep for t in tones0):
            peaks = np.abs(amps).sum(axis=1)
        else:
            if len(key) > 1:
                worst = amps[int(np.argmax(amps.sum(axis=1)))]
                phases, _ = choose_phases(key, worst, fs, fixed=[t.phase_fixed for t in tones0],
                                          start=phases)
            peaks = group_peaks(key, phases, amps, fs)
        for m in range(i, j + 1):
            s = segs[m]
            segs[m] = Segment(s.start_s, s.end_s, tuple(
                ScheduledTone(t.frequency_hz, t.amplitude_v, float(p), t.frequency_end_hz, t.sweep,
                              t.phase_fixed)
                for t, p in zip(s.tones, phases)), s.step, s.goal, float(peaks[m - i]))
        i = j + 1
