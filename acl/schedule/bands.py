"""Honest error bounds: the declared uncertainty of a design, sampled and linearised.

A design declares its uncertainty in the language (docs/language.md): ``param x = v +- s`` with
``uncertainty { correlation(a, b) = r }`` (the covariance a calibration writes), and a transducer's
``gain_uncertainty`` (relative standard deviation of each gain-table value, independent; the stdlib
tables, which are not measured, declare 30 %).  A calibration also declares ``measured(gain)``: the
tones its data drove, each with the standard error of a free gain there; at those tones the table is
held to the calibrated model (:func:`pinned`), elsewhere it keeps its prior.  A design whose pair (secondary
Bjerknes) forces no ``bjerknes_scale`` calibrates (:func:`acl.analysis.effects.first_principles_pairs`) adds one more
source that it does not declare: its Bjerknes force drawn times a scale from the predictive spread of the measured /
first-principles ratio over the paper's pairs (``acl.physics.constants.PAIR_SCALE_ROWS``: a log-Student-t with 2 dof,
95 % 0.051-180x; :func:`pair_scales`), from a random stream of its own so the other draws stay those of the same design with its
force declared.  This module turns it into

* :func:`sample_designs` -- designs drawn from that distribution: the table values multiplied by
  log-normal factors ``exp(s z)`` (one per table point), the uncertain parameters drawn from
  their multivariate normal (those a ``lognormal(a, ...)`` entry names: from the multivariate
  log-normal of the same mean and covariance, :func:`log_moments`, so a positive value never goes
  negative and a ratio the data tie stays tied) and the design resolved again with them (``reload``: overrides ->
  Design, supplied by the caller that knows the source file);
* :func:`error_band` -- the 95th percentile of a goal's RMS and maximum tracking error over those
  designs (bounded from above by an order statistic of the draws: :func:`_quantile`), each re-simulated through the full nonlinear forward model with the schedule's drive,
  plus, for a calibrated design, its declared ``discrepancy(position)`` (the fit's RMS residual:
  what the calibrated model still misses) as an independent Gaussian error per waypoint and axis;
* :func:`gain_sensitivity` -- the linearised spread of the gain matrix, ``Q = sum_j dG_j^T dG_j``
  (K x K), one ``dG_j`` per independent 1-sigma direction (a table point, a principal direction of
  the parameter covariance), for the robust path program (:mod:`acl.schedule.robust`);
* :func:`margin_band` -- the 5th percentile over those designs of a goal's re-simulated margin (a
  hold's snap-in margin, a switch's force over the switching force): a goal without a path has no
  tracking error, but its margin is as uncertain as the design;
* :func:`coverage_warnings` -- ``W-SCHED-COVERAGE`` at each goal that drives outside the range the
  calibration data covered (``covered(voltage|frequency|deflection)``): the voltage and tones (a sweep's
  band) of every goal and sweep, the deflection of a path, a held or crossed pair, a switched latch's
  shuttle, and every capsule under a drive (a sweep: at its worst frequency).

Numbers only; the compiler turns them into report fields and notes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from acl.design.model import Design

Reload = Callable[[dict], Design]          # {param: "value unit"} -> resolved Design


@dataclass(frozen=True)
class Uncertainty:
    """What a design declares: table-point log-sd of the transducer gain, and uncertain parameters."""

    gain_sd: float                          # relative sd of each gain-table value (0: none)
    discrepancy: float                      # m, RMS model discrepancy of a calibration (0: none)
    n_table: int                            # gain factors drawn: the table's points, then the pinned tones
    names: tuple[str, ...]                  # uncertain parameters
    mean: np.ndarray                        # (P,) SI
    cov: np.ndarray                         # (P, P) SI
    units: tuple[str, ...]
    pinned: tuple = ()                      # ((tone Hz, relative sd), ...): gains a calibration measured (:func:`pinned`)
    log: tuple[bool, ...] = ()              # per parameter: drawn log-normal (``lognormal(a, ...)``), else normal
    pair: bool = False                      # first-principles pair forces: their scale is drawn (:func:`pair_scales`)

    @property
    def gain_sds(self) -> np.ndarray:
        """(n_table,) log-sd of each drawn gain factor: the table's prior, then each pinned tone's own."""
        n = self.n_table - len(self.pinned)
        return np.array([self.gain_sd] * n + [s for _, s in self.pinned], float)

    @property
    def empty(self) -> bool:
        return self.gain_sd <= 0 and not self.names and self.discrepancy <= 0 and not self.pair


def declared(design: Design, with_params: bool = True) -> Uncertainty:
    """The uncertainty a design declares (params only when they can be re-resolved: ``with_params``), and the spread of
    a first-principles pair force (:func:`pair_scales`)."""
    from acl.analysis.effects import first_principles_pairs

    t = design.transducer
    gain_sd = float(t.gain_uncertainty or 0.0) if t is not None else 0.0
    ps = design.uncertain_params() if with_params else ()
    pin = pinned(design)
    return Uncertainty(gain_sd, float(design.discrepancy or 0.0),
                       len(t.gain_pa_per_v) + len(pin) if t is not None else 0, tuple(p.name for p in ps),
                       np.array([p.value for p in ps]), design.covariance([p.name for p in ps]) if ps else np.zeros((0, 0)),
                       tuple(p.unit for p in ps), pin, tuple(p.name in design.lognormal for p in ps),
                       first_principles_pairs(design))


PAIR_SOURCE = "first-principles pair force"


def pair_scales(n: int, seed: int = 0) -> np.ndarray:
    """(n,) the Bjerknes-force scales of :func:`sample_designs`' draws on a first-principles pair: the truncated
    predictive log-Student-t of acl.physics.constants (pair_scale_from_uniform), from its own stream ``[seed, 2]``."""
    from acl.physics.constants import pair_scale_from_uniform

    return pair_scale_from_uniform(np.random.default_rng([seed, 2]).random(n))


_RMS_LOG: list = []


def pair_rms_log() -> float:
    """sqrt(E (ln s)^2) of the pair scale s (acl.physics.constants): its root-mean-square log distance from the
    first-principles force, about which the compiler's linearised sources move it (:func:`pair_move`); the midpoint
    rule on 20,000 equal-probability cells of the truncated predictive spread."""
    if not _RMS_LOG:
        from acl.physics.constants import pair_scale_from_uniform

        u = (np.arange(20000) + 0.5) / 20000
        _RMS_LOG.append(float(np.sqrt(np.mean(np.log(pair_scale_from_uniform(u)) ** 2))))
    return _RMS_LOG[0]


def pair_move(design: Design, t: float) -> Design:
    """``design`` with its first-principles pair force moved by ``t`` of :func:`pair_rms_log` in log scale: a linearised
    source (the robust program's Q, the band's cause) whose variance is the pair scale's second moment about first
    principles (its median is itself about 1.5 log units away)."""
    from acl.analysis.effects import with_pair_scale

    return with_pair_scale(design, float(np.exp(pair_rms_log() * t)))


def pair_details(design: Design, values: np.ndarray, seed: int = 0) -> dict | None:
    """What a band says of the first-principles pair force it drew (None when the design's pairs are calibrated):
    the distribution with its source rows, and its share of the band's spread: the squared rank correlation of the
    draws' ``values`` (RMS error or margin; a failed draw ranks as its value says) with their drawn scale (Spearman; for
    independent sources the first-order share of the variance, up to monotone transforms)."""
    from acl.analysis.effects import first_principles_pairs
    from acl.physics import constants as C

    if not first_principles_pairs(design):
        return None
    v = np.asarray(values, float)
    out = {"source": PAIR_SOURCE, "distribution": C.PAIR_SCALE_DISTRIBUTION, "median": C.pair_scale_quantile(0.5),
           "range_95": [C.pair_scale_quantile(0.025), C.pair_scale_quantile(0.975)], "log_sd": C.PAIR_SCALE_LOG_SD,
           "predictive_log_scale": C.PAIR_SCALE_PREDICTIVE_LOG_SCALE, "dof": C.PAIR_SCALE_DOF,
           "rows": [{"source": s, "ratio": r} for s, r in C.PAIR_SCALE_ROWS],
           "variance_share": None}
    if v.size >= 3:
        from scipy.stats import rankdata

        x = rankdata(pair_scales(v.size, seed))
        y = rankdata(np.where(np.isnan(v), np.inf, v))        # ties (failed draws) share their mean rank
        if np.std(x) > 0 and np.std(y) > 0:
            out["variance_share"] = round(float(np.corrcoef(x, y)[0, 1] ** 2), 4)
    return out


def pinned(design: Design) -> tuple:
    """((tone Hz, relative sd), ...): the tones whose gain a calibration measured better than the table's prior.

    ``measured(gain)`` (acl.fit.report.tone_gain_stderr) gives, per tone the calibration data drove, the relative
    standard error of a free gain there, all fitted coefficients free: the calibrated model's gain at that tone
    is known to it, whatever the table's shape.  The draws then hold the table at each such tone to the
    calibrated value times ``exp(s z)`` (a knot inserted there) and keep the prior on every table point: between
    and beyond the measured tones the gain stays as uncertain as the table declares.
    """
    t = design.transducer
    sd = float(t.gain_uncertainty or 0.0) if t is not None else 0.0
    if sd <= 0:
        return ()
    return tuple((m.frequency, m.stddev) for m in design.measured_gain if m.stddev < sd)


def unmeasured_tones(design: Design, tones) -> list[float]:
    """The tones (Hz) whose gain no calibration measured (:func:`pinned`): their band keeps the table's prior."""
    pin = [f for f, _ in pinned(design)]
    if not pin:
        return []
    return [float(f) for f in tones if not any(abs(f - p) <= 1e-6 * p for p in pin)]


def _anchor(design: Design, factors: np.ndarray) -> np.ndarray:
    """Table factors relative to the gain at the calibrated frequencies, when a calibration measured it.

    A calibrated design (``acl fit``) declares ``transducer_gain`` (the fitted pressure scale, with
    its own uncertainty as parameters) and ``covered(frequency)``: the gain there is measured, so the
    table's prior uncertainty only describes the shape relative to it.
    """
    cover = next((c for c in design.coverage if c.quantity == "frequency"), None)
    if cover is None or design.effect("transducer_gain") is None:
        return factors
    from acl.physics.transducer import pressure_per_volt

    t = design.transducer
    f = np.linspace(cover.lower, cover.upper, 5)
    g0, _ = pressure_per_volt(f, t.gain_frequencies, t.gain_pa_per_v)
    g1, _ = pressure_per_volt(f, t.gain_frequencies, np.asarray(t.gain_pa_per_v) * factors)
    return factors / float(np.exp(np.mean(np.log(np.asarray(g1) / np.asarray(g0)))))


def _with_gain(design: Design, factors: np.ndarray) -> Design:
    """The design with its gain table's points times ``factors`` (then, for each pinned tone, a knot there
    at the calibrated gain times its factor: :func:`pinned`)."""
    t = design.transducer
    factors = np.asarray(factors, float)
    pin = pinned(design)
    n = len(t.gain_pa_per_v)
    if not pin:
        factors = _anchor(design, factors)
        gains = tuple(float(g * f) for g, f in zip(t.gain_pa_per_v, factors))
        return design.model_copy(update={"transducer": t.model_copy(update={"gain_pa_per_v": gains})})
    from acl.physics.transducer import pressure_per_volt

    fs0, gs0 = np.asarray(t.gain_frequencies, float), np.asarray(t.gain_pa_per_v, float)
    knots = {float(f): float(g * x) for f, g, x in zip(fs0, gs0, factors[:n])}
    for (f, _), x in zip(pin, factors[n:n + len(pin)]):
        g, _ = pressure_per_volt(f, fs0, gs0)        # the calibrated table's value there (before any draw)
        same = [k for k in knots if abs(k - f) <= 1e-9 * f]
        for k in same:                                # a table point at the tone: measured, its prior is replaced
            del knots[k]
        knots[float(f)] = float(g) * float(x)
    fs = tuple(sorted(knots))
    gains = tuple(knots[f] for f in fs)
    return design.model_copy(update={"transducer": t.model_copy(update={"gain_frequencies": fs, "gain_pa_per_v": gains})})


def _literal(value: float, unit: str) -> str:
    return f"{value:.12g} {unit}".strip()


def _with_params(design: Design, unc: Uncertainty, theta: np.ndarray, reload: Reload | None) -> Design:
    if not unc.names:
        return design
    if reload is None:
        raise ValueError("uncertain parameters need the design to be resolved again (no reload given)")
    return reload({n: _literal(float(v), u) for n, v, u in zip(unc.names, theta, unc.units)})


def _chol(cov: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh(cov)
    return V * np.sqrt(np.maximum(w, 0.0))


def log_moments(mean: np.ndarray, cov: np.ndarray, log) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of ``w`` (``log x`` where ``log``, else ``x``) whose image has the declared mean and covariance.

    Moment matching of a multivariate log-normal (Johnson, Kotz & Balakrishnan, *Continuous Multivariate
    Distributions* (2000), ch. 45): ``cov(ln x_i, ln x_j) = ln(1 + C_ij / (m_i m_j))``, ``E ln x_i = ln m_i -
    var_i / 2``; a log-normal and a normal coordinate, ``cov(ln x_i, y_j) = C_ij / m_i`` (Stein's lemma).  A pair
    whose ``1 + C_ij / (m_i m_j)`` is not positive (a strong negative correlation of two very uncertain values: no
    log-normal has it) is held at the closest one that exists; the variances always match (:func:`_valid_cov`).
    """
    log = np.asarray(log, bool)
    m = np.asarray(mean, float)
    C = np.asarray(cov, float)
    if not log.any():
        return m, C
    S = C.copy()
    ml = np.where(log, m, 1.0)
    both = np.outer(log, log)
    one = np.outer(log, ~log)
    with np.errstate(all="ignore"):
        S = np.where(both, np.log(np.maximum(1.0 + C / np.outer(ml, ml), 1e-12)), S)
        S = np.where(one, C / ml[:, None], S)
        S = np.where(one.T, C / ml[None, :], S)
    mu = np.where(log, np.log(ml) - 0.5 * np.diag(S), m)
    return mu, _valid_cov(S)


def _valid_cov(S: np.ndarray) -> np.ndarray:
    """``S`` with its variances kept and its correlations moved to the nearest valid ones (clipped to -1 .. 1,
    negative eigenvalues of the correlation matrix dropped, its diagonal restored: Higham (2002), IMA J.
    Numer. Anal. 22, 329, one projection step): the matched covariance of two log-normals of very different
    spreads can ask for a correlation no distribution has."""
    sd = np.sqrt(np.maximum(np.diag(S), 0.0))
    if sd.size < 2 or not np.all(sd > 0):
        return S
    R = np.clip(S / np.outer(sd, sd), -1.0, 1.0)
    w, V = np.linalg.eigh(R)
    if w.min() >= -1e-12:
        return R * np.outer(sd, sd)
    R = (V * np.maximum(w, 0.0)) @ V.T
    d = np.sqrt(np.maximum(np.diag(R), 1e-300))
    return R / np.outer(d, d) * np.outer(sd, sd)


def draw_params(unc: Uncertainty, rng: np.random.Generator, L: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """One draw of the uncertain parameters: ``mu + L z``, exponentiated where they are log-normal (:func:`log_moments`)."""
    w = mu + L @ rng.standard_normal(len(unc.names))
    log = np.asarray(unc.log, bool)
    return np.where(log, np.exp(np.where(log, w, 0.0)), w)


def sample_designs(design: Design, n: int, seed: int = 0, reload: Reload | None = None):
    """Yield (index, Design or None) for ``n`` draws of the declared uncertainty (None: failed to resolve)."""
    from acl.analysis.effects import with_pair_scale
    from acl.diagnostics import DiagnosticError

    unc = declared(design, with_params=reload is not None)
    rng = np.random.default_rng(seed)
    if unc.names:
        mu, S = log_moments(unc.mean, unc.cov, unc.log)
        L = _chol(S)
    scales = pair_scales(n, seed) if unc.pair else None
    for i in range(n):
        theta = draw_params(unc, rng, L, mu) if unc.names else None
        z = rng.standard_normal(unc.n_table)
        try:
            d = _with_params(design, unc, theta, reload) if unc.names else design
        except DiagnosticError:
            yield i, None
            continue
        if unc.gain_sd > 0 and d.transducer is not None:
            d = _with_gain(d, np.exp(unc.gain_sds * z))
        if scales is not None:
            d = with_pair_scale(d, scales[i])
        yield i, d


@dataclass
class Band:
    rms_p95_m: float
    max_p95_m: float
    samples: int                            # draws in the percentiles (every draw)
    failed: int                             # of those, draws that did not resolve or lost the equilibrium
    rms_m: np.ndarray                       # per draw (for tests and plots)
    max_m: np.ndarray
    pair: dict | None = None                # the first-principles pair force drawn (:func:`pair_details`)


def error_band(design: Design, forward_for: Callable, u: np.ndarray, targets: np.ndarray, *,
               samples: int = 32, seed: int = 0, reload: Reload | None = None, q: float = 95.0,
               forward_many: Callable | None = None) -> Band | None:
    """95th percentile of RMS and max tracking error over designs drawn from the declared uncertainty.

    ``forward_for(design) -> forward`` (u (N, K) V^2 -> (N, 2) m); ``u`` (K, M) and ``targets`` (M, 2)
    at the re-simulated waypoints.  ``forward_many(designs) -> [prediction or exception]``, when given,
    re-simulates every resolved draw at once instead (acl.schedule.gains.model_forward_many: one batch).
    A draw whose equilibrium is lost at a waypoint (snap-in) counts
    that waypoint as missed by the path's full size in the RMS (never as on target) and has an
    unbounded maximum (as the nominal prediction); a draw that does not resolve or whose model fails
    misses every waypoint so.  None when nothing is declared.
    """
    if declared(design, with_params=reload is not None).empty or samples <= 0:
        return None
    rms, mx, failed = [], [], 0
    disc = float(design.discrepancy or 0.0)
    noise = np.random.default_rng([seed, 1])
    scale = float(np.max(np.linalg.norm(targets - targets.mean(axis=0), axis=1))) + float(
        np.max(np.linalg.norm(targets, axis=1)))
    draws = [d for _, d in sample_designs(design, samples, seed, reload)]
    many = {}
    if forward_many is not None:
        live = [k for k, d in enumerate(draws) if d is not None]
        many = dict(zip(live, forward_many([draws[k] for k in live])))
    for k, d in enumerate(draws):
        try:
            if d is None:
                raise ValueError("did not resolve")
            got = many[k] if k in many else forward_for(d)(u.T)
            if isinstance(got, Exception):
                raise got
            pred = np.asarray(got, float)
        except (ValueError, KeyError, FloatingPointError):
            # a draw that does not resolve (a drawn value outside its physical range, e.g. a negative coefficient) or
            # whose model fails: missing the path, as a lost equilibrium (left out, the band came from the draws
            # that resolved only, and shrank as more of the declared spread became unphysical)
            failed += 1
            rms.append(scale)
            mx.append(float("inf"))
            continue
        if disc > 0:     # what the calibrated model misses, independent per waypoint and axis (conservative)
            pred = pred + noise.normal(0.0, disc, pred.shape)
        err = np.linalg.norm(pred - targets, axis=1)
        bad = ~np.isfinite(err)
        if bad.any():   # lost equilibrium (snap-in): the RMS counts the path's extent, the maximum is unbounded
            failed += 1
            err[bad] = max(scale, float(np.nanmax(err)) if (~bad).any() else scale)
        rms.append(float(np.sqrt(np.mean(err ** 2))))
        mx.append(float("inf") if bad.any() else float(err.max()))
    if not rms:
        return Band(float("nan"), float("nan"), 0, failed, np.array([]), np.array([]))
    rms_a, mx_a = np.array(rms), np.array(mx)
    return Band(_quantile(rms_a, q), _quantile(mx_a, q), len(rms), failed, rms_a, mx_a, pair_details(design, rms_a, seed))


@dataclass
class MarginBand:
    p05: float                              # 5th percentile of the margin over the draws (inf: never reached)
    samples: int                            # draws that gave an answer
    failed: int                             # draws whose design did not resolve or whose model failed
    below_one: int                          # draws where the margin is below 1 (the goal fails there)
    values: np.ndarray                      # per draw
    others_p95: dict                        # {name: 95th percentile} of ratios that must stay below 1
    pair: dict | None = None                # the first-principles pair force drawn (:func:`pair_details`)


def margin_band(design: Design, margin_for: Callable, *, samples: int = 20, seed: int = 0,
                reload: Reload | None = None) -> MarginBand | None:
    """5th percentile of ``margin_for(design)`` over designs drawn from the declared uncertainty, bounded from below
    by an order statistic (:func:`_lower_quantile`: the smallest of 20 draws).

    ``margin_for(d) -> float`` or ``(float, {name: ratio})``: the goal's margin on the drawn design
    (>= 1: the goal is met there) and, optionally, ratios that must stay below 1 (another latch's
    force over its own switching force).  A failed draw counts as a margin of 0 (never as met).
    None when nothing is declared.
    """
    if declared(design, with_params=reload is not None).empty or samples <= 0:
        return None
    vals, others, failed = [], {}, 0
    for _, d in sample_designs(design, samples, seed, reload):
        try:
            if d is None:
                raise ValueError("did not resolve")
            out = margin_for(d)
        except (ValueError, KeyError, FloatingPointError):
            failed += 1
            vals.append(0.0)
            continue
        m, extra = out if isinstance(out, tuple) else (out, {})
        vals.append(float(m) if m is not None and not np.isnan(m) else 0.0)
        for k, r in extra.items():
            others.setdefault(k, []).append(float(r))
    v = np.array(vals)
    # bounds by order statistics, as the error bands: the margin's from below, the ratios' from above
    return MarginBand(_lower_quantile(v, 5.0), len(vals) - failed, failed, int(np.sum(v < 1.0)), v,
                      {k: _quantile(np.array(r), 95.0) for k, r in others.items()}, pair_details(design, v, seed))


def _quantile(x: np.ndarray, q: float) -> float:
    """Upper bound of the q-th percentile from ``n`` draws: the k-th smallest draw, k = ceil(q/100 (n + 1)).

    A draw of the same distribution (the device, when the declared uncertainty is honest) lies below it with
    probability k/(n + 1) >= q/100, whatever the distribution (order statistics); the plug-in percentile
    (linear interpolation, about the (0.95 (n - 1) + 1)-th draw) holds only about 19/21 of the time at n = 20.
    With fewer than 19 draws no draw bounds 95 % so: the largest one (probability n/(n + 1), :func:`level`).
    inf when it reaches an unbounded draw (lost equilibrium).
    """
    x = np.asarray(x, float)
    if x.size == 0:
        return float("nan")
    k = min(int(np.ceil(q / 100.0 * (x.size + 1) - 1e-9)), x.size)
    return float(np.sort(np.where(np.isnan(x), np.inf, x))[k - 1])


def _lower_quantile(x: np.ndarray, q: float) -> float:
    """Lower bound of the q-th percentile from ``n`` draws (:func:`_quantile` mirrored): a new draw lies below it with
    probability at most q/100 (the smallest draw when n < 100/q - 1); -inf when it reaches an unbounded draw."""
    return -_quantile(-np.asarray(x, float), 100.0 - q)


def level(n: int, q: float = 95.0) -> float:
    """Probability that a new draw lies below :func:`_quantile`'s bound from ``n`` draws: k/(n + 1)."""
    return min(int(np.ceil(q / 100.0 * (n + 1) - 1e-9)), n) / (n + 1) if n > 0 else 0.0


def gain_sensitivity(design: Design, gains_for: Callable, reload: Reload | None = None) -> np.ndarray | None:
    """Q (K, K) = sum_j dG_j^T dG_j over independent 1-sigma directions of the declared uncertainty.

    ``gains_for(design) -> (2, K)`` gain matrix at the goal's tones.  Finite differences: a table point
    scaled by ``exp(s)``; a parameter moved along one principal axis of its covariance by 1 sigma; a
    first-principles pair force by its scale's root-mean-square log distance (:func:`pair_move`).
    ``sum_t u_t^T Q u_t`` is the expected squared error the uncertainty adds to the linear plan.
    """
    unc = declared(design, with_params=reload is not None)
    if unc.empty:
        return None
    G0 = np.asarray(gains_for(design), float)
    K = G0.shape[1]
    Q = np.zeros((K, K))
    if unc.gain_sd > 0 and design.transducer is not None:
        sds = unc.gain_sds
        for j in range(unc.n_table):
            f = np.ones(unc.n_table)
            f[j] = np.exp(sds[j])
            dG = np.asarray(gains_for(_with_gain(design, f)), float) - G0
            Q += dG.T @ dG
    if unc.names:
        L = _chol(unc.cov)
        for i in range(L.shape[1]):
            if not np.any(L[:, i]):
                continue
            d = _with_params(design, unc, unc.mean + L[:, i], reload)
            dG = np.asarray(gains_for(d), float) - G0
            Q += dG.T @ dG
    if unc.pair:
        dG = np.asarray(gains_for(pair_move(design, 1.0)), float) - G0
        Q += dG.T @ dG
    return 0.5 * (Q + Q.T)


COVERAGE_CODE = "W-SCHED-COVERAGE"


def coverage_warnings(design: Design, schedule, spans, reach=None, extra=()) -> list:
    """``W-SCHED-COVERAGE`` warnings for goals that drive outside the declared ``covered`` ranges of a calibration.

    ``spans[i]`` locates program step ``i`` (the goal's file:line:column).  ``reach(goal)`` gives the
    largest deflection from rest the goal drives a capsule (or a latch shuttle) to and the phrase that
    says where, ``(metres, phrase)``, or ``(metres, phrase, True)`` when the step then snaps the mechanism
    into contact (never covered: warned whatever the range), or None when unknown; without it only a follow goal's path
    (``target_m``) is checked.  Voltage is the sum of tone amplitudes of the goal's segments; a tone
    counts when driven (amplitude > 0), a chirp (a sweep) by its whole band.  ``extra``: goal records
    checked as well but not in ``schedule.goals`` (a sweep step's, which schedule.json does not list).
    """
    from acl.diagnostics import Diagnostic, Severity

    cover = {c.quantity: c for c in design.coverage}
    if not cover:
        return []
    out = []

    def warn(g, text, q, bench):
        c = cover[q]
        span = spans[g.step] if 0 <= g.step < len(spans) else None
        out.append(Diagnostic(COVERAGE_CODE, Severity.WARNING, f"{g.name}: {text}", span,
                              f"on the bench, measure {bench}, add those rows to the calibration data and refit "
                              "(acl fit --calibrated); or keep the program inside the covered range",
                              notes=(f"covered({q}) is declared at {c.span}",) if c.span else ()))

    def played(segs):
        fs = sorted({t.frequency_hz for s in segs for t in s.tones if t.amplitude_v > 0})
        return ", ".join(f"{f / 1e3:g}" for f in fs[:6]) + (" ..." if len(fs) > 6 else "") + " kHz"

    tol = 1e-9
    for g in sorted([*schedule.goals, *extra], key=lambda g: g.step):      # stable: a step's goals in order
        segs = [s for s in schedule.segments if s.step == g.step and s.goal == g.name]
        if "voltage" in cover and segs:
            v = max(s.amplitude_sum() for s in segs)
            lo, hi = cover["voltage"].lower, cover["voltage"].upper
            if v > hi * (1 + 1e-6) + tol:
                warn(g, f"drives up to {v:.3g} V (sum of tone amplitudes) but the calibration data covered "
                        f"{lo:.3g} .. {hi:.3g} V: the calibrated model is extrapolated", "voltage",
                     f"the displacement under this step's tones ({played(segs)}) up to {v:.3g} V")
            elif g.kind == "hold" and g.details.get("mode") == "above":
                # the promise is "no snap-in below margin x this drive": predicted where the data may not reach
                m = float(g.details.get("margin", 1.0))
                if v * m > hi * (1 + 1e-6) + tol:
                    warn(g, f"promises no snap-in up to {m:g} x its drive, {v * m:.3g} V (sum of tone amplitudes), "
                            f"but the calibration data covered {lo:.3g} .. {hi:.3g} V: the margin is extrapolated",
                         "voltage", f"the displacement under this step's tones ({played(segs)}) up to {v * m:.3g} V")
        if "frequency" in cover and segs:
            lo, hi = cover["frequency"].lower, cover["frequency"].upper
            fs = [t.frequency_hz for s in segs for t in s.tones if t.amplitude_v > 0 and not t.frequency_end_hz]
            outside = sorted({f for f in fs if f < lo * (1 - 1e-6) or f > hi * (1 + 1e-6)})
            if outside:
                warn(g, f"tones {', '.join(f'{f / 1e3:g}' for f in outside)} kHz lie outside "
                        f"the calibrated {lo / 1e3:g} .. {hi / 1e3:g} kHz", "frequency",
                     f"the response at {', '.join(f'{f / 1e3:g}' for f in outside)} kHz (a frequency sweep through "
                     "them at a low voltage)")
            bands = sorted({tuple(sorted((t.frequency_hz, t.frequency_end_hz))) for s in segs for t in s.tones
                            if t.amplitude_v > 0 and t.frequency_end_hz})
            for f0, f1 in bands:          # a chirp plays every frequency between its ends
                if f0 < lo * (1 - 1e-6) or f1 > hi * (1 + 1e-6):
                    warn(g, f"sweeps {f0 / 1e3:g} .. {f1 / 1e3:g} kHz, beyond the calibrated "
                            f"{lo / 1e3:g} .. {hi / 1e3:g} kHz", "frequency",
                         f"the response from {f0 / 1e3:g} to {f1 / 1e3:g} kHz (a frequency sweep at a low voltage)")
        if "deflection" in cover:
            got = reach(g) if reach is not None else None
            if got is None and g.target_m is not None:
                got = (float(np.max(np.linalg.norm(np.asarray(g.target_m), axis=1))), "the path reaches")
            if got is None or not np.isfinite(got[0]):
                continue
            r, phrase, contact = (*got, False)[:3]
            hi = cover["deflection"].upper
            if contact:       # the fit counts no row in contact in any covered range (acl.fit.calibrated._coverage)
                warn(g, f"{phrase} {r * 1e6:.3g} um from rest, then into contact, which no calibration covers "
                        f"(its data covered deflections up to {hi * 1e6:.3g} um, none in contact)", "deflection",
                     "the snap-in: the voltage at which it closes, and the deflection just before")
            elif r > hi * (1 + 1e-6) + 1e-12:
                warn(g, f"{phrase} {r * 1e6:.3g} um from rest but the calibration "
                        f"data covered deflections up to {hi * 1e6:.3g} um", "deflection",
                     f"static deflections up to {r * 1e6:.3g} um (raise the voltage of the covered tones)")
    return out
