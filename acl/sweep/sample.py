"""Points of one chunk of a sweep: {parameter name: SI values}, the same whatever runs the chunk.

Point k of a sweep is grid point ``k // samples`` (axes in C order, the first slowest) and Monte
Carlo draw ``k % samples``.  The draws of chunk c come from
``np.random.Generator(PCG64(SeedSequence([seed, c])))``: a chunk needs nothing from the others, so a
cluster, a process pool or one process give identical rows for the same seed and chunk size.

Spreads (acl.design.model.Spread) are sampled by one function for the design's declared spreads and
``--tolerance`` ones: standard normals z (correlated through the Cholesky factor of the design's
``correlation(a, b)`` matrix) become ``value + mean + sd z`` (normal) or
``value + lo + (hi - lo) Phi(z)`` (uniform, a Gaussian copula so correlations carry over) or
``value exp(s z - s^2/2)``, ``s^2 = ln(1 + b^2)`` (log-normal: a parameter ``lognormal(p)`` names); relative
spreads scale by ``|value|``.
"""
from __future__ import annotations

import numpy as np

from acl.sweep.spec import SweepSpec


def chunk_range(spec: SweepSpec, chunk: int, chunk_size: int) -> tuple[int, int]:
    """[start, stop) point indices of ``chunk``."""
    start = chunk * chunk_size
    return start, min(start + chunk_size, spec.n_points)


def chunk_points(spec: SweepSpec, chunk: int, chunk_size: int, spread: bool = True) -> dict[str, np.ndarray]:
    """{parameter: SI values} of the points of ``chunk``; deterministic per (seed, chunk).

    ``spread=False``: the values the points are drawn about (the grid's or the nominal), before the
    tolerances move them: what a `free` range bounds (acl.sweep.validity.mark_outside_free_ranges)."""
    start, stop = chunk_range(spec, chunk, chunk_size)
    k = np.arange(start, stop, dtype=np.int64)
    g = k // spec.samples
    out = {n: np.full(k.size, spec.nominal[n], dtype=float) for n in spec.names}
    if spec.axes:
        idx = np.unravel_index(g, spec.grid_shape)
        for a, i in zip(spec.axes, idx):
            out[a.name] = a.values[i].astype(float)
    if spread and spec.montecarlo and spec.tolerances:
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([spec.seed, chunk])))
        z = rng.standard_normal((k.size, len(spec.tolerances)))
        if spec.correlation is not None:
            z = z @ _cholesky(spec.correlation).T
        for j, t in enumerate(spec.tolerances):
            out[t.name] = apply_spread(t.spread, out[t.name], z[:, j])
    return out


def apply_spread(spread, value: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``value`` moved by the spread at standard normal draws ``z`` (module docstring)."""
    scale = np.abs(value) if spread.relative else 1.0
    if spread.kind == "normal":
        return value + (spread.a + spread.b * z) * scale
    if spread.kind == "lognormal":
        s2 = np.log1p(spread.b ** 2)                  # mean ``value``, relative sd ``b`` (acl.schedule.bands.log_moments)
        return value * np.exp(np.sqrt(s2) * z - 0.5 * s2)
    from scipy.special import ndtr

    return value + (spread.a + (spread.b - spread.a) * ndtr(z)) * scale


def _cholesky(corr: np.ndarray) -> np.ndarray:
    """Lower factor of a correlation matrix; positive semidefinite ones (|r| = 1) through eigenvalues."""
    try:
        return np.linalg.cholesky(corr)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(corr)
        return v * np.sqrt(np.clip(w, 0.0, None))
