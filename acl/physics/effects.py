"""Formulas of the effect library (docs/fit.md), shared by the fit's forward model and the analysis.

Pure numpy, SI.  :mod:`acl.fit.forward` applies them row-wise to measured data;
:mod:`acl.analysis.acoustics` and :mod:`acl.analysis.mechanics` apply them to a design that declares
``effect ID { ... }``.  One implementation of each formula, its source in its docstring.
"""
from __future__ import annotations

import numpy as np

from acl.physics import cantilever as CB


def gain_tilt(f, f_ref, slope):
    """Pressure gain factor exp(s (f - f_ref)/f_ref), held beyond 2 f_ref: smooth tilt of the transducer transfer function (paper Fig. S1)."""
    # A tilt is a smooth deviation across the transducer's band, narrower than an octave (85 .. 150 kHz in Fig. S1):
    # beyond f = 2 f_ref it is held (like the table, flat outside it), so exp never overflows at the analysis'
    # out-of-band frequencies (a 20 .. 400 kHz selectivity sweep, coupled modes in MHz); f >= 0 keeps the
    # relative offset >= -1 already.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        x = np.minimum(np.asarray(f, float) / f_ref - 1.0, 1.0)
    return np.exp(slope * x)


def saturation(vtot, inv_vsat2):
    """Pressure factor 1/sqrt(1 + (V/V_s)^2) of a saturating drive (soft limiter; paper Fig. 2e is its linear part)."""
    return 1.0 / np.sqrt(1.0 + inv_vsat2 * vtot * vtot)


def transducer_resonance(f, f_ref, inv_ratio, q):
    """Pressure gain |H(f)|/|H(f_ref)| of a second-order transducer resonance H = 1/(1 - (f/f_t)^2 + i f/(f_t Q_t)), u = f_ref/f_t (u = 0: flat; Kinsler et al., Fundamentals of Acoustics, driven oscillator)."""
    def h2(x):
        a = inv_ratio * x / f_ref
        return 1.0 / ((1.0 - a * a) ** 2 + (a / q) ** 2)
    return np.sqrt(h2(f) / h2(f_ref))


def mode_response_ratio(f, fn0, q0, fn, q):
    """|H(f; f_n, Q)|^2 / |H(f; f_n0, Q0)|^2 of the first bubble mode (one-mode term of acl.physics.resonance.volume_response)."""
    def h2(fr, qq):
        return 1.0 / ((fr * fr - f * f) ** 2 + (f * fr / qq) ** 2)
    return h2(fn, q) / h2(fn0, q0)


def shrunk_frequency(fn0, volume, radius, density, surface_tension, ambient_pressure, polytropic_index, rate, t):
    """First natural frequency after the gas volume shrank to V0 exp(-r t): f_n0 f(V(t))/f(V0) with f the Rayleigh-Ritz resonance of acl.physics.resonance (paper Fig. 1e model)."""
    from acl.physics.resonance import single_orifice_frequencies

    ok = volume > 0
    v0 = np.where(ok, volume, 1.0)
    r = np.where(ok, radius, 1.0)
    args = (density, surface_tension, ambient_pressure, polytropic_index)
    f0 = single_orifice_frequencies(v0, r, *args)
    ft = single_orifice_frequencies(v0 * np.exp(-rate * t), r, *args)
    return np.where(ok, fn0 * ft / f0, fn0)


def volume_frequency_table(volume, radius, density, surface_tension, ambient_pressure, polytropic_index, n=241, span=8.0):
    """(ln x, ln f(x V0)/f(V0)) on x in [e^-span, e^span]: the first natural frequency of a single-orifice capsule vs its
    gas volume (acl.physics.resonance.single_orifice_frequencies, paper Fig. 1e model), for fast interpolation."""
    from acl.physics.resonance import single_orifice_frequencies

    lx = np.linspace(-span, span, n)
    f = single_orifice_frequencies(volume * np.exp(lx), radius, density, surface_tension, ambient_pressure,
                                   polytropic_index)
    f0 = single_orifice_frequencies(volume, radius, density, surface_tension, ambient_pressure, polytropic_index)
    return lx, np.log(f / f0)


def capsule_volume_frequency_table(volume, radii, target_hz, density, surface_tension, ambient_pressure, polytropic_index,
                                   n=241, span=8.0):
    """(ln x, ln f_k(x V0)/f_k(V0)) of the undamped mode k of a multi-orifice capsule nearest ``target_hz`` at V0, vs the
    gas volume (Rayleigh-Ritz K x = w^2 M x, acl.physics.resonance.capsule_matrices; k kept by its rank), for shrinkage."""
    from scipy.linalg import eigh

    from acl.physics.resonance import capsule_matrices

    def freqs(v):
        k, m, _, _ = capsule_matrices(v, radii, density, surface_tension, ambient_pressure, polytropic_index)
        return np.sqrt(np.abs(eigh(k, m, eigvals_only=True))) / (2 * np.pi)

    mode = int(np.argmin(np.abs(np.log(freqs(volume) / target_hz))))
    lx = np.linspace(-span, span, n)
    f = np.empty(n)
    for i, x in enumerate(lx):
        f[i] = freqs(volume * np.exp(x))[mode]
    f0 = np.interp(0.0, lx, f)
    return lx, np.log(f / f0)


def elastica_blend(d_eq1, d_elastica, weight):
    """(1 - w) paper Eq. (1) + w dead-load elastica (Bisshopp & Drucker 1945): w = 1 is the large-deflection beam."""
    return (1.0 - weight) * d_eq1 + weight * d_elastica


def drag_load(load, delta, inv_plateau):
    """P (1 - delta/delta_p), floored at 0: drag of a neighbour's jet growing with penetration (paper Fig. 5b plateau; phenomenological)."""
    return load * np.clip(1.0 - inv_plateau * delta, 0.0, None)


def bjerknes_gap_factor(d, d_ref, n):
    """Calibrated gap shape (d_ref/d)^n on the secondary Bjerknes force at centre distance d (paper Fig. S5; n = 0 keeps the monopole law)."""
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        return (d_ref / np.asarray(d, float)) ** n


def substrate_factor(z, h):
    """Force factor 1 - exp(-z/h) near a rigid wall (image-source weakening, Leighton, The Acoustic Bubble, ch. 4; phenomenological)."""
    with np.errstate(divide="ignore", over="ignore"):
        return np.where(h > 0, 1.0 - np.exp(-z / np.maximum(h, 1e-300)), 1.0)


def effective_beam_deflection(P, L, l, EI, e_scale=1.0, gradient=0.0, weight=0.0):
    """Load-point deflection of a cantilever with E scaled, E graded along it and the elastica blended (paper Eq. (1), Suppl. Note 2; Bisshopp & Drucker 1945)."""
    ei = EI * e_scale
    c_d, c_t = CB.stiffness_integrals(L, l, ei, gradient)
    d = CB.eq1_deflection(P, l, c_d, c_t)
    if np.any(weight):                   # a float, or one per row of a batch
        d = elastica_blend(d, CB.elastica_deflection(P, L, l, ei), weight)
    return d


def effective_beam_force(delta, L, l, EI, e_scale=1.0, gradient=0.0, weight=0.0):
    """(load P, tangent dP/d delta) giving load-point deflection ``delta``: inverse of :func:`effective_beam_deflection` (Brent, secant tangent)."""
    delta = float(delta)
    if delta <= 0.0:
        d1 = float(effective_beam_deflection(1e-30, L, l, EI, e_scale, gradient, weight))
        return 0.0, 1e-30 / d1
    def defl(p):
        return float(effective_beam_deflection(p, L, l, EI, e_scale, gradient, weight))
    k0 = 1e-30 / defl(1e-30)                       # small-load stiffness
    lo, hi = 0.0, k0 * delta
    d_hi, d_prev = defl(hi), None
    for _ in range(200):                           # Eq. (1) and the elastica stiffen: expand the bracket
        if d_hi >= delta:
            break
        if d_prev is not None and d_hi <= d_prev * (1.0 + 1e-12):
            # the law saturated (the elastica near its reach): delta is beyond it; a wall as stiff as 200 doublings
            # would give, found without the 200 evaluations (a soft beam made every solve take seconds)
            P = k0 * delta * 2.0 ** 200
            return P, P / delta
        lo, hi, d_prev = hi, 2.0 * hi, d_hi
        d_hi = defl(hi)
    if d_hi >= delta:
        from scipy.optimize import brentq           # ~10 evaluations where bisection to 1e-13 took ~45

        P = float(brentq(lambda p: defl(p) - delta, lo, hi, xtol=1e-300, rtol=1e-13))
    else:
        P = hi
    if not P > 0.0:
        return P, k0
    for rel in (1e-6, 1e-4, 1e-2):                 # a saturated law (the full elastica near its reach) is flat in
        h = rel * P                                # double precision at a small step: widen it, never divide by 0
        dd = defl(P + h) - defl(P - h)
        if dd > 0.0:
            return P, 2 * h / dd
    return P, max(P / delta, k0)                   # still flat: the secant from the origin (finite, stiff)


# The one table of declared effects lives in acl.physics.effect_table (no numpy: `acl check` reads it).
from acl.physics.effect_table import EFFECT_TABLE  # noqa: E402,F401
