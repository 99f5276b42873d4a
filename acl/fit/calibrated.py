"""Write the calibrated design: ``extends`` the original, fitted ``param`` values, the found effects as ``effect`` blocks.

The file goes next to the original (``<stem>.calibrated.acl``) so its ``extends`` obeys the import
safety rule without ``--path``; elsewhere (``acl fit --calibrated PATH``) it loads with ``--path``
naming the original's folder.  A ``param`` replaces the original's value (docs/language.md,
``extends``); effects carry the coefficient names and SI units of :mod:`acl.fit.effects`, read by
:mod:`acl.analysis.effects`.  Coefficients without a design parameter become effects where one is
the same physics (E scale -> ``stiffness_scale``, transducer gain scale -> ``transducer_gain``,
thrust coefficient of a lone actuator -> ``transducer_gain``), otherwise a comment saying how to
declare them.  The result must load with :func:`acl.load` (tested).
"""
from __future__ import annotations

import datetime
import math
import os

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
                    now: datetime.datetime | None = None) -> str:
    """The calibrated design's source, to be written at ``out_path``."""
    final, P = selection.final, problem.prepared
    rel = os.path.relpath(os.path.abspath(problem.path), os.path.dirname(os.path.abspath(out_path)))
    rel = rel.replace(os.sep, "/")
    now = now or datetime.datetime.now(datetime.timezone.utc)
    head = ["# Calibrated by `acl fit`: the original design plus fitted values and the effects found.",
            f"# date: {now.strftime('%Y-%m-%d %H:%M:%S %Z').strip()}",
            f"# design: {os.path.abspath(problem.path)}"]
    head += [f"# data: {os.path.abspath(p)}" for p in data_paths]
    if report_dir:
        head.append(f"# report: {os.path.abspath(report_dir)}/report.json")
    extra = needs_path(problem.path, out_path)
    if extra:
        head.append(f"# load with `--path {extra}` (the original is outside this file's folder tree)")
    lines = head + ["", f'extends "{rel}"', ""]
    params, comments = [], []
    effects = {eid: dict(selection.effects.get(eid, {})) for eid in selection.selected}
    single = not bool(P.pair.any())
    gain = 1.0                                   # pressure scale for transducer_gain
    e_scale = 1.0                                # Young's modulus scale for stiffness_scale
    for k, (c, v) in enumerate(zip(final.coefs, final.values)):
        if c.kind == "effect":
            continue
        lo, hi = (float(x) for x in final.ci[k])
        if c.design_param:
            p = problem.design.param(c.design_param)
            conv = {"gamma": lambda x: p.value * x / P.gamma0, "e_scale": lambda x: p.value * x}.get(c.kind, lambda x: x)
            params.append(f"param {c.design_param} = {_literal(conv(v), p.unit)}"
                          f"    # 95% interval {_literal(conv(lo), p.unit)} .. {_literal(conv(hi), p.unit)}")
        elif c.kind == "e_scale":
            e_scale *= v
            comments.append(f"# E/E_declared = {v:.6g} (95% interval {lo:.6g} .. {hi:.6g}): stiffness_scale below")
        elif c.kind == "gain":
            gain *= v
            comments.append(f"# transducer gain scale = {v:.6g} (95% interval {lo:.6g} .. {hi:.6g}): transducer_gain below")
        elif c.kind == "gamma" and single and P.gamma0 > 0 and v > 0:
            # thrust ~ pressure^2: a lone actuator's thrust coefficient is a pressure scale sqrt(gamma/gamma0)
            gain *= math.sqrt(v / P.gamma0)
            comments.append(f"# gamma (thrust at {P.f_ref / 1e3:.6g} kHz) = {_literal(v, 'N/V^2')} (95% interval "
                            f"{_literal(lo, 'N/V^2')} .. {_literal(hi, 'N/V^2')}): as transducer_gain below "
                            f"(gain = sqrt(gamma/{_literal(P.gamma0, 'N/V^2')})); or declare `param gamma` and "
                            "use it as the capsule's `thrust`")
        elif c.kind == "gamma":
            comments.append(f"# gamma (thrust at {P.f_ref / 1e3:.6g} kHz) = {_literal(v, 'N/V^2')} (95% interval "
                            f"{_literal(lo, 'N/V^2')} .. {_literal(hi, 'N/V^2')}): not applied; declare "
                            "`param gamma = ...` in the original, use it as each capsule's `thrust` (thrust at its "
                            "first mode; docs/data.md) and fit again")
        elif c.kind.split("@")[0] in ("f0", "q"):
            what = "natural frequency" if c.kind.startswith("f0") else "quality factor"
            cap = c.kind.partition("@")[2] or P.ref_capsule
            scope = f"capsule `{cap}`" if "@" in c.kind else f"capsule `{cap}` (every capsule scaled alike)"
            comments.append(f"# {what} of {scope} = {_literal(v, c.unit)} (95% interval {_literal(lo, c.unit)} .. "
                            f"{_literal(hi, c.unit)}): not applied; the language declares the capsule's geometry, "
                            "not its resonance (fit a free cavity parameter to carry it into the design)")
        elif c.kind == "alpha":
            comments.append(f"# alpha (paper Eq. 3) = {_literal(v, 'N*m^2/V^2')} (95% interval {_literal(lo, 'N*m^2/V^2')}"
                            f" .. {_literal(hi, 'N*m^2/V^2')}): not applied; the language has no Bjerknes coefficient "
                            "declaration (the analysis computes it from the capsules); declare `param alpha` to "
                            "record it")
    if e_scale != 1.0:
        eff = effects.setdefault("stiffness_scale", {"e_scale": 1.0})
        eff["e_scale"] = eff.get("e_scale", 1.0) * e_scale
    if gain != 1.0 or "transducer_gain" in effects:
        eff = effects.setdefault("transducer_gain", {"gain_slope": 0.0})
        eff["gain"] = eff.get("gain", 1.0) * gain
    if params:
        lines += ["# fitted design parameters"] + params + [""]
    if comments:
        lines += comments + [""]
    if effects:
        lines.append("# effects (acl.fit.effects; coefficients in SI)")
        for eid, vals in effects.items():
            lines.append(_effect_block(eid, vals, P.f_ref))
    else:
        lines.append("# no effect beyond the base model was found")
    return "\n".join(lines) + "\n"


def _effect_block(eid: str, vals: dict, f_ref: float) -> str:
    parts = []
    for p in EFFECTS[eid].params:
        v = vals.get(p.name, p.null)
        parts.append(f"{p.name} = {_literal(v, p.unit)}")
    if eid == "transducer_resonance":
        parts.append(f"f_ref = {_literal(f_ref, 'Hz')}")
    if eid == "transducer_gain":
        parts.append(f"f_ref = {_literal(f_ref, 'Hz')}")
        parts.append(f"gain = {_literal(vals.get('gain', 1.0), '')}")
    shown = [p.report(vals.get(p.name, p.null)) for p in EFFECTS[eid].params if p.report]   # user-facing forms
    note = "  # " + ", ".join(f"{n} = {_literal(val, u)}" for n, val, u in shown) if shown else ""
    return f"effect {eid} {{ {', '.join(parts)} }}{note}"


def _literal(value, unit):
    """An acl literal: `2.7e-11 N/V^2`, `8.2 V`, `0.5` (SI units, no spaces inside the unit; 9 digits)."""
    if not math.isfinite(value):
        return "inf"
    unit = (unit or "").replace(" ", "")
    if unit.startswith("1/"):                      # the language writes 1/V^2 as V^-2
        base, _, power = unit[2:].partition("^")
        unit = f"{base}^-{power or 1}"
    return f"{value:.9g} {unit}".strip() if unit else f"{value:.9g}"
