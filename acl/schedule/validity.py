"""Validity pass: each step's drive against the limits of the linear bubble model (acl.physics.validity)."""
from __future__ import annotations

import numpy as np

from acl.diagnostics import Diagnostic, Severity
from acl.physics.ties import TIE_RTOL, first_max, first_max_item
from acl.schedule.model import Schedule
from acl.schedule.state import CompileState, diag, mode_frequencies


def check_linear(comp: CompileState, sched: Schedule) -> None:
    """Refuse a segment that drives an interface beyond the linear bubble model (eps/R > LINEAR_AMPLITUDE_LIMIT; docs/physics.md).

    Tone amplitudes add (the worst-case peak); a sweep at its worst frequency (sampled with every mode
    inside, the largest refined: interfaces.sweep_worst_amplitude).  Allowed with
    ``allow_nonlinear`` (then noted): the predicted forces are then not trustworthy.
    """
    from acl.analysis.interfaces import interface_amplitudes, sweep_worst_amplitude
    from acl.design.model import Drive, Tone
    from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT

    worst_of: dict[int, tuple[float, str]] = {}     # step -> (worst eps/R over its segments, interface)
    stream_of: dict[int, tuple[float, str]] = {}    # step -> (largest streaming Reynolds number, interface)
    steady = _steady_amplitudes(comp, sched)
    for seg in sched.segments:
        if not seg.tones or not comp.design.capsules:
            continue
        worst, where = worst_of.get(seg.step, (0.0, ""))
        chirps = [t for t in seg.tones if t.frequency_end_hz]
        if len(chirps) == 1 and len(seg.tones) == 1 and chirps[0].amplitude_v > 0:     # a sweep step
            t = chirps[0]
            v, f_worst, amps = sweep_worst_amplitude(comp.design, t.frequency_hz, t.frequency_end_hz, t.amplitude_v,
                                               mode_frequencies(comp))
            _streaming(comp, stream_of, seg.step, amps, f_worst)
            k, v = first_max_item(amps)
            if v > worst * (1 + TIE_RTOL):
                worst, where = v, k
            worst_of[seg.step] = (worst, where)
            continue
        grid = np.linspace(0.0, 1.0, 21) if chirps else np.zeros(1)
        for x in grid:
            tones = tuple(Tone(frequency=t.frequency_hz + x * ((t.frequency_end_hz or t.frequency_hz) - t.frequency_hz),
                               amplitude=t.amplitude_v) for t in seg.tones if t.amplitude_v > 0)
            if not tones:
                continue
            if chirps:
                amps = interface_amplitudes(comp.design, Drive(tones=tones))
                k, v = first_max_item(amps)            # ties: the first declared interface, the first segment
                _streaming(comp, stream_of, seg.step, amps, max(t.frequency for t in tones))
            else:                                      # steady tones: every segment's in one batch (below)
                k, v, (rs, hot) = steady[id(seg)]
                if rs > stream_of.get(seg.step, (0.0, ""))[0] * (1 + TIE_RTOL):
                    stream_of[seg.step] = (rs, hot)
            if v > worst * (1 + TIE_RTOL):
                worst, where = v, k
        worst_of[seg.step] = (worst, where)
    near = _monopole_distances(comp, sched)
    for step_index in sorted(set(worst_of) | set(stream_of) | set(near)):   # one finding per limit and step
        worst, where = worst_of.get(step_index, (0.0, ""))
        found = []             # (limit, relative model-form force uncertainty, message, hint)
        if worst > LINEAR_AMPLITUDE_LIMIT:
            got = _nonlinear_step(comp, step_index, worst, where)
            if got is None:
                continue           # past the hemisphere, allowed by --allow-nonlinear: noted, no band has a meaning
            found.append(got)
        found += _streaming_finding(step_index, stream_of.get(step_index), _calibrated_at(comp, sched, step_index))
        found += _monopole_finding(step_index, near.get(step_index))
        if found:
            _widen(comp, sched, step_index, found)


def _nonlinear_step(comp: CompileState, step_index: int, worst: float, where: str):
    """A step past the amplitude limits (acl.physics.validity): past the hemisphere (no meaning) E-SCHED-NONLINEAR
    unless ``allow_nonlinear`` (then noted, None); past the soft limit (W-ACOUSTIC-AMPLITUDE) its finding
    (limit, the model-form force uncertainty :func:`acl.physics.validity.amplitude_model_form`, message, hint)
    for :func:`_widen`."""
    from acl.physics import validity as VA

    step = comp.program.steps[step_index]
    text = (f"step {step_index + 1} drives interface `{where}` to eps/R = {worst:.6g}, beyond the linear "
            f"bubble model (eps/R <= {VA.AMPLITUDE.value:g}; docs/physics.md)")
    if worst > VA.AMPLITUDE_MEANING.value:
        text = (f"step {step_index + 1} drives interface `{where}` to eps/R = {worst:.6g}, past the hemisphere "
                f"(eps/R = {VA.AMPLITUDE_MEANING.value:g}), where the interface leaves the orifice and the bubble "
                "model has no meaning (docs/physics.md)")
        if comp.opts.allow_nonlinear:
            comp.notes.append(text + ": allowed by --allow-nonlinear; forces there are not trustworthy")
            return
        raise diag("E-SCHED-NONLINEAR", text, step.span,
                    "lower the voltage, move the tone off resonance, or pass --allow-nonlinear")
    from acl.analysis.acoustics import capsule_modes

    cap = where.split(".")[0]
    qs = [m.q for m in capsule_modes(comp.design, cap)] if cap in {c.name for c in comp.design.capsules} else []
    q = max(qs, default=10.0)
    rel = float(VA.amplitude_model_form(worst, q))
    return (VA.AMPLITUDE, rel, f"{text}: forces carry a model-form uncertainty of {100 * rel:.2g} % (Q {q:.3g}; "
            "acl.physics.validity)", "lower the voltage or move the tone off resonance to stay inside the validated "
            "linear model")


def _reynolds(comp: CompileState, labels, eps: np.ndarray, top_hz: float) -> np.ndarray:
    """Streaming Reynolds numbers omega eps^2/nu (acl.physics.forces) (B, n) of eps/R ``eps`` (B, n) of the
    interfaces ``labels`` at the drive's highest frequency ``top_hz`` (as analyze does)."""
    from acl.physics.constants import WATER_20C
    from acl.physics.forces import streaming_reynolds

    med = comp.design.medium or WATER_20C
    r = np.array([comp.design.capsule(k.split(".")[0]).orifice(k.split(".")[1]).radius for k in labels], float)
    return np.atleast_2d(streaming_reynolds(np.asarray(eps, float) * r, 2 * np.pi * top_hz, med.density,
                                            med.viscosity))


def _streaming(comp: CompileState, stream_of: dict, step: int, amps: dict, top_hz: float) -> None:
    """Record in ``stream_of`` the largest streaming Reynolds number omega eps^2/nu (acl.physics.forces) of the
    interfaces ``amps`` ({interface: eps/R}) at the drive's highest frequency ``top_hz`` (as analyze does)."""
    from acl.physics.constants import WATER_20C
    from acl.physics.forces import streaming_reynolds

    med = comp.design.medium or WATER_20C
    best, where = stream_of.get(step, (0.0, ""))
    for key, x in amps.items():
        cap, ori = key.split(".")
        r = comp.design.capsule(cap).orifice(ori).radius
        rs = float(streaming_reynolds(x * r, 2 * np.pi * top_hz, med.density, med.viscosity))
        if rs > best * (1 + TIE_RTOL):
            best, where = rs, key
    stream_of[step] = (best, where)


def _calibrated_at(comp: CompileState, sched: Schedule, step_index: int) -> str | None:
    """The covered ranges of the design's calibration (``uncertainty { covered(...) }``, acl fit) when the step's drive
    lies inside them (voltage: the sum of its segments' amplitudes; frequency: every tone, a chirp's whole band), else
    None: the thrust constant was then fitted on data taken at that drive, so its regime is measured, not extrapolated."""
    cover = {c.quantity: c for c in comp.design.coverage}
    segs = [g for g in sched.segments if g.step == step_index and g.tones]
    if "voltage" not in cover or not segs:
        return None
    tol = 1e-9
    v = max(g.amplitude_sum() for g in segs)
    if not cover["voltage"].lower * (1 - tol) <= v <= cover["voltage"].upper * (1 + tol):
        return None
    if "frequency" in cover:
        lo, hi = cover["frequency"].lower, cover["frequency"].upper
        fs = [f for g in segs for t in g.tones if t.amplitude_v > 0 for f in (t.frequency_hz, t.frequency_end_hz or t.frequency_hz)]
        if any(not lo * (1 - tol) <= f <= hi * (1 + tol) for f in fs):
            return None
    return ", ".join(f"covered({q}) at {c.span.line}" if c.span else f"covered({q})" for q, c in cover.items()
                     if q in ("voltage", "frequency"))


def _streaming_finding(step_index: int, got, calibrated: str | None = None) -> list:
    """[(limit, rel, message, hint)] for a step past the streaming Reynolds limit (none inside it); inside the covered
    range of the design's calibration (``calibrated``) or not, warned with no model-form uncertainty (the data, or the
    paper's Fig. 2c, are the evidence)."""
    from acl.physics import validity as VA

    if got is None or got[0] <= VA.STREAMING_REYNOLDS.value:
        return []
    rs, where = got
    text = (f"step {step_index + 1} drives interface `{where}` to streaming Reynolds number R_s = {rs:.4g}, beyond "
            f"the thrust law's Stokes outer flow (R_s <= {VA.STREAMING_REYNOLDS.value:g}; docs/physics.md)")
    hint = "lower the voltage to keep the streaming flow viscous, or calibrate the thrust at this drive (acl fit)"
    if calibrated:
        return [(VA.STREAMING_REYNOLDS, 0.0, f"{text}: inside the range the design's calibration covered ({calibrated}),"
                 " so its thrust was fitted there and no model-form uncertainty is added", hint)]
    # the evidence (acl.physics.validity.STREAMING_REYNOLDS): the paper's deflections stay quadratic in voltage at
    # drives past this limit (Fig. 2c), so the V^2 thrust law is kept and the step is only warned
    return [(VA.STREAMING_REYNOLDS, 0.0, f"{text}: the V^2 thrust law is kept, as the paper's deflections stay "
             "quadratic in voltage past this limit (Fig. 2c; acl.physics.validity)", hint)]


def _monopole_distances(comp: CompileState, sched: Schedule) -> dict:
    """{step: (smallest d/(R_a + R_b), orifice, orifice, d m)} over the pairs of orifices of two capsules, for every
    step that plays a drive: the capsules at rest (each orifice at its declared centre), a follow goal's capsule also
    displaced to each predicted waypoint (ties: the first pair declared)."""
    caps = comp.design.capsules
    if len(caps) < 2:
        return {}
    pairs = [(a.name, b.name, f"{a.name}.{x.name}", f"{b.name}.{y.name}", x.radius + y.radius,
              np.asarray(y.center, float) - np.asarray(x.center, float))
             for i, a in enumerate(caps) for b in caps[i + 1:] for x in a.orifices for y in b.orifices]
    driven = sorted({s.step for s in sched.segments if any(t.amplitude_v > 0 for t in s.tones)})
    out = {}
    for step in driven:
        moves = []          # (capsule, (N, 3) displacements) of the step's follow goals
        for g in comp.goals:
            pts = g.predicted_m if g.predicted_m is not None else g.target_m
            if g.step == step and g.kind == "follow" and g.capsule and pts is not None:
                p = np.asarray(pts, float).reshape(-1, np.shape(pts)[-1])
                p = p[np.all(np.isfinite(p), axis=1)]
                moves.append((g.capsule, np.pad(p, ((0, 0), (0, max(0, 3 - p.shape[1]))))[:, :3]))
        got = None
        for ca, cb, oa, ob, rsum, v0 in pairs:
            d = float(np.linalg.norm(v0))
            for cap, disp in moves:
                if len(disp) and cap in (ca, cb):       # b - a: a moved by u gives v0 - u, b moved gives v0 + u
                    d = min(d, float(np.min(np.linalg.norm(v0 + (disp if cap == cb else -disp), axis=1))))
            if got is None or d / rsum < got[0] * (1 - TIE_RTOL):
                got = (d / rsum, oa, ob, d)
        out[step] = got
    return out


def _monopole_finding(step_index: int, got) -> list:
    """[(limit, rel, message, hint)] for a step whose closest orifices of two capsules are nearer than the
    point-monopole limit (none beyond it)."""
    from acl.physics import validity as VA

    if got is None or got[0] >= VA.MONOPOLE_DISTANCE.value:
        return []
    ratio, oa, ob, d = got
    rel = float(VA.monopole_model_form(d, d / ratio))
    return [(VA.MONOPOLE_DISTANCE, rel,
             f"step {step_index + 1} drives orifices `{oa}` and `{ob}` {d * 1e6:.4g} um apart, {ratio:.3g} x the "
             f"sum of their radii (point monopoles need >= {VA.MONOPOLE_DISTANCE.value:g} x; docs/physics.md): pair "
             f"forces carry a model-form uncertainty of {rel:.0%} (acl.physics.validity)",
             "keep the capsules further apart under this drive, or calibrate the pair force at this gap (acl fit)")]


def _widen(comp: CompileState, sched: Schedule, step_index: int, found: list) -> None:
    """Widen the error bands of the step's goals by the model-form force uncertainty of every limit it is past
    (``found``), added in quadrature (independent corrections), times the goal's largest predicted displacement
    (a switch: its margin's 5th percentile times 1 - rel); then one located warning per limit at the step."""
    step = comp.program.steps[step_index]
    rel = min(1.0, float(np.sqrt(sum(r * r for _, r, _, _ in found))))
    widened = []
    for g in comp.goals:
        if g.step != step_index:
            continue
        g.details["model_form_force_rel"] = rel
        if [lim.code for lim, _, _, _ in found] != ["W-ACOUSTIC-AMPLITUDE"]:
            g.details["model_form_force_rel_by_limit"] = {lim.code: r for lim, r, _, _ in found}
        band = g.details.get("band")
        if isinstance(band, dict) and band.get("margin_p05") is not None:     # a switch: the force may be lower
            band["margin_p05_model_form"] = float(band["margin_p05"]) * (1.0 - rel)
            widened.append(g.name)
        pts = g.predicted_m if g.predicted_m is not None else g.target_m
        if pts is None or g.rms_error_p95_m is None:
            continue
        extra = rel * float(np.nanmax(np.linalg.norm(np.asarray(pts, float), axis=-1)))
        g.rms_error_p95_m = float(np.hypot(g.rms_error_p95_m, extra))
        if g.max_error_p95_m is not None:
            g.max_error_p95_m = float(np.hypot(g.max_error_p95_m, extra))
        _widen_expected(comp, g, extra)
        widened.append(g.name)
    for lim, r, text, hint in found:
        msg = text + (f", added to the error band of {', '.join(widened)}" if widened and r > 0 else "")
        if len(found) > 1 and r > 0:
            msg += f" (in quadrature with the step's other limits: {100 * rel:.2g} %)"
        w = Diagnostic(lim.code, Severity.WARNING, msg, step.span, hint, notes=(lim.evidence,))
        sched.warnings.append(w)
        comp.notes.append(f"warning: {msg}")


def _widen_expected(comp: CompileState, goal, extra: float) -> None:
    """The band the proposed readings are expected to leave (acl.schedule.experiment) keeps the model-form term
    ``extra`` m: the readings calibrate the declared uncertainties, not the limit the step is past; the goal's note
    is rewritten with the widened figures."""
    from acl.schedule import experiment

    band = goal.details.get("band")
    cause = band.get("cause") if isinstance(band, dict) else None
    m = cause.get("measurement") if isinstance(cause, dict) else None
    if not m or extra <= 0:
        return
    old = experiment.summary(goal.name, cause)
    m["model_form_m"] = float(np.hypot(m.get("model_form_m", 0.0), extra))
    m["expected_rms_p95_m"] = float(np.hypot(m["expected_rms_p95_m"], extra))
    m["expected_max_p95_m"] = float(np.hypot(m["expected_max_p95_m"], extra))
    if m.get("nominal_rms_p95_m") is not None:
        m["nominal_rms_p95_m"] = float(np.hypot(m["nominal_rms_p95_m"], extra))
    w = m.get("with_readings_of")
    if w:                     # the promise on another goal's readings keeps the term too
        for key in ("expected_rms_p95_m", "expected_max_p95_m"):
            w[key] = float(np.hypot(w[key], extra))
    new = experiment.summary(goal.name, cause)
    comp.notes[:] = [new if n == old else n for n in comp.notes]


def _steady_amplitudes(comp: CompileState, sched: Schedule) -> dict:
    """{id(segment): (interface, eps/R)} of the largest interface amplitude (ties: the first declared) of every
    segment of steady tones (no chirp), the segments sharing a set of tones evaluated as one batch
    (acoustics.interface_amplitudes_batch)."""
    from acl.analysis.acoustics import interface_labels
    from acl.analysis.interfaces import interface_amplitudes_batch

    labels = interface_labels(comp.design)
    groups: dict = {}
    for seg in sched.segments:
        if not seg.tones or not comp.design.capsules or any(t.frequency_end_hz for t in seg.tones):
            continue
        live = [t for t in seg.tones if t.amplitude_v > 0]
        if live:
            key = tuple(t.frequency_hz for t in live)
            groups.setdefault(key, []).append((seg, [t.amplitude_v for t in live]))
    out = {}
    for freqs, rows in groups.items():
        eps = interface_amplitudes_batch(comp.design, freqs, np.array([a for _, a in rows], float))
        if not labels:
            out.update({id(seg): ("", 0.0, (0.0, "")) for seg, _ in rows})
            continue
        top = first_max(eps, axis=1)
        rs = _reynolds(comp, labels, eps, max(freqs))
        hot = first_max(rs, axis=1)
        for (seg, _), k, row, h, rrow in zip(rows, np.atleast_1d(top), eps, np.atleast_1d(hot), rs):
            out[id(seg)] = (labels[int(k)], float(row[int(k)]), (float(rrow[int(h)]), labels[int(h)]))
    return out
