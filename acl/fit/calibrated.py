"""Write the calibrated design: ``extends`` the original, every fitted value applied, with its covariance.

The file goes next to the original (``<stem>.calibrated.acl``) so its ``extends`` obeys the import
safety rule without ``--path``; elsewhere (``acl fit --calibrated PATH``) it loads with ``--path``
naming the original's folder.

Everything the fit found is *applied* by the analysis, compile and lint (tested: fit -> calibrated
design -> ``acl analyze`` reproduces the fit's predictions):

* every fitted coordinate is a parameter with its standard error, ``param fit_X = v +- s`` (a
  fitted design parameter keeps its own name and replaces the original's value), and the fit's
  correlations are an ``uncertainty { correlation(a, b) = r }`` block: the covariance of the fit,
  in the language, for ``acl compile``'s robust mode and error bands; a coordinate fitted within
  positive bounds (every one but a signed effect coefficient) is named in ``lognormal(...)``, so the
  bands draw it from the log-normal of the same mean and covariance: a poorly identified gamma and
  alpha the data tie in ratio are drawn along that ratio, never negative;
* effects are ``effect ID { coefficient = fit_ID_coefficient }`` (:mod:`acl.fit.effects` names, SI),
  read by :mod:`acl.analysis.effects`;
* coefficients without a design parameter are written as the physics they stand for: the thrust
  coefficient gamma scales the drive pressure (thrust ~ p^2: ``transducer_gain { gain =
  (fit_gamma / gamma0)^0.5 }``, which scales thrust, jet drag and Bjerknes force alike); the Bjerknes
  coefficient alpha of a pair is then ``bjerknes_scale { factor = (fit_alpha / alpha0) / (fit_gamma /
  gamma0) }``; a modulus scale E is ``stiffness_scale``; a gain scale multiplies ``transducer_gain``;
* ``discrepancy(position)`` is the fit's RMS residual: what the calibrated model still misses
  (model error and measurement noise), which the error bands add per waypoint; for a pair whose
  calibrated analysis (full force model) departs from the Eq. 3 fit's predictions at the measured
  drives by more than 2x that residual, that departure is added in quadrature (W-FIT-PAIR-MODEL,
  acl/fit/modelcheck.py);
* ``covered(voltage|frequency|deflection)`` records the range of the data, so a program that drives
  outside it is warned about (``acl compile``), and the transducer's prior table uncertainty
  becomes relative to the gain at the covered frequencies (acl.schedule.bands).

The result must load with :func:`acl.load` (tested).
"""
from __future__ import annotations

import datetime
import math
import os
import re

from acl.fit.effects import EFFECTS


def default_path(design_path: str) -> str:
    """``<folder>/<stem>.calibrated.acl`` next to the original design."""
    folder, name = os.path.split(os.path.abspath(design_path))
    stem = name[:-4] if name.endswith(".acl") else name
    return os.path.join(folder, f"{stem}.calibrated.acl")


def needs_path(design_path: str, calibrated_path: str) -> str | None:
    """The folder to pass as ``--path`` when the calibrated file is outside the original's folder tree, else None."""
    orig = os.path.dirname(os.path.abspath(design_path))
    here = os.path.dirname(os.path.abspath(calibrated_path))
    inside = os.path.commonpath([orig, here]) == here
    return None if inside else orig


def calibrated_text(problem, selection, out_path: str, data_paths=(), report_dir: str | None = None,
                    now: datetime.datetime | None = None, model_discrepancy: float = 0.0,
                    model_scale_sd: float = 0.0, tone_gain: dict | None = None) -> str:
    """The calibrated design's source, to be written at ``out_path``.

    ``model_discrepancy`` (m): the largest difference between the calibrated design's analysis and the fit's
    own predictions at the measured drives checked (acl/fit/modelcheck.py, pairs); added in quadrature to
    ``discrepancy(position)`` so later stages do not inherit the Eq. 3 fit's residual as their error.
    ``model_scale_sd``: the relative mismatch of the drive scale at snap-in between the fit's Eq. 3 model and the
    calibrated design's analysis (acl.fit.modelcheck.snap_mismatch); declared as ``param fit_pair_model_scale =
    1 +- model_scale_sd`` multiplying the transducer gain, so compile's hold/cross margin bands draw it.
    ``tone_gain``: the gain at each tone the data drove and its relative standard error (acl.fit.report.tone_gains),
    written as ``measured(gain)`` entries ``(tone, table value there, relative sd)``: the calibrated design's table
    carries the tone's own gain; ``discrepancy(position)`` is then the residual of the model with those gains."""
    import numpy as np

    final, P = selection.final, problem.prepared
    rel = os.path.relpath(os.path.abspath(problem.path), os.path.dirname(os.path.abspath(out_path)))
    rel = rel.replace(os.sep, "/")
    now = now or datetime.datetime.now(datetime.timezone.utc)
    head = ["# Calibrated by `acl fit`: the original design with every fitted value and effect applied.",
            f"# date: {now.strftime('%Y-%m-%d %H:%M:%S %Z').strip()}",
            f"# design: {os.path.normpath(problem.path)}"]
    # the paths as the user gave them (the command line, and diagnostics, name them so), not absolute ones
    # that would carry the machine's folders into a file meant to be shared
    head += [f"# data: {os.path.normpath(p)}" for p in data_paths]
    if report_dir:
        head.append(f"# report: {os.path.join(os.path.normpath(report_dir), 'report.json')}")
    if needs_path(problem.path, out_path):
        head.append(f"# load with `--path {os.path.dirname(os.path.normpath(problem.path)) or '.'}` (the original "
                    "is outside this file's folder tree)")
    lines = head + ["", f'extends "{rel}"', ""]
    pair = bool(P.pair.any() or (P.group_row is not None and P.group_row.any()))
    names, params = [], []              # parameter name per fitted coordinate; its declaration
    positive: list[str] = []            # fitted within positive bounds: drawn log-normal (``lognormal(...)``)
    effects: dict[str, dict[str, str]] = {eid: {} for eid in selection.selected}
    gain_terms: list[str] = []          # factors of the transducer_gain `gain` (pressure scale)
    notes: list[str] = []
    by_kind: dict[str, str] = {}
    # coefficients the gain measured at each tone spans (a gain scale, a tilt, a thrust coefficient): at those tones
    # their error is the measured(gain) figures, so they are declared exact (drawn again they would count it twice)
    spanned = set(getattr(tone_gain, "spanned", ()))
    for k, (c, v) in enumerate(zip(final.coefs, final.values)):
        se = float(final.stderr[k]) if np.isfinite(final.stderr[k]) else float("nan")
        lo, hi = (float(x) for x in final.ci[k])
        if c.kind == "effect":
            unit = next((q.unit for q in EFFECTS[c.effect].params if q.name == c.param), c.unit)
            name = f"fit_{c.effect}_{c.param}"
            effects.setdefault(c.effect, {})[c.param] = name
        elif c.design_param:
            p = problem.design.param(c.design_param)
            factor = {"gamma": p.value / P.gamma0, "e_scale": p.value}.get(c.kind, 1.0)
            v, se, lo, hi, unit, name = v * factor, se * factor, lo * factor, hi * factor, p.unit, c.design_param
            if c.kind == "gamma":
                caps = sorted(getattr(P, "gamma_caps", None) or ())
                others = sorted({cap.name for cap in problem.design.capsules} - set(caps))
                if caps:
                    notes.append(f"# {name}: the fitted thrust coefficient of capsule{'s' if len(caps) > 1 else ''} "
                                 f"{', '.join(f'`{x}`' for x in caps)} (each declares `thrust = {name}`; the fit scaled "
                                 "exactly these, the analysis applies it to exactly these)"
                                 + (f"; {', '.join(f'`{x}`' for x in others)} keep{'s' if len(others) == 1 else ''} "
                                    "the physics' own thrust" if others else ""))
        else:
            unit = {"gamma": "N/V^2", "alpha": "N*m^2/V^2"}.get(c.kind, c.unit or "")
            name = "fit_" + re.sub(r"\W", "_", c.kind)      # f0@left -> fit_f0_left
            if c.kind == "spread":
                notes.append(f"# {name}: relative scatter of the latch's switching force from ramp to ramp (0/1 state "
                             "rows); a property of the data, not applied (the analysis switches at the force itself)")
            if c.kind.split("@")[0] in ("f0", "q"):
                what = "natural frequency" if c.kind.startswith("f0") else "quality factor"
                cap = c.kind.partition("@")[2] or P.ref_capsule
                whose = (f"the mode orifice `{cap}` dominates" if "." in cap else f"capsule `{cap}`")
                notes.append(f"# {name}: the {what} of {whose}; not applied to the design (the language "
                             "declares the capsule's geometry, not its resonance: fit a free cavity parameter to "
                             "carry it into the design)")
        names.append(name)
        by_kind[c.kind] = name
        rel_se = se / max(abs(v), 1e-300)
        if c.kind != "effect" and (not np.isfinite(rel_se) or rel_se > 1.0):     # as solve.fit's warning
            notes.append(f"# WARNING: {name} is not identifiable from these data (relative standard error "
                         f"{rel_se:.3g}): its value is where the optimizer stopped, not a measurement; later stages "
                         "draw it from its +- (acl compile's bands), so they are wide")
        if c.name in spanned:
            params.append(f"param {name} = {_literal(v, unit)}    # fitted +- {_literal(se, unit)}; spanned by the "
                          "gain measured at each tone (measured(gain) below), which carries its error")
            continue
        if c.lower >= 0 and v > 0 and _pm(se, unit):
            positive.append(name)
        params.append(f"param {name} = {_literal(v, unit)}{_pm(se, unit)}"
                      f"    # 95% interval {_literal(lo, unit)} .. {_literal(hi, unit)}")
    if model_scale_sd > 0:
        # nominal 1: the analysis is unchanged; its spread is what the Eq. 3 fit cannot tell about snap-in
        params.append(f"param fit_pair_model_scale = 1 +- {model_scale_sd:.6g}    # drive (pressure) scale: "
                      "W-FIT-PAIR-MODEL")
        positive.append("fit_pair_model_scale")
        notes.append("# fit_pair_model_scale: the calibrated analysis (full force model) and this fit's pair model "
                     "(paper Eq. 3) put the snap-in at different drive scales; its +- is twice that difference "
                     "(acl/fit/modelcheck.py snap_mismatch, docs/fit.md Limits), drawn by acl compile's margin bands "
                     "(hold, cross) and error bands; its nominal 1 changes nothing")
    # coefficients that stand for physics the design has no parameter for
    if "e_scale" in by_kind and not _is_design(final, "e_scale"):
        effects.setdefault("stiffness_scale", {})
        prev = effects["stiffness_scale"].get("e_scale")
        effects["stiffness_scale"]["e_scale"] = by_kind["e_scale"] + (f" * {prev}" if prev else "")
    if "gain" in by_kind:
        gain_terms.append(by_kind["gain"])
    if model_scale_sd > 0:
        gain_terms.append("fit_pair_model_scale")
    if "gamma" in by_kind and not _is_design(final, "gamma") and P.gamma0 > 0:
        gain_terms.append(f"({by_kind['gamma']} / {_literal(P.gamma0, 'N/V^2')})^0.5")
        notes.append(f"# gamma is the thrust per V^2 of capsule `{P.ref_capsule}` at {P.f_ref / 1e3:.6g} kHz, every "
                     "capsule's thrust scaled alike; the design's is "
                     f"{_literal(P.gamma0, 'N/V^2')}: thrust ~ pressure^2, so it scales the drive pressure by "
                     "(gamma/gamma0)^0.5 (transducer_gain below)")
    if pair and "alpha" in by_kind:
        alpha_phys = _alpha_physics(P)
        if alpha_phys > 0:
            g = f"{by_kind['gamma']} / {_literal(P.gamma0, 'N/V^2')}" if "gamma" in by_kind and not _is_design(final, "gamma") else "1"
            effects.setdefault("bjerknes_scale", {})["factor"] = \
                f"({by_kind['alpha']} / {_literal(alpha_phys, 'N*m^2/V^2')}) / ({g})"
            what = ("the coupled model's Bjerknes coefficient at rest (acl fit --model coupled)"
                    if getattr(problem, "model", "eq3") == "coupled" else "paper Eq. 3")
            notes.append(f"# alpha ({what}) at {P.f_ref / 1e3:.6g} kHz; the physics gives "
                         f"{_literal(alpha_phys, 'N*m^2/V^2')}: bjerknes_scale below applies the ratio beyond the "
                         "pressure scale")
        else:
            notes.append("# alpha: not applied (the physics predicts no Bjerknes attraction for this pair)")
    if gain_terms or "transducer_gain" in effects:
        eff = effects.setdefault("transducer_gain", {})
        eff["gain"] = " * ".join(gain_terms) if gain_terms else "1"
    amb = getattr(selection, "ambiguous", None) or []
    if amb:
        lines.append(f"# AMBIGUOUS: these data do not tell the selected effects ({', '.join(selection.selected)}) from "
                     "the alternatives below, which explain them as well (docs/explanation/fit-effects.md); the effects applied "
                     "here are one choice among them.  The discrepancy below covers the alternatives' predictions at "
                     "the data; outside the covered range nothing does (acl compile warns there).")
        for a in amb:
            vals = ", ".join(f"{c.param} = {_literal(float(v), next((q.unit for q in EFFECTS[c.effect].params if q.name == c.param), c.unit))}"
                             for c, v in zip(a["fit"].coefs, a["fit"].values) if c.effect == a["by"])
            lines.append(f"#   {' + '.join(a['effects'])}: -2 ln L {a['delta_chi2']:+.3g}; instead of {a['replaces']}: "
                         f"effect {a['by']} {{ {vals} }}")
            lines.append(f"#     to separate {a['replaces']} from {a['by']}: {a['separate_by']}")
        lines.append("")
    lines += ["# fitted values with their standard errors (+-); correlations below"] + params + [""]
    corr = _correlations(final, names, skip={names[k] for k, c in enumerate(final.coefs) if c.name in spanned})
    cover = _coverage(problem)
    from acl.fit.report import alternative_spread, length_rmse, tone_gains_table

    measured = {f: (g, s) for f, (g, s) in tone_gains_table(tone_gain, problem).items()
                if math.isfinite(s) and 0 <= s <= 1 and (g is None or (math.isfinite(g) and g > 0))}
    if corr or cover or measured or positive:
        lines.append("uncertainty {")
        lines += [f"  correlation({a}, {b}) = {r:.6g}" for a, b, r in corr]
        if positive:
            lines.append(f"  lognormal({', '.join(positive)})    # positive: compile's bands draw them log-normal "
                         "(same mean, +- and correlations), never <= 0")
        lines += [f"  covered({q}) = {_literal(lo, u)} .. {_literal(hi, u)}" for q, (lo, hi, u) in cover.items()]
        if measured:
            # rounded up: a written figure must not be smaller than the one computed
            lines.append("  measured(gain) = [" + ", ".join(
                f"({_literal(f, 'Hz')}, " + (f"{g:.6g} Pa/V, " if g is not None else "") + f"{_round_up(100 * s)} %)"
                for f, (g, s) in sorted(measured.items()))
                + ("]    # the gain-table value each tone the data drove asks for, with its relative standard error "
                   "(acl.fit.report.tone_gains): the table carries it there (the transducer_gain effect below "
                   "multiplies it as the rest of the table), and compile's bands hold it to that error instead of the "
                   "prior" if any(g is not None for g, _ in measured.values()) else
                   "]    # relative error of the calibrated gain at each tone the data drove (acl.fit.report."
                   "tone_gain_stderr): compile's bands hold the gain table there to it instead of its prior"))
        rmse = length_rmse(problem, final)
        if getattr(tone_gain, "residual", None) is not None and measured:
            r = np.asarray(tone_gain.residual, float)
            r = r[np.isfinite(r)]
            rmse = float(np.sqrt(np.mean(r * r))) if r.size else rmse
        spread = alternative_spread(problem, selection)
        md = float(model_discrepancy or 0.0)
        if md > 0 and math.isfinite(rmse):
            # the pair's Eq. 3 fit is not the analysis' force model: its residual understates the analysis' error
            total = math.sqrt(rmse * rmse + spread * spread + md * md)
            lines.append(f"  discrepancy(position) = {_literal(total, 'm')}    # RMS residual of the fit "
                         f"({_literal(rmse, 'm')})" + (f", alternatives' spread ({_literal(spread, 'm')})" if spread > 0 else "")
                         + f" and the largest difference between this design's analysis (full force model) and the "
                         f"fit's pair model (paper Eq. 3) at the measured drives checked ({_literal(md, 'm')}), in "
                         "quadrature: W-FIT-PAIR-MODEL, docs/fit.md Limits")
        elif spread > 0 and math.isfinite(rmse):
            # ambiguous: later stages must not inherit the confidence of one arbitrary choice among equal fits
            total = math.sqrt(rmse * rmse + spread * spread)
            lines.append(f"  discrepancy(position) = {_literal(total, 'm')}    # RMS residual of the fit "
                         f"({_literal(rmse, 'm')}) with the largest RMS difference of an equally good alternative "
                         f"effect set's predictions ({_literal(spread, 'm')}), in quadrature: see AMBIGUOUS above")
        elif math.isfinite(rmse) and rmse > 0:
            lines.append(f"  discrepancy(position) = {_literal(rmse, 'm')}    # RMS residual of the fit")
        lines += ["}", ""]
    if notes:
        lines += notes + [""]
    # an effect written here replaces the one the original declares: its declared coefficients the fit held fixed
    # (P.declared, acl.fit.effects.declared_effects) are written with it, so none is lost (a calibration's shape)
    declared = dict(getattr(P, "declared", None) or {})
    if "bjerknes_scale" in effects or "bjerknes_shape" in effects:
        for eid in ("bjerknes_scale", "bjerknes_shape"):
            if eid in declared:
                effects.setdefault(eid, {})
    for eid in list(effects):
        for k, v in declared.get(eid, {}).items():
            effects[eid].setdefault(k, _literal(v, next((q.unit for q in EFFECTS[eid].params if q.name == k), "")))
    if "bjerknes_shape" in effects:     # the analysis' bjerknes_scale carries the shape (gap_exponent, gap_ref)
        from acl.fit.effects import GAP_REF

        shape = effects.pop("bjerknes_shape")
        bs = effects.setdefault("bjerknes_scale", {})
        bs["gap_exponent"] = shape["gap_exponent"]
        bs["gap_ref"] = _literal(GAP_REF, "m")
    if effects:
        lines.append("# effects (acl.fit.effects; coefficients in SI), applied by analyze, compile and lint")
        for eid, vals in effects.items():
            lines.append(_effect_block(eid, vals, P.f_ref))
    else:
        lines.append("# no effect beyond the base model was found")
    from acl.fmt import canonical

    return canonical("\n".join(lines) + "\n", out_path)   # `acl fmt --check` flagged every calibrated design


def _is_design(final, kind) -> bool:
    return any(c.kind == kind and c.design_param for c in final.coefs)


def _round_up(x: float, digits: int = 3) -> str:
    """``x`` (>= 0) to ``digits`` significant digits, rounded up."""
    if x <= 0:
        return "0"
    e = math.floor(math.log10(x)) - digits + 1
    return f"{math.ceil(x / 10 ** e - 1e-9) * 10 ** e:.{digits}g}"


def _pm(se: float, unit: str) -> str:
    """`` +- s`` when the standard error is known."""
    if not (math.isfinite(se) and se > 0):
        return ""
    return f" +- {_literal(se, unit)}"


def _correlations(final, names, skip=frozenset()) -> list[tuple[str, str, float]]:
    """Pairs (a, b, r) of the fit's correlation matrix, rounded but still positive semidefinite (``skip``: names
    declared without an uncertainty)."""
    import numpy as np

    ok = [i for i in range(len(names)) if np.isfinite(final.stderr[i]) and final.stderr[i] > 0
          and names[i] not in skip]
    if len(ok) < 2:
        return []
    C = np.array([[float(final.corr[i, j]) for j in ok] for i in ok])
    C = np.where(np.isfinite(C), C, 0.0)
    np.fill_diagonal(C, 1.0)
    for _ in range(60):                         # rounding must not break positive semidefiniteness
        R = np.round(C, 6)
        np.fill_diagonal(R, 1.0)
        if np.linalg.eigvalsh(R).min() >= 1e-9:
            break
        C = C * 0.999
        np.fill_diagonal(C, 1.0)
    return [(names[ok[i]], names[ok[j]], float(R[i, j])) for i in range(len(ok)) for j in range(i + 1, len(ok))
            if abs(R[i, j]) >= 1e-6]


def _coverage(problem) -> dict:
    """The range of the data: voltage (sum of tone amplitudes), frequency, deflection; unit strings for writing.

    Deflection: the largest deviation of an observable from its rest value (half a gap's closing); a latch state
    row in state b, the shuttle's travel from state a to state b (the latch geometry's, acl.physics.latch), which a
    ``switch`` goal's reach is checked against; a state row in state a, none (0: the position was not measured)."""
    import numpy as np

    data, P = problem.data, problem.prepared
    value = np.asarray(data.value, float)
    n = value.size
    pair = np.asarray(P.pair, bool) if P.pair is not None else np.zeros(n, bool)
    gap = pair & (np.asarray(P.s0) != 0) & (np.asarray(P.s1) != 0)   # a pair's gap: both sides move it
    d0 = np.asarray(P.d0, float) if P.d0 is not None else np.full(n, np.nan)
    if getattr(P, "group_row", None) is not None:                  # a group's gap rows (d0: their rest gap)
        gap = gap | (np.asarray(P.group_row, bool) & np.isfinite(d0))
    # a gap measured in contact (below 5 % of the rest gap) shows that the pair snapped, not the
    # force or beam laws there: it widens neither the covered voltage nor the covered deflection
    contact = gap & (value < 0.05 * np.where(np.isfinite(d0), d0, 0.0))
    tones = [t for t, c in zip(data.tones, contact) if not c]
    volts = [sum(v for _, v in t) for t in tones]
    vmax = max((v for t in tones for _, v in t), default=0.0)
    # a tone counts as calibrated where it was driven at 10 % or more of the largest amplitude
    freqs = [f for t in tones for f, v in t if v > 0 and v >= 0.1 * vmax]
    out = {}
    if volts:
        out["voltage"] = (0.0, float(max(volts)), "V")
    if freqs:
        out["frequency"] = (float(min(freqs)), float(max(freqs)), "Hz")
    dev = np.abs(value - np.asarray(P.base, float))
    dev = np.where(gap, 0.5 * dev, dev)           # the gap closes by both deflections: one side moved >= half
    keep = ~contact
    if P.state is not None and np.any(P.state):
        # a latch state (0/1) is no measured position, but state b (1) shows the shuttle travelled from state a
        # (where every fitted latch rests, E810) to state b: that travel is covered; state a (0) covers none
        dev = np.where(P.state, 0.0, dev)
        geos = P.latch_geometries or []
        switched = P.state & (value == 1.0) & (np.asarray(P.latch_id) >= 0)
        if np.any(switched):
            from acl.physics.latch import latch_landscape

            for tid in np.unique(np.asarray(P.latch_id)[switched]):
                b = latch_landscape(*geos[tid]).state_b if tid < len(geos) else None
                rows = switched & (np.asarray(P.latch_id) == tid)
                dev = np.where(rows, abs(float(b)) if b is not None else np.nan, dev)
    dev = dev[keep]
    dev = dev[np.isfinite(dev)]
    if dev.size:
        out["deflection"] = (0.0, float(dev.max()), "m")
    return out


def _alpha_physics(P) -> float:
    """The physics' Bjerknes coefficient at f_ref of the reference pair (what the analysis computes)."""
    from acl.fit.mechanism import pair_alpha_per_v2, reference_pair, reference_unit

    inst = next(iter(P.instances.values()))
    unit = reference_unit(inst, "pair") or reference_unit(inst, "group")
    return abs(float(pair_alpha_per_v2(inst, *reference_pair(inst, unit), P.f_ref))) if unit is not None else 0.0


def _effect_block(eid: str, vals: dict, f_ref: float) -> str:
    """``effect ID { coefficient = expression, ... }``; ``vals`` maps coefficients to parameter expressions."""
    parts = []
    lib = EFFECTS[eid].params if eid in EFFECTS else ()
    for p in lib:
        parts.append(f"{p.name} = {vals.get(p.name, _literal(p.null, p.unit))}")
    if eid == "transducer_gain":
        parts.append(f"f_ref = {_literal(f_ref, 'Hz')}")
        parts.append(f"gain = {vals.get('gain', '1')}")
    parts += [f"{k} = {v}" for k, v in vals.items() if k not in {p.name for p in lib} | {"gain"}]
    return f"effect {eid} {{ {', '.join(parts)} }}"


def _literal(value, unit):
    """An acl literal: `2.7e-11 N/V^2`, `8.2 V`, `0.5` (SI units, no spaces inside the unit; 9 digits)."""
    if not math.isfinite(value):
        return "inf"
    from acl.units import conventional_unit

    unit = conventional_unit((unit or "").replace(" ", ""))
    if unit.startswith("1/"):                      # the language writes 1/V^2 as V^-2
        base, _, power = unit[2:].partition("^")
        unit = f"{base}^-{power or 1}"
    return f"{value:.9g} {unit}".strip() if unit else f"{value:.9g}"
