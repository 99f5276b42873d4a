"""Critical distance of a capsule pair where the full force model's net force changes sign (issue 24).

The reduced law of paper Eq. 3, d_c = sqrt(alpha / 2 gamma) (:func:`acl.analysis.acoustics.pair_table`), takes the
pair's attraction and thrusts at one configuration and assumes the neighbour's jet drag equals one thrust.  The
force model differs: the coupled responses change with the gap and the jet drag is a laminar-jet law (about 0.8
of one thrust at the Fig. 4 geometry).  Here the second capsule is moved along the line between the capsule
centres, every other capsule at rest, and the gap between the two closest orifices where the closing force
(attraction positive, the mean of the two capsules' forces along the line) changes sign from attraction to
repulsion is returned: the d_c a user sees.  ``drag_fraction`` 1 gives the same with paper Eq. 3's neighbour drag
(F_d = F_AS at every distance, acl.physics.forces.PAPER_DRAG_FRACTION): the other end of the drag law's model form,
so the two bracket d_c.
"""
from __future__ import annotations

import numpy as np

from acl.design.model import Design, Drive

GRID = 80             # gaps sampled between contact and the far end, geometric


def closing_component(forces: np.ndarray, centres: np.ndarray, a, b) -> np.ndarray:
    """Closing force (N, attraction positive) of capsule pairs (a, b): the mean of the two capsules' forces along the
    line from a's centre to b's.  ``forces`` and ``centres`` (..., C, 3); ``a``, ``b`` capsule indices (ints, or
    arrays broadcasting against the leading axes)."""
    line = centres[..., b, :] - centres[..., a, :]
    u = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-300)
    return 0.5 * np.einsum("...k,...k->...", forces[..., a, :] - forces[..., b, :], u)


def closing_force(design: Design, drive: Drive, a: str, b: str, shifts,
                  drag_fraction: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(gap between the closest orifices (S,) m, closing force (S,) N, attraction positive) with capsule ``b`` moved
    by ``shifts`` (S,) m along the line from ``a``'s centre to ``b``'s (acoustics.force_batch: the full force model)."""
    from acl.analysis.acoustics import force_batch

    names = [c.name for c in design.capsules]
    ia, ib = names.index(a), names.index(b)
    rest = np.array([c.center for c in design.capsules], float)
    unit = rest[ib] - rest[ia]
    unit = unit / np.linalg.norm(unit)
    s = np.atleast_1d(np.asarray(shifts, float))
    centres = np.repeat(rest[None], s.size, axis=0)
    centres[:, ib] = centres[:, ib] + s[:, None] * unit
    f = force_batch(design, centres, drive,
                    None if drag_fraction is None else {"jet_drag_fraction": float(drag_fraction)})
    close = closing_component(f, rest, ia, ib)             # along the line at rest: b moves along it
    ca, cb = design.capsule(a), design.capsule(b)
    oa = np.array([o.center for o in ca.orifices], float) - np.asarray(ca.center, float) + rest[ia]
    ob = np.array([o.center for o in cb.orifices], float) - np.asarray(cb.center, float)
    gaps = np.array([np.min(np.linalg.norm((ob + c)[:, None, :] - oa[None, :, :], axis=-1)) for c in centres[:, ib]])
    return gaps, close


def net_critical_distance(design: Design, drive: Drive, a: str, b: str, far: float = 400e-6,
                          drag_fraction: float | None = None) -> float | None:
    """Gap (m) between the closest orifices of ``a`` and ``b`` where the net closing force changes from attraction
    to repulsion as ``b`` moves away along the centre line (the first such change from near contact out to ``far``
    beyond the rest gap); None if it never does (always attracting or always repelling there).  ``drag_fraction``:
    :func:`closing_force`'s (None: the force model's own jet-drag law)."""
    from acl.physics.roots import brentq          # analyze imports no scipy (tests/test_analyze_ties.py)

    ca, cb = design.capsule(a), design.capsule(b)
    touch = min(x.radius for x in ca.orifices) + min(y.radius for y in cb.orifices)
    g0, _ = closing_force(design, drive, a, b, [0.0], drag_fraction)
    near = 1.05 * touch - float(g0[0])                  # a shift that brings the orifices close to touching
    grid = np.concatenate([np.linspace(near, 0.0, GRID // 2, endpoint=False),
                           np.geomspace(1e-7, far, GRID // 2)])
    grid.sort()
    gaps, close = closing_force(design, drive, a, b, grid, drag_fraction)
    ok = np.isfinite(close) & (gaps >= touch)
    idx = np.flatnonzero(ok[:-1] & ok[1:] & (close[:-1] > 0) & (close[1:] <= 0))
    if idx.size == 0:
        return None
    k = int(idx[0])
    s = brentq(lambda x: float(closing_force(design, drive, a, b, [x], drag_fraction)[1][0]), grid[k], grid[k + 1],
               xtol=1e-12)
    return float(closing_force(design, drive, a, b, [s], drag_fraction)[0][0])


def net_sign_over_pair_scale(design: Design, drive: Drive, a: str, b: str) -> dict:
    """The net closing force of ``a`` and ``b`` at rest under ``drive`` and its sign over the first-principles pair-scale
    spread (acl.physics.constants.pair_scale_cdf): the force is c0 + s (c1 - c0) in the Bjerknes scale s (c0 with the
    Bjerknes force off, c1 at first principles; the scale multiplies that force alone), so it changes sign at
    s* = c0 / (c0 - c1) and P(other sign) is the spread's mass beyond s* on the far side from 1.
    {"attract" (at s = 1), "closing_n" (c1), "flip_scale" (s*, None when the sign never changes for s > 0),
    "p_other_sign"}."""
    from acl.analysis.effects import with_pair_scale
    from acl.physics.constants import pair_scale_cdf

    _, (c1,) = closing_force(design, drive, a, b, [0.0])
    _, (c0,) = closing_force(with_pair_scale(design, 0.0), drive, a, b, [0.0])
    c0, c1 = float(c0), float(c1)
    flip = c0 / (c0 - c1) if c0 != c1 else None
    if flip is not None and flip <= 0.0:
        flip = None
    if flip is None:
        p = 0.0
    else:
        p = 1.0 - pair_scale_cdf(flip) if flip > 1.0 else pair_scale_cdf(flip)
    return {"attract": c1 > 0, "closing_n": c1, "flip_scale": flip, "p_other_sign": float(p)}


def drive_step_scale_note(design: Design, drive: Drive, span, step_text: str) -> dict | None:
    """N-PAIR-SCALE for a drive step of a design whose pair forces are first principles (no bjerknes_scale): such a
    step has no goal and so no band to draw the pair force's spread; the note gives, per pair, the net sign at rest
    and its probability of the other sign over that spread (:func:`net_sign_over_pair_scale`).  None when the pair
    forces are calibrated or the design has fewer than two capsules."""
    from acl.analysis.acoustics import pair_forces
    from acl.analysis.effects import first_principles_pairs

    if not first_principles_pairs(design):
        return None
    parts = []
    for pf in pair_forces(design, drive):
        r = net_sign_over_pair_scale(design, drive, pf.a, pf.b)
        if (not r["closing_n"] and r["flip_scale"] is None) or not np.isfinite([r["closing_n"], r["p_other_sign"]]).all():
            continue                                # no force at all (a 0 V tone), or none defined: no sign to state
        sign, other = ("attracts", "repel") if r["attract"] else ("repels", "attract")
        s = r["flip_scale"]           # the other sign lies on the side of s* away from 1
        where = f" ({other}s {'above' if s > 1.0 else 'below'} {s:.3g}x)" if s else ""
        parts.append(f"{pf.a}-{pf.b} {sign} at rest, P({other}) = {r['p_other_sign']:.2f}{where}")
    if not parts:
        return None
    return {"code": "N-PAIR-SCALE", "file": span.file, "line": span.line, "column": span.column, "message": (
        f"{step_text}: no bjerknes_scale calibrates this design's pair forces and a drive step has no band to draw "
        "their spread; over the first-principles pair-scale spread (acl.physics.constants, 95 % 0.051-180x) the net "
        "force " + "; ".join(parts) + " (acl analyze's P(other sign) gives the Bjerknes sign under the declared "
        "uncertainty)")}


def quality_bound(design: Design, name: str) -> float:
    """Largest plausible Q of capsule ``name``'s first mode (acl.physics.resonance.plausible_quality_bound: twice
    the Q of its viscous and radiation losses alone, thermal loss left out)."""
    from acl.analysis.acoustics import medium_constants, thermal_radius
    from acl.physics.resonance import capsule_modes, plausible_quality_bound

    cap = design.capsule(name)
    rho, mu, c, sigma, p0, kappa, diff, gamma = medium_constants(design).as_tuple()
    m = capsule_modes(cap.cavity.volume, np.array([o.radius for o in cap.orifices]), rho, sigma, p0, kappa, mu, c,
                      thermal_radius(cap.cavity), heat_capacity_ratio=gamma, thermal_diffusivity=diff, thermal=False)
    return float(plausible_quality_bound(m.quality[0])) if m.quality.size else float("inf")


def _note(design: Design, name: str, code: str, message: str) -> dict:
    span = design.capsule(name).span
    return {"code": code, "file": span.file, "line": span.line, "column": span.column, "message": message}


def uncoupled_phase_difference(design: Design, a: str, b: str, frequency: float) -> float:
    """|phase difference| (deg, 0..180) of the total volume responses of capsules ``a`` and ``b`` each alone at
    ``frequency`` (acl.physics.resonance.volume_response; the single-bubble picture of paper Fig. 4f: above 90 deg
    the pair repels)."""
    from acl.analysis.acoustics import modal_data
    from acl.physics.resonance import volume_response

    va, vb = (volume_response(modal_data(design, n), [frequency])[0].sum() for n in (a, b))
    return abs(float(np.degrees(np.angle(va * np.conj(vb)))))


def pair_notes(design: Design, pair: dict) -> list[dict]:
    """Located notes (code, file, line, column, message) on one analysed pair entry of ``acl analyze``.

    N-PAIR-DC where d_c moves with the neighbour-drag law by more than 5 % and the pair rests within 2x of it
    (``critical_distance_paper_drag_m``: the other end of that law); N-PAIR-SIGN where the sign rests on a declared
    Q beyond the plausible bound (:func:`quality_bound`), or where the single-bubble phases (paper Fig. 4f) say
    repel, the coupled bubbles attract, and repulsion needs a Q beyond that bound."""
    out = []
    a, b, f = pair["a"], pair["b"], pair["frequency_hz"] / 1e3
    dc, dc1, gap = pair.get("critical_distance_m"), pair.get("critical_distance_paper_drag_m"), pair["gap_m"]
    if dc and dc1 and abs(dc / dc1 - 1) > 0.05 and gap < 2 * max(dc, dc1):
        out.append(_note(design, b, "N-PAIR-DC", (
            f"{a}-{b} at {f:g} kHz: d_c {dc * 1e6:.1f} um with the laminar-jet drag of the neighbour, "
            f"{dc1 * 1e6:.1f} um with paper Eq. (3)'s F_d = F_AS (one thrust); the interval is d_c's model-form "
            "uncertainty (docs/explanation/paper-comparison.md)")))
    if pair.get("phase_difference_predicted_q_deg") is None:
        return out                                  # an identical pair: no sign study
    qmax = min(quality_bound(design, a), quality_bound(design, b))
    rq = pair.get("repel_from_q")
    declared = [c.quality_factor for c in design.capsules if c.name in (a, b) and c.quality_factor]
    where = f"{a}-{b} at {f:g} kHz"
    if pair["attract"] and (rq is None or rq > qmax):
        alone = uncoupled_phase_difference(design, a, b, pair["frequency_hz"])
        if alone > 90.0:
            need = f"Q >= {rq:g}" if rq else "a Q above 1000"
            out.append(_note(design, a, "N-PAIR-SIGN", (
                f"{where}: each alone, the bubbles are {alone:.0f} deg apart (repel, paper Fig. 4f); coupled at this "
                f"gap they attract, and repulsion needs {need} on both capsules, above the plausible Q <= {qmax:.1f} "
                "(acl.physics.resonance.plausible_quality_bound)")))
    elif not pair["attract"] and declared and max(declared) > qmax and pair["attract_with_predicted_q"]:
        out.append(_note(design, a, "N-PAIR-SIGN", (
            f"{where} repels only with the declared Q = {max(declared):g} (from Q {rq:g}), above the plausible "
            f"Q <= {qmax:.1f} (acl.physics.resonance.plausible_quality_bound); with the predicted Q it attracts")))
    return out


def scale_note(design: Design, pair: dict) -> list[dict]:
    """N-PAIR-SCALE, once per frequency on its first attracting pair: the design's pair forces are acl's first-principles
    values, and its snap-in voltage at the median measured / first-principles ratio of the paper's pairs is lower."""
    from acl.physics.constants import FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN as S

    if "snap_in_voltage_median_pair_scale_v" not in pair or not pair["attract"]:
        return []
    v0, v1 = pair.get("snap_in_voltage_v"), pair["snap_in_voltage_median_pair_scale_v"]
    if v1 is None or (v0 is not None and v1 >= v0):
        return []
    here = f"snaps in at {v0:.3g} V" if v0 is not None else "does not snap in up to the transducer's maximum voltage"
    return [_note(design, pair["b"], "N-PAIR-SCALE", (
        f"at {pair['frequency_hz'] / 1e3:g} kHz the design {here} with acl's first-principles pair forces; the "
        f"paper's measured pairs attract 1.86-15x harder (median {S:.3g}), and at the median it snaps in at {v1:.3g} V. "
        "acl compile's bands and acl sweep's yield interval draw that spread; a calibration on measured pairs "
        "(stdlib/calibrations.acl, acl fit) replaces it"))]
