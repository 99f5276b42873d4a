"""Write the calibrated design in the current language: a copy of the design with fitted parameter values.

The language has no ``effect`` declaration yet, so selected effects and fitted coefficients that no
design parameter carries are written as comments in the proposed syntax (``# effect
drive_saturation { v_sat = 8.2 V }``); relative imports and csv() paths are made absolute so the
copy loads from anywhere.  The result must load with :func:`acl.load` (tested).
"""
from __future__ import annotations

import os
import re

from acl.fit.effects import EFFECTS


def _si(value, unit):
    from acl.units import format_si

    text = format_si(value, unit) if unit else f"{value:.6g}"
    return text.replace(" ", " ") if unit and not any(ch in unit for ch in "*/^") else (
        f"{value:.6g} {unit}".strip())


def calibrated_text(problem, selection) -> str:
    src_path = problem.path
    with open(src_path, encoding="utf-8") as fh:
        text = fh.read()
    base_dir = os.path.dirname(os.path.abspath(src_path))

    def absolutize(m):
        path = m.group(2)
        if os.path.isabs(path):
            return m.group(0)
        return f'{m.group(1)}"{os.path.join(base_dir, path)}"'

    text = re.sub(r'(import\s+)"([^"]+)"', absolutize, text)
    text = re.sub(r'(csv\(\s*)"([^"]+)"', absolutize, text)
    final, P = selection.final, problem.prepared
    notes = []
    for c, v in zip(final.coefs, final.values):
        if c.kind == "effect":
            continue
        if c.design_param:
            p = problem.design.param(c.design_param)
            if c.kind == "gamma":
                new = p.value * v / P.gamma0
            elif c.kind == "e_scale":
                new = p.value * v
            else:
                new = v
            text, n = re.subn(rf"(?m)^(\s*param\s+{re.escape(c.design_param)}\s*=\s*)([^\n#]*?)(\s+free\b[^\n#]*)?(\s*(#.*)?)$",
                              lambda m: f"{m.group(1)}{_literal(new, p.unit)}{m.group(4) or ''}", text, count=1)
            if n:
                notes.append(f"# {c.design_param}: fitted by `acl fit` ({_literal(new, p.unit)})")
                continue
        notes.append(_coef_comment(c, v, P))
    lines = ["", "# ---- calibrated by `acl fit` " + "-" * 40] + notes
    if selection.selected:
        lines.append("# effects found (proposed syntax; the language has no `effect` declaration yet):")
        for eid in selection.selected:
            vals = selection.effects.get(eid, {})
            parts = []
            for p in EFFECTS[eid].params:
                v = vals.get(p.name, p.null)
                if p.report:
                    name, val, unit = p.report(v)
                    if name in ("v_sat", "plateau"):
                        parts.append(f"{name} = {_literal(val, unit)}")
                        continue
                parts.append(f"{p.name} = {_literal(v, p.unit)}")
            lines.append(f"# effect {eid} {{ {', '.join(parts)} }}")
    else:
        lines.append("# no effect beyond the base model was found")
    return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"


def _coef_comment(c, v, P):
    if c.kind == "gamma":
        return f"# gamma (thrust coefficient at {P.f_ref / 1e3:.6g} kHz) = {_literal(v, 'N/V^2')}"
    if c.kind == "alpha":
        return f"# alpha (paper Eq. 3) = {_literal(v, 'N*m^2/V^2')}"
    if c.kind == "e_scale":
        return f"# E (beams) = {_literal(v * P.E0, 'Pa')}"
    return f"# transducer gain scale = {v:.6g}"


def _literal(value, unit):
    """An acl literal: `2.7e-11 N/V^2`, `8.2 V`, `0.5` (SI units, no spaces inside the unit)."""
    import math

    if not math.isfinite(value):
        return "inf"
    unit = (unit or "").replace(" ", "")
    return f"{value:.6g} {unit}".strip() if unit else f"{value:.6g}"
