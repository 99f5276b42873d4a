"""Interface amplitudes of a design: the centre amplitude over radius, eps/R, of every interface (orifice or
membrane) under a drive or a sweep, from the coupled response at rest (:func:`acl.analysis.acoustics.coupled_response`),
and the largest value of a quantity over a frequency band (:func:`band_maximum`)."""
from __future__ import annotations

import numpy as np

from acl.analysis.acoustics import _layout, _tones, coupled_response, effect_pressure_factor
from acl.design.model import Design, Drive, Tone
from acl.physics.forces import interface_centre_amplitude
from acl.physics.roots import grid_max


def sweep_interface_amplitudes(design: Design, frequencies, amplitude: float) -> np.ndarray:
    """eps/R (F, n) of every interface under a single tone of ``amplitude`` at each of ``frequencies``:
    :func:`interface_amplitudes` of each tone alone, in one coupled solve."""
    lay = _layout(design)
    f = np.atleast_1d(np.asarray(frequencies, float))
    if f.size == 0 or not lay.labels:
        return np.zeros((f.size, len(lay.labels)))
    gain = effect_pressure_factor(design, f, float(amplitude))
    u = coupled_response(design, f) * (amplitude * gain)[:, None]
    return interface_centre_amplitude(np.abs(u), lay.radii) / lay.radii


def interface_amplitudes(design: Design, drive: Drive, positions=None) -> dict[str, float]:
    """Centre amplitude over radius, eps/R, of every interface under ``drive`` (tone amplitudes summed: the peak)."""
    lay = _layout(design)
    f, v = _tones(drive)
    eps = interface_amplitudes_batch(design, f, v[None], positions)[0]
    return {lab: float(e) for lab, e in zip(lay.labels, eps)}


def interface_amplitudes_batch(design: Design, frequencies, amplitudes, positions=None) -> np.ndarray:
    """eps/R (B, n) of every interface (``interface_labels`` order) under B drives of the tones ``frequencies`` (Hz),
    row b with amplitudes ``amplitudes[b]`` (V; summed: the peak; drive saturation at each row's total): the
    coupled response at rest (or ``positions``) solved once for every row."""
    lay = _layout(design)
    f = np.atleast_1d(np.asarray(frequencies, float))
    v = np.atleast_2d(np.asarray(amplitudes, float)).reshape(-1, f.size)
    if f.size == 0 or not lay.labels:
        return np.zeros((v.shape[0], len(lay.labels)))
    gain = effect_pressure_factor(design, f, v.sum(axis=1, keepdims=True))
    u = coupled_response(design, f, positions)[None] * (v * gain)[:, :, None]
    eps = interface_centre_amplitude(np.abs(u).sum(axis=1), lay.radii)
    return eps / lay.radii


def sweep_worst_amplitude(design: Design, f0: float, f1: float, amplitude: float, extra=(),
                          samples: int = 21) -> tuple[float, float, dict[str, float]]:
    """Largest eps/R a single tone of ``amplitude`` V reaches anywhere in ``f0 .. f1`` (a sweep):
    (eps/R, frequency Hz, every interface's eps/R there).

    ``samples`` log-spaced frequencies plus ``extra`` (e.g. the modes inside), the largest refined by
    golden section between its neighbours: a grid alone misses a resonance peak between its points
    (9 linear points across 100-150 kHz gave 0.672 for a peak of 0.686: optimistic).
    """
    def at(f):
        amps = interface_amplitudes(design, Drive(tones=(Tone(frequency=float(f), amplitude=amplitude),)))
        return max(amps.values(), default=0.0), amps

    best, best_f = band_maximum(lambda f: at(f)[0], f0, f1, extra, samples)
    return best, best_f, at(best_f)[1]


def band_maximum(value, f0: float, f1: float, extra=(), samples: int = 21, rtol: float = 1e-9) -> tuple[float, float]:
    """(largest ``value(f)``, its frequency Hz) over ``f0 .. f1``: ``samples`` log-spaced frequencies plus the ``extra``
    ones inside (the modes), the largest refined by golden section between its neighbours down to ``rtol``
    (:func:`sweep_worst_amplitude`; ties: the first, lowest, frequency)."""
    lo, hi = sorted((float(f0), float(f1)))
    extra = np.asarray(list(extra), float)
    fs = np.unique(np.concatenate([np.geomspace(lo, hi, max(samples, 2)) if lo > 0 else np.linspace(lo, hi, samples),
                                   extra[(extra >= lo) & (extra <= hi)]]))
    vals = [value(f) for f in fs]
    best, best_f = grid_max(value, fs, vals, iterations=40, rtol=rtol)   # ties: the first (lowest) frequency
    return best, float(best_f)
