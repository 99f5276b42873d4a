"""Multi-tone phases with a low crest factor: Schroeder phases, then a local search on the sampled peak.

The peak of ``sum_k A_k sin(2 pi f_k t + phi_k)`` never exceeds ``sum_k A_k``; for incommensurate
frequencies it comes arbitrarily close whatever the phases.  When the tones share a common period
of ``M`` samples at the sample rate (frequencies on a common grid), the sampled waveform repeats
every ``M`` samples and the phases decide its peak: we minimise the peak over one period.
Otherwise the phases are Schroeder's and the peak is measured over ``window`` samples.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np


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


def choose_phases(frequencies, amplitudes, sample_rate: float, window: int = 4096,
                  iterations: int = 200) -> tuple[np.ndarray, float]:
    """Phases (K,) rad and the resulting sampled peak (V) over one period (or ``window`` samples)."""
    f = np.asarray(frequencies, float)
    a = np.asarray(amplitudes, float)
    if f.size <= 1 or np.count_nonzero(a) <= 1:
        return np.zeros(f.size), float(np.sum(np.abs(a)))
    period = common_period_samples(f, sample_rate)
    n = period if period is not None and period <= 1 << 16 else window
    base = _basis(f, sample_rate, n)
    sinb, cosb = np.sin(base), np.cos(base)

    def peak(phi_rest):
        phi = np.concatenate([[0.0], phi_rest])
        # sin(x + phi) = sin x cos phi + cos x sin phi, so no new sin() per evaluation
        w = (a * np.cos(phi)) @ sinb + (a * np.sin(phi)) @ cosb
        return float(np.max(np.abs(w)))

    start = schroeder_phases(a)
    start = np.mod(start - start[0], 2 * np.pi)[1:]
    best_x, best = start, peak(start)
    if period is not None:
        from scipy.optimize import minimize

        for x0 in (start, np.zeros_like(start), np.linspace(0.5, 2.5, start.size)):
            r = minimize(peak, x0, method="Nelder-Mead",
                         options={"maxfev": iterations, "xatol": 1e-3, "fatol": 1e-6 * a.sum()})
            if r.fun < best:
                best_x, best = np.asarray(r.x), float(r.fun)
    phi = np.mod(np.concatenate([[0.0], best_x]), 2 * np.pi)
    return phi, best


def group_peaks(frequencies, phases, amplitudes: np.ndarray, sample_rate: float,
                window: int = 4096, chunk: int = 512) -> np.ndarray:
    """Peak (V) of each row of ``amplitudes`` (N, K) with shared tones: the sampled peak over one
    common period when there is one, else the bound ``sum_k A_k`` (reached for incommensurate tones)."""
    a = np.atleast_2d(np.asarray(amplitudes, float))
    f = np.asarray(frequencies, float)
    if f.size == 0:
        return np.zeros(a.shape[0])
    period = common_period_samples(f, sample_rate)
    if period is None or period > 1 << 16:
        return np.abs(a).sum(axis=1)
    S = np.sin(_basis(f, sample_rate, period) + np.asarray(phases, float)[:, None])
    out = np.empty(a.shape[0])
    for s in range(0, a.shape[0], chunk):
        out[s:s + chunk] = np.max(np.abs(a[s:s + chunk] @ S), axis=1)
    return out
