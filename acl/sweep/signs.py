"""The probability of each bubble pair's other sign under the design's declared uncertainty (issue 24).

A pair's Bjerknes sign (paper Fig. 4f-h, Fig. S6) does not depend on the drive amplitude, but it does depend on the
damping, the orifice radii and the gap.  Where a design declares uncertainty on its parameters (``+- ...``,
``uncertainty { ... }``), ``acl sweep``'s draws of it give, per pair and frequency, the fraction of draws that
attract; the probability of the other sign is the smaller of that fraction and its complement.
"""
from __future__ import annotations

import numpy as np

from acl.design.model import Design

DRAWS = 200     # draws per design: P(other sign) to about +-0.03 at 0.2 (binomial standard error)


def declares_uncertainty(design: Design) -> bool:
    """True when any parameter of ``design`` declares a spread (``+- ...``)."""
    return bool(design.uncertain_params())


def _fkey(f: float) -> str:
    return f"{f / 1e3:g}khz".replace(".", "p")          # as acl.sweep.columns' frequency tags


def attract_fractions(design: Design, pairs, n: int = DRAWS, seed: int = 0) -> dict:
    """{(a, b, frequency_hz): fraction of ``n`` draws of the declared uncertainty in which the pair attracts} for
    ``pairs`` (a, b, frequency_hz); draws the evaluation rejects (``valid`` False) are left out, and pairs the
    batched evaluation has no sign column for are missing (not drawn)."""
    from acl.diagnostics import DiagnosticError
    from acl.sweep.driver import sweep
    from acl.sweep.evaluate import supported

    names = set(supported(design, None)[0])
    cols = {c: (a, b, f) for a, b, f in pairs if (c := f"attract_{a}_{b}_{_fkey(f)}") in names}
    if not cols:
        return {}                     # the batched evaluation has no sign column for this design: not drawn
    try:
        tab = sweep(design, n=n, seed=seed, quantities=list(cols))
    except DiagnosticError:           # a design the sweep cannot draw (its own diagnostics say why): not drawn
        return {}
    ok = np.asarray(tab["valid"], bool) if "valid" in tab.columns else np.ones(len(tab), bool)
    out = {}
    for c, key in cols.items():
        if c in tab.columns and ok.any():
            out[key] = float(np.mean(np.asarray(tab[c], float)[ok]))
    return out


def annotate_pairs(design: Design, pairs: list, n: int | None = None) -> None:
    """Set ``p_other_sign`` (None: not drawn) and ``sign_draws`` on each of an analysis' ``pairs`` (dicts of
    acl.analysis.report.Report.pairs) from ``n`` draws (default :data:`DRAWS`; 0: none) of the design's declared
    uncertainty; what `acl analyze` and ``acl.analyze`` both report."""
    if not pairs:
        return
    n = DRAWS if n is None else n
    frac = (attract_fractions(design, [(p["a"], p["b"], p["frequency_hz"]) for p in pairs], n)
            if n and declares_uncertainty(design) else {})
    for p in pairs:
        f = frac.get((p["a"], p["b"], p["frequency_hz"]))
        p["p_other_sign"] = None if f is None else (1.0 - f if p["attract"] else f)
        p["sign_draws"] = n if f is not None else 0
