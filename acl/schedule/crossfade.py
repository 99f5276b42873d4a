"""The drive while the renderer crossfades two segments: bounds on a force that is quadratic in the amplitudes.

At a boundary the renderer plays ``(1 - x) s_1(t) + x s_2(t)`` with ``x`` rising from 0 to 1 (a raised cosine,
acl.emit.render).  A tone present on both sides with phasors ``P`` and ``Q`` plays ``(1 - x) P + x Q``, whose
magnitude lies between ``|(1 - x) p - x q|`` and ``(1 - x) p + x q`` (``p = |P|``, ``q = |Q|``) depending on the
phase difference; a tone on one side only plays ``(1 - x) p`` or ``x q``.  Tones add in power (paper Eq. 2), so a
force ``F = sum_k g_k A_k^2`` takes, at the worst phases (a pushing tone in phase, a counter-pushing one in
anti-phase), ``f(x) = a (1 - x)^2 + 2 c x (1 - x) + b x^2`` with ``a = sum g p^2``, ``b = sum g q^2`` and
``c = sum |g| p q``: a quadratic in ``x``, maximised exactly.  Phase-independent, so it also holds for an
instrument replaying segments.csv with its own phases.  Where the phase difference ``theta`` of a kept tone is
known when the boundary is checked (a phase the user wrote on both sides, a lone tone, whose phase the compiler
does not choose) its term is ``g p q cos(theta)`` instead: two identical drives in a row do not mix at all.

Consequences: without a tone shared by both sides (``c = 0``) the force never exceeds the larger end (or zero,
when both ends pull the other way); a force
with ``g >= 0`` for every tone (a snap index ``sum u_k / Vcrit_k^2``) never does either (``c <= sqrt(a b)``,
Cauchy-Schwarz), nor does one tone alone (``|(1 - x) P + x Q| <= max(p, q)``).  Only a tone kept across the
boundary, with a counter-pushing tone that changes, can push harder than either side: the kept tone plays
throughout while the counter push dips.
"""
from __future__ import annotations

import numpy as np

FADE_POINTS = (0.25, 0.5, 0.75)     # crossfade weights sampled where no bound is exact (saturation, critical scale)


def crossfade_peak(g, p, q, cos=None) -> tuple[np.ndarray, np.ndarray]:
    """(largest force over the crossfade, its weight x) per row of ``g`` (L, K) force per V^2; ``p``, ``q`` (K,) V.

    The quadratic f(x) = a (1-x)^2 + 2 c x (1-x) + b x^2 maximised over 0 <= x <= 1 (module doc), with
    c = sum g p q cos(theta) where the phase difference theta of a tone kept across the boundary is known (``cos``
    (K,), NaN where not) and the worst phase, c = sum |g| p q, where it is not.
    """
    g = np.atleast_2d(np.asarray(g, float))
    p, q = np.asarray(p, float), np.asarray(q, float)
    kappa = np.sign(g) + (g == 0)
    if cos is not None:
        known = np.isfinite(np.asarray(cos, float))
        kappa = np.where(known[None, :], np.nan_to_num(np.asarray(cos, float))[None, :], kappa)
    a, b, c = g @ (p * p), g @ (q * q), (g * kappa) @ (p * q)
    curv = a + b - 2.0 * c                      # f(x) = a + 2 (c - a) x + curv x^2
    with np.errstate(divide="ignore", invalid="ignore"):
        xv = np.where(curv < 0, np.clip((a - c) / curv, 0.0, 1.0), 0.0)
    fv = a + 2.0 * (c - a) * xv + curv * xv * xv
    best = np.maximum(np.maximum(a, b), fv)
    x = np.where(best == fv, xv, np.where(b > a, 1.0, 0.0))
    return best, x


def crossfade_amplitudes(p, q, x: float, signs, cos=None) -> np.ndarray:
    """(K,) V: each tone's amplitude |(1-x) P + x Q| at crossfade weight ``x``: with the phase difference known
    (``cos`` (K,), NaN where not) as it is, else the worst phase for a force whose per-tone sign is ``signs``
    (>= 0: in phase, the larger amplitude (1-x) p + x q; < 0: anti-phase, |(1-x) p - x q|)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    worst = np.where(np.asarray(signs, float) >= 0, (1 - x) * p + x * q, np.abs((1 - x) * p - x * q))
    if cos is None:
        return worst
    c = np.asarray(cos, float)
    exact = np.sqrt(np.maximum(((1 - x) * p) ** 2 + 2 * x * (1 - x) * p * q * np.nan_to_num(c) + (x * q) ** 2, 0.0))
    return np.where(np.isfinite(c), exact, worst)
