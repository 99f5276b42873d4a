"""Forward model: predict every observable of every row from design + overrides + drive + coefficients + effects.

Rows are grouped by override set (one :class:`acl.fit.mechanism.Instance` each); the frequency
responses are looked up once per (instance, frequency); then every row is evaluated at once with
numpy (no per-row Python).  Base model, per row:

* thrust of actuator i: gamma tau_i(f) V^2 summed over tones (tones add in power), tau_i the thrust
  per V^2 of :mod:`acl.analysis.acoustics` relative to the reference actuator at ``f_ref``;
* single actuator: load P = thrust x (share perpendicular to the beam); deflection by paper Eq. (1);
* facing pair: paper Eq. (3) with attraction positive, P(d) = alpha a(f) V^2/d^2 - (thrust_a + thrust_b)
  (own thrust plus the drag of the partner's jet, F_AS = F_d as the paper assumes), each beam
  deflecting by Eq. (1); the stable equilibrium d = d0 - delta_a - delta_b reached from the rest gap,
  or contact (d = 0) past snap-in.  Solved by a vectorized bracket search and bisection.

Effects (acl.fit.effects) modify these steps; each modifier below cites its source.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.fit import beam as B

N_GRID = 32
N_BISECT = 30


@dataclass
class Prepared:
    """Row-aligned arrays for the forward model (built once per data set)."""

    n: int
    f: np.ndarray            # (n, T) Hz (0 where no tone)
    v: np.ndarray            # (n, T) V peak
    tau: np.ndarray          # (2, n, T) relative thrust of actuators 0, 1
    arel: np.ndarray         # (n, T) relative Bjerknes coefficient
    pair: np.ndarray         # (n,) bool
    L: np.ndarray            # (2, n)
    l: np.ndarray            # (2, n)
    EI: np.ndarray           # (2, n)
    cd: np.ndarray           # (2, n) Eq. (1) integrals at declared uniform stiffness
    ct: np.ndarray           # (2, n)
    height: np.ndarray       # (2, n)
    proj: np.ndarray         # (n,) thrust share perpendicular to the beam (single)
    d0: np.ndarray           # (n,) rest gap (pair)
    base: np.ndarray         # (n,) observable = base + s0 delta_0 + s1 delta_1
    s0: np.ndarray
    s1: np.ndarray
    fn: np.ndarray           # (2, n) natural frequency of each actuator
    q: np.ndarray            # (2, n) its quality factor
    t: np.ndarray            # (n,) time (s), 0 where not given
    f_ref: float
    gamma0: float            # thrust per V^2 of the reference actuator at f_ref (design value)
    alpha0: float            # Bjerknes coefficient at f_ref (design or physics)
    E0: float                # declared Young's modulus of the first beam
    vmax: float
    instances: dict          # override key -> Instance


def prepare(data, load_instance, f_ref: float | None = None) -> Prepared:
    """Build the row arrays; ``load_instance(key)`` returns the Instance of an override set."""
    from acl.fit.mechanism import alpha_per_v2, thrust_per_v2

    n = data.n
    T = max(1, max((len(t) for t in data.tones), default=1))
    f = np.zeros((n, T))
    v = np.zeros((n, T))
    for i, tones in enumerate(data.tones):
        for k, (fk, vk) in enumerate(tones):
            f[i, k], v[i, k] = fk, vk
    if f_ref is None:
        used = f[v > 0]
        vals, counts = np.unique(used, return_counts=True) if used.size else (np.array([1e5]), np.array([1]))
        top = vals[counts == counts.max()]
        f_ref = float(top[np.argmin(np.abs(top - np.median(used)))]) if used.size else 1e5
    keys = [data.override_key(i) for i in range(n)]
    instances = {}
    for key in dict.fromkeys(keys):
        instances[key] = load_instance(key)
    ref = instances[keys[0]]
    gamma0 = float(thrust_per_v2(ref, f_ref)[0])
    alpha_ref = alpha_per_v2(ref, f_ref) if ref.kind == "pair" else 0.0
    arr = {k: np.zeros((2, n)) for k in ("L", "l", "EI", "height", "fn", "q")}
    arr["L"][:] = 1.0
    arr["EI"][:] = 1.0
    tau = np.zeros((2, n, T))
    arel = np.zeros((n, T))
    pair = np.zeros(n, bool)
    proj = np.ones(n)
    d0 = np.full(n, np.nan)
    base, s0, s1 = np.zeros(n), np.zeros(n), np.zeros(n)
    by_key: dict = {}
    for i, key in enumerate(keys):
        by_key.setdefault(key, []).append(i)
    for key, rows in by_key.items():
        inst = instances[key]
        rows = np.asarray(rows)
        k = len(inst.capsules)
        for name, src in (("L", inst.L), ("l", inst.l), ("EI", inst.EI), ("height", inst.height)):
            arr[name][:k, rows] = src[:, None]
        arr["fn"][:k, rows] = inst.modes[:, 0][:, None]
        arr["q"][:k, rows] = inst.modes[:, 1][:, None]
        pair[rows] = inst.kind == "pair"
        proj[rows] = inst.proj[0]
        d0[rows] = inst.d0
        for fk in np.unique(f[rows][v[rows] > 0]):
            m = (f[rows] == fk) & (v[rows] > 0)
            tp = thrust_per_v2(inst, fk) / gamma0
            for c in range(k):
                tau[c, rows] += m * tp[c]
            if inst.kind == "pair" and alpha_ref:
                arel[rows] += m * alpha_per_v2(inst, fk) / alpha_ref
        for name in set(data.observable[rows]):
            b, a0, a1 = inst.output_map(inst.design.observe(name))
            sel = rows[data.observable[rows] == name]
            base[sel], s0[sel], s1[sel] = b, a0, a1
    cd, ct = B.stiffness_integrals(arr["L"], arr["l"], arr["EI"])
    alpha0 = _alpha0(ref, alpha_ref)
    t = np.where(np.isfinite(data.time), data.time, 0.0)
    return Prepared(n, f, v, tau, arel, pair, arr["L"], arr["l"], arr["EI"], cd, ct, arr["height"], proj, d0,
                    base, s0, s1, arr["fn"], arr["q"], t, f_ref, gamma0, alpha0, float(ref.E[0]),
                    float(max(v.sum(axis=1).max(), 1e-9)), instances)


def _alpha0(inst, alpha_ref: float) -> float:
    """Design value of alpha: a parameter named `alpha`, else the physics prediction at f_ref."""
    for p in inst.design.params:
        if p.name == "alpha":
            return float(p.value)
    return float(alpha_ref) if alpha_ref > 0 else 1.745e-19   # paper Eq. (3): 174.5 nN um^2/V^2


# ----------------------------------------------------------------------------------------------
# Effect modifiers (each one formula, its source in the docstring)
# ----------------------------------------------------------------------------------------------

# The formulas live in acl.physics.effects (the analysis applies the same ones to declared effects).
from acl.physics.effects import (drag_load, elastica_blend, gain_tilt, saturation,  # noqa: E402,F401
                                 shrinkage_factor, substrate_factor)


# ----------------------------------------------------------------------------------------------
# Prediction
# ----------------------------------------------------------------------------------------------

def predict(P: Prepared, coeffs: dict, effects: dict) -> np.ndarray:
    """Predicted value (SI) of every row.  ``coeffs``: gamma, alpha, e_scale, gain (absent = design value);
    ``effects``: effect id -> {param: value} (internal coordinates, acl.fit.effects)."""
    with np.errstate(all="ignore"):
        return _predict(P, coeffs, effects)


def _predict(P: Prepared, coeffs: dict, effects: dict) -> np.ndarray:
    gamma = coeffs.get("gamma", P.gamma0)
    alpha = coeffs.get("alpha", P.alpha0)
    e_scale = coeffs.get("e_scale", 1.0)
    gain = coeffs.get("gain", 1.0)
    v2 = P.v * P.v
    g2 = np.full(P.v.shape, gain * gain)
    if "transducer_gain" in effects:
        g2 = g2 * gain_tilt(P.f, P.f_ref, effects["transducer_gain"]["gain_slope"]) ** 2
    if "drive_saturation" in effects:
        vtot = P.v.sum(axis=1, keepdims=True)
        g2 = g2 * saturation(vtot, effects["drive_saturation"]["inv_vsat2"]) ** 2
    w = v2 * g2
    thrust = np.empty((2, P.n))
    sub = np.ones((2, P.n))
    if "substrate_proximity" in effects:
        sub = substrate_factor(P.height, effects["substrate_proximity"]["h_substrate"])
    shrink = [np.ones_like(w), np.ones_like(w)]
    for c in range(2):
        if "bubble_shrinkage" in effects:
            shrink[c] = shrinkage_factor(P.f, P.fn[c][:, None], P.q[c][:, None], P.t[:, None],
                                         effects["bubble_shrinkage"]["shrink_rate"])
        thrust[c] = gamma * (P.tau[c] * w * shrink[c]).sum(axis=1) * sub[c]
    es = e_scale * (effects["stiffness_scale"]["e_scale"] if "stiffness_scale" in effects else 1.0)
    if "stiffness_gradient" in effects:
        cd, ct = B.stiffness_integrals(P.L, P.l, P.EI * es, effects["stiffness_gradient"]["e_gradient"])
    else:
        cd, ct = P.cd / es, P.ct / es
    lam = effects["large_deflection"]["elastica_weight"] if "large_deflection" in effects else 0.0

    def rows(idx):
        """Deflection laws of beams 0 and 1 restricted to rows ``idx`` (one law when both beams are alike)."""
        arrs = [(P.l[c, idx], cd[c, idx], ct[c, idx], P.L[c, idx], P.EI[c, idx] * es) for c in range(2)]

        def make(l_, cd_, ct_, L_, EI_):
            if lam:
                return lambda load: elastica_blend(B.eq1_deflection(load, l_, cd_, ct_),
                                                   B.elastica_deflection(load, L_, l_, EI_), lam)
            return lambda load: B.eq1_deflection(load, l_, cd_, ct_)

        first = make(*arrs[0])
        same = all(np.array_equal(a, b) for a, b in zip(arrs[0], arrs[1]))
        return first, (first if same else make(*arrs[1])), same

    d_0 = np.zeros(P.n)
    d_1 = np.zeros(P.n)
    single = ~P.pair
    if np.any(single):
        idx = np.flatnonzero(single)
        law0, _, _ = rows(idx)
        load = thrust[0, idx] * P.proj[idx]
        if "neighbour_drag" in effects and effects["neighbour_drag"]["inv_plateau"] > 0:
            d_0[idx] = _drag_equilibrium(law0, load, effects["neighbour_drag"]["inv_plateau"])
        else:
            d_0[idx] = law0(load)
    if np.any(P.pair):
        idx = np.flatnonzero(P.pair)
        law0, law1, same = rows(idx)
        sub_ab = np.sqrt(sub[0, idx] * sub[1, idx])
        # Bjerknes force ~ product of the two volume amplitudes: geometric mean of the per-bubble factors
        a_rad = alpha * (P.arel[idx] * w[idx] * np.sqrt(shrink[0][idx] * shrink[1][idx])).sum(axis=1) * sub_ab
        push = thrust[0, idx] + thrust[1, idx]
        da, db = _pair_equilibrium(law0, law1, a_rad, push, P.d0[idx], same)
        d_0[idx], d_1[idx] = da, db
    out = P.base + P.s0 * d_0 + P.s1 * d_1
    if "offset_drift" in effects:
        e = effects["offset_drift"]
        out = out + e["offset"] + e["drift"] * P.t
    return out


def _drag_equilibrium(law, load, c_p):
    """delta = law(P (1 - c_p delta)) on [0, law(P)]: bisection (the residual decreases in delta)."""
    lo = np.zeros_like(load)
    hi = np.minimum(law(load), 1.0 / c_p)
    for _ in range(N_BISECT):
        mid = 0.5 * (lo + hi)
        r = law(drag_load(load, mid, c_p)) - mid
        lo = np.where(r > 0, mid, lo)
        hi = np.where(r > 0, hi, mid)
    return 0.5 * (lo + hi)


def _pair_equilibrium(law0, law1, a_rad, push, d0, same=False):
    """Stable gap of a facing pair under P(d) = a/d^2 - b, first root of d0 - d - delta_a - delta_b from d0.

    Bracketed on a grid from d0 (towards contact when the pair attracts at rest, outwards up to the
    largest repulsive opening otherwise), then bisection and a final secant step inside the bracket.
    Returns (delta_a, delta_b); past snap-in (no root before contact) the pair is in contact, d = 0.
    """
    def both(load):
        da = law0(load)
        return da, (da if same else law1(load))

    def g(d):
        da, db = both(a_rad / (d * d) - push)
        return d0 - d - da - db

    attract = a_rad / (d0 * d0) - push >= 0
    ra, rb = both(-push)
    far = np.where(attract, 0.02 * d0, d0 - ra - rb + 1e-12)
    prev = d0.copy()
    g_prev = g(prev)
    lo = prev.copy()
    hi = prev.copy()
    g_lo = g_prev.copy()
    found = g_prev == 0
    for sk in np.linspace(0.0, 1.0, N_GRID + 1)[1:]:
        d = d0 + sk * (far - d0)
        gd = g(d)
        cross = ~found & (np.sign(gd) != np.sign(g_prev))
        lo = np.where(cross, prev, lo)
        g_lo = np.where(cross, g_prev, g_lo)
        hi = np.where(cross, d, hi)
        found |= cross
        prev, g_prev = d, gd
    a, b, ga = lo, hi, g_lo
    for _ in range(N_BISECT):
        m = 0.5 * (a + b)
        gm = g(m)
        same_sign = np.sign(gm) == np.sign(ga)
        a, ga = np.where(same_sign, m, a), np.where(same_sign, gm, ga)
        b = np.where(same_sign, b, m)
    gb = g(b)
    denom = gb - ga
    sec = np.where(denom != 0, a - ga * (b - a) / np.where(denom != 0, denom, 1.0), 0.5 * (a + b))
    lo_ab, hi_ab = np.minimum(a, b), np.maximum(a, b)
    d = np.where(found, np.clip(sec, lo_ab, hi_ab), d0)
    load = a_rad / (d * d) - push
    da, db = both(load)
    return np.where(found, da, 0.5 * d0), np.where(found, db, 0.5 * d0)
