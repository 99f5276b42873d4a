"""The 95 % band's cause and cure: which declared uncertainty dominates it, and which bench measurement narrows it.

A follow goal's band (:func:`acl.schedule.bands.error_band`) comes from draws of the declared uncertainty.  This
module linearises the same forward model around the nominal design, one direction per independent source (each
transducer gain-table point, log-normal with the declared relative sd; each uncertain parameter, 1 sd), so that

* :func:`explain` attributes the band's variance to the sources (first-order variance decomposition: each source's
  share of the expected squared tracking error, ``sum_i |J_ij|^2 / sum_ij |J_ij|^2`` with ``J`` the path's
  sensitivity per 1 sd; correlations between parameters are left out of the shares, not of the bands), checks the
  linearised band against the Monte Carlo one, and
* designs the experiment that narrows it: candidate readings are the capsule's static displacement (x, y) under one
  tone at one voltage, read with an assumed noise (:data:`READING_NOISE_M` per axis); each reading's Fisher
  information ``H^T H / sigma^2`` (``H``: its sensitivity per 1 sd) updates the prior covariance (Kalman form,
  ``S' = S - S H^T (H S H^T + sigma^2 I)^-1 H S``), and readings are chosen greedily to minimise the expected squared
  tracking error ``tr(J S' J^T)`` (A-optimal for the path; Atkinson, Donev & Tobias, *Optimum Experimental
  Designs*, 2007, ch. 10).  The band promised after the chosen readings (:func:`promise`) is the 95th percentile of
  the error a recompile with the measured values leaves, over devices drawn from the prior, each read with the
  stated noise and fitted as ``acl fit --free gain`` fits it (the gain at each read tone): the Fisher information of
  a reading is taken at the drawn device's own gain, since a device with a lower gain moves less under the proposed
  voltage and is measured worse (``tr(J S' J^T)`` at the nominal design alone, kept as ``nominal_rms_p95_m``, left
  the lab's loop outside the promise more often than one in twenty; issue 28).

Numbers only; the compiler stores them in the goal's ``details["band"]`` and a note.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from acl.design.model import Design
from acl.schedule import bands
from acl.units import shown_unit

# Assumed noise of one reading (m, per axis): a capsule's position tracked in a video over a held tone, averaged
# over about 30 frames (acl track's synthetic error is 0.01 px RMS per frame; 0.1 um leaves room for drift and
# the pixel scale).  Stated with every proposal; `acl compile --reading-noise` sets another.
READING_NOISE_M = 0.1e-6
STEP = 0.5                 # finite-difference step, in sds (central differences)
MAX_READINGS = 4           # at most this many readings proposed
DRAWS = 4000               # draws of the linearised band (and of the truths behind the promise, :func:`promise`)
TOP = 3                    # sources listed (largest shares first)
# the truth's log gain over the nominal at a read tone, where a reading's information is evaluated (:func:`promise`):
# +-1.5 is 5 sd of a 30 % table point; a truth beyond it is read as at its end
GAIN_GRID = np.linspace(-1.5, 1.5, 13)


Many = Callable[[list, list, np.ndarray], list]     # (designs, tones Hz, u (N, K) V^2) -> [(N, 2) m or exception]


def directions(design: Design, reload=None) -> tuple[list, np.ndarray]:
    """([(label, kind, frequency Hz or None, sd, make(t) -> Design)], prior correlation (D, D)) of the declared sources.

    ``make(t)``: the design moved by ``t`` sds along the source (a gain-table point times ``exp(s t)``; a parameter by
    ``t`` sd).  The prior of the moves is N(0, R): independent gain points, the parameters' declared correlation."""
    unc = bands.declared(design, with_params=reload is not None)
    out = []
    if unc.gain_sd > 0 and design.transducer is not None:
        sds = unc.gain_sds
        t = design.transducer
        fs = list(t.gain_frequencies) + [f for f, _ in unc.pinned]
        for j in range(unc.n_table):
            def make(x, j=j):
                f = np.ones(unc.n_table)
                f[j] = np.exp(sds[j] * x)
                return bands._with_gain(design, f)
            measured = j >= len(t.gain_frequencies)
            label = (f"transducer gain at {fs[j] / 1e3:g} kHz ("
                     + ("measured" if measured else "table point") + f", {sds[j]:.0%})")
            out.append((label, "gain", float(fs[j]), float(sds[j]), make))
    P = len(unc.names)
    sd = np.sqrt(np.maximum(np.diag(unc.cov), 0.0)) if P else np.zeros(0)
    for i, name in enumerate(unc.names):
        if sd[i] <= 0:
            continue

        def make(x, i=i):
            theta = unc.mean.copy()
            theta[i] = theta[i] + x * sd[i]
            return bands._with_params(design, unc, theta, reload)
        k, unit = shown_unit(unc.units[i])
        out.append((f"parameter {name} (+- {sd[i] * k:.3g} {unit})".replace("  ", " "), "parameter", None,
                    float(sd[i]), make))
    D = len(out)
    R = np.eye(D)
    keep = [i for i in range(P) if sd[i] > 0]
    if keep:
        C = unc.cov[np.ix_(keep, keep)]
        s = sd[keep]
        R[D - len(keep):, D - len(keep):] = C / np.outer(s, s)
    if unc.pair:        # a first-principles pair force, independent of the rest (acl.schedule.bands.pair_move)
        from acl.physics.constants import PAIR_SCALE_ROWS

        lo, hi = min(r for _, r in PAIR_SCALE_ROWS), max(r for _, r in PAIR_SCALE_ROWS)
        out.append((f"{bands.PAIR_SOURCE} (no bjerknes_scale: measured pairs {lo:.3g}-{hi:.3g}x, "
                    f"x{np.exp(bands.pair_rms_log()):.3g} at 1 sd)", "pair", None, bands.pair_rms_log(),
                    lambda x: bands.pair_move(design, x)))
        R = np.pad(R, ((0, 1), (0, 1)))
        R[-1, -1] = 1.0
    return out, R


_PREPARED: list = []     # [(design, reload, (dirs, R, moved))], newest first: the last few designs


def prepared(design: Design, reload=None) -> tuple[list, np.ndarray, list]:
    """(dirs, R) of :func:`directions` and the designs the central differences of :func:`sensitivity` move to (``+STEP``,
    ``-STEP`` per source; None where the move fails), made once per design (by identity): the compiler re-simulates
    them with the band's draws in one batch, and :func:`explain` reuses them for every candidate reading."""
    for d, r, hit in _PREPARED:
        if d is design and r is reload:
            return hit
    dirs, R = directions(design, reload)
    hit = (dirs, R, _moves(dirs))
    _PREPARED[:] = ([(design, reload, hit)] + _PREPARED)[:2]
    return hit


def _moves(dirs) -> list:
    moved = []
    for _, _, _, _, make in dirs:
        for x in (STEP, -STEP):
            try:
                moved.append(make(x))
            except (ValueError, KeyError):
                moved.append(None)
    return moved


def sensitivity(design: Design, dirs, many: Many, tones, u_rows: np.ndarray, moved=None) -> tuple[np.ndarray, np.ndarray]:
    """(nominal (N, 2), J (N, 2, D)): the prediction and its derivative per 1 sd of each source (central differences
    of ``STEP`` sd; a move whose model fails counts as no sensitivity there).  ``moved``: the moved designs
    (:func:`prepared`), made here when not given."""
    moved = _moves(dirs) if moved is None else moved
    live = [k for k, d in enumerate(moved) if d is not None]
    return _sensitivity_of(many([design, *[moved[k] for k in live]], list(tones), u_rows), dirs, moved, live)


def _sensitivity_of(got: list, dirs, moved, live) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sensitivity` from the predictions ``got`` of the nominal design and the moves ``live`` (indices into
    ``moved``), in that order."""
    nominal = got[0]
    if isinstance(nominal, Exception):
        raise nominal
    nominal = np.asarray(nominal, float)
    preds: list = [None] * len(moved)
    for k, g in zip(live, got[1:]):
        preds[k] = None if isinstance(g, Exception) else np.asarray(g, float)
    J = np.zeros((*nominal.shape, len(dirs)))
    for j in range(len(dirs)):
        a, b = preds[2 * j], preds[2 * j + 1]
        if a is not None and b is not None:
            J[..., j] = np.nan_to_num((a - b) / (2 * STEP))
    return nominal, J


def linear_band(e0: np.ndarray, J: np.ndarray, S: np.ndarray, disc: float = 0.0, seed: int = 0) -> tuple[float, float]:
    """(RMS, max) 95th percentiles of the tracking error ``e0 + J z``, ``z ~ N(0, S)`` (plus ``disc`` per axis)."""
    rng = np.random.default_rng([seed, 28])
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    L = V * np.sqrt(np.maximum(w, 0.0))
    z = rng.standard_normal((DRAWS, S.shape[0])) @ L.T                     # (DRAWS, D)
    err = e0[None] + np.einsum("nad,sd->sna", J, z)
    if disc > 0:
        err = err + rng.normal(0.0, disc, err.shape)
    r = np.sqrt(err[..., 0] * err[..., 0] + err[..., 1] * err[..., 1])       # |err| (x, y): norm's sum, 10x faster
    return float(np.percentile(np.sqrt(np.mean(r ** 2, axis=1)), 95)), float(np.percentile(r.max(axis=1), 95))


def update(S: np.ndarray, H: np.ndarray, noise: float) -> np.ndarray:
    """Posterior covariance after a reading ``y = H z + e``, ``e ~ N(0, noise^2 I)`` (Kalman form)."""
    G = H @ S @ H.T + noise ** 2 * np.eye(H.shape[0])
    K = S @ H.T @ np.linalg.solve(G, np.eye(H.shape[0]))
    return S - K @ H @ S


def gain_map(design: Design, freqs, reload=None) -> tuple[np.ndarray, np.ndarray]:
    """(g0 (F,) Pa/V, A (F, G)): the transducer gain at each of ``freqs`` as ``g0 + A (exp(s z) - 1)`` for moves
    ``z`` of the gain sources of :func:`directions` (table points, then measured tones; linear interpolation of the
    table, paper Fig. S1: exact, except where a calibration anchors the table to its fitted gain, bands._anchor:
    linearised)."""
    from acl.physics.transducer import pressure_per_volt

    n = bands.declared(design, with_params=reload is not None).n_table
    f = np.asarray(freqs, float)

    def at(factors):
        t = bands._with_gain(design, factors).transducer
        return np.asarray(pressure_per_volt(f, t.gain_frequencies, t.gain_pa_per_v)[0], float)

    g0 = at(np.ones(n))
    return g0, (np.column_stack([at(1.0 + e) - g0 for e in np.eye(n)]) if n else np.zeros((f.size, 0)))


def gain_scaled(design: Design, c: float) -> Design:
    """The design with its whole gain table times ``c`` (a truth whose gain is ``c`` x the nominal at every tone)."""
    t = design.transducer
    return design.model_copy(update={"transducer": t.model_copy(
        update={"gain_pa_per_v": tuple(float(g * c) for g in t.gain_pa_per_v)})})


_READ_MEMO: list = []     # [(design, {(tone Hz, volts): (X,) |dy/dlog g|^2 m^2 on GAIN_GRID})], newest first


def reading_slopes(design: Design, many: Many, readings) -> dict:
    """{(tone Hz, volts): (X,) squared length of the reading's derivative per log gain, ``|dy/dlog g|^2`` m^2, on a
    truth whose gain is ``exp(x)`` x the nominal there (x on GAIN_GRID)}: one batch of gain-scaled designs (their gain
    table times exp(x): the static displacement's slope at the drive the truth feels).  A grid point
    without an equilibrium gives no information (0)."""
    from scipy.interpolate import CubicSpline

    memo = next((m for d, m in _READ_MEMO if d is design), None)
    if memo is None:
        memo = {}
        _READ_MEMO[:] = ([(design, memo)] + _READ_MEMO)[:2]
    want = sorted({(float(f), float(v)) for f, v in readings if (float(f), float(v)) not in memo})
    if want:
        # one batch: every reading a row that drives its own tone alone (the others at zero amplitude)
        fs = sorted({f for f, _ in want})
        u = np.array([[v * v if g == f else 0.0 for g in fs] for f, v in want])
        try:
            got = many([gain_scaled(design, float(np.exp(x))) for x in GAIN_GRID], fs, u)
        except (ValueError, KeyError, FloatingPointError):
            got = [None] * GAIN_GRID.size
        Y = np.stack([np.full((len(want), 2), np.nan) if g is None or isinstance(g, Exception) else np.asarray(g, float)
                      for g in got])                                          # (X, R, 2)
        for r, key in enumerate(want):
            ok = np.all(np.isfinite(Y[:, r]), axis=1)
            if ok.all():          # the cubic spline's derivative (a gap: no equilibrium there, no information)
                memo[key] = np.sum(CubicSpline(GAIN_GRID, Y[:, r], axis=0)(GAIN_GRID, 1) ** 2, axis=1)
            else:
                with np.errstate(invalid="ignore"):
                    memo[key] = np.nan_to_num(np.sum(np.gradient(Y[:, r], GAIN_GRID, axis=0) ** 2, axis=1))
    return {(float(f), float(v)): memo[(float(f), float(v))] for f, v in readings}


def promise(design: Design, many: Many, e0: np.ndarray, J: np.ndarray, R: np.ndarray, dirs, tones, readings,
            noise: float, *, reload=None, disc: float = 0.0, seed: int = 0, moves=None) -> dict | None:
    """The band a recompile on ``readings`` [(tone Hz, volts)] is expected to leave, as the lab's loop makes it.

    ``acl fit --free gain`` fits the gain at each read tone (acl.fit.report.tone_gains), with no prior: its log
    error is Gaussian with variance ``noise^2 / sum_r |dy_r/dlog g|^2`` (the readings' Fisher information) at the
    gain of the device read, which is the truth's, not the nominal: a device with a lower gain at a tone moves less
    under the proposed voltage, and its gain there is measured worse.  A played tone not read (or read with less
    information than the table's prior) keeps the table's gain, off by the truth's own offset.  ``--free gain`` does
    not fit the uncertain parameters: they keep their prior, but what a parameter does to a reading the gain fitted at
    its tone absorbs (:func:`_absorbed`: a gain scale entirely, a stiffness as far as it scales the reading).
    Propagated to the path with its derivative per log gain at each played tone (``J``'s gain columns through the
    tones' gains, ``d log g / d z``; the recompile plans the same path on the calibrated gains, so this derivative
    is taken as the nominal plan's), over DRAWS truths drawn from the declared prior, each with its own estimation
    error.  95th percentiles of RMS and maximum error over them: ``rms_p95_m``, ``max_p95_m``; ``tone_gain_sd`` the
    log-gain sd each read tone is fitted to at the nominal design; ``cov_m2`` the path's covariance there (the plot's
    band after the readings).  None when the tones' gains cannot be told apart in ``J`` (more played tones than gain
    sources) or nothing is read."""
    gi = [j for j, d in enumerate(dirs) if d[1] == "gain"]
    pi = [j for j, d in enumerate(dirs) if d[1] != "gain"]
    tones = [float(f) for f in tones]
    K = len(tones)
    if not gi or not readings or K == 0 or K > len(gi):
        return None
    g0, A = gain_map(design, tones, reload)
    if not np.all(g0 > 0):
        return None
    sds = np.array([dirs[j][3] for j in gi])
    W0 = A[:K] * sds / g0[:K, None]                                  # (K, G): d log g at the played tones / d z
    if np.linalg.matrix_rank(W0) < K:
        return None
    Jt = J[..., gi] @ np.linalg.pinv(W0)                             # (N, 2, K): per log gain at each played tone
    var0 = np.sum(W0 ** 2, axis=1)                                   # the tones' prior log-gain variance
    slopes = reading_slopes(design, many, readings)
    Jp = J[..., pi] - Jt @ _absorbed(design, many, dirs, moves, gi, pi, W0, tones, readings) if pi else J[..., pi]
    rng = np.random.default_rng([seed, 28, 1])
    Z = rng.standard_normal((DRAWS, len(gi)))
    c = np.log(np.maximum(g0 + (np.exp(Z * sds) - 1.0) @ A.T, 1e-300) / g0)       # (S, K): the truth's log offset

    delta = c.copy()                          # not measured: the calibrated gain is the table's, off by the truth's
    sd0 = {}                                  # {read tone: log sd of its fitted gain at the nominal design}
    for k, f in enumerate(tones):
        mine = [s for (fr, _), s in slopes.items() if abs(fr - f) <= 1e-9 * f]
        if not mine:
            continue
        info = sum(_at(c[:, k], s) for s in mine) / noise ** 2        # at each truth's own gain
        use = info * var0[k] > 1.0                    # the readings say more than the table's prior
        delta[use, k] = rng.standard_normal(int(use.sum())) / np.sqrt(info[use])
        info0 = float(sum(_at(np.zeros(1), s) for s in mine)[0])
        if info0 * var0[k] > noise ** 2:
            sd0[f] = float(noise / np.sqrt(info0))
    err = e0[None] + (delta @ Jt.reshape(-1, K).T).reshape(-1, *e0.shape)
    if pi:
        w, V = np.linalg.eigh(0.5 * (R[np.ix_(pi, pi)] + R[np.ix_(pi, pi)].T))
        theta = rng.standard_normal((DRAWS, len(pi))) @ (V * np.sqrt(np.maximum(w, 0.0))).T
        err = err + (theta @ Jp.reshape(-1, len(pi)).T).reshape(err.shape)
    if disc > 0:
        err = err + rng.normal(0.0, disc, err.shape)
    r2 = err[..., 0] * err[..., 0] + err[..., 1] * err[..., 1]               # the sum over (x, y), without a reduction
    return {"rms_p95_m": float(np.percentile(np.sqrt(np.mean(r2, axis=1)), 95)),
            "max_p95_m": float(np.percentile(np.sqrt(r2.max(axis=1)), 95)),
            "tone_gain_sd": [{"frequency_hz": f, "log_sd": v} for f, v in sd0.items()],
            "cov_m2": _tone_covs(Jt, sd0, tones, Jp, R[np.ix_(pi, pi)], var0)}


def _each_tone(design: Design, dirs, many_tones, by_tone: dict, moves) -> dict | None:
    """{tone: (nominal, J) or the exception} of :func:`sensitivity` at each tone alone at its voltages ``by_tone``
    ({tone Hz: [volts]}, the same count per tone), from one ``many_tones`` batch; None when the counts differ."""
    if len({len(v) for v in by_tone.values()}) != 1:
        return None
    tones = list(by_tone)
    live = [k for k, d in enumerate(moves) if d is not None]
    u = np.array([[x * x for x in by_tone[f]] for f in tones])
    got = many_tones([design, *[moves[k] for k in live]], tones, u)
    out = {}
    for f, g in zip(tones, got):
        try:
            out[f] = _sensitivity_of(g, dirs, moves, live)
        except (ValueError, KeyError, FloatingPointError) as exc:
            out[f] = exc
    return out


def _absorbed(design: Design, many: Many, dirs, moves, gi, pi, W0, tones, readings) -> np.ndarray:
    """(K, P): the log gain each played tone's fit takes up per 1 sd of each uncertain parameter, at the nominal design.

    A parameter moves a reading at tone k by ``H_p`` (its column of the reading's sensitivity); ``acl fit --free gain``
    explains that with the gain there, least squares along the reading's slope per log gain ``h``: ``h . H_p / |h|^2``
    (summed over the tone's readings).  The calibrated design carries that gain, so the path's error from the
    parameter is ``J_p - J_t A`` (``J_t`` per log gain at each played tone); a tone not read takes up nothing."""
    out = np.zeros((len(tones), len(pi)))
    by_tone: dict = {}
    for f, v in readings:
        by_tone.setdefault(float(f), []).append(float(v))
    for k, f in enumerate(tones):
        vs = next((x for g, x in by_tone.items() if abs(g - f) <= 1e-9 * f), None)
        if not vs:
            continue
        try:
            _, H = sensitivity(design, dirs, many, [f], np.array([[v * v] for v in vs]), moves)
        except (ValueError, KeyError, FloatingPointError):
            continue
        w = W0[k]
        h = H[..., gi] @ w / float(w @ w)                      # (R, 2): each reading's slope per log gain at tone k
        den = float(np.sum(h * h))
        if den > 0:
            out[k] = np.einsum("ra,rap->p", h, H[..., pi]) / den
    return out


def _at(x: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """A reading's squared slope (:func:`reading_slopes`) at log gains ``x``: interpolated in its logarithm (it grows
    as exp(4 x) where the displacement is quadratic in the pressure), 0 where a grid point has none."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.nan_to_num(np.exp(np.interp(x, GAIN_GRID, np.log(slope))), nan=0.0, posinf=0.0)


def _tone_covs(Jt, sd0: dict, tones, Jp, Rp, var0) -> list:
    """[[xx, xy, yy]] m^2 per waypoint after the readings at the nominal truth: the read tones at their fitted sd,
    the others at their prior, the parameters at theirs."""
    v = np.array([sd0[f] ** 2 if f in sd0 else var0[k] for k, f in enumerate(tones)])
    C = np.einsum("nak,k,nbk->nab", Jt, v, Jt)
    if Jp.shape[-1]:
        C = C + np.einsum("nad,de,nbe->nab", Jp, Rp, Jp)
    return [[float(x[0, 0]), float(x[0, 1]), float(x[1, 1])] for x in C]


def _score(J2: np.ndarray, S: np.ndarray) -> float:
    return float(np.trace(J2 @ S @ J2.T))


def _covs(J: np.ndarray, S: np.ndarray) -> list:
    """[[xx, xy, yy]] m^2 per waypoint: ``J_i S J_i^T``."""
    C = np.einsum("nad,de,nbe->nab", J, S, J)
    return [[float(c[0, 0]), float(c[0, 1]), float(c[1, 1])] for c in C]


def candidates(design: Design, tones, u: np.ndarray) -> list[tuple[float, float]]:
    """[(tone Hz, volts)]: each goal tone and each gain-table frequency inside the transducer's band, at the largest
    single-tone amplitude the goal plays, at half and at a quarter of it (a range the plan already drives; :func:`explain`
    keeps those that move the capsule at most twice as far as the path reaches)."""
    t = design.transducer
    fs = {float(f) for f in tones}
    if t is not None:
        lo, hi = (t.band if getattr(t, "band", None) else (min(t.gain_frequencies), max(t.gain_frequencies)))
        fs |= {float(f) for f in t.gain_frequencies if lo <= f <= hi}
    v = float(np.sqrt(np.max(u))) if u.size else 0.0
    if v <= 0:
        return []
    return [(f, x) for f in sorted(fs) for x in (v / 4, v / 2, v)]


def explain(design: Design, many: Many, capsule: str, tones, u: np.ndarray, targets: np.ndarray, *,
            reload=None, band=None, noise: float = READING_NOISE_M, seed: int = 0, name: str = "",
            earlier=None, many_tones=None) -> dict | None:
    """The band's cause and cure for a follow goal (module docstring); None when nothing is declared or the model fails.

    ``u`` (K, M) V^2 and ``targets`` (M, 2) m at the re-simulated waypoints; ``band`` the Monte Carlo one
    (:class:`acl.schedule.bands.Band`) for the check; ``name`` the goal's; ``earlier`` (goal name, [(tone Hz,
    volts)]): another goal's proposed readings, under which the band expected after them is promised too (a lab
    that takes only those).  ``many_tones`` (designs, tones, u (K, N) V^2 of each tone alone) -> [[prediction per
    design] per tone]: the candidate readings' sensitivities as one batch (acl.schedule.gains.model_forward_tones),
    the same numbers as ``many`` tone by tone."""
    dirs, R, moves = prepared(design, reload)
    if not dirs:
        return None
    try:
        p0, J = sensitivity(design, dirs, many, tones, u.T, moves)
    except (ValueError, KeyError, FloatingPointError):
        return None
    ok = np.all(np.isfinite(p0), axis=1)
    if not ok.any():
        return None
    p0, J, tg = p0[ok], J[ok], np.asarray(targets, float)[ok]
    e0 = p0 - tg
    disc = float(design.discrepancy or 0.0)
    rms0, max0 = linear_band(e0, J, R, disc, seed)
    v = np.mean(np.sum(J ** 2, axis=1), axis=0)                               # (D,) mean squared error per 1 sd
    total = float(v.sum())
    shares = v / total if total > 0 else np.zeros_like(v)
    order = np.argsort(-shares)
    sources = [{"source": dirs[j][0], "kind": dirs[j][1], "frequency_hz": dirs[j][2], "sd": dirs[j][3],
                "share": round(float(shares[j]), 4)} for j in order[:TOP]]
    gain_share = float(sum(shares[j] for j in range(len(dirs)) if dirs[j][1] == "gain"))
    pair_share = [float(shares[j]) for j in range(len(dirs)) if dirs[j][1] == "pair"]
    out = {"sources": sources, "gain_table_share": round(gain_share, 4), "reading_noise_m": noise,
           "other_sources_share": round(float(shares[order[TOP:]].sum()), 4),
           "linearised_rms_p95_m": rms0, "linearised_max_p95_m": max0,
           "monte_carlo_rms_p95_m": None if band is None else float(band.rms_p95_m),
           # per re-simulated waypoint: predicted position and the 2x2 covariance the sources give it (the plot's band;
           # the compiler keeps it off schedule.json)
           "plot": {"waypoints_m": [[float(a), float(b)] for a, b in p0], "cov_m2": _covs(J, R)}}
    if pair_share:
        out["pair_force_share"] = round(pair_share[0], 4)
    # the experiment: readings chosen greedily to minimise the expected squared tracking error
    cands = candidates(design, tones, u)
    reach = float(np.max(np.linalg.norm(tg, axis=1)))      # the path's farthest point from rest
    H = {}
    by_tone: dict = {}
    for f, x in cands:
        by_tone.setdefault(f, []).append(x)
    each = _each_tone(design, dirs, many_tones, by_tone, moves) if many_tones is not None else None
    for f, vs in by_tone.items():
        try:
            got = each[f] if each is not None else \
                sensitivity(design, dirs, many, [f], np.array([[x * x] for x in vs]), moves)
            if isinstance(got, Exception):
                raise got
            y0, Hf = got
        except (ValueError, KeyError, FloatingPointError):
            continue
        for r, x in enumerate(vs):
            if np.all(np.isfinite(y0[r])) and np.linalg.norm(y0[r]) <= 2 * reach:
                # the readings calibrate the gain (acl fit --free gain), not a pair force's scale: it stays as drawn
                H[(f, x)] = (np.where([k == "pair" for _, k, *_ in dirs], 0.0, Hf[r]), y0[r])
    J2 = J.reshape(-1, J.shape[-1]) / np.sqrt(J.shape[0])
    S, chosen, best = R.copy(), [], _score(J2, R)
    for _ in range(MAX_READINGS):
        trial = {c: _score(J2, update(S, h, noise)) for c, (h, _) in H.items() if c not in chosen}
        if not trial:
            break
        c = min(trial, key=trial.get)
        if trial[c] > best * 0.9:        # less than 10 % more of the squared error removed: stop
            break
        chosen.append(c)
        S, best = update(S, H[c][0], noise), trial[c]
    if chosen:
        reads = [(f, round(x, 4)) for f, x in chosen]          # as written: the voltages the lab sets
        rms1, max1 = linear_band(e0, J, S, disc, seed)
        pr = promise(design, many, e0, J, R, dirs, tones, reads, noise, reload=reload, disc=disc, seed=seed,
                     moves=moves)
        out["plot"]["cov_after_m2"] = _covs(J, S) if pr is None else pr["cov_m2"]
        post_sd = np.sqrt(np.maximum(np.diag(S), 0.0))
        out["measurement"] = {
            "observable": f"static displacement (x, y) of capsule `{capsule}` under one tone",
            "noise_m": noise,
            "readings": [{"frequency_hz": f, "voltage_v": x,
                          "expected_displacement_m": [float(a) for a in H[(f, c)][1]]} for (f, x), (_, c) in
                         zip(reads, chosen)],
            "readings_of": name,
            "expected_rms_p95_m": rms1 if pr is None else pr["rms_p95_m"],
            "expected_max_p95_m": max1 if pr is None else pr["max_p95_m"],
            # how the promise is made: over truths drawn from the prior, the fitted gains' error at each truth's own
            # gain (promise); or, where the tones' gains cannot be told apart, the posterior at the nominal design
            "promise": "over truths" if pr is not None else "at the nominal design",
            # the posterior at the nominal design alone (the promise before issue 28's fix), for comparison
            "nominal_rms_p95_m": rms1,
            "posterior_sd": [{"source": dirs[j][0], "prior": 1.0, "after": round(float(post_sd[j]), 4)}
                             for j in order[:3]],
        }
        if pr is not None:
            out["measurement"]["tone_gain_sd"] = pr["tone_gain_sd"]
        if earlier and earlier[0] != name and sorted(earlier[1]) == sorted(reads):
            out["measurement"]["same_readings_as"] = earlier[0]
        elif earlier and earlier[0] != name:
            alt = promise(design, many, e0, J, R, dirs, tones, earlier[1], noise, reload=reload, disc=disc, seed=seed,
                          moves=moves)
            if alt is not None:
                out["measurement"]["with_readings_of"] = {
                    "goal": earlier[0], "readings": [{"frequency_hz": f, "voltage_v": x} for f, x in earlier[1]],
                    "expected_rms_p95_m": alt["rms_p95_m"], "expected_max_p95_m": alt["max_p95_m"]}
    return out


def summary(name: str, ex: dict) -> str:
    """One note for the CLI and schedule.json: the dominant source with its share, the proposed readings, the band after."""
    top = ex["sources"][0]
    s = (f"{name}: the 95 % band's dominant cause is the {top['source']}, {top['share']:.0%} of its variance "
         f"(all gain-table points together: {ex['gain_table_share']:.0%}; linearised band "
         f"{ex['linearised_rms_p95_m'] * 1e6:.3g} um RMS")
    if ex.get("monte_carlo_rms_p95_m") is not None:
        s += f" against {ex['monte_carlo_rms_p95_m'] * 1e6:.3g} um from the draws"
    s += ")"
    m = ex.get("measurement")
    if m:
        reads = ", ".join(f"{r['frequency_hz'] / 1e3:g} kHz at {r['voltage_v']:.3g} V" for r in m["readings"])
        whose = f" ({m['readings_of']}'s)" if m.get("readings_of") else ""
        if m.get("same_readings_as"):
            whose = f" ({m['readings_of']}'s, the same as {m['same_readings_as']}'s)"
        s += (f"; to narrow it, measure the {m['observable']} at {reads} (assumed noise {m['noise_m'] * 1e6:.3g} um "
              f"per axis): expected band after recompiling on these readings{whose} "
              f"{m['expected_rms_p95_m'] * 1e6:.3g} um RMS / {m['expected_max_p95_m'] * 1e6:.3g} um max")
        if m.get("promise") == "over truths":
            s += (f" (95 % over devices drawn from the declared uncertainty, each read with that noise and fitted: "
                  f"a device with a lower gain moves less under these voltages and is measured worse; at the nominal "
                  f"design alone {m['nominal_rms_p95_m'] * 1e6:.3g} um)")
        s += (" (acl fit with `--free gain` on these readings fits the gain at each of these tones, one per tone "
              "where a gain scale cannot follow them, and a compile on its calibrated design plays them)")
        if m.get("model_form_m"):
            s += (f", of which {m['model_form_m'] * 1e6:.3g} um is the model-form term of the validity limits the "
                  "step is past, which these readings do not remove")
        w = m.get("with_readings_of")
        if w:
            s += (f"; on {w['goal']}'s readings alone (the same as a lab that takes only those) it is "
                  f"{w['expected_rms_p95_m'] * 1e6:.3g} um RMS / {w['expected_max_p95_m'] * 1e6:.3g} um max")
    return s


def moved(design: Design, z, reload=None) -> Design:
    """The design with every source of :func:`directions` moved by ``z`` sds at once (a truth drawn from the prior, or
    the estimate a measurement gives)."""
    unc = bands.declared(design, with_params=reload is not None)
    dirs, _ = directions(design, reload)
    z = np.asarray(z, float)
    ng = sum(1 for d in dirs if d[1] == "gain")
    npar = sum(1 for d in dirs if d[1] == "parameter")
    d = design
    if npar:
        theta = unc.mean.copy()
        sd = np.sqrt(np.maximum(np.diag(unc.cov), 0.0))
        live = [i for i in range(len(unc.names)) if sd[i] > 0]
        theta[live] = theta[live] + z[ng:ng + npar] * sd[live]
        d = bands._with_params(design, unc, theta, reload)
    if ng:
        d = bands._with_gain(d, np.exp(unc.gain_sds * z[:ng]))
    if unc.pair:
        d = bands.pair_move(d, z[ng + npar])
    return d


def estimate(R: np.ndarray, readings) -> tuple[np.ndarray, np.ndarray]:
    """(posterior mean, covariance) of the sources (in sds) from ``readings`` [(H (2, D), observed - nominal (2,) m,
    noise m)]: the linear Gaussian update of the prior N(0, R), one reading after the other."""
    m, S = np.zeros(R.shape[0]), R.copy()
    for H, r, noise in readings:
        G = H @ S @ H.T + noise ** 2 * np.eye(H.shape[0])
        K = S @ H.T @ np.linalg.inv(G)
        m = m + K @ (np.asarray(r, float) - H @ m)
        S = S - K @ H @ S
    return m, S


def fit_readings(design: Design, many: Many, readings, observed, noise: float, reload=None,
                 iterations: int = 6) -> np.ndarray:
    """The sources (in sds) that readings ``[(tone Hz, volts)]`` with ``observed`` displacements ((2,) m each) point to:
    the maximum a posteriori estimate under the prior N(0, R), by Gauss-Newton with the Jacobian taken again at each
    estimate (a reading's displacement grows as the gain squared, so the nominal slope alone over- or undershoots)."""
    dirs, R = directions(design, reload)
    D = len(dirs)
    z = np.zeros(D)
    y = np.concatenate([np.asarray(o, float) for o in observed])
    for _ in range(iterations):
        rows, hs = [], []
        for f, v in readings:
            zs = [z] + [z + s * STEP * e for e in np.eye(D) for s in (1, -1)]
            got = many([moved(design, x, reload) for x in zs], [f], np.array([[v * v]]))
            got = [np.asarray(g, float)[0] for g in got]
            hs.append(got[0])
            rows.append(np.stack([(got[1 + 2 * j] - got[2 + 2 * j]) / (2 * STEP) for j in range(D)], axis=1))
        H, h = np.concatenate(rows), np.concatenate(hs)
        G = H @ R @ H.T + noise ** 2 * np.eye(len(y))
        new = R @ H.T @ np.linalg.solve(G, y - h + H @ z)
        if np.max(np.abs(new - z)) < 1e-4:
            return new
        z = new
    return z
