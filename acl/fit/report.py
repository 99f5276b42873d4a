"""Before/after report of a fit: rich table, ``report.json`` (fields in docs/fit.md), PNG figures, atomically."""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

import numpy as np

from acl.fit import solve
from acl.fit.effects import EFFECTS

REPORT_VERSION = 1


def shown(unit: str) -> tuple[float, str]:
    """(scale, unit) a value in SI ``unit`` is printed with (acl.units.shown_unit: um for lengths, 1/V^2 ...)."""
    from acl.units import shown_unit

    return shown_unit(unit)


def param_entries(fit, problem) -> list[dict]:
    """Each fitted coordinate with value, 95 % interval and the user-facing form (E in Pa, v_sat in V, ...)."""
    P = problem.prepared
    out = []
    for k, c in enumerate(fit.coefs):
        v, se = float(fit.values[k]), float(fit.stderr[k])
        lo, hi = (float(x) for x in fit.ci[k])
        e = {"name": c.name, "value": _n(v), "unit": c.unit, "stderr": _n(se), "ci95": [_n(lo), _n(hi)],
             "initial": _n(c.value), "lower": _n(c.lower), "upper": _n(c.upper), "design_param": c.design_param}
        if c.kind == "gamma":
            e["note"] = f"thrust coefficient of the first actuator at f_ref = {P.f_ref:.6g} Hz"
        if c.kind == "e_scale":
            e.update(name="E", value=_n(v * P.E0), unit="Pa", stderr=_n(se * P.E0), ci95=[_n(lo * P.E0), _n(hi * P.E0)],
                     initial=_n(P.E0), note="Young's modulus of the beams (fitted as a scale of the declared value)")
        if c.kind == "effect":
            spec = next(p for p in EFFECTS[c.effect].params if p.name == c.param)
            if spec.report:
                name, val, unit = spec.report(v)
                e["reported"] = {"name": name, "value": _n(val), "unit": unit}
        out.append(e)
    return out


def per_observable(problem, fit) -> dict:
    d = problem.data
    w = 1.0 / np.where(np.isfinite(problem.sigma), problem.sigma, solve.NOMINAL_SIGMA)
    out = {}
    for name in sorted(set(d.observable)):
        m = d.observable == name
        r = fit.residual[m]
        out[name] = {"n": int(m.sum()), "rmse": _n(float(np.sqrt(np.mean(r * r)))),
                     "redchi": _n(float(np.sum((r * w[m]) ** 2) / max(m.sum() - fit.p * m.mean(), 1)))}
        if problem.design.observe(name).kind == "state":
            # a latch state's residual is its Pearson residual (p - y)/sqrt(p (1 - p)), a pure number
            out[name]["unit"] = "Pearson"
    return out


def length_rmse(problem, fit) -> float:
    """RMS residual (m) over the rows that observe a length (latch states, 0/1, left out)."""
    st = problem.prepared.state
    if st is None or not np.any(st):
        return fit.rmse
    r = fit.residual[~st]
    return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")


MAX_TONES = 16      # tone_gains, tone_gain_stderr: a data set with more distinct tones (a sweep) keeps the gain model
TONE_P = 0.01       # tone_gains: the per-tone gains are kept when they beat the gain model at this p-value
IDENTIFIABLE = 1e-6  # smallest singular value, relative to the largest, of the normalised columns a direction keeps


@dataclass
class ToneGains:
    """The transducer gain at each tone the data drove (:func:`tone_gains`)."""

    factor: dict          # {tone Hz: gain the data ask for there / the calibrated model's (its gain scale and tilt)}
    stderr: dict          # {tone Hz: relative standard error of that gain (log scale)}
    residual: np.ndarray  # (n,) residual (m) of the calibrated model with these gains, every row
    dof: int              # train rows minus identified directions
    spanned: tuple = ()   # fitted coefficients (names) the per-tone gains alone span: their error is the tones'
    p_value: float = 0.0  # of the test that the per-tone gains explain the data better than the gain model


def tone_gains(problem, fit, max_tones: int = MAX_TONES) -> ToneGains | None:
    """The transducer gain at each tone the data drove, fitted one per tone, and its relative standard error.

    A tone counts where it was driven at 10 % or more of the largest amplitude (as ``covered(frequency)``).  Each
    tone's gain is a factor exp(h) on its pressure (the squared pressure of every row driven at that tone by
    exp(2 h)), over the calibrated model (its gain scale and tilt, every fitted coefficient at its value): Gauss-
    Newton on the weighted residual.  The calibrated design carries the result as a gain-table point at the tone
    (``measured(gain)``, acl/fit/calibrated.py), so the analysis and compile use the tone's own gain, not the
    table's shape times the fitted scale, which left a drawn table's gains 20-33 % off (tests/test_band_cure_cli.py).

    Standard errors (linearised least squares, s^2 (J^T J)^-1 as acl.fit.solve, central differences): every tone's
    gain free together with every fitted coefficient the per-tone gains and the coefficients before it do not
    already span (a gain scale, a tilt, a single capsule's thrust coefficient is a combination of the tones' gains
    and is left at its value: identifiability; ``spanned`` names those the tones' gains alone span, which the
    calibrated design then declares exact).  s^2 is the
    reduced chi-square of the per-tone model, at least 1 when the data state their sigma; without a sigma column
    it is an estimate from ``dof`` degrees of freedom, and the error is widened by t(0.975, dof) / 1.96.

    The per-tone gains are a model choice, made as the fit's effects are: kept when they explain the data better
    than the gain model at p < TONE_P (the drop of chi-square, scaled by s^2, against chi-square with the number
    of directions they add when the data state their sigma; an F-test otherwise).  A gain model that fits (a
    tilt-shaped transducer) keeps its coefficients and their covariance.

    None (the gain model is kept at every tone; :func:`tone_gain_stderr` gives its error there) when the per-tone
    gains add no direction the fitted coefficients do not span (one tone and a free gain or thrust: the calibrated
    model already fits it) or do not fit significantly better, for latch states (their rows are not least
    squares), more than ``max_tones`` tones (a sweep: its tilt and resonance effects are the model), a rank-deficient
    fit, or no degree of freedom left to estimate the noise; a tone whose gain the data cannot tell apart from the
    others' is left out.
    """
    from scipy.stats import t as student

    from acl.fit.forward import predict

    P = problem.prepared
    if fit is None or (P.state is not None and np.any(P.state)) or not fit.full_rank:
        return None
    v = np.asarray(P.v, float)
    live = (v > 0) & (v >= 0.1 * float(v.max(initial=0.0)))
    tones = np.unique(np.asarray(P.f, float)[live])
    if tones.size == 0 or tones.size > max_tones or not np.isfinite(fit.redchi):
        return None
    train = np.asarray(fit.train)
    w = 1.0 / np.where(np.isfinite(problem.sigma), problem.sigma, solve.NOMINAL_SIGMA)
    y = np.asarray(problem.y, float)
    vals = np.asarray(fit.values, float)
    masks = [(np.asarray(P.f) == f) & (v > 0) for f in tones]

    def full(h, values=vals):
        coeffs, effects = solve.split_coefs(fit.coefs, values)
        weight = np.ones(v.shape)
        for m, hf in zip(masks, h):
            weight = np.where(m, np.exp(2.0 * hf), weight)
        coeffs["tone_weight"] = weight
        return predict(P, coeffs, effects)

    def pred(h, values=vals):
        return full(h, values)[train] * w[train]

    def cols_h(h, which):
        out = []
        for k in which:
            up, dn = h.copy(), h.copy()
            up[k] += 1e-4
            dn[k] -= 1e-4
            out.append((pred(up) - pred(dn)) / 2e-4)
        return out

    yw = y[train] * w[train]
    h = np.zeros(tones.size)
    keep = _independent(cols_h(h, range(tones.size)), [])
    if not keep:
        return None
    sel = np.array(keep)
    cost = _sumsq(yw - pred(h))
    for _ in range(8):                                  # Gauss-Newton with step halving
        r = yw - pred(h)
        J = np.column_stack(cols_h(h, sel))
        ok = np.all(np.isfinite(J), axis=1) & np.isfinite(r)
        if ok.sum() < sel.size:
            return None
        step = np.linalg.lstsq(J[ok], r[ok], rcond=None)[0]
        for _ in range(20):
            trial = h.copy()
            trial[sel] += step
            c = _sumsq(yw - pred(trial))
            if c <= cost:
                break
            step = 0.5 * step
        else:
            break
        h, cost = trial, c
        if np.max(np.abs(step)) < 1e-7:
            break
    # standard errors at the fitted gains: every tone free, with the coefficients they do not span
    hc = cols_h(h, sel)
    cc = _coefficient_columns(fit.coefs, vals, lambda values: pred(h, values))
    added = len(_independent(hc, cc))
    if not added:
        return None             # the coefficients already fit each tone's gain: nothing to carry (tone_gain_stderr)
    coef_keep = _independent(cc, hc)
    J = np.column_stack(hc + [cc[i] for i in coef_keep])
    r = yw - pred(h)
    ok = np.all(np.isfinite(J), axis=1) & np.isfinite(r)
    J, r = J[ok], r[ok]
    dof = int(J.shape[0] - J.shape[1])
    if dof < (0 if problem.data.has_sigma else 1):
        return None
    norm = np.linalg.norm(J, axis=0)
    if not np.all(norm > 0):
        return None             # a direction the usable rows do not see
    Jn = J / norm
    s2 = _sumsq(r) / max(dof, 1)
    widen = 1.0
    if problem.data.has_sigma:
        s2 = max(s2, 1.0)                               # the stated noise is a floor: few rows can scatter less
    else:
        widen = float(student.ppf(0.975, dof)) / 1.959963984540054
    # the per-tone gains are a model choice, made as the fit's effects are: kept only where they explain the data
    # significantly better than the gain model (chi-square of the drop at the stated noise, else an F-test)
    from scipy.stats import chi2 as chi2_dist
    from scipy.stats import f as f_dist

    drop = max(_sumsq((yw - pred(np.zeros_like(h)))[ok]) - _sumsq(r), 0.0)
    if problem.data.has_sigma:
        p_value = float(chi2_dist.sf(drop / s2, added))
    else:
        p_value = float(f_dist.sf(drop / added / s2, added, dof))
    if not p_value < TONE_P:
        return None
    cov = np.linalg.inv(Jn.T @ Jn) * s2
    se = np.sqrt(np.clip(np.diag(cov)[:sel.size], 0.0, None)) / norm[:sel.size] * widen
    resid = y - full(h)
    factor, stderr = {}, {}
    for k, s in zip(sel, se):
        if np.isfinite(h[k]) and abs(h[k]) < 700.0 and np.isfinite(s):
            factor[float(tones[k])] = float(np.exp(h[k]))
            stderr[float(tones[k])] = float(s)
    spanned = tuple(c.name for i, c in enumerate(fit.coefs) if not _independent([cc[i]], hc))
    return ToneGains(factor, stderr, resid, dof, spanned, p_value) if factor else None


def tone_gains_table(tones, problem) -> dict:
    """{tone Hz: (gain-table value Pa/V measured there, relative standard error)}: the design's table at the tone
    (acl.physics.transducer.pressure_per_volt) times the fitted factor (:func:`tone_gains`); the value None without a
    transducer, or for {tone Hz: relative error} of :func:`tone_gain_stderr` (the gain model kept there)."""
    from acl.physics.transducer import pressure_per_volt

    if tones is None:
        return {}
    if isinstance(tones, dict):
        return {f: (None, s) for f, s in tones.items()}
    t = problem.design.transducer
    out = {}
    for f, x in tones.factor.items():
        g = float(pressure_per_volt(f, t.gain_frequencies, t.gain_pa_per_v)[0]) * x if t is not None else None
        out[f] = (g, tones.stderr[f])
    return out


def tone_gain_entries(tones, problem) -> list[dict]:
    """report.json ``tone_gains``: per tone, the fitted factor over the calibrated model, the gain-table value and
    its relative standard error (:func:`tone_gains`); factor and value None where the gain model is kept."""
    return [{"frequency_hz": f, "factor": None if g is None else _n(tones.factor[f]), "gain_pa_per_v": _n(g),
             "relative_stderr": _n(s)} for f, (g, s) in tone_gains_table(tones, problem).items()]


def _coefficient_columns(coefs, vals, pred) -> list:
    """d pred / d value of each fitted coefficient by central differences (1e-4 relative steps, kept within bounds)."""
    cols = []
    for i, c in enumerate(coefs):
        d = 1e-4 * max(abs(vals[i]), abs(c.scale), 1e-300)
        up, dn = vals.copy(), vals.copy()
        up[i] = min(vals[i] + d, c.upper) if np.isfinite(c.upper) else vals[i] + d
        dn[i] = max(vals[i] - d, c.lower) if np.isfinite(c.lower) else vals[i] - d
        cols.append((pred(up) - pred(dn)) / (up[i] - dn[i]))
    return cols


def tone_gain_stderr(problem, fit, max_tones: int = MAX_TONES) -> dict:
    """{tone Hz: relative error} of the calibrated model's transducer gain at each tone the data measured: the
    standard error of a free gain there, all fitted coefficients free (linearised least squares, s^2 (J^T J)^-1 as
    acl.fit.solve, by central differences), combined in quadrature with how far the data put that free gain from the
    calibrated model's (one Gauss-Newton step), since the calibrated design carries the fitted coefficients, not
    the tone's own gain.

    A tone counts where it was driven at 10 % or more of the largest amplitude (as ``covered(frequency)``).  The
    calibrated model's gain there holds to this figure whatever the gain table's shape (the tone's own gain is
    a free coordinate here, not the table times the fitted tilt), so the calibrated design declares it
    (``measured(gain)``) and the error bands of a compile hold the table at the tone to it instead of the
    table's prior (acl.schedule.bands).  Nothing (``{}``) for latch states (their rows are not least squares),
    more than ``max_tones`` tones, or a rank-deficient fit; a tone whose gain the data cannot tell is left out.
    """
    from acl.fit.forward import predict

    P = problem.prepared
    if fit is None or (P.state is not None and np.any(P.state)) or not fit.full_rank:
        return {}
    v = np.asarray(P.v, float)
    live = (v > 0) & (v >= 0.1 * float(v.max(initial=0.0)))
    tones = np.unique(np.asarray(P.f, float)[live])
    if tones.size == 0 or tones.size > max_tones or not np.isfinite(fit.redchi):
        return {}
    train = np.asarray(fit.train)
    w = 1.0 / np.where(np.isfinite(problem.sigma), problem.sigma, solve.NOMINAL_SIGMA)
    vals = np.asarray(fit.values, float)

    def pred(values, tone=None, h=0.0):
        coeffs, effects = solve.split_coefs(fit.coefs, values)
        if tone is not None:
            coeffs["tone_weight"] = np.where((P.f == tone) & (P.v > 0), np.exp(2.0 * h), 1.0)
        return predict(P, coeffs, effects)[train] * w[train]

    cols = _coefficient_columns(fit.coefs, vals, pred)
    base = pred(vals)
    resid = np.asarray(problem.y, float)[train] * w[train] - base       # weighted residual of the fitted model
    out = {}
    for f in tones:
        jh = (pred(vals, f, 1e-4) - pred(vals, f, -1e-4)) / 2e-4
        J = np.column_stack(cols + [jh])
        ok = np.all(np.isfinite(J), axis=1) & np.isfinite(resid)
        J, r = J[ok], resid[ok]
        norm = np.linalg.norm(J, axis=0)
        if J.shape[0] <= J.shape[1] or not np.all(norm > 0):
            continue
        Jn = J / norm
        sv = np.linalg.svd(Jn, compute_uv=False)
        if sv[-1] <= 1e-9 * sv[0]:
            continue                                    # the tone's own gain is degenerate with the coefficients
        cov = np.linalg.inv(Jn.T @ Jn) * fit.redchi
        se = float(np.sqrt(max(cov[-1, -1], 0.0)) / norm[-1])
        # the tone's gain that the data ask for (one Gauss-Newton step with every coefficient free): the calibrated
        # design does not carry it, so its offset from the calibrated model's gain is part of the gain's error there
        h = float(np.linalg.lstsq(Jn, r, rcond=None)[0][-1] / norm[-1])
        offset = math.expm1(h) if np.isfinite(h) and h < 700.0 else math.inf     # exp(700) ~ 1e304
        sd = math.hypot(se, offset)
        if np.isfinite(sd):
            out[float(f)] = sd
    return out


def _independent(cols, base) -> list[int]:
    """Indices of ``cols`` kept, in order, each adding a direction the kept ones (after ``base``) do not span
    (normalised columns, smallest singular value above IDENTIFIABLE x the largest)."""
    kept, acc = [], [c / n for c in base if (n := np.linalg.norm(c)) > 0 and np.all(np.isfinite(c))]
    for i, c in enumerate(cols):
        n = np.linalg.norm(c)
        if not (np.isfinite(n) and n > 0):
            continue
        trial = np.column_stack(acc + [c / n])
        if trial.shape[0] < trial.shape[1]:
            continue
        sv = np.linalg.svd(trial, compute_uv=False)
        if sv[-1] > IDENTIFIABLE * sv[0]:
            acc.append(c / n)
            kept.append(i)
    return kept


def _sumsq(r) -> float:
    r = np.asarray(r, float)
    return float(r @ r) if np.all(np.isfinite(r)) else math.inf


def covariance(fit) -> dict:
    """Covariance of the fitted coordinates (SI, the order of ``names``): cov = corr x stderr stderr^T (s^2 (J^T J)^-1),
    for later stages (acl/fit/calibrated.py writes it; robust compile samples it)."""
    se = np.asarray(fit.stderr, float)
    cov = np.asarray(fit.corr, float) * np.outer(se, se)
    return {"names": [c.name for c in fit.coefs], "units": [c.unit for c in fit.coefs],
            "values": [_n(float(v)) for v in fit.values],
            "matrix": [[_n(float(x)) for x in row] for row in cov]}


def critical_distance(fit, problem) -> dict | None:
    """d_c = sqrt(alpha/(2 gamma)) (paper Eq. 3) with a delta-method 95 % interval, when both were fitted or known."""
    P = problem.prepared
    coupled = getattr(problem, "model", "eq3") == "coupled" and P.group_row is not None and np.any(P.group_row)
    if not (np.any(P.pair) or coupled):
        return None
    names = [c.kind for c in fit.coefs]
    a = fit.values[names.index("alpha")] if "alpha" in names else P.alpha0
    g = fit.values[names.index("gamma")] if "gamma" in names else P.gamma0
    va = (fit.stderr[names.index("alpha")] / a) ** 2 if "alpha" in names else 0.0
    vg = (fit.stderr[names.index("gamma")] / g) ** 2 if "gamma" in names else 0.0
    cov = 0.0
    if "alpha" in names and "gamma" in names:
        i, j = names.index("alpha"), names.index("gamma")
        cov = fit.corr[i, j] * fit.stderr[i] * fit.stderr[j] / (a * g)
    dc = math.sqrt(a / (2 * g))
    rel = 0.5 * math.sqrt(max(va + vg - 2 * cov, 0.0))
    return {"value": _n(dc), "unit": "m", "stderr": _n(dc * rel), "ci95": [_n(dc * (1 - 1.96 * rel)), _n(dc * (1 + 1.96 * rel))],
            "formula": "sqrt(alpha / (2 gamma)), paper Eq. (3)" + (
                ", with the coupled model's coefficients at rest (acl analyze reports the analysis' own)" if coupled
                and not np.any(P.pair) else "")}


def outliers(problem, fit, limit: float = solve.JUMP) -> list[dict]:
    """Rows farther than ``limit`` sigma from the final model (typically measured just before a snap-in the
    model puts slightly earlier, or vice versa: the fold makes the prediction jump)."""
    d = problem.data
    sig = np.where(np.isfinite(problem.sigma), problem.sigma, solve.NOMINAL_SIGMA)
    z = fit.residual / sig
    if not problem.data.has_sigma:
        z = z / max(math.sqrt(fit.redchi), 1e-300)
    out = []
    for i in np.flatnonzero(np.abs(z) > limit)[:50]:
        sp = d.spans[i]
        out.append({"file": sp.file if sp else None, "line": sp.line if sp else None, "observable": d.observable[i],
                    "value": _n(d.value[i]), "prediction": _n(fit.prediction[i]), "z": _n(z[i])})
    return out


def alternative_spread(problem, selection) -> float:
    """Largest RMS difference (m) between the selected model's and an ambiguous alternative's predictions over the
    rows that observe a length (0 when nothing is ambiguous): what the data cannot decide, added to the calibrated
    design's discrepancy (acl/fit/calibrated.py)."""
    st = problem.prepared.state
    keep = ~st if st is not None else np.ones(problem.data.n, bool)
    out = 0.0
    for a in getattr(selection, "ambiguous", []) or []:
        d = (a["fit"].prediction - selection.final.prediction)[keep]
        d = d[np.isfinite(d)]
        if d.size:
            out = max(out, float(np.sqrt(np.mean(d * d))))
    return out


def ambiguous_entries(selection, problem) -> list[dict]:
    """report.json `ambiguous`: each alternative effect set that explains the data as well as the selected one."""
    from acl.fit.select import AMBIGUOUS_CHI2

    out = []
    for a in getattr(selection, "ambiguous", []) or []:
        out.append({"effects": list(a["effects"]), "replaces": a["replaces"], "by": a["by"],
                    "delta_chi2": _n(a["delta_chi2"]), "delta_bic": _n(a["delta_bic"]),
                    "threshold_chi2": AMBIGUOUS_CHI2, "separate_by": a["separate_by"],
                    "parameters": [e for e in param_entries(a["fit"], problem) if e["name"].startswith(a["by"] + ".")],
                    "rmse": _n(length_rmse(problem, a["fit"]))})
    return out


def build_report(problem, selection, tests_before, tests_after, calibrated_name=None) -> dict:
    from acl.fit.residuals import structured

    base, final = selection.base, selection.final
    P = problem.prepared
    tried = []
    for t in selection.trials:
        item = {"effect": t.effect, "round": t.round, "status": t.status, "reason": t.reason,
                "f_statistic": _n(t.f_stat), "p_value": _n(t.p_value), "delta_bic": _n(t.delta_bic),
                "delta_aicc": _n(t.delta_aicc), "cv_mse": _n(t.cv), "cv_mse_current": _n(t.cv_current)}
        if t.fit is not None:
            item["rmse"] = _n(t.fit.rmse)
            item["parameters"] = [e for e in param_entries(t.fit, problem) if e["name"].startswith(t.effect + ".")]
        tried.append(item)
    return {
        "version": REPORT_VERSION,
        "design": problem.path,
        "data": list(problem.data.files),
        "rows": problem.data.n,
        "f_ref": P.f_ref,
        "sigma_given": problem.data.has_sigma,
        "base": {"parameters": param_entries(base, problem), "rmse": _n(base.rmse), "redchi": _n(base.redchi),
                 "chi2": _n(base.chi2), "aicc": _n(base.aicc), "bic": _n(base.bic), "warnings": base.warnings,
                 "per_observable": per_observable(problem, base)},
        "residual_tests_before": [t.as_dict() for t in tests_before],
        "effects_tried": tried,
        "effects_selected": list(selection.selected),
        "ambiguous": ambiguous_entries(selection, problem),
        "effects_tentative": list(getattr(selection, "tentative", [])),
        "adequacy": getattr(selection, "adequacy", {}),
        "final": {"parameters": param_entries(final, problem), "effects": selection.effects,
                  "rmse": _n(final.rmse), "redchi": _n(final.redchi), "chi2": _n(final.chi2),
                  "aicc": _n(final.aicc), "bic": _n(final.bic), "warnings": final.warnings,
                  "per_observable": per_observable(problem, final),
                  "covariance": covariance(final)},
        "critical_distance": critical_distance(final, problem),
        "rmse_before": _n(length_rmse(problem, base)),
        "rmse_after": _n(length_rmse(problem, final)),
        "unexplained": [t.as_dict() for t in structured(tests_after)],
        "outliers": outliers(problem, final),
        "residual_tests_after": [t.as_dict() for t in tests_after],
        "calibrated_design": calibrated_name,
    }


def render_table(report, console=None) -> None:
    """Rich tables: parameters before/after, per-observable and overall errors, effects tried."""
    from acl._console import make_console
    from acl._console import table as Table
    from acl.units import conventional_unit

    con = console or make_console(highlight=False)
    t = Table(title="fit: before (base model) and after (with selected effects)")
    for col in ("observable", "n", "RMSE before", "RMSE after", "red. chi2 before", "red. chi2 after"):
        t.add_column(col, justify="right" if col != "observable" else "left")
    b, a = report["base"]["per_observable"], report["final"]["per_observable"]
    for name in b:
        fmt = _um if b[name].get("unit") != "Pearson" else (lambda x: f"{_g(x)} (Pearson)")
        t.add_row(name, str(b[name]["n"]), fmt(b[name]["rmse"]), fmt(a[name]["rmse"]),
                  _g(b[name]["redchi"]), _g(a[name]["redchi"]))
    t.add_row("[bold]overall", str(report["rows"]), _um(report["rmse_before"]), _um(report["rmse_after"]),
              _g(report["base"]["redchi"]), _g(report["final"]["redchi"]))
    con.print(t)
    pt = Table(title="parameters (95 % intervals)")
    for col in ("parameter", "before", "after", "95 % interval", "unit"):
        pt.add_column(col, no_wrap=True)
    before = {p["name"]: p for p in report["base"]["parameters"]}
    for p in report["final"]["parameters"]:
        rep = p.get("reported")
        k, unit = shown(p["unit"])

        def g(x):
            return _g(x * k if isinstance(x, (int, float)) else x)
        pt.add_row(p["name"], g(before[p["name"]]["value"]) if p["name"] in before else "-", g(p["value"]),
                   f"[{g(p['ci95'][0])}, {g(p['ci95'][1])}]",
                   unit + (f"  ({rep['name']} = {_g(rep['value'])} {conventional_unit(rep['unit'])})" if rep else ""))
    con.print(pt)
    if report.get("critical_distance"):
        dc = report["critical_distance"]
        con.print(f"critical distance d_c = sqrt(alpha/(2 gamma)) = {_um(dc['value'])} "
                  f"[{_um(dc['ci95'][0])}, {_um(dc['ci95'][1])}]")
    carried = [e for e in report.get("tone_gains") or [] if e.get("factor") is not None]
    if carried:
        con.print("gain at each tone, fitted one per tone (the calibrated design's measured(gain)): "
                  + ", ".join(f"{e['frequency_hz'] / 1e3:g} kHz {_g(e['gain_pa_per_v'])} Pa/V (x{e['factor']:.3g} the "
                              f"gain model) +- {100 * e['relative_stderr']:.2g} %" for e in carried)
                  + (f"; with them the residual is {_um(report.get('tone_gains_rmse'))} RMS (the gain model's: "
                     f"{_um(report['rmse_after'])}, p = {report.get('tone_gains_p_value', 0.0):.2g}), and the notes "
                     "below on the gain model's residual do not apply to the calibrated design"
                     if report.get("tone_gains_rmse") is not None else ""))
    et = Table(title="effects tried (full reasons and CV scores: report.json of --report, or --output-format json)")
    et.add_column("#", no_wrap=True)
    et.add_column("effect", no_wrap=True)
    et.add_column("status", no_wrap=True)
    et.add_column("F-test p", no_wrap=True, justify="right")
    et.add_column("dBIC", no_wrap=True, justify="right")
    et.add_column("reason", overflow="fold", min_width=12)
    for e in report["effects_tried"]:
        short = e["reason"].split(" (")[0].split(":")[0].split(";")[0]
        status = {"not applicable": "n/a"}.get(e["status"], e["status"])
        et.add_row(str(e["round"]), e["effect"], status, _g3(e["p_value"]), _g3(e["delta_bic"]), short)
    con.print(et)
    sel = report["effects_selected"]
    con.print(f"effects selected: {', '.join(sel) if sel else 'none'}")
    for a in report.get("ambiguous") or []:
        con.print(f"[yellow]ambiguous:[/yellow] {', '.join(a['effects'])} explains these data as well "
                  f"(-2 ln L {a['delta_chi2']:+.3g}, rows beyond {solve.JUMP:g} sigma clipped; within "
                  f"{a['threshold_chi2']:g}): the data cannot tell {a['replaces']} from {a['by']}; to separate them: "
                  f"{a['separate_by']}")
    if report.get("effects_tentative"):
        ad = report["adequacy"]
        con.print(f"[yellow]withdrawn (tentative): {', '.join(report['effects_tentative'])}: they improve the fit but "
                  f"the model still fails the goodness of fit (chi2 = {ad['chi2']:.4g} for {ad['dof']} dof, "
                  f"p = {ad['p_value']:.2g}); what remains is outside the library[/yellow]")
    for w in report["final"]["warnings"]:
        con.print(f"[yellow]warning:[/yellow] {w}")
    if report.get("outliers"):
        o = report["outliers"]
        where = ", ".join(f"{x['file']}:{x['line']}" for x in o[:5])
        con.print(f"[yellow]warning:[/yellow] {len(o)} row(s) more than {solve.JUMP:g} sigma from the model "
                  f"({where}{', ...' if len(o) > 5 else ''}); near a snap-in the prediction jumps, so a row "
                  "measured just before (or after) the fold can sit on the other branch")
    if report["unexplained"]:
        if sel:
            con.print("[yellow]the selected effects leave structure in the residual:[/yellow]")
        for u in report["unexplained"]:
            con.print(f"[yellow]unexplained:[/yellow] the residual still follows {u['covariate']} "
                      f"({u['test']}, statistic {_g(u['statistic'])}, p = {_g(u['p_value'])}); "
                      "no effect in the library explains it")
    else:
        con.print("no structure left in the residual (every test p_adjusted >= 0.01)")


def figures(problem, selection, outdir) -> list[str]:
    """fit.png (data and model before/after vs voltage, or vs frequency for a one-voltage sweep) and residuals.png
    (residual vs every covariate)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acl.fit.residuals import covariates

    P, d = problem.prepared, problem.data
    volts = P.v.sum(axis=1)
    names = sorted(set(d.observable))
    files = []
    fig, axes = plt.subplots(2, 2 * len(names), figsize=(6 * len(names) + 2, 7), squeeze=False)
    strongest = P.f[np.arange(P.n), np.argmax(P.v, axis=1)]
    driven = P.v.sum(axis=1) > 0
    # a frequency sweep at one voltage is drawn against frequency (against voltage it is one stack of points)
    by_freq = (np.unique(volts[driven]).size < 2 and np.unique(strongest[driven]).size >= 2)
    xs_all, xlabel = ((strongest / 1e3, "frequency (kHz)") if by_freq else (volts, "voltage (V)"))
    keys = np.array([" ".join(f"{k}={v}" for k, v in d.override_key(i)) for i in range(d.n)], dtype=object)
    from acl.fit.forward import predict

    for j, name in enumerate(names):
        m = d.observable == name
        state = problem.design.observe(name).kind == "state"     # 0/1: plotted as is, the model as a probability
        scale, unit = (1.0, "state (0 a, 1 b)") if state else (1e6, "um")
        groups = list(dict.fromkeys((keys[i], volts[i] if by_freq else strongest[i])
                                    for i in np.flatnonzero(m & driven)))
        for k, (label, fit) in enumerate((("before", selection.base), ("after", selection.final))):
            ax, axr = axes[0, 2 * j + k], axes[1, 2 * j + k]
            model = fit.prediction
            if state:
                held, P.pearson = P.pearson, None
                try:
                    model = predict(P, *fit.as_inputs())
                finally:
                    P.pearson = held
            for gi, (key, level) in enumerate(groups):
                if by_freq:        # one curve per voltage (undriven rows have no frequency to sit at)
                    sel, tag = m & (keys == key) & driven & (volts == level), f"{level:g} V {key}"
                else:
                    sel, tag = m & (keys == key) & (~driven | (strongest == level)), f"{level / 1e3:g} kHz {key}"
                colour = f"C{gi % 10}"
                x = xs_all[sel]
                order = np.argsort(x, kind="stable")
                ax.plot(x, d.value[sel] * scale, ".", ms=3, color=colour, label=tag if len(groups) <= 10 else None)
                ax.plot(x[order], model[sel][order] * scale, "-", lw=0.8, color=colour)
                axr.plot(x, fit.residual[sel] * scale, ".", ms=3, color=colour)
            ax.set_title(f"{name}: {label}\n(dots data, lines model)", fontsize=9, wrap=True)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(unit)
            if groups and len(groups) <= 10:
                ax.legend(fontsize=6)
            axr.axhline(0, color="k", lw=0.5)
            axr.set_xlabel(xlabel)
            axr.set_ylabel(f"residual {label} ({'Pearson' if state else 'um'})")
    fig.tight_layout()
    _fit_titles(fig)
    path = os.path.join(outdir, "fit.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    files.append("fit.png")
    cov = covariates(d, P, selection.final.prediction)
    cov["frequency"] = np.where(driven, cov["frequency"], np.nan)   # an undriven row sits at no frequency
    usable = [(k, v) for k, v in cov.items() if np.unique(v[np.isfinite(v)]).size >= 2]
    fig, axes = plt.subplots(2, max(1, len(usable)), figsize=(3.2 * max(1, len(usable)), 6), squeeze=False)
    for j, (k, x) in enumerate(usable):
        for i, (label, fit) in enumerate((("before", selection.base), ("after", selection.final))):
            ax = axes[i, j]
            xs, xlabel = covariate_axis(k, x)
            ax.plot(xs, fit.residual * 1e6, ".", ms=2)
            ax.axhline(0, color="k", lw=0.5)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(f"residual {label} (um)")
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, "residuals.png"), dpi=90)
    plt.close(fig)
    files.append("residuals.png")
    return files


REPORT_FILES = frozenset({"report.json", "fit.png", "residuals.png"})


def report_dir_problem(target: str) -> str | None:
    """Why ``target`` cannot take a report (it is replaced as a whole), or None: it must be new, empty,
    or a previous report (report.json and its figures, nothing else).  Before, `--report FOLDER` renamed
    any folder away and deleted it, the user's files (the design and data too) with it."""
    if not os.path.lexists(target):
        return None
    if os.path.islink(target) or not os.path.isdir(target):
        return f"{target} exists and is not a folder"
    try:
        entries = os.listdir(target)
    except OSError as exc:
        return f"cannot list {target}: {exc.strerror or exc}"
    foreign = sorted(n for n in entries if n not in REPORT_FILES or os.path.islink(os.path.join(target, n))
                     or not os.path.isfile(os.path.join(target, n)))
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        return f"report folder {target} holds files acl fit did not write there: {shown}"
    return None


def write_report_dir(target, write) -> None:
    """Run ``write(tmpdir)`` then move the directory to ``target`` atomically (rename).

    ``target`` must pass :func:`report_dir_problem` (new, empty or a previous report): OSError otherwise."""
    import shutil
    import tempfile

    problem = report_dir_problem(target)
    if problem:
        raise OSError(problem)
    target = os.path.abspath(target)
    parent = os.path.dirname(target) or "."
    os.makedirs(parent, exist_ok=True)
    from acl._files import as_umask, deferred_signals

    tmp = None
    try:
        with deferred_signals():
            tmp = tempfile.mkdtemp(prefix=".acl-fit-", dir=parent)
        as_umask(tmp, directory=True)
        write(tmp)
        if os.path.isdir(target):
            old = tempfile.mkdtemp(prefix=".acl-fit-old-", dir=parent)
            os.rmdir(old)
            os.rename(target, old)
            os.rename(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, target)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise


def dump_json(report, path) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(report, fh, indent=2, allow_nan=False)
        fh.write("\n")


def _n(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _g(x):
    return "-" if x is None else f"{x:.4g}"


def _g3(x):
    return "-" if x is None else f"{x:.3g}"


def _um(x):
    return "-" if x is None else f"{x * 1e6:.4g} um"


# one unit per axis kind: lengths in um, frequencies in kHz, voltages in V, times in s (SI inside, units at edges)
_AXIS_UNITS = {"voltage": (1.0, "V"), "frequency": (1e-3, "kHz"), "time": (1.0, "s"), "height": (1e6, "um")}


def covariate_axis(name: str, x):
    """(values, axis label with its unit) of a residual covariate (acl.fit.residuals.covariates): the predicted value
    and the height in um like the residuals, frequency in kHz; a set: column keeps its SI value."""
    scale, unit = _AXIS_UNITS.get(name, (1e6, "um") if name.startswith("predicted") or name == "prediction"
                                  else (1.0, "SI"))
    return np.asarray(x, float) * scale, f"{name} ({unit})"


def _fit_titles(fig) -> None:
    """Shrink each panel title until it is no wider than its panel (a long observable name ran into the next panel
    and past the figure's edge)."""
    fig.canvas.draw()
    for ax in fig.axes:
        t = ax.title
        if not t.get_text():
            continue
        width = ax.get_window_extent().width
        while t.get_window_extent().width > width and t.get_fontsize() > 5:
            t.set_fontsize(t.get_fontsize() - 0.5)
