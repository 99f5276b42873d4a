"""Safety checks: numbers, voltage peaks, slews, contact left by an earlier step, calibration tables after a latch moved."""
from __future__ import annotations

import numpy as np

from acl.diagnostics import Diagnostic, DiagnosticError, Severity
from acl.schedule import latch_state as LS
from acl.schedule.fades import segment_slews
from acl.schedule.model import Schedule
from acl.schedule.state import (
    CALIBRATION_STATE_CODE,
    CALIBRATION_STATE_RTOL,
    CONTACT_CODE,
    MAX_PROGRAM_S,
    SLEW_RANGE,
    VOLTAGE_RANGE,
    CompileState,
    diag,
    drive_limit,
    is_fade,
)


def check_slews(comp: CompileState, sched: Schedule) -> None:
    """Every step with a slew limit: the emitted amplitude envelope, crossfades included, obeys it.

    At a boundary faded over 2h by a raised cosine, a tone's phasor moves from A1 e^(i phi1) to
    A2 e^(i phi2) with weight slope at most pi / (4 h): its amplitude changes at most
    pi |A2 e^(i phi2) - A1 e^(i phi1)| / (4 h) per second (docs/schedule.md, Waveforms).
    """
    rates = segment_slews(sched)
    for i, seg in enumerate(sched.segments):
        if is_fade(seg):       # silence: its neighbours' fades into it are checked at their own steps
            continue
        step = comp.program.steps[seg.step]
        slew = drive_limit(comp.design, getattr(step, "limits", None), comp.opts)[1]
        if slew is None:
            continue
        worst = rates[i]
        for g in comp.goals:
            if g.step == seg.step:
                g.details["emitted_max_slew_v_per_s"] = max(
                    g.details.get("emitted_max_slew_v_per_s", 0.0), float(worst))
        if worst > slew * (1 + 1e-6):
            raise diag("E-SCHED-LIMIT",
                        f"step {seg.step + 1}: the amplitude changes at up to {worst:.4g} V/s in the "
                        f"crossfades of the segment at t = {seg.start_s:.4g} s, over its slew limit "
                        f"{slew:g} V/s", step.span,
                        "lengthen the crossfade (--ramp, up to --waypoint-dt inside a path); start a "
                        "path where the previous drive leaves the capsule (a line from rest); or "
                        "raise the slew limit")


def full_scale(comp: CompileState, vmax: float) -> tuple[float, str]:
    """WAV full scale: --full-scale, else the transducer's max voltage, else the largest limit."""
    if comp.opts.full_scale_v is not None:
        return float(comp.opts.full_scale_v), "--full-scale"
    tr = comp.design.transducer
    if tr is not None and tr.max_voltage and np.isfinite(tr.max_voltage):
        return float(tr.max_voltage), f"max_voltage of transducer `{tr.name}`"
    return float(vmax), "largest voltage limit of the program (no transducer declared)"


def check_numbers(comp: CompileState) -> None:
    """Durations, limits and slews the solver and the renderer can work with (finite, in range)."""
    t = 0.0
    for i, step in enumerate(comp.program.steps):
        d = getattr(step, "duration", None)
        if d is not None:
            if not (np.isfinite(d) and d > 0):
                raise diag("E-SCHED-DURATION", f"step {i + 1}: duration {d:g} s is not a positive "
                            "finite time", step.span)
            t += d
            if t > MAX_PROGRAM_S:
                raise diag("E-SCHED-DURATION", f"step {i + 1}: the program would last {t:.4g} s, "
                            f"more than {MAX_PROGRAM_S:g} s", step.span,
                            "split it into several programs, or shorten the steps")
        lim = getattr(step, "limits", None)
        if lim is None:
            continue
        lo, hi = VOLTAGE_RANGE
        if lim.max_voltage is not None and not lo <= lim.max_voltage <= hi:
            raise diag("E-SCHED-LIMIT", f"step {i + 1}: limit {lim.max_voltage:g} V is outside "
                        f"{lo:g} V .. {hi:g} V", step.span, "give the amplifier's real peak voltage")
        lo, hi = SLEW_RANGE
        if lim.slew_rate is not None and not lo <= lim.slew_rate <= hi:
            raise diag("E-SCHED-LIMIT", f"step {i + 1}: slew {lim.slew_rate:g} V/s is outside "
                        f"{lo:g} .. {hi:g} V/s", step.span)


def check_peaks(comp: CompileState, sched: Schedule) -> None:
    """Every segment's analog peak within its step's limit and the WAV full scale."""
    for seg in sched.segments:
        step = comp.program.steps[seg.step]
        vmax, _ = drive_limit(comp.design, getattr(step, "limits", None), comp.opts)
        if seg.peak_v is not None and seg.peak_v > vmax * (1 + 1e-6):
            raise diag("E-SCHED-VOLTAGE",
                        f"step {seg.step + 1}: peak {seg.peak_v:.4g} V exceeds the {vmax:g} V limit "
                        f"at t = {seg.start_s:.4g} s", step.span,
                        "lower the tone amplitudes or raise the transducer's max voltage")
        if seg.peak_v is not None and seg.peak_v > sched.full_scale_v * (1 + 1e-9):
            raise diag("E-SCHED-FULLSCALE",
                        f"step {seg.step + 1}: peak {seg.peak_v:.4g} V exceeds the WAV full scale "
                        f"{sched.full_scale_v:g} V ({sched.full_scale_source})", step.span,
                        "raise --full-scale, or lower the step's amplitudes or limit")


def contact_check(comp: CompileState, i: int, step) -> None:
    """W-SCHED-CONTACT at a hold (above) or follow step that may start with a pair in contact.

    The pairs are those the program's hold steps and the design's `observe gap(...)` name.  A `hold ... cross` snaps its pair in, and so does a
    drive, switch or hold (of another pair) whose whole drive reaches the pair's snap-in (gains.critical_scale
    <= 1, the hold planner's model).  Once in contact the pair is held by the Bjerknes force at contact, far
    stronger than at the rest gap, for as long as a drive plays: the compiler has no release model, so it takes
    the contact to last until a `pause` (silence: no acoustic force, the beams pull the capsules apart).  A hold
    that keeps the pair apart, or a path of one of its capsules, is planned from the pair at rest: that plan does
    not hold from contact.  (A sweep step is not checked: its worst frequency is not searched here.)"""
    from acl.schedule.gains import critical_scale

    pairs = {frozenset((o.a.split(".")[0], o.b.split(".")[0])): (o.a, o.b)
             for o in comp.design.observes if o.kind == "gap" and o.a and o.b}
    pairs.update({frozenset((st.a.split(".")[0], st.b.split(".")[0])): (st.a, st.b)
                  for st in comp.program.steps if st.kind == "hold"})
    pairs = {p: ab for p, ab in pairs.items() if len(p) == 2}
    if step.kind == "hold":
        if step.mode != "above":
            return
        mine = [frozenset((step.a.split(".")[0], step.b.split(".")[0]))]
    else:
        mine = [p for p in pairs if step.capsule in p]
    if not mine:
        return
    start = max((j + 1 for j in range(i) if comp.program.steps[j].kind == "pause"), default=0)
    for pair in mine:
        a, b = pairs.get(pair, (step.a, step.b) if step.kind == "hold" else (None, None))
        why = None
        for j in range(start, i):
            st = comp.program.steps[j]
            if st.kind == "hold" and st.mode == "cross" and frozenset(
                    (st.a.split(".")[0], st.b.split(".")[0])) == pair:
                why = f"step {j + 1} (hold ... cross) snaps it in"
            elif st.kind in ("drive", "switch", "hold"):
                tones = [(t.frequency_hz, t.amplitude_v) for g in comp.segments if g.step == j
                         for t in g.tones if t.amplitude_v > 0 and not t.frequency_end_hz]
                if not tones:
                    continue
                try:
                    scale = critical_scale(comp.design, a, b, tones, 1.0)
                    if scale is not None and scale <= 1.0 and comp.design.latches:
                        scale = scale if _snaps_from_state(comp, j, a, tones) else None
                except (ValueError, KeyError, ArithmeticError, np.linalg.LinAlgError, DiagnosticError):
                    scale = None
                if scale is not None and scale <= 1.0:
                    why = f"the drive of step {j + 1} ({st.kind}) reaches its snap-in"
            if why:
                break
        if why is None:
            continue
        what = ("the hold keeps it apart from the pair at rest" if step.kind == "hold"
                else f"the path of `{step.capsule}` is planned from the pair at rest")
        comp.step_warnings.append(Diagnostic(
            CONTACT_CODE, Severity.WARNING,
            f"step {i + 1}: {step.kind}: the pair {' / '.join(sorted(pair))} may be in contact when the step "
            f"starts: {why} and no pause releases it before this step; {what}", step.span,
            "insert a `pause` before this step (with no drive the Bjerknes force vanishes and the beams pull the "
            "capsules apart); the compiler takes a contact to last while any drive plays"))


def _snaps_from_state(comp: CompileState, j: int, a: str, tones) -> bool:
    """Whether the drive ``tones`` of step ``j`` loses the mechanism's equilibrium from the latch states the step
    starts in: the fold gains.critical_scale finds may be a bistable latch's snap-through (a `switch`), after which
    the mechanism goes on from the latch's other state (gains.model_forward) with the pair apart."""
    from acl.schedule.gains import model_forward, state_positions

    states = {n: st for n, (st, _, _) in LS.latch_track(comp, j).items()}
    freqs = [f for f, _ in tones]
    forward, _ = model_forward(comp.design, a.split(".")[0], freqs, start=state_positions(comp.design, states))
    return not np.all(np.isfinite(forward(np.array([[v * v for _, v in tones]]))))


def calibration_state_check(comp: CompileState, i: int, name: str, step, freqs) -> None:
    """W-SCHED-CALIBRATION-STATE: a measured gain table (--calibration) is taken with the latches in their declared
    states (the device as printed); where an earlier step has switched a latch, its capsules have moved and their
    forces on the path's capsule changed, which the table cannot know.  The model says by how much: the gains at
    the chosen tones where the latch states put the capsules against those at rest (acl.schedule.gains
    .model_gain_table); beyond CALIBRATION_STATE_RTOL of their size the step warns, below it a note says so."""
    from acl.schedule.gains import model_gain_table, state_positions

    track = LS.latch_track(comp, i)
    states = {n: st for n, (st, _, _) in track.items()}
    moved = [l.name for l in comp.design.latches if states.get(l.name, l.state) != l.state]
    if not moved:
        return
    try:
        g0 = np.asarray(model_gain_table(comp.design, step.capsule, freqs).gains, float)
        g1 = np.asarray(model_gain_table(comp.design, step.capsule, freqs,
                                        positions=state_positions(comp.design, states)).gains, float)
    except (ValueError, KeyError, ArithmeticError):
        comp.notes.append(f"{name}: the calibration table was measured with the latches as declared; "
                          f"{', '.join(f'`{n}`' for n in moved)} switched since, and no model says what that changes")
        return
    size = float(np.linalg.norm(g0))
    change = float(np.linalg.norm(g1 - g0)) / size if size > 0 else float("inf")
    which = ", ".join(f"latch `{n}` in state {states[n]}" for n in moved)
    if change <= CALIBRATION_STATE_RTOL:
        comp.notes.append(f"{name}: the calibration table was measured with the latches as declared; with {which} "
                          f"the model's gains at the chosen tones change by {change:.2%} (kept)")
        return
    comp.step_warnings.append(Diagnostic(
        CALIBRATION_STATE_CODE, Severity.WARNING,
        f"{name}: planned on the calibration table, measured with the latches as declared, while the step starts "
        f"with {which}: there the model's gains at the chosen tones differ by {change:.0%} of their size "
        "(the moved capsules' Bjerknes force and jet drag), so the plan and its predicted error do not hold",
        step.span, "measure the calibration sweep with the latch in that state, or compile this path on the model "
        "(without --calibration)"))
