"""Coverage pass: how far each hold, switch, drive and sweep goal moves the capsules (checked against the calibrated range)."""
from __future__ import annotations

import numpy as np

from acl.diagnostics import DiagnosticError
from acl.physics.ties import TIE_RTOL
from acl.schedule import latch_state as LS
from acl.schedule.model import GoalReport
from acl.schedule.state import CompileState, mode_frequencies


def reach(comp: CompileState, goal: GoalReport):
    """(largest deflection from rest, m, the phrase saying where) a hold, cross or switch goal drives to; None if unknown.

    hold above: each capsule of the pair at the equilibrium under the whole drive; cross: the last
    stable equilibrium before snap-in (the pair passes through it), then contact, which no calibration
    covers: ``(m, phrase, True)`` as a drive that snaps (:func:`_static_reach`), warned whatever the range;
    switch: the shuttle's travel between the latch's two stable states (it ends in the other one); drive
    and sweep: every capsule at
    the static equilibrium under the drive (a sweep's at its worst frequency: :func:`_static_reach`).
    A follow goal: None (its path).
    """
    if goal.kind in ("drive", "sweep"):
        return _static_reach(comp, goal)
    if goal.kind not in ("hold", "switch"):
        return None
    step = comp.program.steps[goal.step]
    tones = tuple((t.frequency_hz, t.amplitude_v) for s in comp.segments
                  if s.step == goal.step and s.goal == goal.name for t in s.tones if t.amplitude_v > 0)
    try:
        if goal.kind == "switch":
            from acl.analysis.mechanics import latch_geometry
            from acl.physics.latch import latch_landscape

            if not tones:          # already in the state: nothing moves
                return None
            lt = next(l for l in comp.design.latches if l.name == step.latch)
            land = latch_landscape(*latch_geometry(lt, comp.design))
            if land.state_b is None:
                return None
            return abs(float(land.state_b)), f"the shuttle of latch `{lt.name}` travels to state {step.state},"
        if not tones:
            return None
        from acl.analysis import acoustics, mechanics
        from acl.design.model import Drive, Tone

        shape = Drive(tones=tuple(Tone(frequency=f, amplitude=a) for f, a in tones))
        sw = mechanics.sweep_voltage(comp.design, shape, 1.0, acoustics.force_model_for(comp.design))
        pos = sw.snap_positions if (step.mode == "cross" and sw.snap_positions is not None) else \
            {k: v[-1] for k, v in sw.positions.items()}
        best, who = 0.0, ""
        for name in (step.a.split(".")[0], step.b.split(".")[0]):
            c = comp.design.capsule(name)
            r = float(np.linalg.norm(np.asarray(pos[name], float) - np.asarray(c.center, float)))
            if r > best * (1 + TIE_RTOL):     # a symmetric pair: the first capsule named
                best, who = r, name
        if step.mode == "cross":        # a cross ends in contact by definition: warned whatever the range
            return best, f"the pair passes, before it snaps in, through capsule `{who}` at", True
        return best, f"the drive holds capsule `{who}` at"
    except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError):
        return None         # no mechanics model for this design: the deflection is unknown, not covered


def _static_reach(comp: CompileState, goal: GoalReport):
    """(largest capsule displacement from rest, m, phrase) under a drive or sweep step; None if unknown.

    The analysis' mechanics (acl.analysis.mechanics.equilibrium: lone actuators, pairs, groups, springs,
    latches) at the whole drive, from the latch states the step starts in (:func:`latch_state.settle`; a latch an earlier
    drive left in an uncertain state (:func:`latch_state.latch_track`): from either state, the larger reach).  A sweep
    (a chirp of one tone) is taken at its worst frequency: the largest displacement over the band, sampled
    with every mode inside and refined (interfaces.band_maximum), each frequency held long enough to settle
    (quasi-static: what the analysis predicts everywhere).  A drive that snaps the mechanism in reports the
    last stable point before it (a sweep: at the first frequency found to snap it) and ends in contact, which
    no calibration covers (the fit counts no contact row): ``(m, phrase, True)``, warned whatever the range.
    """
    tones = [t for s in comp.segments if s.step == goal.step and s.goal == goal.name
             for t in s.tones if t.amplitude_v > 0]
    if not tones or not comp.design.capsules:
        return None
    from acl.analysis import acoustics

    try:
        fm = acoustics.force_model_for(comp.design)
        track = LS.latch_track(comp, goal.step)
        states = {n: st for n, (st, _, _) in track.items()}
        doubt = [n for n, (_, sure, _) in track.items() if not sure][:3]
        best = None
        for k in range(2 ** len(doubt)):     # an uncertain latch: either state, the larger reach (contact first)
            alt = dict(states)
            for b, n in enumerate(doubt):
                if k >> b & 1:
                    alt[n] = "a" if states[n] == "b" else "b"
            got = _static_reach_from(comp, tones, fm, alt)
            if k and got is not None:
                moved = ", ".join(f"`{n}` in state {alt[n]}" for n in doubt if alt[n] != states[n])
                got = (got[0], got[1].replace("capsule `", f"(latch {moved}, where an earlier drive may have left "
                                              "it) capsule `", 1), *got[2:])
            if got is not None and (best is None or (len(got) > 2, got[0]) > (len(best) > 2, best[0])):
                best = got
        return best
    except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None         # no mechanics model for this design: the deflection is unknown, not covered


def _static_reach_from(comp: CompileState, tones, fm, states: dict):
    """:func:`_static_reach` from the latch states ``states``."""
    from acl.analysis import interfaces
    from acl.design.model import Drive, Tone

    chirp = next((t for t in tones if t.frequency_end_hz), None)
    if chirp is None:
        r, who, status = LS.settle(comp, Drive(tones=tuple(Tone(frequency=t.frequency_hz, amplitude=t.amplitude_v)
                                                        for t in tones)), fm, states)
        if status == "snap_in":
            return r, f"the drive snaps the mechanism in; before it does, capsule `{who}` already moves", True
        return r, f"the drive moves capsule `{who}`"
    seen = {}

    def at(f):
        if f not in seen:
            seen[f] = LS.settle(comp, Drive(tones=(Tone(frequency=float(f), amplitude=chirp.amplitude_v),)),
                                   fm, states)
            if seen[f][2] == "snap_in":
                raise _Snapped(f)
        return seen[f][0]

    try:      # the deflection is flat at its peak: refined to 1e-3 of the frequency (Q ~ 20: < 0.1 %)
        r, f = interfaces.band_maximum(at, chirp.frequency_hz, chirp.frequency_end_hz, mode_frequencies(comp),
                                       samples=11, rtol=1e-3)
    except _Snapped as snap:          # the lowest snapping frequency found: the sweep snaps the mechanism in
        f = snap.frequency
        r, who, _ = seen[f]
        return (r, f"at {f / 1e3:.4g} kHz the sweep snaps the mechanism in; before it does, capsule `{who}` "
                   "already moves", True)
    return r, f"at {f / 1e3:.4g} kHz the sweep moves capsule `{seen[f][1]}`"


class _Snapped(Exception):
    """A sweep's frequency at which the mechanism snaps in (:func:`_static_reach` stops there)."""

    def __init__(self, frequency: float):
        super().__init__(frequency)
        self.frequency = float(frequency)
