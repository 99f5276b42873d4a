"""Crossfade pass: the boundary between two steps, faded through silence where the direct crossfade pushes too hard."""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from acl.diagnostics import Diagnostic, DiagnosticError, Severity
from acl.schedule import latch_state as LS
from acl.schedule.model import Schedule, Segment
from acl.schedule.state import CROSSFADE_CODE, FADE_GOAL, LATCH_STATE_MARGIN, CompileState, drive_limit


def crossfade(comp: CompileState, i: int, k: int) -> None:
    """Check the crossfade from step ``i - 1`` into step ``i`` (its first segment is ``segments[k]``), and fade
    through silence where it pushes harder than either step.

    The renderer blends the last segment of step i-1 into the first of step i over 2 h (acl.emit.render).  A
    tone kept across the boundary with a counter-pushing tone that changes can push a latch over the force that
    switches it, or bring a held pair nearer snap-in, while each step alone is within its margin
    (acl.schedule.crossfade).  Checked: every bistable latch towards the state it is not in when step i starts
    (:func:`latch_state.latch_track`; an uncertain one both ways), unless step i is a switch of it to that state
    (:func:`_crossfade_latches`); the pair of a `hold ... above` on either side (:func:`_crossfade_holds`).
    Where the crossfade goes past the larger of the safe level (1/LATCH_STATE_MARGIN of the switching force, the
    hold's margin) and what either step alone does, a silent segment of ``ramp_s`` is inserted before step i:
    each drive then fades alone, a scaling whose force scales with it, and silence is force-free (a bistable
    latch keeps its state, a pair does not snap).  When that fade would break a step's slew limit the crossfade
    is kept and W-SCHED-CROSSFADE warns at step i with the overshoot ratio.
    """
    if i == 0 or k == 0 or k >= len(comp.segments) or comp.opts.ramp_s <= 0:
        return
    before, after = comp.segments[k - 1], comp.segments[k]
    if not any(t.amplitude_v > 0 for t in before.tones) or not any(t.amplitude_v > 0 for t in after.tones):
        return          # a drive fading from or into silence is only scaled: no tone mixes
    freqs, p, q, cos = boundary_tones(before, after)
    found = []
    for check, what in ((functools.partial(_crossfade_latches, comp), "latches"),
                        (functools.partial(_crossfade_holds, comp), "held pairs")):
        try:
            found += check(i, freqs, p, q, cos)
        except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError,
                np.linalg.LinAlgError) as exc:
            comp.notes.append(f"step {i + 1}: the crossfade from step {i} could not be checked for {what} ({exc})")
    if not found:
        return
    over = max(r for r, _ in found)
    text = "; ".join(w for _, w in found)
    step = comp.program.steps[i]
    blocked = _fade_slew(comp, before, after)
    if blocked is not None:
        comp.step_warnings.append(Diagnostic(
            CROSSFADE_CODE, Severity.WARNING, f"step {i + 1}: {step.kind}: the crossfade from step {i} pushes "
            f"{text}: {over:.3g} x beyond the larger of the safe level and either step alone", step.span,
            "change the tones of one step so that no tone is kept across the boundary while a counter-pushing "
            "one changes; or raise the slew limit so the compiler can fade through silence there",
            notes=(f"not faded through silence: {blocked}",)))
        return
    ramp = comp.opts.ramp_s
    fade = Segment(after.start_s, after.start_s + ramp, (), i, f"step {i + 1}: {FADE_GOAL}")
    comp.segments[k:] = [fade] + [dataclasses.replace(s, start_s=s.start_s + ramp, end_s=s.end_s + ramp)
                                  for s in comp.segments[k:]]
    comp.t += ramp
    for g in comp.goals + comp.inner_goals:
        if g.step == i:
            g.start_s, g.end_s = g.start_s + ramp, g.end_s + ramp
            if g.times_s is not None:
                g.times_s = g.times_s + ramp
    comp.notes.append(f"step {i + 1}: faded through {ramp * 1e3:.4g} ms of silence after step {i} (t = "
                      f"{fade.start_s:.4g} s): a direct crossfade would push {text} ({over:.3g} x beyond the "
                      "larger of the safe level and either step alone)")


def _crossfade_latches(comp: CompileState, i: int, freqs, p, q, cos) -> list:
    """[(overshoot ratio, phrase)] for the bistable latches the crossfade into step ``i`` pushes towards a state
    they are not in past max(1/LATCH_STATE_MARGIN, either end's push) (:func:`crossfade`).

    Forces per V^2 of each tone along each latch axis with the capsules where the latch states put them when
    step i starts (acl.schedule.gains.latch_forces, state_positions; or the injected ``latch_provider``), the
    capsules undeflected.  Quadratic in amplitude: the worst-phase maximum over the crossfade, exact in that
    model (acl.schedule.crossfade.crossfade_peak); with declared drive saturation the whole mixed drive
    (latch_drive_forces) at the crossfade weights FADE_POINTS, each shared tone at its worst phase: sampled.
    """
    if not comp.design.latches:
        return []
    bi = LS.bistable(comp)
    if not bi:
        return []
    from acl.schedule.crossfade import FADE_POINTS, crossfade_amplitudes, crossfade_peak

    if comp.opts.latch_provider is not None:
        quadratic = True
    else:
        from acl.analysis.acoustics import force_model_for

        quadratic = force_model_for(comp.design).quadratic_in_amplitude
    if quadratic and (not np.any((p > 0) & (q > 0)) or len(freqs) < 2):
        return []       # no kept tone, or one tone alone: never past the larger end (acl.schedule.crossfade)
    track = LS.latch_track(comp, i)
    states = {n: s for n, (s, _, _) in track.items()}
    step = comp.program.steps[i]
    pos = None
    if comp.opts.latch_provider is not None:
        G, to_b, to_a = comp.opts.latch_provider(comp.design, tuple(freqs))
    else:
        from acl.schedule.gains import latch_forces, state_positions

        pos = state_positions(comp.design, states)
        G, to_b, to_a = latch_forces(comp.design, freqs, pos)
    G = np.asarray(G, float).reshape(len(to_b), len(freqs))
    safe = 1.0 / LATCH_STATE_MARGIN
    out = []
    for n, j in bi.items():
        state, certain, _ = track.get(n, (None, False, None))
        for to in (("b" if state == "a" else "a",) if certain and state in ("a", "b") else ("b", "a")):
            if step.kind == "switch" and step.latch == n and step.state == to:
                continue            # the switch pushes it there anyway
            sig = 1.0 if to == "b" else -1.0
            thr = float(to_b[j] if to == "b" else to_a[j])
            g = sig * G[j]
            if quadratic:
                peak, x = crossfade_peak(g, p, q, cos)
                r, x = float(peak[0]) / thr, float(x[0])
                r0, r1 = float(g @ (p * p)) / thr, float(g @ (q * q)) / thr
                how = "worst phases" if np.isnan(cos[(p > 0) & (q > 0)]).any() else "the phases as played"
            else:
                from acl.schedule.gains import latch_drive_forces

                def push(amps):
                    tones = [(f, float(a)) for f, a in zip(freqs, amps) if a > 0]
                    return sig * float(latch_drive_forces(comp.design, tones, pos)[j]) / thr

                r0, r1 = push(p), push(q)
                r, x = max((push(crossfade_amplitudes(p, q, x, g, cos)), x) for x in FADE_POINTS)
                how = f"sampled at weights {', '.join(f'{w:g}' for w in FADE_POINTS)} (declared drive saturation)"
            top = max(safe, r0, r1)
            if r > top * (1 + 1e-6):
                force = "switching" if to == "b" else "release"
                out.append((r / top, f"latch `{n}` (in state {state}{'' if certain else ', uncertain'}) to "
                            f"{r:.3g} x its {force} force at crossfade weight {x:.2f} ({how}; step {i}'s drive "
                            f"alone {max(r0, 0.0):.3g} x, step {i + 1}'s {max(r1, 0.0):.3g} x)"))
    return out


def _crossfade_holds(comp: CompileState, i: int, freqs, p, q, cos) -> list:
    """[(overshoot ratio, phrase)] for the pair of a `hold ... above` step on either side of the boundary into
    step ``i`` that the mixed drive brings nearer snap-in than min(margin, either end) (:func:`crossfade`).

    The snap index sum_k u_k / Vcrit_k^2 never exceeds the larger end over a crossfade (acl.schedule.crossfade),
    but the whole drive's critical scale (acl.schedule.gains.critical_scale, or the injected
    ``critical_provider``) is not bound by it: it is re-simulated at the crossfade weights FADE_POINTS, a tone
    on both sides at either phase extreme (in phase, anti-phase; up to 2 such tones in every combination, more:
    all in phase or all anti-phase), searched up to 1.5 x the margin as the hold itself.  Sampled, not a bound.
    """
    from acl.schedule.crossfade import FADE_POINTS, crossfade_amplitudes

    out = []
    for h in (i - 1, i):
        st = comp.program.steps[h]
        if st.kind != "hold" or st.mode != "above":
            continue
        provider = comp.opts.critical_provider
        if provider is None:
            if comp.opts.snap_provider is not None:
                continue            # an injected snap model: its index never exceeds the larger end
            from acl.schedule.gains import critical_scale as provider

        def scale(amps):
            tones = [(f, float(a)) for f, a in zip(freqs, amps) if a > 0]
            s = provider(comp.design, st.a, st.b, tones, 1.5 * st.margin, st.bound)
            return None if s is None else float(s)

        s0, s1 = scale(p), scale(q)
        if s0 is None or s1 is None:
            continue
        shared = [kk for kk in range(len(freqs)) if p[kk] > 0 and q[kk] > 0 and np.isnan(cos[kk])]
        combos = ([[(b >> m) & 1 for m in range(len(shared))] for b in range(2 ** len(shared))]
                  if len(shared) <= 2 else [[0] * len(shared), [1] * len(shared)])
        worst = None
        for x in FADE_POINTS:
            for bits in combos:
                signs = np.ones(len(freqs))
                signs[[kk for kk, b in zip(shared, bits) if b]] = -1.0
                s = scale(crossfade_amplitudes(p, q, x, signs, cos))
                if s is not None and (worst is None or s < worst[0]):
                    worst = (s, x)
        floor = min(st.margin, s0, s1)
        if worst is not None and worst[0] < floor * (1 - 1e-3):
            out.append((floor / max(worst[0], 1e-300),
                        f"the pair {st.a}/{st.b} that step {h + 1} holds apart to snap-in at {worst[0]:.3g} x the "
                        f"mixed drive at crossfade weight {worst[1]:.2f} (sampled; step {i}'s drive alone "
                        f"{s0:.3g} x, step {i + 1}'s {s1:.3g} x, margin {st.margin:g})"))
    return out


def _fade_slew(comp: CompileState, before: Segment, after: Segment) -> str | None:
    """Why fading ``before`` out and ``after`` in through silence would break a step's slew limit; None if not.

    A tone faded alone over 2 h = min(ramp, the segment) by a raised cosine changes its amplitude at up to
    pi A / (4 h) (segment_slews)."""
    ramp = comp.opts.ramp_s
    for seg, verb in ((before, "out"), (after, "in")):
        slew = drive_limit(comp.design, getattr(comp.program.steps[seg.step], "limits", None), comp.opts)[1]
        if slew is None:
            continue
        h = min(ramp / 2, seg.duration_s / 2)
        rate = np.pi * max(t.amplitude_v for t in seg.tones) / (4 * h) if h > 0 else np.inf
        if rate > slew * (1 + 1e-6):
            return (f"fading step {seg.step + 1}'s drive {verb} alone over {2 * h:.4g} s changes its amplitude at "
                    f"{rate:.4g} V/s, over its slew limit {slew:g} V/s")
    return None


def boundary_tones(before: Segment, after: Segment) -> tuple[list[float], np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies Hz, amplitudes V before, after, cos of the phase difference or NaN) of the tones the renderer
    crossfades at the boundary between ``before`` and ``after``.

    A tone is identified by its frequency there (a chirp by its end frequency before the boundary, its start
    frequency after it); two tones of one frequency in a segment add (an upper bound).  The phase difference of a
    constant tone on both sides is known when neither phase is left to the crest-factor search (_choose_all_phases):
    a phase the user wrote, or the only tone of its segment; otherwise NaN (the worst phase is taken)."""
    def at(seg, end):
        out, ph = {}, {}
        lone = len(seg.tones) == 1
        for t in seg.tones:
            if t.amplitude_v > 0:
                f = float(t.frequency_end_hz if (end and t.frequency_end_hz) else t.frequency_hz)
                ph[f] = t.phase_rad if (f not in out and t.sweep is None and (t.phase_fixed or lone)) else None
                out[f] = out.get(f, 0.0) + float(t.amplitude_v)
        return out, ph

    (a, pa), (b, pb) = at(before, True), at(after, False)
    freqs = sorted(set(a) | set(b))
    cos = np.array([np.cos(pb[f] - pa[f]) if pa.get(f) is not None and pb.get(f) is not None else np.nan
                    for f in freqs])
    return freqs, np.array([a.get(f, 0.0) for f in freqs]), np.array([b.get(f, 0.0) for f in freqs]), cos


def segment_slews(sched: Schedule) -> np.ndarray:
    """Bound (V/s) on the rate of change of any tone's emitted amplitude while each segment plays
    (n,), crossfades included (the renderer's law, docs/schedule.md Waveforms).

    A raised cosine over L has slope at most pi / (2 L).  Where segments i and i+1 crossfade
    (weights summing to one) a tone's phasor moves along P_i -> P_i+1: |P_i+1 - P_i| pi / (2 L).
    The first segment fades in over [0, 2h] and may still be fading in when its fade-out starts
    (the last one likewise): there both slopes add, each times the largest phasor it can move.
    """
    segs = sched.segments
    n = len(segs)
    d = np.array([s.duration_s for s in segs])
    half = sched.ramp_s / 2
    h = np.empty(n + 1)
    h[0], h[-1] = min(half, d[0] / 2), min(half, d[-1] / 2)
    if n > 1:
        h[1:-1] = np.minimum(half, np.minimum(d[:-1], d[1:]) / 2)
    starts = np.array([s.start_s for s in segs])
    a0, a1, b0, b1 = starts - h[:n], starts + h[:n], starts + d - h[1:], starts + d + h[1:]
    a0[0], a1[0] = starts[0], starts[0] + 2 * h[0]
    b0[-1], b1[-1] = starts[-1] + d[-1] - 2 * h[-1], starts[-1] + d[-1]
    fs = sched.sample_rate_hz or np.inf

    def phasors(i):
        if i < 0 or i >= n:
            return {}
        return {(t.frequency_hz, t.sweep): t.amplitude_v * (np.exp(1j * t.phase_rad) if t.sweep is None else 1)
                for t in segs[i].tones}

    def jump(p, q, *extra):
        keys = set(p) | set(q)
        return max((max([abs(q.get(k, 0) - p.get(k, 0))] + [abs(e.get(k, 0)) for e in extra])
                    for k in keys), default=0.0)

    def rate(j, length):
        if j == 0:
            return 0.0
        return np.inf if length < 1.0 / fs or length <= 0 else np.pi * j / (2 * length)

    out = np.zeros(n)
    for i in range(n):
        prev, cur, nxt = phasors(i - 1), phasors(i), phasors(i + 1)
        r_in, r_out = rate(jump(prev, cur), a1[i] - a0[i]), rate(jump(cur, nxt), b1[i] - b0[i])
        out[i] = max(r_in, r_out)
        if a1[i] > b0[i] and np.isfinite(out[i]):      # fading in and out at once
            out[i] = max(out[i], _overlap_slew(prev, cur, nxt, a0[i], a1[i], b0[i], b1[i]))
    return out


def _overlap_slew(prev, cur, nxt, a0, a1, b0, b1, n: int = 2001) -> float:
    """Bound on |d/dt| of each tone's envelope (1 - x) P_prev + x (1 - y) P_cur + y P_next on
    [b0, a1], x = rc over [a0, a1], y = rc over [b0, b1]: the exact derivative on a grid of n
    points plus (grid step / 2) x a bound on the second derivative."""
    lx, ly = a1 - a0, b1 - b0
    t = np.linspace(b0, a1, n)
    ux, uy = np.clip((t - a0) / lx, 0, 1), np.clip((t - b0) / ly, 0, 1)
    x, y = 0.5 - 0.5 * np.cos(np.pi * ux), 0.5 - 0.5 * np.cos(np.pi * uy)
    dx, dy = np.pi / (2 * lx) * np.sin(np.pi * ux), np.pi / (2 * ly) * np.sin(np.pi * uy)
    step = (a1 - b0) / (n - 1)
    worst = 0.0
    for k in set(prev) | set(cur) | set(nxt):
        pp, pc, pn = prev.get(k, 0), cur.get(k, 0), nxt.get(k, 0)
        d = np.abs(dx * (pc * (1 - y) - pp) + dy * (pn - x * pc)).max()
        j1, j2 = max(abs(pc - pp), abs(pp)), max(abs(pn - pc), abs(pn))
        e2 = (np.pi ** 2 / (2 * lx ** 2) * j1 + np.pi ** 2 / (2 * ly ** 2) * j2
              + np.pi ** 2 / (2 * lx * ly) * abs(pc))
        worst = max(worst, float(d + e2 * step / 2))
    return worst
