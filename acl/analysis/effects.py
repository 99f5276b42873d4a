"""Declared effects (``effect ID { ... }``, Design.effects) as the coefficients the analysis applies.

Coefficient names and SI units are those of :mod:`acl.fit.effects` (the calibrated design written by
`acl fit` uses them); the user-facing forms the fit reports are accepted too (``v_sat`` for
drive_saturation, ``plateau`` for neighbour_drag, ``factor`` for stiffness_scale).  transducer_gain
also takes ``f_ref`` (Hz, where the tilt is 1; required with a non-zero ``gain_slope``) and ``gain``
(a frequency-independent pressure scale, default 1).  The formulas are in :mod:`acl.physics.effects`.
"""
from __future__ import annotations

import math

from acl.design.model import Design
from acl.physics.effect_table import EFFECT_TABLE

# All read from the one table of effects (acl.physics.effects.EFFECT_TABLE):
# effect -> {coefficient: value at which the effect vanishes} (acl.fit.effects internal coordinates)
NULLS = {e.name: {c.name: c.null for c in e.internal()} for e in EFFECT_TABLE.values()}
# (effect, user-facing coefficient) -> (internal coefficient, conversion)
ALIASES = {(e.name, c.name): (c.alias_of, c.to_internal) for e in EFFECT_TABLE.values() for c in e.coefficients
           if c.alias_of}
STATIC_NOTES = {e.name: e.static_note for e in EFFECT_TABLE.values() if e.static_note}
WHERE = {e.name: e.acts_on for e in EFFECT_TABLE.values() if not e.static_note}


def coefficients(design: Design, name: str) -> dict | None:
    """Coefficients (internal SI coordinates) of the declared effect ``name``, nulls filled in; None if not declared."""
    eff = design.effect(name)
    if eff is None:
        return None
    out = dict(NULLS.get(name, {}))
    for key, value in eff.params.items():
        if (name, key) in ALIASES:
            key, conv = ALIASES[(name, key)]
            value = conv(value)
        out[key] = float(value)
    return out


def bjerknes_shape(coefs: dict) -> tuple[float, float]:
    """(gap exponent n, reference distance m) of a declared bjerknes_scale; (0, 1) (no shape) without a finite gap_ref."""
    n, ref = float(coefs.get("gap_exponent", 0.0)), float(coefs.get("gap_ref", math.nan))
    return (n, ref) if n and math.isfinite(ref) and ref > 0 else (0.0, 1.0)


def unused_coefficients(design: Design) -> list[str]:
    """``effect.coefficient`` names the analysis does not know (reported as notes)."""
    bad = []
    for eff in design.effects:
        known = set(NULLS.get(eff.name, {})) | {k for (e, k) in ALIASES if e == eff.name}
        bad.extend(f"{eff.name}.{k}" for k in eff.params if k not in known)
    return bad


def notes(design: Design) -> list[str]:
    """One note per declared effect: where it acts, or why it does not change static predictions."""
    out = []
    for eff in design.effects:
        coefs = ", ".join(f"{k} = {v:.6g}" for k, v in eff.params.items())
        if eff.name in STATIC_NOTES:
            out.append(f"declared effect {eff.name} does not change static predictions: {STATIC_NOTES[eff.name]}")
        else:
            out.append(f"effect {eff.name} active ({coefs}): {WHERE[eff.name]}")
    tg = coefficients(design, "transducer_gain")
    if tg and tg["gain_slope"] and not math.isfinite(tg["f_ref"]):
        out.append("effect transducer_gain has a gain_slope but no f_ref: the tilt is ignored (declare `f_ref = 125 kHz`)")
    bs = coefficients(design, "bjerknes_scale")
    if bs and bs["gap_exponent"] and not math.isfinite(bs["gap_ref"]):
        out.append("effect bjerknes_scale has a gap_exponent but no gap_ref: the shape is ignored (declare `gap_ref = 40 um`)")
    for name in unused_coefficients(design):
        out.append(f"effect coefficient {name} is not used by the analysis")
    return out


def neighbour_capsules(design: Design) -> frozenset[str]:
    """Capsules that have a neighbour for ``neighbour_drag``: those named with another capsule in a ``gap`` observe.

    Mirrors the fit's units (acl.fit.mechanism: such two capsules form a pair; capsules of different units do not
    interact), so a calibration actuator far from the pair is not dragged, in the fit and in the analysis alike."""
    out = set()
    for o in design.observes:
        if o.kind == "gap" and o.a and o.b:
            a, b = o.a.partition(".")[0], o.b.partition(".")[0]
            if a != b:
                out.update((a, b))
    return frozenset(out)


def first_principles_pairs(design: Design) -> bool:
    """Whether ``design``'s pair (secondary Bjerknes) forces are acl's first-principles values: two or more capsules
    and no declared ``bjerknes_scale`` (a calibration on measured pairs, or a declared spread)."""
    return len(design.capsules) >= 2 and design.effect("bjerknes_scale") is None


def with_pair_scale(design: Design, factor: float) -> Design:
    """``design`` with its Bjerknes force times ``factor`` (an effect ``bjerknes_scale { factor }`` added, located at the
    first capsule): a draw of the first-principles pair-scale spread (acl.physics.constants.PAIR_SCALE_ROWS)."""
    from acl.design.model import Effect

    eff = Effect(name="bjerknes_scale", params={"factor": float(factor)}, units={"factor": ""}, span=design.capsules[0].span)
    return design.model_copy(update={"effects": tuple(design.effects) + (eff,)})
