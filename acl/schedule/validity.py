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
    inside, the largest refined: acoustics.sweep_worst_amplitude).  Allowed with
    ``allow_nonlinear`` (then noted): the predicted forces are then not trustworthy.
    """
    from acl.analysis.acoustics import interface_amplitudes, sweep_worst_amplitude
    from acl.design.model import Drive, Tone
    from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT

    worst_of: dict[int, tuple[float, str]] = {}     # step -> (worst eps/R over its segments, interface)
    steady = _steady_amplitudes(comp, sched)
    for seg in sched.segments:
        if not seg.tones or not comp.design.capsules:
            continue
        worst, where = worst_of.get(seg.step, (0.0, ""))
        chirps = [t for t in seg.tones if t.frequency_end_hz]
        if len(chirps) == 1 and len(seg.tones) == 1 and chirps[0].amplitude_v > 0:     # a sweep step
            t = chirps[0]
            v, _, amps = sweep_worst_amplitude(comp.design, t.frequency_hz, t.frequency_end_hz, t.amplitude_v,
                                               mode_frequencies(comp))
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
            else:                                      # steady tones: every segment's in one batch (below)
                k, v = steady[id(seg)]
            if v > worst * (1 + TIE_RTOL):
                worst, where = v, k
        worst_of[seg.step] = (worst, where)
    for step_index, (worst, where) in sorted(worst_of.items()):   # one finding per step, its worst segment
        if worst <= LINEAR_AMPLITUDE_LIMIT:
            continue
        _nonlinear_step(comp, sched, step_index, worst, where)


def _nonlinear_step(comp: CompileState, sched: Schedule, step_index: int, worst: float, where: str) -> None:
    """A step past the amplitude limits (acl.physics.validity): past the hemisphere (no meaning) E-SCHED-NONLINEAR
    unless ``allow_nonlinear``; past the soft limit W-ACOUSTIC-AMPLITUDE at the step, and the step's error bands
    widened by the model-form force uncertainty (:func:`acl.physics.validity.amplitude_model_form`) times the
    goal's largest predicted displacement, added in quadrature."""
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
    widened = []
    for g in comp.goals:
        if g.step != step_index:
            continue
        g.details["model_form_force_rel"] = rel
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
        widened.append(g.name)
    msg = (f"{text}: forces carry a model-form uncertainty of {rel:.0%} (Q {q:.3g}; acl.physics.validity)"
           + (f", added to the error band of {', '.join(widened)}" if widened else ""))
    w = Diagnostic(VA.AMPLITUDE.code, Severity.WARNING, msg, step.span,
                   "lower the voltage or move the tone off resonance to stay inside the validated linear model",
                   notes=(VA.AMPLITUDE.evidence,))
    sched.warnings.append(w)
    comp.notes.append(f"warning: {msg}")


def _steady_amplitudes(comp: CompileState, sched: Schedule) -> dict:
    """{id(segment): (interface, eps/R)} of the largest interface amplitude (ties: the first declared) of every
    segment of steady tones (no chirp), the segments sharing a set of tones evaluated as one batch
    (acoustics.interface_amplitudes_batch)."""
    from acl.analysis.acoustics import interface_amplitudes_batch, interface_labels

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
            out.update({id(seg): ("", 0.0) for seg, _ in rows})
            continue
        top = first_max(eps, axis=1)
        for (seg, _), k, row in zip(rows, np.atleast_1d(top), eps):
            out[id(seg)] = (labels[int(k)], float(row[int(k)]))
    return out
