"""Program -> Schedule: every step becomes segments of tones; goals are solved as convex programs.

Entry point: :func:`compile_program`.  Steps map as follows (see docs/schedule.md):

* drive  -> one segment with the given tones;     sweep -> one chirp segment;  pause -> silence
* follow -> one segment per waypoint from ONE path program (:mod:`acl.schedule.path`)
* switch -> one segment from the latch LP (:mod:`acl.schedule.latch`)
* hold   -> one segment from the snap-in LP (:mod:`acl.schedule.hold`)

After solving, each follow goal is re-simulated through a forward model (injected, default
:func:`acl.schedule.gains.model_forward`) and its predicted tracking error is reported.  Multi-tone
phases are chosen for a low peak (:mod:`acl.schedule.phases`).  Problems become diagnostics.
"""
from __future__ import annotations

import dataclasses

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from acl.design.model import Design, FollowStep, HoldStep, Limits, Program, SwitchStep
from acl.diagnostics import Diagnostic, DiagnosticError, Severity, Span, error
from acl.physics.ties import TIE_RTOL, first_max, first_max_item
from acl.schedule.model import GoalReport, Schedule, ScheduledTone, Segment
from acl.schedule.path import UM, DriveLimits

DEFAULT_MAX_VOLTAGE = 10.0
MAX_ROBUST_SPREAD = 100.0          # --robust: 1-sigma gain spread sqrt(|Q|) at most this many times |G0| (E-SCHED-UNCERTAINTY)
MAX_PROGRAM_S = 86_400.0          # a program longer than a day is refused (E-SCHED-DURATION)
MAX_WAYPOINTS = 20_000            # per follow goal (E-SCHED-PATH): raise --waypoint-dt
VOLTAGE_RANGE = (1e-3, 1e4)       # V: a `limit` outside it is refused (E-SCHED-LIMIT)
SLEW_RANGE = (1e-6, 1e12)         # V/s
LATCH_STATE_MARGIN = 1.2          # a drive pushing a latch within this factor of the force that switches it leaves its
                                  # state uncertain: the switch step's default margin (what a switch or a keep promises)
LATCH_STATE_CODE = "W-SCHED-LATCH-STATE"
LATCH_FLIP_CODE = "W-SCHED-LATCH-FLIP"   # a follow or hold step's drive switches a latch (or may): docs/schedule.md
TRACKING_CODE = "W-SCHED-TRACKING"       # the re-simulated path misses by more than the tolerance: docs/schedule.md
CALIBRATION_STATE_CODE = "W-SCHED-CALIBRATION-STATE"   # a measured table used where a latch moved capsules: docs/schedule.md
CALIBRATION_STATE_RTOL = 0.1              # model gain change (of their size) beyond which that table is not trusted
CONTACT_CODE = "W-SCHED-CONTACT"         # a step starts with a pair an earlier drive snapped in: docs/schedule.md
CROSSFADE_CODE = "W-SCHED-CROSSFADE"     # a crossfade between steps pushes a latch or pair past its margin, and no fade
                                         # through silence can replace it (a slew limit): docs/schedule.md
FADE_GOAL = "fade through silence"       # goal suffix of the silent segment inserted between two steps (_crossfade)
DRIVEN_KINDS = ("drive", "sweep", "follow", "hold")     # steps whose played drive can push a latch (_latch_track)
FLIP_KINDS = ("follow", "hold")           # ... whose purpose is not the latch: a switch under them is warned


@dataclass(frozen=True)
class CompileOptions:
    sample_rate_hz: float | None = None          # None: >= 10x the highest tone (rounded up)
    waypoint_dt_s: float = 0.01                  # time between waypoints of a follow goal
    tolerance_m: float = 0.5 * UM                # tracking tolerance of the path program
    ramp_s: float = 1e-3                         # raised-cosine crossfade between segments
    calibration: object | None = None            # GainTable from a measured sweep, or None
    gain_provider: Callable | None = None        # (design, capsule) -> GainTable; default model
    forward_provider: Callable | None = None     # (design, capsule, freqs) -> (forward, name)
    latch_provider: Callable | None = None       # (design, freqs) -> (forces, to_b, to_a)
    snap_provider: Callable | None = None        # (design, a, b, freqs, vmax, bound) -> (K,) V | None
    critical_provider: Callable | None = None    # (design, a, b, [(f, V)], s_max, bound) -> scale | None
    max_voltage: float | None = None             # overrides every other limit if given
    full_scale_v: float | None = None            # WAV full scale; default: the transducer's max voltage
    lam: float = 1e-3
    slew_model: str = "auto"
    refine: int = 0
    resim_points: int = 100                      # waypoints re-simulated per goal (evenly spaced)
    tones_per_path: int = 3
    robust: bool = False                         # path program with the declared uncertainty (acl.schedule.robust)
    robust_mode: str = "mean"                    # "mean" (expected squared error, QP) | "worst" (1-sigma ellipsoid, SOC)
    band_samples: int = 0                        # draws of the declared uncertainty for the 95 % band (0: none)
    band_seed: int = 0
    reload: Callable | None = None               # {param: "v unit"} -> Design, to sample uncertain params
    nonlinear_passes: int = 0                    # re-plan against the nonlinear model (acl.schedule.correct)
    allow_nonlinear: bool = False                # plan drives beyond the linear bubble model (eps/R > limit)


def auto_sample_rate(max_frequency_hz: float, factor: float = 10.0, grid_hz: float = 1e3) -> float:
    """At least ``factor`` x the highest tone, rounded up to a multiple of ``grid_hz``."""
    return float(max(np.ceil(factor * max_frequency_hz / grid_hz) * grid_hz, grid_hz))


def _limit(design: Design, limits: Limits | None, opts: CompileOptions) -> tuple[float, float | None]:
    if opts.max_voltage is not None:
        vmax = opts.max_voltage
    else:
        amp, gen = design.amplifier, design.generator       # the declared drive chain caps the drive too
        cands = [v for v in ((limits.max_voltage if limits else None),
                             design.transducer.max_voltage if design.transducer else None,
                             amp.max_voltage if amp else None,
                             gen.max_voltage * (amp.gain if amp else 1.0) if gen else None) if v]
        vmax = min(cands) if cands else DEFAULT_MAX_VOLTAGE
    return vmax, (limits.slew_rate if limits else None)


def compile_program(design: Design, program: str | Program, options: CompileOptions | None = None) -> Schedule:
    """Compile ``program`` of ``design`` into a :class:`Schedule`; raise DiagnosticError on failure."""
    opts = options or CompileOptions()
    prog = design.program(program) if isinstance(program, str) else program
    c = _Compiler(design, prog, opts)
    return c.run()


@dataclass
class _Compiler:
    design: Design
    program: Program
    opts: CompileOptions
    segments: list[Segment] = field(default_factory=list)
    goals: list[GoalReport] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    t: float = 0.0
    vmax_seen: list[float] = field(default_factory=list)
    states_memo: dict = field(default_factory=dict)     # step -> {latch: (state, certain, why)} (:meth:`_latch_track`)
    switch_outcome: dict = field(default_factory=dict)  # switch step -> (state, certain, why) of its latch after it
    push_memo: dict = field(default_factory=dict)       # driven step -> its push on each latch (_push_ratios)
    step_warnings: list = field(default_factory=list)  # W-SCHED-LATCH-STATE (at a switch), -FLIP (a follow or hold),
    #                                                     W-SCHED-TRACKING (a follow's re-simulated miss)
    settled: dict = field(default_factory=dict)         # (tones, latch states) -> :meth:`_settle`'s answer
    branch_memo: dict = field(default_factory=dict)     # (tones, latch states, latch, to) -> :meth:`_branch_pushes`
    inner_goals: list = field(default_factory=list)     # goal records checked for coverage, not in schedule.json (sweeps)
    forward_now: Callable | None = None                 # the current follow goal's forward provider (:meth:`_models_for`)
    many_now: Callable | None = None                    # (designs, capsule, freqs, u) -> [prediction]: one batch, or None
    gains_now: Callable | None = None                   # and its gain provider ((design, capsule, freqs) -> GainTable)

    def run(self) -> Schedule:
        self._check_numbers()
        from acl.schedule.solve import SolverFailure

        for i, step in enumerate(self.program.steps):
            try:
                if step.kind in ("hold", "follow"):
                    self._contact_check(i, step)
                k = len(self.segments)
                getattr(self, f"_{step.kind}")(i, step)
                self._crossfade(i, k)
            except SolverFailure as exc:   # every step, not only follow: a located error, never E-INTERNAL
                raise _diag("E-SCHED-SOLVER", f"step {i + 1}: {exc}", step.span,
                            "no solver could handle this step's convex program: check its margin, limit and "
                            "slew for absurd values") from None
        if not self.segments:
            raise DiagnosticError([error("E-SCHED-EMPTY", f"program `{self.program.name}` has no steps",
                                         self.program.span)])
        flips = [k for k, st in enumerate(self.program.steps) if st.kind in FLIP_KINDS]
        if flips and self.design.latches:       # a path or hold that may switch a latch: warned (W-SCHED-LATCH-FLIP)
            self._latch_track(flips[-1] + 1)
        vmax = max(self.vmax_seen) if self.vmax_seen else _limit(self.design, None, self.opts)[0]
        full_scale, source = self._full_scale(vmax)
        fs = self.opts.sample_rate_hz or auto_sample_rate(
            max((t.max_frequency_hz for s in self.segments for t in s.tones), default=1e3))
        sched = Schedule(program=self.program.name, segments=self.segments, goals=self.goals,
                         max_voltage_v=vmax, full_scale_v=full_scale, ramp_s=self.opts.ramp_s,
                         source=self.design.file, notes=self.notes, full_scale_source=source)
        sched.sample_rate_hz = fs
        gen, amp = self.design.generator, self.design.amplifier
        if gen is not None or amp is not None:      # the declared drive chain, for `acl play` (docs/bench.md)
            sched.chain = {k: v.model_dump(exclude={"span"}) for k, v in (("generator", gen), ("amplifier", amp))
                           if v is not None}
        for w in self.step_warnings:
            sched.warnings.append(w)
            self.notes.append(f"warning: {w.message}")
        from acl.schedule.bands import coverage_warnings

        for w in coverage_warnings(self.design, sched, [st.span for st in self.program.steps], self._reach,
                                   extra=self.inner_goals):
            sched.warnings.append(w)
            self.notes.append(f"warning: {w.message}")
        _choose_all_phases(sched, fs)
        self._check_peaks(sched)
        self._check_slews(sched)
        self._check_linear(sched)
        return sched

    def _reach(self, goal: GoalReport):
        """(largest deflection from rest, m, the phrase saying where) a hold, cross or switch goal drives to; None if unknown.

        hold above: each capsule of the pair at the equilibrium under the whole drive; cross: the last
        stable equilibrium before snap-in (the pair passes through it), then contact, which no calibration
        covers: ``(m, phrase, True)`` as a drive that snaps (:meth:`_static_reach`), warned whatever the range;
        switch: the shuttle's travel between the latch's two stable states (it ends in the other one); drive
        and sweep: every capsule at
        the static equilibrium under the drive (a sweep's at its worst frequency: :meth:`_static_reach`).
        A follow goal: None (its path).
        """
        if goal.kind in ("drive", "sweep"):
            return self._static_reach(goal)
        if goal.kind not in ("hold", "switch"):
            return None
        step = self.program.steps[goal.step]
        tones = tuple((t.frequency_hz, t.amplitude_v) for s in self.segments
                      if s.step == goal.step and s.goal == goal.name for t in s.tones if t.amplitude_v > 0)
        try:
            if goal.kind == "switch":
                from acl.analysis.mechanics import latch_geometry
                from acl.physics.latch import latch_landscape

                if not tones:          # already in the state: nothing moves
                    return None
                lt = next(l for l in self.design.latches if l.name == step.latch)
                land = latch_landscape(*latch_geometry(lt, self.design))
                if land.state_b is None:
                    return None
                return abs(float(land.state_b)), f"the shuttle of latch `{lt.name}` travels to state {step.state},"
            if not tones:
                return None
            from acl.analysis import acoustics, mechanics
            from acl.design.model import Drive, Tone

            shape = Drive(tones=tuple(Tone(frequency=f, amplitude=a) for f, a in tones))
            sw = mechanics.sweep_voltage(self.design, shape, 1.0, acoustics.force_model_for(self.design))
            pos = sw.snap_positions if (step.mode == "cross" and sw.snap_positions is not None) else \
                {k: v[-1] for k, v in sw.positions.items()}
            best, who = 0.0, ""
            for name in (step.a.split(".")[0], step.b.split(".")[0]):
                c = self.design.capsule(name)
                r = float(np.linalg.norm(np.asarray(pos[name], float) - np.asarray(c.center, float)))
                if r > best * (1 + TIE_RTOL):     # a symmetric pair: the first capsule named
                    best, who = r, name
            if step.mode == "cross":        # a cross ends in contact by definition: warned whatever the range
                return best, f"the pair passes, before it snaps in, through capsule `{who}` at", True
            return best, f"the drive holds capsule `{who}` at"
        except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError):
            return None         # no mechanics model for this design: the deflection is unknown, not covered

    def _static_reach(self, goal: GoalReport):
        """(largest capsule displacement from rest, m, phrase) under a drive or sweep step; None if unknown.

        The analysis' mechanics (acl.analysis.mechanics.equilibrium: lone actuators, pairs, groups, springs,
        latches) at the whole drive, from the latch states the step starts in (:meth:`_settle`; a latch an earlier
        drive left in an uncertain state (:meth:`_latch_track`): from either state, the larger reach).  A sweep
        (a chirp of one tone) is taken at its worst frequency: the largest displacement over the band, sampled
        with every mode inside and refined (acoustics.band_maximum), each frequency held long enough to settle
        (quasi-static: what the analysis predicts everywhere).  A drive that snaps the mechanism in reports the
        last stable point before it (a sweep: at the first frequency found to snap it) and ends in contact, which
        no calibration covers (the fit counts no contact row): ``(m, phrase, True)``, warned whatever the range.
        """
        tones = [t for s in self.segments if s.step == goal.step and s.goal == goal.name
                 for t in s.tones if t.amplitude_v > 0]
        if not tones or not self.design.capsules:
            return None
        from acl.analysis import acoustics

        try:
            fm = acoustics.force_model_for(self.design)
            track = self._latch_track(goal.step)
            states = {n: st for n, (st, _, _) in track.items()}
            doubt = [n for n, (_, sure, _) in track.items() if not sure][:3]
            best = None
            for k in range(2 ** len(doubt)):     # an uncertain latch: either state, the larger reach (contact first)
                alt = dict(states)
                for b, n in enumerate(doubt):
                    if k >> b & 1:
                        alt[n] = "a" if states[n] == "b" else "b"
                got = self._static_reach_from(tones, fm, alt)
                if k and got is not None:
                    moved = ", ".join(f"`{n}` in state {alt[n]}" for n in doubt if alt[n] != states[n])
                    got = (got[0], got[1].replace("capsule `", f"(latch {moved}, where an earlier drive may have left "
                                                  "it) capsule `", 1), *got[2:])
                if got is not None and (best is None or (len(got) > 2, got[0]) > (len(best) > 2, best[0])):
                    best = got
            return best
        except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None         # no mechanics model for this design: the deflection is unknown, not covered

    def _static_reach_from(self, tones, fm, states: dict):
        """:meth:`_static_reach` from the latch states ``states``."""
        from acl.analysis import acoustics
        from acl.design.model import Drive, Tone

        chirp = next((t for t in tones if t.frequency_end_hz), None)
        if chirp is None:
            r, who, status = self._settle(Drive(tones=tuple(Tone(frequency=t.frequency_hz, amplitude=t.amplitude_v)
                                                            for t in tones)), fm, states)
            if status == "snap_in":
                return r, f"the drive snaps the mechanism in; before it does, capsule `{who}` already moves", True
            return r, f"the drive moves capsule `{who}`"
        seen = {}

        def at(f):
            if f not in seen:
                seen[f] = self._settle(Drive(tones=(Tone(frequency=float(f), amplitude=chirp.amplitude_v),)),
                                       fm, states)
                if seen[f][2] == "snap_in":
                    raise _Snapped(f)
            return seen[f][0]

        try:      # the deflection is flat at its peak: refined to 1e-3 of the frequency (Q ~ 20: < 0.1 %)
            r, f = acoustics.band_maximum(at, chirp.frequency_hz, chirp.frequency_end_hz, self._mode_frequencies(),
                                          samples=11, rtol=1e-3)
        except _Snapped as snap:          # the lowest snapping frequency found: the sweep snaps the mechanism in
            f = snap.frequency
            r, who, _ = seen[f]
            return (r, f"at {f / 1e3:.4g} kHz the sweep snaps the mechanism in; before it does, capsule `{who}` "
                       "already moves", True)
        return r, f"at {f / 1e3:.4g} kHz the sweep moves capsule `{seen[f][1]}`"

    def _latch_track(self, i: int) -> dict:
        """{latch: (state, certain, why)} when step ``i`` starts.

        As the switch steps before it left them (:attr:`switch_outcome`), and every other step that plays a drive
        before it -- drive, sweep, follow (each waypoint) and hold (:meth:`_switched_by`): a bistable latch stays
        switched when the drive stops.  ``why`` names the step that set the state (None: the declared state);
        ``certain`` is False where a drive pushed the latch near the force that switches it, or over it only in part
        of the declared uncertainty: then ``state`` is the likelier one (the nominal pushes in the played order).
        """
        memo = self.states_memo
        if 0 not in memo:
            memo[0] = {l.name: (l.state, True, None) for l in self.design.latches}
        k = max(j for j in memo if j <= i)
        cur = dict(memo[k])
        for j in range(k, i):
            st = self.program.steps[j]
            if st.kind == "switch" and st.latch in cur:
                cur[st.latch] = self.switch_outcome.get(j, (st.state, True, f"step {j + 1} (switch)"))
            elif st.kind in DRIVEN_KINDS:
                changed = self._switched_by(j, cur)
                if st.kind in FLIP_KINDS:
                    self._flip_warn(j, cur, changed)
                cur.update(changed)
            memo[j + 1] = dict(cur)
        return cur

    def _switched_by(self, j: int, cur: dict) -> dict:
        """{latch: (state, certain, why)} for the bistable latches whose state the drive of step ``j`` (a drive, sweep,
        follow or hold) changes or makes uncertain, from the states ``cur`` it starts in.

        The push is the switch planner's force model: the force of the drive along each latch's axis
        (acl.schedule.gains.latch_drive_forces, or the injected ``latch_provider``, at rest) over the force that
        switches it to the other state (a->b its switching force, b->a its release force), with the capsules at the
        drive's static equilibrium and undeflected (:meth:`_branch_pushes`: both must be on the same side); a sweep's
        at its band's worst frequency (acoustics.band_maximum); a path's at its most-switching waypoint
        (:meth:`_push_ratios`).  Switched for sure: push >= LATCH_STATE_MARGIN and, with a margin band
        (``band_samples``), its 5th percentile over the declared uncertainty >= 1, and never pushed back (below);
        left for sure: the largest push towards the other state (a path's between its waypoints too) <=
        1/LATCH_STATE_MARGIN and the band's 95th percentile < 1.  Anything between: uncertain, in the state the
        nominal pushes leave it in (a path: waypoint by waypoint; a push >= 1 x switches).
        """
        step = f"step {j + 1} ({self.program.steps[j].kind})"
        try:
            pushes = self._push_ratios(j, cur)
        except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            try:
                bi = self._bistable()
            except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError):
                bi = set(cur)           # not even the thresholds: any latch may have moved
            return {n: (s, False, f"{step}: its push on the latch could not be computed ({exc})")
                    for n, (s, _, _) in cur.items() if n in bi}
        M = LATCH_STATE_MARGIN
        out = {}

        def text(n, to):
            p = pushes[n][to]
            what = "switching" if to == "b" else "release"
            s = f"{step} pushed it to {p.r:.3g} x its {what} force{p.where}"
            if "waypoint" in p.where and p.up > max(p.r, p.r0) * (1 + 1e-3) and p.up > 1.0 / M:
                s += f", up to {p.up:.3g} x while crossfading between waypoints"
            if p.band:
                s += f" ({p.lo:.3g} .. {p.hi:.3g} x in the margin band over {p.band})"
            return s

        def sure(n, to):          # at its equilibrium and undeflected (the branch in between is not solved)
            p = pushes[n][to]
            return min(p.r, p.r0) >= M and p.lo >= 1.0 if np.isfinite(p.r0) else p.r >= M and p.lo >= 1.0

        def never(n, to):         # a branch the drive loses (the mechanism snaps off it) is not left for sure
            p = pushes[n][to]
            return max(p.r, p.up) <= 1.0 / M and p.hi < 1.0 and not p.lost

        def flip(to):
            return "a" if to == "b" else "b"

        for n, (state, certain, why) in cur.items():
            if n not in pushes:
                continue
            other = flip(state)
            likely = pushes[n]["seq"][state]
            if certain:
                if never(n, other):
                    continue
                if sure(n, other) and never(n, state):
                    out[n] = (other, True, text(n, other))
                    continue
                p = pushes[n][other]
                if sure(n, other):
                    near = "then pushed back: " + text(n, state)
                elif p.lost:
                    near = "under the drive no equilibrium stays on that branch: the mechanism snaps off it"
                elif np.isfinite(p.r0) and (min(p.r, p.r0) < M <= max(p.r, p.r0)
                                            or min(p.r, p.r0) <= 1.0 / M < max(p.r, p.r0)):
                    near = f"its deflected and undeflected pushes fall on either side of {1.0 / M:.3g} .. {M:g} x"
                else:
                    near = f"within {M:g} x of it" if 1.0 / M < max(p.r, p.up) and p.r < M else "the band straddles it"
                out[n] = (likely, False, text(n, other) + f": {near}, it may or may not have switched")
                continue
            to = next((t for t in ("b", "a") if sure(n, t) and never(n, flip(t))), None)
            if to is not None:          # from either state it ends there
                out[n] = (to, True, text(n, to))
            elif not (never(n, "a") and never(n, "b")):
                moved = other if not never(n, other) else state
                out[n] = (likely, False, f"{why}; then {text(n, moved)}")
        return out

    def _flip_warn(self, j: int, cur: dict, changed: dict) -> None:
        """W-SCHED-LATCH-FLIP at a follow or hold step whose drive switches a latch, or may (:meth:`_switched_by`)."""
        step = self.program.steps[j]
        for n, (state, certain, why) in changed.items():
            was, was_sure, _ = cur[n]
            if certain and was_sure and state == was:
                continue
            what = (f"switches latch `{n}` from state {was} to state {state}; later steps are planned from state "
                    f"{state}" if certain and state != was else
                    f"may switch latch `{n}`: it ends in state a or b (likelier {state}); a later `switch` is planned "
                    "to work from both")
            goal = "path" if step.kind == "follow" else "hold"
            self.step_warnings.append(Diagnostic(
                LATCH_FLIP_CODE, Severity.WARNING, f"step {j + 1}: {step.kind}: the {goal}'s drive {what}",
                step.span, "keep the step's drive away from the latch's switching and release forces (other tones, "
                "a lower limit), or switch the latch back afterwards with a `switch` step", notes=(why,)))

    # -- boundaries between steps ---------------------------------------------------------------
    def _crossfade(self, i: int, k: int) -> None:
        """Check the crossfade from step ``i - 1`` into step ``i`` (its first segment is ``segments[k]``), and fade
        through silence where it pushes harder than either step.

        The renderer blends the last segment of step i-1 into the first of step i over 2 h (acl.emit.render).  A
        tone kept across the boundary with a counter-pushing tone that changes can push a latch over the force that
        switches it, or bring a held pair nearer snap-in, while each step alone is within its margin
        (acl.schedule.crossfade).  Checked: every bistable latch towards the state it is not in when step i starts
        (:meth:`_latch_track`; an uncertain one both ways), unless step i is a switch of it to that state
        (:meth:`_crossfade_latches`); the pair of a `hold ... above` on either side (:meth:`_crossfade_holds`).
        Where the crossfade goes past the larger of the safe level (1/LATCH_STATE_MARGIN of the switching force, the
        hold's margin) and what either step alone does, a silent segment of ``ramp_s`` is inserted before step i:
        each drive then fades alone, a scaling whose force scales with it, and silence is force-free (a bistable
        latch keeps its state, a pair does not snap).  When that fade would break a step's slew limit the crossfade
        is kept and W-SCHED-CROSSFADE warns at step i with the overshoot ratio.
        """
        if i == 0 or k == 0 or k >= len(self.segments) or self.opts.ramp_s <= 0:
            return
        before, after = self.segments[k - 1], self.segments[k]
        if not any(t.amplitude_v > 0 for t in before.tones) or not any(t.amplitude_v > 0 for t in after.tones):
            return          # a drive fading from or into silence is only scaled: no tone mixes
        freqs, p, q, cos = _boundary_tones(before, after)
        found = []
        for check, what in ((self._crossfade_latches, "latches"), (self._crossfade_holds, "held pairs")):
            try:
                found += check(i, freqs, p, q, cos)
            except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError,
                    np.linalg.LinAlgError) as exc:
                self.notes.append(f"step {i + 1}: the crossfade from step {i} could not be checked for {what} ({exc})")
        if not found:
            return
        over = max(r for r, _ in found)
        text = "; ".join(w for _, w in found)
        step = self.program.steps[i]
        blocked = self._fade_slew(before, after)
        if blocked is not None:
            self.step_warnings.append(Diagnostic(
                CROSSFADE_CODE, Severity.WARNING, f"step {i + 1}: {step.kind}: the crossfade from step {i} pushes "
                f"{text}: {over:.3g} x beyond the larger of the safe level and either step alone", step.span,
                "change the tones of one step so that no tone is kept across the boundary while a counter-pushing "
                "one changes; or raise the slew limit so the compiler can fade through silence there",
                notes=(f"not faded through silence: {blocked}",)))
            return
        ramp = self.opts.ramp_s
        fade = Segment(after.start_s, after.start_s + ramp, (), i, f"step {i + 1}: {FADE_GOAL}")
        self.segments[k:] = [fade] + [dataclasses.replace(s, start_s=s.start_s + ramp, end_s=s.end_s + ramp)
                                      for s in self.segments[k:]]
        self.t += ramp
        for g in self.goals + self.inner_goals:
            if g.step == i:
                g.start_s, g.end_s = g.start_s + ramp, g.end_s + ramp
                if g.times_s is not None:
                    g.times_s = g.times_s + ramp
        self.notes.append(f"step {i + 1}: faded through {ramp * 1e3:.4g} ms of silence after step {i} (t = "
                          f"{fade.start_s:.4g} s): a direct crossfade would push {text} ({over:.3g} x beyond the "
                          "larger of the safe level and either step alone)")

    def _crossfade_latches(self, i: int, freqs, p, q, cos) -> list:
        """[(overshoot ratio, phrase)] for the bistable latches the crossfade into step ``i`` pushes towards a state
        they are not in past max(1/LATCH_STATE_MARGIN, either end's push) (:meth:`_crossfade`).

        Forces per V^2 of each tone along each latch axis with the capsules where the latch states put them when
        step i starts (acl.schedule.gains.latch_forces, state_positions; or the injected ``latch_provider``), the
        capsules undeflected.  Quadratic in amplitude: the worst-phase maximum over the crossfade, exact in that
        model (acl.schedule.crossfade.crossfade_peak); with declared drive saturation the whole mixed drive
        (latch_drive_forces) at the crossfade weights FADE_POINTS, each shared tone at its worst phase: sampled.
        """
        if not self.design.latches:
            return []
        bi = self._bistable()
        if not bi:
            return []
        from acl.schedule.crossfade import FADE_POINTS, crossfade_amplitudes, crossfade_peak

        if self.opts.latch_provider is not None:
            quadratic = True
        else:
            from acl.analysis.acoustics import force_model_for

            quadratic = force_model_for(self.design).quadratic_in_amplitude
        if quadratic and (not np.any((p > 0) & (q > 0)) or len(freqs) < 2):
            return []       # no kept tone, or one tone alone: never past the larger end (acl.schedule.crossfade)
        track = self._latch_track(i)
        states = {n: s for n, (s, _, _) in track.items()}
        step = self.program.steps[i]
        pos = None
        if self.opts.latch_provider is not None:
            G, to_b, to_a = self.opts.latch_provider(self.design, tuple(freqs))
        else:
            from acl.schedule.gains import latch_forces, state_positions

            pos = state_positions(self.design, states)
            G, to_b, to_a = latch_forces(self.design, freqs, pos)
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
                        return sig * float(latch_drive_forces(self.design, tones, pos)[j]) / thr

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

    def _crossfade_holds(self, i: int, freqs, p, q, cos) -> list:
        """[(overshoot ratio, phrase)] for the pair of a `hold ... above` step on either side of the boundary into
        step ``i`` that the mixed drive brings nearer snap-in than min(margin, either end) (:meth:`_crossfade`).

        The snap index sum_k u_k / Vcrit_k^2 never exceeds the larger end over a crossfade (acl.schedule.crossfade),
        but the whole drive's critical scale (acl.schedule.gains.critical_scale, or the injected
        ``critical_provider``) is not bound by it: it is re-simulated at the crossfade weights FADE_POINTS, a tone
        on both sides at either phase extreme (in phase, anti-phase; up to 2 such tones in every combination, more:
        all in phase or all anti-phase), searched up to 1.5 x the margin as the hold itself.  Sampled, not a bound.
        """
        from acl.schedule.crossfade import FADE_POINTS, crossfade_amplitudes

        out = []
        for h in (i - 1, i):
            st = self.program.steps[h]
            if st.kind != "hold" or st.mode != "above":
                continue
            provider = self.opts.critical_provider
            if provider is None:
                if self.opts.snap_provider is not None:
                    continue            # an injected snap model: its index never exceeds the larger end
                from acl.schedule.gains import critical_scale as provider

            def scale(amps):
                tones = [(f, float(a)) for f, a in zip(freqs, amps) if a > 0]
                s = provider(self.design, st.a, st.b, tones, 1.5 * st.margin, st.bound)
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

    def _fade_slew(self, before: Segment, after: Segment) -> str | None:
        """Why fading ``before`` out and ``after`` in through silence would break a step's slew limit; None if not.

        A tone faded alone over 2 h = min(ramp, the segment) by a raised cosine changes its amplitude at up to
        pi A / (4 h) (segment_slews)."""
        ramp = self.opts.ramp_s
        for seg, verb in ((before, "out"), (after, "in")):
            slew = _limit(self.design, getattr(self.program.steps[seg.step], "limits", None), self.opts)[1]
            if slew is None:
                continue
            h = min(ramp / 2, seg.duration_s / 2)
            rate = np.pi * max(t.amplitude_v for t in seg.tones) / (4 * h) if h > 0 else np.inf
            if rate > slew * (1 + 1e-6):
                return (f"fading step {seg.step + 1}'s drive {verb} alone over {2 * h:.4g} s changes its amplitude at "
                        f"{rate:.4g} V/s, over its slew limit {slew:g} V/s")
        return None

    def _bistable(self) -> dict:
        """{latch: index} of the latches that stay switched when the drive stops (a finite release force)."""
        _, to_b, to_a = self._latch_thresholds(self.design)
        return {l.name: k for k, l in enumerate(self.design.latches) if np.isfinite(to_a[k]) and np.isfinite(to_b[k])}

    def _latch_thresholds(self, design):
        provider = self.opts.latch_provider
        if provider is None:
            from acl.schedule.gains import latch_forces as provider
        return provider(design, [])

    def _latch_push(self, design, tones) -> tuple:
        """((L,) force N of ``tones`` ((Hz, V)) along each latch axis, to_b, to_a): the switch planner's model."""
        provider = self.opts.latch_provider
        if provider is not None:        # an injected model: force per V^2 of each tone (as the switch LP)
            forces, to_b, to_a = provider(design, tuple(f for f, _ in tones))
            return np.asarray(forces, float) @ np.array([a * a for _, a in tones], float), to_b, to_a
        from acl.schedule.gains import latch_drive_forces, latch_forces

        _, to_b, to_a = latch_forces(design, [])
        return latch_drive_forces(design, tones), to_b, to_a

    def _waypoint_pushes(self, design, freqs, U) -> tuple:
        """((L, N) force N of each waypoint drive, (L, N-1, 2) upper bounds of the force towards b / towards a while
        crossfading from waypoint w to w + 1, to_b, to_a); ``U`` (K, N) amplitudes V of the tones ``freqs``.

        Tones add in power, each quadratic in its amplitude (force_model.quadratic_in_amplitude): the force is
        G @ U^2 with G the force per V^2 of each tone (acl.schedule.gains.latch_forces, the switch LP's), and while
        the renderer crossfades two waypoints each tone's power lies between its two ends, so the force towards a
        state is at most the sum over tones of the larger end.  A drive whose forces are not quadratic (declared
        drive saturation) is evaluated waypoint by waypoint, without the crossfade bound (its ends only).
        """
        U = np.asarray(U, float)
        provider = self.opts.latch_provider
        quadratic = provider is not None
        if provider is None:
            from acl.analysis.acoustics import force_model_for
            from acl.schedule.gains import latch_forces as provider

            quadratic = force_model_for(design).quadratic_in_amplitude
        if quadratic:
            G, to_b, to_a = provider(design, tuple(float(f) for f in freqs))
            G = np.asarray(G, float).reshape(len(to_b), len(freqs))
            P = U * U
            F = G @ P
            if U.shape[1] > 1:
                pos = np.maximum(G[:, :, None] * P[None, :, :-1], G[:, :, None] * P[None, :, 1:]).sum(axis=1)
                neg = np.maximum(-G[:, :, None] * P[None, :, :-1], -G[:, :, None] * P[None, :, 1:]).sum(axis=1)
                up = np.stack([pos, neg], axis=-1)
            else:
                up = np.zeros((len(to_b), 0, 2))
            return F, up, np.asarray(to_b, float), np.asarray(to_a, float)
        seen, cols = {}, []
        for w in range(U.shape[1]):
            key = tuple(U[:, w])
            if key not in seen:
                seen[key], to_b, to_a = self._latch_push(design, [(float(f), float(a)) for f, a in zip(freqs, key)])
            cols.append(seen[key])
        _, to_b, to_a = self._latch_thresholds(design) if not seen else (None, to_b, to_a)
        F = np.array(cols, float).T.reshape(len(to_b), U.shape[1])
        up = np.stack([np.maximum(F[:, :-1], F[:, 1:]), np.maximum(-F[:, :-1], -F[:, 1:])], axis=-1)
        return F, up, np.asarray(to_b, float), np.asarray(to_a, float)

    def _push_ratios(self, j: int, cur: dict | None = None) -> dict:
        """{bistable latch: {"b": _Push, "a": _Push, "seq": {start state: end state}}} for the drive of step ``j``,
        from the latch states ``cur`` it starts in ({latch: (state, certain, why)}; None: the declared ones).

        Its push towards each state over the force that switches the latch there (:meth:`_switched_by`).  A drive or
        hold plays one drive; a sweep is taken at its band's worst frequency; a follow step plays one drive per
        waypoint: its most-switching waypoint's push (``where`` names it), ``up`` the largest push also between
        waypoints (:meth:`_waypoint_pushes`), and ``seq`` the state the nominal pushes leave the latch in, waypoint by
        waypoint, from each state (a push >= 1 x switches).  The worst drive (waypoint, frequency) is found with the
        capsules at rest; its push is then taken with the capsules where they are (:meth:`_branch_pushes`): at the
        static equilibrium under the drive on the branch the latch leaves (state a for the push towards b, b for the
        push back), ``r``, and undeflected on that branch, ``r0``; the other latches in their (likelier) states.
        ``lo`` .. ``hi``: the 5th percentile of the most-switching waypoint's push and the 95th of the largest one over
        the declared uncertainty (acl.schedule.bands.margin_band, at rest: the percentiles of each draw's extremes
        over the whole path, so every waypoint's band is inside), moved by the nominal change from rest to
        the worse of ``r`` and ``r0`` (lo = hi = the push without a band)."""
        if j in self.push_memo:
            return self.push_memo[j]
        bi = self._bistable()
        segs = [s for s in self.segments if s.step == j and not _is_fade(s)]
        tones = [t for s in segs for t in s.tones if t.amplitude_v > 0]
        chirp = next((t for t in tones if t.frequency_end_hz), None)
        freqs = sorted({t.frequency_hz for t in tones})
        U = np.array([[sum(t.amplitude_v for t in s.tones if t.frequency_hz == f and t.amplitude_v > 0)
                       for s in segs] for f in freqs], float).reshape(len(freqs), len(segs))
        steps = self.program.steps[j].kind == "follow" and len(segs) > 1

        def ratios(d):
            """{latch: {to: (push at the worst drive, its waypoint index or frequency, largest push incl. crossfades)}},
            the waypoint pushes (rb, ra) per latch for the nominal order (None: one drive)."""
            if not tones:
                return {n: {"b": (0.0, 0, 0.0), "a": (0.0, 0, 0.0)} for n in bi}, None
            if chirp is None:
                F, up, to_b, to_a = self._waypoint_pushes(d, freqs, U)
                out, seq = {}, {}
                for n, k in bi.items():
                    rb, ra = F[k] / to_b[k], -F[k] / to_a[k]
                    ub = np.max(up[k, :, 0], initial=-np.inf) / to_b[k]
                    ua = np.max(up[k, :, 1], initial=-np.inf) / to_a[k]
                    wb, wa = int(np.argmax(rb)), int(np.argmax(ra))
                    out[n] = {"b": (float(rb[wb]), wb, float(max(rb[wb], ub))),
                              "a": (float(ra[wa]), wa, float(max(ra[wa], ua)))}
                    seq[n] = (rb, ra)
                return out, seq
            seen = {}

            def at(f):
                if f not in seen:
                    seen[f] = self._latch_push(d, [(float(f), chirp.amplitude_v)])
                return seen[f]

            out = {}
            for n, k in bi.items():
                rb, fb = acoustics.band_maximum(lambda f: float(at(f)[0][k] / at(f)[1][k]), chirp.frequency_hz,
                                                chirp.frequency_end_hz, self._mode_frequencies(), rtol=1e-6)
                ra, fa = acoustics.band_maximum(lambda f: float(-at(f)[0][k] / at(f)[2][k]), chirp.frequency_hz,
                                                chirp.frequency_end_hz, self._mode_frequencies(), rtol=1e-6)
                out[n] = {"b": (rb, float(fb), rb), "a": (ra, float(fa), ra)}
            return out, None

        from acl.analysis import acoustics

        nominal, seq = ratios(self.design)
        times = [s.start_s for s in segs]

        def where(w):
            return f" at waypoint {w + 1} of {len(segs)} (t = {times[w]:.4g} s)" if steps else ""

        def drive_of(w):
            if chirp is not None:
                return ((float(w), chirp.amplitude_v),)
            return tuple((f, float(U[i, w])) for i, f in enumerate(freqs) if U[i, w] > 0)

        states = {n: s for n, (s, _, _) in (cur or {}).items()}
        res, shift = {}, {}
        for n, v in nominal.items():
            res[n] = {}
            for to, (r_rest, w, up) in v.items():
                eq = self._branch_pushes(drive_of(w), states, n, to) if tones else None
                r, r0, note, lost = (r_rest, r_rest, "", False) if eq is None else eq
                worse_lo, worse_hi = min(r, r0) - r_rest, max(r, r0) - r_rest
                shift[n, to] = (min(worse_lo, 0.0), max(worse_hi, 0.0))
                res[n][to] = _Push(r, r, max(r, r0, up + shift[n, to][1]), "", max(r, r0, up + shift[n, to][1]),
                                   where(w) + note, r0, lost)
            res[n]["seq"] = {s0: _nominal_end(s0, *seq[n]) if seq and steps else     # a path: at rest, in order
                             ("b" if s0 == "a" and res[n]["b"].r >= 1.0 else "a" if s0 == "b" and res[n]["a"].r >= 1.0
                              else s0) for s0 in ("a", "b")}
        for n, v in res.items():            # r0 below r: the lower end counts for "switched for sure"
            for to in ("a", "b"):
                p = v[to]
                v[to] = dataclasses.replace(p, lo=min(p.r, p.r0))
        if self.opts.band_samples > 0 and self.opts.latch_provider is None and tones and bi:
            from acl.schedule.bands import margin_band

            def margin_for(d):
                r, _ = ratios(d)
                return 1.0, {k: x for n, v in r.items() for to, (x0, _, xu) in v.items()
                             for k, x in ((f"+{n}>{to}", xu), (f"-{n}>{to}", -x0))}

            band = margin_band(self.design, margin_for, samples=self.opts.band_samples, seed=self.opts.band_seed,
                               reload=self.opts.reload)
            if band is not None:
                n_all = band.samples + band.failed
                what = f"{n_all} draws of the declared uncertainty" + (
                    f", {band.failed} failed: counted as unknown" if band.failed else "")
                for n in nominal:
                    for to in ("a", "b"):
                        p = res[n][to]
                        lo, hi = -band.others_p95.get(f"-{n}>{to}", np.inf), band.others_p95.get(f"+{n}>{to}", np.inf)
                        if band.failed:
                            lo, hi = -np.inf, np.inf
                        dlo, dhi = shift[n, to]
                        res[n][to] = dataclasses.replace(p, lo=min(lo + dlo, p.lo), hi=max(hi + dhi, p.hi), band=what)
        self.push_memo[j] = res
        return res

    def _branch_pushes(self, tones, states: dict, latch: str, to: str):
        """(push ratio at the static equilibrium under ``tones``, push ratio undeflected, note) of latch ``latch``
        towards state ``to``, on the branch it leaves (the other state); None without the mechanics (an injected
        latch model, no capsules) or when the forces cannot be evaluated.

        The capsules are placed as the latch states put them (a latch in a state other than its declared one: the
        capsules it carries moved by the travel between its states; ``latch`` itself in the state it leaves, the
        others in ``states``, default their declared ones), then the mechanism is solved under the drive from there
        (acl.analysis.mechanics.equilibrium, warm-started: the branch the device is on), and the drive's force along
        the latch axis is taken at those positions (acl.schedule.gains.latch_drive_forces): the thrust and the
        Bjerknes forces of capsules that moved.  A drive that snaps the mechanism in: at the last stable point before
        (the furthest the branch goes).  When no equilibrium stays on that branch (the solver falls back to the
        declared one), the undeflected push is used for both, with a note, and ``lost`` is True: the mechanism
        leaves the branch, and the latch may go with it.  (r, r0, note, lost).
        """
        if self.opts.latch_provider is not None or not self.design.capsules or not tones:
            return None
        key = (tuple(tones), tuple(sorted(states.items())), latch, to)
        if key in self.branch_memo:
            return self.branch_memo[key]
        from acl.analysis import acoustics, mechanics
        from acl.design.model import Drive, Tone
        from acl.physics.latch import latch_landscape
        from acl.schedule.gains import latch_drive_forces, latch_forces, state_positions

        try:
            k = next(i for i, l in enumerate(self.design.latches) if l.name == latch)
            branch = dict(states)
            branch[latch] = "a" if to == "b" else "b"
            lands = {lt.name: latch_landscape(*mechanics.latch_geometry(lt, self.design)) for lt in self.design.latches}
            pos = state_positions(self.design, branch)
            _, to_b, to_a = latch_forces(self.design, [])
            thr = float(to_b[k]) if to == "b" else -float(to_a[k])
            r0 = float(latch_drive_forces(self.design, tones, pos)[k] / thr)
            drive = Drive(tones=tuple(Tone(frequency=f, amplitude=a) for f, a in tones))
            st = mechanics.equilibrium(self.design, drive, acoustics.force_model_for(self.design), start=pos)
            on_branch = st.status in ("ok", "snap_in")
            for lt in self.design.latches:
                land, u = lands[lt.name], st.deflections.get(lt.name)
                if land.unstable is None or u is None:
                    continue
                if (u > land.unstable) != (branch.get(lt.name, lt.state) == "b"):
                    on_branch = False
            if not on_branch:
                out = (r0, r0, " (undeflected)", True)
            else:
                r = float(latch_drive_forces(self.design, tones, st.positions)[k] / thr)
                note = f" at its static equilibrium ({r0:.3g} x undeflected)" if f"{r:.3g}" != f"{r0:.3g}" else ""
                out = (r, r0, note, False)
        except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError):
            out = None
        self.branch_memo[key] = out
        return out

    def _settle(self, drive, force_model, states: dict):
        """(largest capsule displacement from rest, m, that capsule, status) at the equilibrium under ``drive``.

        A latch that rests in state a but is in state b when the step starts (an earlier switch), or that the
        drive itself switches (acl.analysis.mechanics.latch_margins: its push reaches the switching force), is
        solved from its state b (the shuttle's capsules moved by the travel there): the branch the device is on.
        ValueError when the mechanics does not converge.
        """
        key = (tuple((t.frequency, t.amplitude) for t in drive.tones), tuple(sorted(states.items())))
        if key in self.settled:             # a ramp repeats its drives
            return self.settled[key]
        from acl.analysis import mechanics
        from acl.schedule.gains import state_positions

        want, margins = {}, None
        for lt in self.design.latches:
            if lt.state != "a":
                continue
            if states.get(lt.name, lt.state) == "a":
                margins = margins if margins is not None else mechanics.latch_margins(self.design, drive, force_model)
                if not margins[lt.name].margin >= 1.0:
                    continue
            want[lt.name] = "b"
        # the capsules each such latch carries (mounted and trussed to them) moved by its travel
        st = mechanics.equilibrium(self.design, drive, force_model, start=state_positions(self.design, want))
        if st.status not in ("ok", "snap_in"):
            raise ValueError(f"no equilibrium ({st.status})")
        who, best = first_max_item({c.name: float(np.linalg.norm(np.asarray(st.displacements[c.name], float)))
                                    for c in self.design.capsules})     # ties: the first capsule declared
        self.settled[key] = (best, who, st.status)
        return self.settled[key]

    def _check_linear(self, sched: Schedule) -> None:
        """Refuse a segment that drives an interface beyond the linear bubble model (eps/R > LINEAR_AMPLITUDE_LIMIT; docs/physics.md).

        Tone amplitudes add (the worst-case peak); a sweep at its worst frequency (sampled with every mode
        inside, the largest refined: acoustics.sweep_worst_amplitude).  Allowed with
        ``allow_nonlinear`` (then noted): the predicted forces are then not trustworthy.
        """
        from acl.analysis.acoustics import interface_amplitudes, sweep_worst_amplitude
        from acl.design.model import Drive, Tone
        from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT

        worst_of: dict[int, tuple[float, str]] = {}     # step -> (worst eps/R over its segments, interface)
        steady = self._steady_amplitudes(sched)
        for seg in sched.segments:
            if not seg.tones or not self.design.capsules:
                continue
            worst, where = worst_of.get(seg.step, (0.0, ""))
            chirps = [t for t in seg.tones if t.frequency_end_hz]
            if len(chirps) == 1 and len(seg.tones) == 1 and chirps[0].amplitude_v > 0:     # a sweep step
                t = chirps[0]
                v, _, amps = sweep_worst_amplitude(self.design, t.frequency_hz, t.frequency_end_hz, t.amplitude_v,
                                                   self._mode_frequencies())
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
                    amps = interface_amplitudes(self.design, Drive(tones=tones))
                    k, v = first_max_item(amps)            # ties: the first declared interface, the first segment
                else:                                      # steady tones: every segment's in one batch (below)
                    k, v = steady[id(seg)]
                if v > worst * (1 + TIE_RTOL):
                    worst, where = v, k
            worst_of[seg.step] = (worst, where)
        for step_index, (worst, where) in sorted(worst_of.items()):   # one finding per step, its worst segment
            if worst <= LINEAR_AMPLITUDE_LIMIT:
                continue
            self._nonlinear_step(sched, step_index, worst, where)

    def _nonlinear_step(self, sched: Schedule, step_index: int, worst: float, where: str) -> None:
        """A step past the amplitude limits (acl.physics.validity): past the hemisphere (no meaning) E-SCHED-NONLINEAR
        unless ``allow_nonlinear``; past the soft limit W-ACOUSTIC-AMPLITUDE at the step, and the step's error bands
        widened by the model-form force uncertainty (:func:`acl.physics.validity.amplitude_model_form`) times the
        goal's largest predicted displacement, added in quadrature."""
        from acl.physics import validity as VA

        step = self.program.steps[step_index]
        text = (f"step {step_index + 1} drives interface `{where}` to eps/R = {worst:.6g}, beyond the linear "
                f"bubble model (eps/R <= {VA.AMPLITUDE.value:g}; docs/physics.md)")
        if worst > VA.AMPLITUDE_MEANING.value:
            text = (f"step {step_index + 1} drives interface `{where}` to eps/R = {worst:.6g}, past the hemisphere "
                    f"(eps/R = {VA.AMPLITUDE_MEANING.value:g}), where the interface leaves the orifice and the bubble "
                    "model has no meaning (docs/physics.md)")
            if self.opts.allow_nonlinear:
                self.notes.append(text + ": allowed by --allow-nonlinear; forces there are not trustworthy")
                return
            raise _diag("E-SCHED-NONLINEAR", text, step.span,
                        "lower the voltage, move the tone off resonance, or pass --allow-nonlinear")
        from acl.analysis.acoustics import capsule_modes

        cap = where.split(".")[0]
        qs = [m.q for m in capsule_modes(self.design, cap)] if cap in {c.name for c in self.design.capsules} else []
        q = max(qs, default=10.0)
        rel = float(VA.amplitude_model_form(worst, q))
        widened = []
        for g in self.goals:
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
        self.notes.append(f"warning: {msg}")

    def _steady_amplitudes(self, sched: Schedule) -> dict:
        """{id(segment): (interface, eps/R)} of the largest interface amplitude (ties: the first declared) of every
        segment of steady tones (no chirp), the segments sharing a set of tones evaluated as one batch
        (acoustics.interface_amplitudes_batch)."""
        from acl.analysis.acoustics import interface_amplitudes_batch, interface_labels

        labels = interface_labels(self.design)
        groups: dict = {}
        for seg in sched.segments:
            if not seg.tones or not self.design.capsules or any(t.frequency_end_hz for t in seg.tones):
                continue
            live = [t for t in seg.tones if t.amplitude_v > 0]
            if live:
                key = tuple(t.frequency_hz for t in live)
                groups.setdefault(key, []).append((seg, [t.amplitude_v for t in live]))
        out = {}
        for freqs, rows in groups.items():
            eps = interface_amplitudes_batch(self.design, freqs, np.array([a for _, a in rows], float))
            if not labels:
                out.update({id(seg): ("", 0.0) for seg, _ in rows})
                continue
            top = first_max(eps, axis=1)
            for (seg, _), k, row in zip(rows, np.atleast_1d(top), eps):
                out[id(seg)] = (labels[int(k)], float(row[int(k)]))
        return out

    def _mode_frequencies(self) -> np.ndarray:
        """Every capsule's mode frequencies (Hz) and the coupled modes' (two or more capsules): a chirp's peaks."""
        if not hasattr(self, "_modes_hz"):
            from acl.analysis import acoustics as AC

            fs = [m.frequency_hz for c in self.design.capsules for m in AC.capsule_modes(self.design, c)]
            if len(self.design.capsules) > 1:
                fs += [m.frequency_hz for m in AC.coupled_modes(self.design)]
            self._modes_hz = np.array(fs, float)
        return self._modes_hz

    def _check_slews(self, sched: Schedule) -> None:
        """Every step with a slew limit: the emitted amplitude envelope, crossfades included, obeys it.

        At a boundary faded over 2h by a raised cosine, a tone's phasor moves from A1 e^(i phi1) to
        A2 e^(i phi2) with weight slope at most pi / (4 h): its amplitude changes at most
        pi |A2 e^(i phi2) - A1 e^(i phi1)| / (4 h) per second (docs/schedule.md, Waveforms).
        """
        rates = segment_slews(sched)
        for i, seg in enumerate(sched.segments):
            if _is_fade(seg):       # silence: its neighbours' fades into it are checked at their own steps
                continue
            step = self.program.steps[seg.step]
            slew = _limit(self.design, getattr(step, "limits", None), self.opts)[1]
            if slew is None:
                continue
            worst = rates[i]
            for g in self.goals:
                if g.step == seg.step:
                    g.details["emitted_max_slew_v_per_s"] = max(
                        g.details.get("emitted_max_slew_v_per_s", 0.0), float(worst))
            if worst > slew * (1 + 1e-6):
                raise _diag("E-SCHED-LIMIT",
                            f"step {seg.step + 1}: the amplitude changes at up to {worst:.4g} V/s in the "
                            f"crossfades of the segment at t = {seg.start_s:.4g} s, over its slew limit "
                            f"{slew:g} V/s", step.span,
                            "lengthen the crossfade (--ramp, up to --waypoint-dt inside a path); start a "
                            "path where the previous drive leaves the capsule (a line from rest); or "
                            "raise the slew limit")

    def _full_scale(self, vmax: float) -> tuple[float, str]:
        """WAV full scale: --full-scale, else the transducer's max voltage, else the largest limit."""
        if self.opts.full_scale_v is not None:
            return float(self.opts.full_scale_v), "--full-scale"
        tr = self.design.transducer
        if tr is not None and tr.max_voltage and np.isfinite(tr.max_voltage):
            return float(tr.max_voltage), f"max_voltage of transducer `{tr.name}`"
        return float(vmax), "largest voltage limit of the program (no transducer declared)"

    def _check_numbers(self) -> None:
        """Durations, limits and slews the solver and the renderer can work with (finite, in range)."""
        t = 0.0
        for i, step in enumerate(self.program.steps):
            d = getattr(step, "duration", None)
            if d is not None:
                if not (np.isfinite(d) and d > 0):
                    raise _diag("E-SCHED-DURATION", f"step {i + 1}: duration {d:g} s is not a positive "
                                "finite time", step.span)
                t += d
                if t > MAX_PROGRAM_S:
                    raise _diag("E-SCHED-DURATION", f"step {i + 1}: the program would last {t:.4g} s, "
                                f"more than {MAX_PROGRAM_S:g} s", step.span,
                                "split it into several programs, or shorten the steps")
            lim = getattr(step, "limits", None)
            if lim is None:
                continue
            lo, hi = VOLTAGE_RANGE
            if lim.max_voltage is not None and not lo <= lim.max_voltage <= hi:
                raise _diag("E-SCHED-LIMIT", f"step {i + 1}: limit {lim.max_voltage:g} V is outside "
                            f"{lo:g} V .. {hi:g} V", step.span, "give the amplifier's real peak voltage")
            lo, hi = SLEW_RANGE
            if lim.slew_rate is not None and not lo <= lim.slew_rate <= hi:
                raise _diag("E-SCHED-LIMIT", f"step {i + 1}: slew {lim.slew_rate:g} V/s is outside "
                            f"{lo:g} .. {hi:g} V/s", step.span)

    def _check_peaks(self, sched: Schedule) -> None:
        """Every segment's analog peak within its step's limit and the WAV full scale."""
        for seg in sched.segments:
            step = self.program.steps[seg.step]
            vmax, _ = _limit(self.design, getattr(step, "limits", None), self.opts)
            if seg.peak_v is not None and seg.peak_v > vmax * (1 + 1e-6):
                raise _diag("E-SCHED-VOLTAGE",
                            f"step {seg.step + 1}: peak {seg.peak_v:.4g} V exceeds the {vmax:g} V limit "
                            f"at t = {seg.start_s:.4g} s", step.span,
                            "lower the tone amplitudes or raise the transducer's max voltage")
            if seg.peak_v is not None and seg.peak_v > sched.full_scale_v * (1 + 1e-9):
                raise _diag("E-SCHED-FULLSCALE",
                            f"step {seg.step + 1}: peak {seg.peak_v:.4g} V exceeds the WAV full scale "
                            f"{sched.full_scale_v:g} V ({sched.full_scale_source})", step.span,
                            "raise --full-scale, or lower the step's amplitudes or limit")

    # -- simple steps --------------------------------------------------------------------------
    def _add(self, duration, tones, step, goal=None):
        if not self.t + duration <= MAX_PROGRAM_S:
            raise _diag("E-SCHED-DURATION", f"step {step + 1}: the program would last "
                        f"{self.t + duration:.4g} s, more than {MAX_PROGRAM_S:g} s",
                        self.program.steps[step].span, "split it into several programs")
        self.segments.append(Segment(self.t, self.t + duration, tuple(tones), step, goal))
        self.t += duration

    def _drive(self, i, step):
        vmax, _ = _limit(self.design, None, self.opts)
        self.vmax_seen.append(vmax)
        tones = [ScheduledTone(t.frequency, t.amplitude, t.phase, phase_fixed=t.phase_given)
                 for t in step.drive.tones]
        self._add(step.duration, tones, i, f"step {i + 1}: drive")
        self.goals.append(GoalReport(f"step {i + 1}: drive", "drive", i, self.t - step.duration, self.t,
                                     tuple(t.frequency_hz for t in tones), details={"limit_v": vmax}))

    def _sweep(self, i, step):
        self.vmax_seen.append(_limit(self.design, None, self.opts)[0])
        tone = ScheduledTone(step.f_start, step.amplitude, 0.0, step.f_stop, "log" if step.log else "linear")
        name = f"step {i + 1}: sweep"
        self._add(step.duration, [tone], i, name)
        # checked against the covered range like every goal, but not a goal of schedule.json (it promises nothing)
        self.inner_goals.append(GoalReport(name, "sweep", i, self.t - step.duration, self.t,
                                           (step.f_start, step.f_stop)))

    def _pause(self, i, step):
        self._add(step.duration, [], i, f"step {i + 1}: pause")

    # -- contact left by an earlier step ---------------------------------------------------------
    def _contact_check(self, i: int, step) -> None:
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
                 for o in self.design.observes if o.kind == "gap" and o.a and o.b}
        pairs.update({frozenset((st.a.split(".")[0], st.b.split(".")[0])): (st.a, st.b)
                      for st in self.program.steps if st.kind == "hold"})
        pairs = {p: ab for p, ab in pairs.items() if len(p) == 2}
        if step.kind == "hold":
            if step.mode != "above":
                return
            mine = [frozenset((step.a.split(".")[0], step.b.split(".")[0]))]
        else:
            mine = [p for p in pairs if step.capsule in p]
        if not mine:
            return
        start = max((j + 1 for j in range(i) if self.program.steps[j].kind == "pause"), default=0)
        for pair in mine:
            a, b = pairs.get(pair, (step.a, step.b) if step.kind == "hold" else (None, None))
            why = None
            for j in range(start, i):
                st = self.program.steps[j]
                if st.kind == "hold" and st.mode == "cross" and frozenset(
                        (st.a.split(".")[0], st.b.split(".")[0])) == pair:
                    why = f"step {j + 1} (hold ... cross) snaps it in"
                elif st.kind in ("drive", "switch", "hold"):
                    tones = [(t.frequency_hz, t.amplitude_v) for g in self.segments if g.step == j
                             for t in g.tones if t.amplitude_v > 0 and not t.frequency_end_hz]
                    if not tones:
                        continue
                    try:
                        scale = critical_scale(self.design, a, b, tones, 1.0)
                        if scale is not None and scale <= 1.0 and self.design.latches:
                            scale = scale if self._snaps_from_state(j, a, tones) else None
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
            self.step_warnings.append(Diagnostic(
                CONTACT_CODE, Severity.WARNING,
                f"step {i + 1}: {step.kind}: the pair {' / '.join(sorted(pair))} may be in contact when the step "
                f"starts: {why} and no pause releases it before this step; {what}", step.span,
                "insert a `pause` before this step (with no drive the Bjerknes force vanishes and the beams pull the "
                "capsules apart); the compiler takes a contact to last while any drive plays"))

    # -- follow --------------------------------------------------------------------------------
    def _follow(self, i, step: FollowStep):
        from acl.design.paths import PathError, path_length, sample_path
        from acl.schedule.path import PathInfeasible, plan_path
        from acl.schedule.solve import SolverFailure
        from acl.schedule.tones import choose_tones

        name = f"step {i + 1}: follow {step.capsule}"
        vmax, slew = _limit(self.design, step.limits, self.opts)
        self.vmax_seen.append(vmax)
        try:
            duration = step.duration or path_length(step.path) / step.speed
            if not (np.isfinite(duration) and 0 < duration <= MAX_PROGRAM_S):
                raise _diag("E-SCHED-DURATION", f"{name}: the path takes {duration:.4g} s, not a positive "
                            f"time up to {MAX_PROGRAM_S:g} s", step.span, "give a duration or a sensible speed")
            n = duration / self.opts.waypoint_dt_s
            if not n <= MAX_WAYPOINTS:
                raise _diag("E-SCHED-PATH", f"{name}: {n:.4g} waypoints, more than {MAX_WAYPOINTS}",
                            step.span, f"raise --waypoint-dt above {duration / MAX_WAYPOINTS:.3g} s")
            n = max(2, int(round(n)))
            path = sample_path(step.path, n)
            miss = _sampling_miss(step.path, path.points, sample_path)
            if miss > self.opts.tolerance_m:
                raise _diag("E-SCHED-PATH", f"{name}: {n} waypoints {duration / n:.3g} s apart cut corners: the "
                            f"device, moving from waypoint to waypoint, misses the path by up to {miss * 1e6:.3g} um "
                            f"(tolerance {self.opts.tolerance_m * 1e6:g} um)", step.span,
                            f"give the path more time, or lower --waypoint-dt below {self.opts.waypoint_dt_s:g} s")
        except (PathError, TypeError, ZeroDivisionError) as exc:
            raise _diag("E-SCHED-PATH", f"{name}: {exc}", step.span,
                        "give a duration or a positive speed, and a well-formed path")
        dt = duration / n
        try:
            self.forward_now, self.gains_now = self._models_for(i, name)
            table = self._gain_table(step.capsule)
            choice = choose_tones(table, path.points, vmax, self.opts.tones_per_path, step.tones)
        except ValueError as exc:
            raise _diag("E-SCHED-TONES", f"{name}: {exc}", step.span,
                        "pin the tones with `, using [85 kHz, 125 kHz]` on the follow step, or give a calibration sweep (--calibration)")
        if self.opts.calibration is not None and self.design.latches:
            self._calibration_state_check(i, name, step, choice.frequencies)
        # the renderer crossfades consecutive waypoints with a raised cosine over min(ramp, dt), whose
        # steepest slope is pi/2 x the mean: the plan's step per waypoint must leave room for it
        fade = min(self.opts.ramp_s, dt)
        plan_slew = None if slew is None else slew * 2.0 * fade / (np.pi * dt) * (1 - 1e-4)
        limits = DriveLimits(max_voltage=vmax, slew_rate=plan_slew)
        rq = self._robust_q(name, step.capsule, choice.frequencies, step.span) if self.opts.robust else None
        if not self.opts.robust and self._band_planned():     # refuse an absurd spread before planning (each
            self._robust_q(name, step.capsule, choice.frequencies, step.span, band=True)   # draw can take seconds)
        u_start = None
        if slew is not None:        # slew from what is playing before the goal (silence at the start)
            before = {t.frequency_hz: t.amplitude_v for t in self.segments[-1].tones} if self.segments else {}
            u_start = np.array([before.get(f, 0.0) ** 2 for f in choice.frequencies])
        try:
            plan = plan_path(choice.gains, path.points, dt, limits, tolerance=self.opts.tolerance_m,
                             u_start=u_start, lam=self.opts.lam, slew_model=self.opts.slew_model,
                             refine=self.opts.refine, robust_q=rq, robust_mode=self.opts.robust_mode)
        except PathInfeasible as exc:
            d = exc.diagnosis
            raise DiagnosticError([Diagnostic(
                "E-SCHED-INFEASIBLE", Severity.ERROR,
                f"{name}: infeasible: {d.summary()}", step.span,
                "relax: " + "; or ".join(d.relax),
                notes=(f"tones {', '.join(f'{f / 1e3:g} kHz' for f in choice.frequencies)}, "
                       f"reach margin {choice.margin:.3g} (>= 1 needed)",
                       f"limits: {vmax:g} V total" + (f", slew {slew:g} V/s" if slew else ""),)
                + ((f"the slew limit allows {plan_slew:.4g} V/s from waypoint to waypoint: the renderer "
                    f"crossfades them over min(--ramp, --waypoint-dt) = {fade:g} s with a raised cosine, "
                    "whose steepest slope is pi/2 x its mean; a longer --ramp relaxes it",)
                   if slew else ()))])
        except SolverFailure as exc:
            raise _diag("E-SCHED-SOLVER", f"{name}: {exc}", step.span, "report this design")
        if self.opts.nonlinear_passes > 0:
            plan = self._correct(name, step.capsule, choice, plan, path.points, dt, limits, rq, u_start)
        amps = plan.amplitudes                                      # (K, N)
        start = self.t
        for w in range(n):
            tones = [ScheduledTone(f, float(amps[k, w])) for k, f in enumerate(choice.frequencies)]
            self._add(dt, tones, i, name)
        rep = GoalReport(name, "follow", i, start, self.t, choice.frequencies,
                         times_s=start + dt * np.arange(n), target_m=path.points,
                         amplitudes_v=amps.T.copy(), capsule=step.capsule)
        rep.linear_rms_error_m = float(np.sqrt(np.mean(plan.error ** 2)))
        self._resimulate(rep, step.capsule, plan.u, path.points, plan.predicted)
        if rep.max_error_m is not None and not rep.max_error_m <= self.opts.tolerance_m * (1 + 1e-6) \
                and rep.model.startswith("nonlinear"):
            worst = ("has waypoints without a stable equilibrium (its error is unbounded)"
                     if not np.isfinite(rep.max_error_m) else
                     f"is missed by up to {rep.max_error_m * 1e6:.3g} um (RMS {rep.rms_error_m * 1e6:.3g} um)")
            self.step_warnings.append(Diagnostic(
                TRACKING_CODE, Severity.WARNING, f"{name}: re-simulated through the nonlinear model the path {worst}, "
                f"beyond the {self.opts.tolerance_m * 1e6:g} um tolerance the plan meets on its linear gains",
                step.span,
                (f"re-plan against the nonlinear model (--nonlinear-passes {max(3, 2 * self.opts.nonlinear_passes)}); or "
                 if self.opts.nonlinear_passes < 3 else
                 f"{self.opts.nonlinear_passes} nonlinear passes were not enough: ")
                + "move the path or the tones to where "
                "the linear model holds (the plan's gains are the model linearised at zero drive where the step starts: "
                "a large deflection and the change of the neighbours' forces as the capsules move are not in them)"))
        rep.details.update({
            "tone_margin": choice.margin, "tone_conditioning": choice.conditioning,
            "gains_source": table.source, "waypoints": n, "dt_s": dt, "solver": plan.result.solver,
            "solver_status": plan.result.status, "max_voltage_v": vmax,
            "max_slew_v_per_s": plan.max_slew_v_per_s(dt), "notes": plan.notes})
        if slew is not None:
            rep.details["slew_limit_v_per_s"] = slew
        if self.opts.robust:
            rep.details["robust"] = rq is not None
            rep.details["robust_mode"] = self.opts.robust_mode
        self.goals.append(rep)

    def _correct(self, name, capsule, choice, plan, points, dt, limits, rq, u_start=None):
        """Re-plan against the nonlinear forward model (acl.schedule.correct); the first plan if unavailable."""
        from acl.schedule.correct import correct_plan
        from acl.schedule.path import PathInfeasible, plan_path
        from acl.schedule.solve import SolverFailure

        provider = self.forward_now
        try:
            forward, _ = provider(self.design, capsule, choice.frequencies)
        except (KeyError, ValueError, ImportError) as exc:
            self.notes.append(f"{name}: no nonlinear correction ({exc})")
            return plan

        def plan_for(p):
            return plan_path(choice.gains, p, dt, limits, tolerance=self.opts.tolerance_m, u_start=u_start,
                             lam=self.opts.lam, slew_model=self.opts.slew_model, refine=self.opts.refine,
                             robust_q=rq, robust_mode=self.opts.robust_mode)

        try:
            best, history = correct_plan(plan_for, forward, points, plan, self.opts.nonlinear_passes)
        except (PathInfeasible, SolverFailure):
            self.notes.append(f"{name}: a nonlinear correction pass was infeasible; kept the linear plan")
            return plan
        best.notes.append("nonlinear correction: RMS error " + " -> ".join(f"{h * 1e6:.3g}" for h in history)
                          + " um over the passes (the best plan kept)")
        best.targets = np.asarray(points, float)
        return best

    def _models_for(self, i: int, name: str):
        """(forward provider (design, capsule, freqs) -> (forward, name), gain provider (design, capsule, freqs=None) ->
        GainTable) of the follow goal of step ``i``: the injected ones, or acl.schedule.gains.model_forward and
        model_gain_table from where the latch states put the capsules when the step starts (:meth:`_latch_track`;
        each draw of a band or of --robust at its own travel).  Fig. 6f: after `switch ctl to b` partner faces arm_cap
        inside d_c and their attraction bends the beam the other way; planned and re-simulated from the declared
        state a, a path of arm_cap after the switch was predicted as if partner were 110 um away."""
        from acl.schedule.gains import model_forward, model_forward_many, model_gain_table, state_positions

        forward = self.opts.forward_provider or model_forward
        # the re-simulation and its band's draws as one batch (gains.model_forward_many) when the model is the default
        self.many_now = None if self.opts.forward_provider is not None else \
            (lambda ds, capsule, freqs, u: model_forward_many(ds, capsule, freqs, u))
        given = self.opts.gain_provider
        gains = (lambda d, capsule, freqs=None: given(d, capsule) if freqs is None else given(d, capsule, freqs)) \
            if given is not None else model_gain_table
        if not self.design.latches:
            return forward, gains
        track = self._latch_track(i)
        states = {n: s for n, (s, _, _) in track.items()}
        moved = [l.name for l in self.design.latches if states.get(l.name, l.state) != l.state]
        doubt = [n for n, (_, sure, _) in track.items() if not sure]
        if doubt:
            self.notes.append(f"{name}: planned and re-simulated with " + ", ".join(
                f"latch `{n}` in state {states[n]}" for n in doubt)
                + " (its likelier state: an earlier drive left it uncertain)")
        if not moved:
            return forward, gains
        self.notes.append(f"{name}: planned and re-simulated with " + ", ".join(
            f"latch `{n}` in state {states[n]}" for n in moved) + " (its capsules moved by the latch's travel)")
        if self.opts.forward_provider is None:
            forward = lambda d, capsule, freqs: model_forward(d, capsule, freqs, start=state_positions(d, states))  # noqa: E731
            self.many_now = lambda ds, capsule, freqs, u: model_forward_many(  # noqa: E731
                ds, capsule, freqs, u, [state_positions(d, states) for d in ds])
        if given is None:
            gains = lambda d, capsule, freqs=None: model_gain_table(d, capsule, freqs,  # noqa: E731
                                                                    positions=state_positions(d, states))
        return forward, gains

    def _snaps_from_state(self, j: int, a: str, tones) -> bool:
        """Whether the drive ``tones`` of step ``j`` loses the mechanism's equilibrium from the latch states the step
        starts in: the fold gains.critical_scale finds may be a bistable latch's snap-through (a `switch`), after which
        the mechanism goes on from the latch's other state (gains.model_forward) with the pair apart."""
        from acl.schedule.gains import model_forward, state_positions

        states = {n: st for n, (st, _, _) in self._latch_track(j).items()}
        freqs = [f for f, _ in tones]
        forward, _ = model_forward(self.design, a.split(".")[0], freqs, start=state_positions(self.design, states))
        return not np.all(np.isfinite(forward(np.array([[v * v for _, v in tones]]))))

    def _calibration_state_check(self, i: int, name: str, step, freqs) -> None:
        """W-SCHED-CALIBRATION-STATE: a measured gain table (--calibration) is taken with the latches in their declared
        states (the device as printed); where an earlier step has switched a latch, its capsules have moved and their
        forces on the path's capsule changed, which the table cannot know.  The model says by how much: the gains at
        the chosen tones where the latch states put the capsules against those at rest (acl.schedule.gains
        .model_gain_table); beyond CALIBRATION_STATE_RTOL of their size the step warns, below it a note says so."""
        from acl.schedule.gains import model_gain_table, state_positions

        track = self._latch_track(i)
        states = {n: st for n, (st, _, _) in track.items()}
        moved = [l.name for l in self.design.latches if states.get(l.name, l.state) != l.state]
        if not moved:
            return
        try:
            g0 = np.asarray(model_gain_table(self.design, step.capsule, freqs).gains, float)
            g1 = np.asarray(model_gain_table(self.design, step.capsule, freqs,
                                            positions=state_positions(self.design, states)).gains, float)
        except (ValueError, KeyError, ArithmeticError):
            self.notes.append(f"{name}: the calibration table was measured with the latches as declared; "
                              f"{', '.join(f'`{n}`' for n in moved)} switched since, and no model says what that changes")
            return
        size = float(np.linalg.norm(g0))
        change = float(np.linalg.norm(g1 - g0)) / size if size > 0 else float("inf")
        which = ", ".join(f"latch `{n}` in state {states[n]}" for n in moved)
        if change <= CALIBRATION_STATE_RTOL:
            self.notes.append(f"{name}: the calibration table was measured with the latches as declared; with {which} "
                              f"the model's gains at the chosen tones change by {change:.2%} (kept)")
            return
        self.step_warnings.append(Diagnostic(
            CALIBRATION_STATE_CODE, Severity.WARNING,
            f"{name}: planned on the calibration table, measured with the latches as declared, while the step starts "
            f"with {which}: there the model's gains at the chosen tones differ by {change:.0%} of their size "
            "(the moved capsules' Bjerknes force and jet drag), so the plan and its predicted error do not hold",
            step.span, "measure the calibration sweep with the latch in that state, or compile this path on the model "
            "(without --calibration)"))

    def _band_planned(self) -> bool:
        """Whether follow goals get an error band from draws of the declared uncertainty (:meth:`_band`)."""
        return self.opts.band_samples > 0 and not (self.opts.forward_provider is None and self.opts.calibration is not None)

    def _robust_q(self, name, capsule, freqs, span, band: bool = False):
        """Q of the declared uncertainty at the chosen tones (None, with a note, when there is none).

        A 1-sigma spread beyond MAX_ROBUST_SPREAD x the gains is E-SCHED-UNCERTAINTY, for --robust and
        (``band``) for the error band of --band-samples, whose draws would all lose the path, each after
        seconds of re-simulation (a finite but absurd `+- s` made every draw cost ~20 s).
        """
        from acl.schedule.robust import robust_q

        if self.opts.calibration is not None:
            if not band:
                self.notes.append(f"{name}: --robust ignored: a measured calibration table declares no uncertainty")
            return None
        provider = self.gains_now
        with np.errstate(all="ignore"):      # overflow is checked below, as a located error
            try:
                q = robust_q(self.design, lambda d: provider(d, capsule, freqs).gains.T, self.opts.reload)
            except (ValueError, KeyError, DiagnosticError):
                if not band:
                    raise
                return None           # a 1-sigma design that does not resolve: the draws count it as failed
            if q is None:
                if not band:
                    self.notes.append(f"{name}: --robust: the design declares no uncertainty; the plan is the nominal one")
                return q
            g0 = np.linalg.norm(np.asarray(provider(self.design, capsule, freqs).gains, float), 2)
            spread = float(np.sqrt(np.max(np.abs(np.linalg.eigvalsh(q))))) if np.all(np.isfinite(q)) else float("inf")
        if not (math.isfinite(spread) and spread <= MAX_ROBUST_SPREAD * g0):
            what = [f"`{p.name} +- {p.stddev:g} {p.unit}`".replace(" `", "`") for p in self.design.uncertain_params()]
            t = self.design.transducer
            if t is not None and t.gain_uncertainty:
                what.append(f"`{t.name}.gain_uncertainty = {t.gain_uncertainty:g}`")
            option, outcome = (("--band-samples", "an error band over such draws is not computed")
                               if band else ("--robust", "no plan can be robust to it"))
            raise _diag("E-SCHED-UNCERTAINTY", f"{name}: {option}: at 1 sigma the declared uncertainty moves the "
                        f"gains by {'more than' if not math.isfinite(spread) else ''} "
                        f"{spread / g0 if math.isfinite(spread) and g0 > 0 else float('inf'):.3g} times their size "
                        f"(at most {MAX_ROBUST_SPREAD:g}): {outcome}".replace("by  ", "by "),
                        span, "check the declared uncertainty: " + (", ".join(what) or "none found")
                        + ("; or compile without an error band: --band-samples 0" if band else ""))
        return q

    def _gain_table(self, capsule):
        if self.opts.calibration is not None:
            return self.opts.calibration
        try:
            return self.gains_now(self.design, capsule)
        except (KeyError, ValueError) as exc:
            raise ValueError(f"no gain model for `{capsule}`: {exc}") from None

    def _resimulate(self, rep: GoalReport, capsule, u, targets, linear_pred):
        provider = self.forward_now
        if self.opts.forward_provider is None and self.opts.calibration is not None:
            # a calibrated device has no better model than its calibration: report the linear plan
            err = np.linalg.norm(linear_pred - targets, axis=1)
            rep.model = "linear calibration gains"
            rep.predicted_m = linear_pred
            rep.rms_error_m, rep.max_error_m = float(np.sqrt(np.mean(err ** 2))), float(err.max())
            return
        if provider is None:
            from acl.schedule.gains import model_forward as provider
        try:
            forward, model = provider(self.design, capsule, rep.frequencies_hz)
        except (KeyError, ValueError, ImportError) as exc:
            rep.model = f"unavailable: {exc}"
            return
        n = u.shape[1]
        idx = np.unique(np.linspace(0, n - 1, min(n, self.opts.resim_points)).astype(int))
        band, nominal = None, []
        if self.opts.band_samples > 0 and self.opts.forward_provider is None and self.many_now is not None:
            # the nominal design and the band's draws re-simulated as one batch (gains.model_forward_many)
            many = self.many_now

            def forward_many(ds):
                got = many([self.design, *ds], capsule, rep.frequencies_hz, u[:, idx].T)
                nominal.append(got[0])
                return got[1:]

            band = self._error_band(provider, capsule, rep, u[:, idx], targets[idx], forward_many)
        got = nominal[0] if nominal else forward(u[:, idx].T)
        if isinstance(got, Exception):
            raise got
        pred = np.asarray(got, float)
        ok = np.all(np.isfinite(pred), axis=1)
        err = np.linalg.norm(pred[ok] - targets[idx][ok], axis=1)
        rep.model = model
        if err.size:
            rep.rms_error_m = float(np.sqrt(np.mean(err ** 2)))
            rep.max_error_m = float(np.max(err))
        if not ok.all():
            rep.details["unconverged_waypoints"] = int((~ok).sum())
            rep.max_error_m = float("inf")     # a waypoint without equilibrium: its error is unbounded
            self.notes.append(f"{rep.name}: the forward model found no stable equilibrium at "
                              f"{int((~ok).sum())} of {ok.size} re-simulated waypoints (snap-in?); "
                              "the RMS error leaves them out and the maximum error is unbounded (null)")
        full = np.full_like(targets, np.nan)
        full[idx] = pred
        rep.predicted_m = full
        rep.details["resimulated_waypoints"] = int(idx.size)
        if self.opts.band_samples > 0:
            self._band(rep, provider, capsule, u[:, idx], targets[idx], band if nominal else None)

    def _error_band(self, provider, capsule, rep: GoalReport, u, targets, forward_many=None):
        from acl.schedule.bands import error_band

        return error_band(self.design, lambda d: provider(d, capsule, rep.frequencies_hz)[0], u, targets,
                          samples=self.opts.band_samples, seed=self.opts.band_seed, reload=self.opts.reload,
                          forward_many=forward_many)

    def _band(self, rep: GoalReport, provider, capsule, u, targets, band=None):
        """95th percentile of the re-simulated error over draws of the declared uncertainty (``band``: computed with
        the nominal re-simulation, :meth:`_resimulate`)."""
        from acl.schedule.bands import level, pinned, unmeasured_tones

        if band is None:
            band = self._error_band(provider, capsule, rep, u, targets)
        if band is None:
            self.notes.append(f"{rep.name}: the design declares no uncertainty: no error band "
                              "(declare `+- s` on parameters or `gain_uncertainty` on the transducer)")
            return
        rep.rms_error_p95_m, rep.max_error_p95_m = band.rms_p95_m, band.max_p95_m
        rep.details["band"] = {"samples": band.samples, "failed": band.failed, "seed": self.opts.band_seed,
                               "quantile": 95, "level": round(level(band.samples), 4), "parameters": [p.name for p in self.design.uncertain_params()]
                               if self.opts.reload is not None else [],
                               "gain_uncertainty": self.design.transducer.gain_uncertainty
                               if self.design.transducer else None}
        if 0 < band.samples and level(band.samples) < 0.95:
            self.notes.append(f"{rep.name}: the error band is the largest of {band.samples} draws, which bounds the "
                              f"95th percentile only with probability {level(band.samples):.0%}: give --band-samples "
                              "19 or more")
        pin = pinned(self.design)
        if pin:
            rep.details["band"]["measured_gain"] = [{"frequency_hz": f, "stddev": sd} for f, sd in pin]
            off = unmeasured_tones(self.design, rep.frequencies_hz)
            rep.details["band"]["unmeasured_tones_hz"] = off
            if off:
                self.notes.append(f"{rep.name}: the calibration did not measure the transducer gain at "
                                  f"{', '.join(f'{f / 1e3:g}' for f in off)} kHz (measured: "
                                  f"{', '.join(f'{f / 1e3:g}' for f, _ in pin)} kHz): the band keeps the table's "
                                  f"{self.design.transducer.gain_uncertainty:.0%} prior there")
        from acl.schedule import experiment     # the band's cause and the reading that narrows it (band's hook)
        ex = experiment.explain(self.design, lambda ds, f, uu: self.many_now(ds, capsule, f, uu) if self.many_now else
                                [provider(d, capsule, f)[0](uu) for d in ds], capsule, rep.frequencies_hz, u, targets,
                                reload=self.opts.reload, band=band, seed=self.opts.band_seed)
        if ex is not None:
            rep.band_plot = ex.pop("plot", None)
            rep.details["band"]["cause"] = ex
            self.notes.append(experiment.summary(rep.name, ex))
        if band.failed:
            self.notes.append(f"{rep.name}: {band.failed} of {self.opts.band_samples} uncertainty draws lost the "
                              "equilibrium (snap-in) or did not resolve; they count as missing the path")

    # -- switch --------------------------------------------------------------------------------
    def _switch(self, i, step: SwitchStep):
        """Plan a switch from the state the latch is in when the step starts (:meth:`_latch_track`: earlier switches,
        drives, sweeps, paths and holds).  Already there: nothing played.  Uncertain (a drive pushed it near its
        switching force): planned from the other state, which also leaves it in the wanted state if it is there
        already (the drive pushes it further in); when no drive does that within the limits, W-SCHED-LATCH-STATE at
        the step.  Another latch in an uncertain state is kept put in both directions, or, when no drive does that,
        in its likelier state with W-SCHED-LATCH-STATE."""
        from acl.schedule.latch import SwitchInfeasible, plan_switch

        name = f"step {i + 1}: switch {step.latch} -> {step.state}"
        vmax, _ = _limit(self.design, step.limits, self.opts)
        self.vmax_seen.append(vmax)
        names = [l.name for l in self.design.latches]
        if step.latch not in names:
            raise _diag("E-SCHED-MODEL", f"{name}: no latch named `{step.latch}`", step.span)
        track = self._latch_track(i)
        state, certain, why = track[step.latch]
        source = why or "its declared state"
        before = state if certain else "a or b"
        if certain and state == step.state:
            self.notes.append(f"{name}: latch already in state {step.state} ({source}); nothing to do")
            self._add(step.duration, [], i, name)
            self.goals.append(GoalReport(name, "switch", i, self.t - step.duration, self.t, (),
                                         model="nothing played: the latch is already in that state",
                                         details={"state_before": state, "state_from": source, "already": True}))
            self.switch_outcome[i] = (state, True, why)
            return
        other = "a" if step.state == "b" else "b"
        doubt = [k for k, n in enumerate(names) if n != step.latch and not track[n][1]]
        freqs = tuple(step.tones) or tuple(self._latch_candidates())
        j = names.index(step.latch)
        states = [track[n][0] for n in names]
        states[j] = other                # certain: it is there; uncertain: a drive from there works from both
        positions = None
        if self.opts.latch_provider is None:
            # the forces where the capsules are: a latch in a state other than its declared one carries its capsules
            # moved by the travel (Fig. 6f: in state b `partner` faces `arm_cap` 40 um away, whose attraction at
            # 125 kHz pushes the shuttle further into b, where at rest 125 kHz pushed it back towards a)
            from acl.schedule.gains import latch_forces, state_positions

            positions = state_positions(self.design, dict(zip(names, states)))
            forces, to_b, to_a = latch_forces(self.design, freqs, positions)
        else:
            forces, to_b, to_a = self.opts.latch_provider(self.design, freqs)

        def infeasible(exc):
            return DiagnosticError([Diagnostic(
                "E-SCHED-INFEASIBLE", Severity.ERROR, f"{name}: infeasible: binding "
                + "; ".join(exc.binding), step.span, "relax: " + "; or ".join(exc.relax),
                notes=(f"at t = {self.t:.4g} s, {len(freqs)} candidate tones",)
                + ((f"latch `{step.latch}` is in state {other}: {why}",) if why else ()))])

        kept_both = bool(doubt)
        plan = None
        if not certain and self.opts.latch_provider is None:
            # planned from the other state, the drive must also leave the latch where it is if it is in the wanted
            # state already: its push back from there, with the capsules where that state puts them, kept below
            # 1/margin of the force that switches it back (when no drive does that, planned without it and warned)
            where = dict(zip(names, states))
            where[step.latch] = step.state
            Fw, _, _ = latch_forces(self.design, freqs, state_positions(self.design, where))
            sig_w = 1.0 if step.state == "b" else -1.0
            back = (-sig_w * np.asarray(Fw, float)[j], float(to_a[j] if step.state == "b" else to_b[j]))
            if np.isfinite(back[1]):
                try:
                    plan = plan_switch(forces, to_b, to_a, states, names, j, step.state, step.margin,
                                       DriveLimits(vmax), either=doubt, extra=[back])
                except SwitchInfeasible:
                    plan = None
        try:
            if plan is None:
                plan = plan_switch(forces, to_b, to_a, states, names, j, step.state, step.margin, DriveLimits(vmax),
                                   either=doubt)
        except SwitchInfeasible as exc:
            plan = None
            if doubt:
                try:
                    plan = plan_switch(forces, to_b, to_a, states, names, j, step.state, step.margin, DriveLimits(vmax))
                    kept_both = False
                except SwitchInfeasible as exc2:
                    exc = exc2
            if plan is None:
                if certain:
                    raise infeasible(exc) from None
                self._latch_warn(i, step, f"{name}: latch `{step.latch}` may be in state {other} and no drive within "
                                 f"the limits switches it from there: the step plays nothing, and the latch may stay "
                                 f"in state {other}",
                                 f"make the earlier drive decisive (well above or below the latch's switching force), "
                                 f"or give the switch tones that push the latch to state {step.state}",
                                 (why, "planned from state " + other + ": binding " + "; ".join(exc.binding)))
                self._add(step.duration, [], i, name)
                self.goals.append(GoalReport(name, "switch", i, self.t - step.duration, self.t, (),
                                             model="nothing played: no drive switches the latch from its other state",
                                             details={"state_before": before, "state_from": source, "already": False,
                                                      "state_certain": False}))
                self.switch_outcome[i] = (state, False, why)
                return
        if doubt and not kept_both:
            self._latch_warn(i, step, f"{name}: " + ", ".join(f"latch `{names[k]}`" for k in doubt)
                + " may be in state a or b: no drive within the limits keeps it put in both; the drive keeps it in state "
                + ", ".join(f"{track[names[k]][0]} (`{names[k]}`)" for k in doubt) + " only",
                "make the earlier drive decisive (well above or below the other latch's switching force), "
                "or switch that latch to a known state first",
                tuple(f"latch `{names[k]}`: {track[names[k]][2]}" for k in doubt))
        # interior-point dust: a tone with < 1e-6 of the largest power adds < 1e-6 of the force;
        # the margins reported are those of the tones actually emitted
        keep = plan.u > 1e-6 * plan.u.max()
        used = [(f, a) for f, a, k in zip(freqs, plan.amplitudes, keep) if k]
        sig = 1.0 if step.state == "b" else -1.0
        thr_t = float(to_b[j] if step.state == "b" else to_a[j])
        F = np.asarray(forces, float) @ np.where(keep, plan.u, 0.0)            # (L,) N
        model = "linear force per V^2"
        if self.opts.latch_provider is None:
            used, F_full = self._switch_full_model(name, step, used, j, sig, thr_t, vmax, positions)
            if F_full is not None:
                F, model = F_full, "force of the whole drive (declared drive saturation)"
                plan = dataclasses.replace(plan, required_force=step.margin * thr_t)
        self._add(step.duration, [ScheduledTone(f, float(a)) for f, a in used], i, name)
        after = {n: track[n][0] for n in names}
        after[step.latch] = step.state
        force = float(sig * F[j])
        others = {}
        for k, n in enumerate(names):
            if n != step.latch:       # force along the other latch's own switching direction / threshold
                own = 1.0 if after[n] == "a" else -1.0
                thr = to_b[k] if own > 0 else to_a[k]
                others[n] = float(own * F[k] / thr)
                if kept_both and k in doubt:     # and along the other direction: it stays in either state
                    thr2 = to_a[k] if own > 0 else to_b[k]
                    others[n] = max(others[n], float(-own * F[k] / thr2))
        if force < plan.required_force * (1 - 1e-6) or any(r > 1 / step.margin * (1 + 1e-6)
                                                              for r in others.values()):
            raise _diag("E-SCHED-SOLVER", f"{name}: the emitted tones miss the switching margins "
                        "the latch program promised", step.span, "report this design")
        details = {"force_n": force, "required_n": plan.required_force,
                   "margin": force / plan.required_force * step.margin, "other_latch_ratios": others,
                   "state_before": before, "state_from": source, "planned_from": other,
                   "forces_at": "the declared positions" if positions is None else
                   "the latch states' positions (" + ", ".join(f"`{n}` in state {s}" for n, s, lt in
                                                             zip(names, states, self.design.latches)
                                                             if s != lt.state) + ")"}
        if not certain:
            back = self._push_back(used, names, states, j, step.state) if self.opts.latch_provider is None else None
            if back is not None and back > 1.0 / step.margin:
                # where the capsules are in the wanted state the drive may push the other way (a neighbour's attraction
                # that only acts there): "it pushes it further in" is not so
                details["push_back_ratio"] = back
                self._latch_warn(i, step, f"{name}: latch `{step.latch}` may be in state a or b; planned from "
                                 f"state {other}, but if it is in state {step.state} already the drive pushes it back "
                                 f"towards state {other} at {back:.3g} x the force that switches it there",
                                 "make the earlier drive decisive (well above or below the latch's switching force), "
                                 "or switch the latch to a known state first", (why,))
            else:
                self.notes.append(f"{name}: latch `{step.latch}` may be in state a or b ({why}): planned from state "
                                  f"{other}, which also leaves it in state {step.state} if it is there already (the "
                                  "drive pushes it further in)")
        self._switch_aftermath(i, step, name, used, after, details)
        rep = GoalReport(name, "switch", i, self.t - step.duration, self.t,
                         tuple(f for f, _ in used), model=model, details=details)
        self.goals.append(rep)
        self.switch_outcome[i] = (step.state, True, f"step {i + 1} (switch)")
        if self.opts.band_samples > 0 and self.opts.latch_provider is None:
            self._switch_band(rep, used, step, j, names, after, [names[k] for k in doubt] if kept_both else [],
                              dict(zip(names, states)))

    def _switch_aftermath(self, i, step, name, used, after: dict, details: dict) -> None:
        """W-SCHED-CONTACT at a switch whose drive, once the latch is in its new state, leaves the mechanism no stable
        equilibrium there (gains.settle_from the new states' positions, the drive's power ramped up): the moved
        capsules now face a neighbour inside its critical distance and the switch's own drive snaps them in (Fig. 6f:
        after `switch ctl to b` partner faces arm_cap 40 um away, and 85 kHz, below both bubbles' resonance, drives
        them in phase: they attract).  ``details["aftermath"]`` says what was found."""
        if self.opts.latch_provider is not None or not used:
            return
        from acl.design.model import Drive, Tone
        from acl.schedule.gains import settle_from, state_positions

        start = state_positions(self.design, after) or {c.name: np.asarray(c.center, float)
                                                        for c in self.design.capsules}
        drive = Drive(tones=tuple(Tone(frequency=float(f), amplitude=float(a)) for f, a in used if a > 0))
        try:
            eq = settle_from(self.design, drive, start)
        except (ValueError, KeyError, ArithmeticError, np.linalg.LinAlgError, DiagnosticError) as exc:
            details["aftermath"] = f"not checked ({exc})"
            return
        if eq is not None:
            details["aftermath"] = "stable in the new state under the switch's drive"
            return
        details["aftermath"] = "no stable equilibrium in the new state under the switch's drive (snap-in)"
        self.step_warnings.append(Diagnostic(
            CONTACT_CODE, Severity.WARNING,
            f"{name}: once latch `{step.latch}` is in state {step.state}, the switch's own drive leaves the mechanism no "
            "stable equilibrium there (acl.analysis.mechanics, the drive ramped up from the new state): capsules the "
            "latch moved snap in to a neighbour, and stay in contact while a drive plays", step.span,
            "switch with tones that do not attract the moved capsules to their neighbours, or with a lower limit if "
            "the latch still switches below the snap-in; a `pause` after the switch releases the contact"))

    def _push_back(self, used, names, states, j, to) -> float | None:
        """The push of the drive ``used`` on latch ``j`` back from state ``to`` (the other latches in ``states``), with
        the capsules where that state puts them, over the force that switches it back; None when not computable."""
        from acl.schedule.gains import latch_drive_forces, latch_forces, state_positions

        where = dict(zip(names, states))
        where[names[j]] = to
        try:
            F = latch_drive_forces(self.design, used, state_positions(self.design, where))
            _, to_b, to_a = latch_forces(self.design, [])
        except (DiagnosticError, KeyError, ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
        return float(-F[j] / to_a[j]) if to == "b" else float(F[j] / to_b[j])

    def _latch_warn(self, i, step, message: str, hint: str, notes=()) -> None:
        self.step_warnings.append(Diagnostic(LATCH_STATE_CODE, Severity.WARNING, message, step.span, hint,
                                              notes=tuple(notes)))

    def _switch_full_model(self, name, step: SwitchStep, used, j, sig, thr_t, vmax, positions=None):
        """Re-check a switch with the full force model when forces are not ~V^2 (drive saturation).

        The LP plans with the force per V^2 at 1 V; a declared saturation makes the real force of the
        planned drive smaller.  The drive is scaled up (bisection: the force grows with the scale)
        until the latch gets ``margin`` x its switching force, within the limit; (tones, forces (L,)), the capsules at
        ``positions`` (the latch states', :func:`acl.schedule.gains.state_positions`; None: at rest).
        """
        from acl.analysis.acoustics import force_model_for

        if force_model_for(self.design).quadratic_in_amplitude or not used:
            return used, None
        from acl.schedule.gains import latch_drive_forces

        def at(scale):
            F = latch_drive_forces(self.design, [(f, a * scale) for f, a in used], positions)
            return float(sig * F[j] / thr_t), F

        r, F = at(1.0)
        if r >= step.margin * (1 - 1e-6):
            return used, F
        top = vmax / sum(a for _, a in used)
        r_top, F_top = at(top)
        if r_top < step.margin:
            raise _diag("E-SCHED-INFEASIBLE", f"{name}: infeasible: with the declared drive saturation the "
                        f"drive reaches only {r_top:.3g} x the switching force at the {vmax:g} V limit "
                        f"(margin {step.margin:g} wanted; the force per V^2 promised it at "
                        f"{sum(a for _, a in used):.4g} V)", step.span,
                        f"raise the max voltage above {vmax:g} V; or lower the margin")
        lo, hi = 1.0, top
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if at(mid)[0] >= step.margin else (mid, hi)
            if hi - lo <= 1e-9 * hi:
                break
        F = at(hi)[1]
        self.notes.append(f"{name}: the declared drive saturation leaves the planned drive at {r:.3g} x the "
                          f"switching force; amplitudes scaled by {hi:.4g} to reach the margin {step.margin:g}")
        return [(f, a * hi) for f, a in used], F

    def _switch_band(self, rep: GoalReport, used, step: SwitchStep, j, names, states: dict, either=(), start=None):
        """5th percentile of the switch margin (and 95th of the other latches' ratios) over the uncertainty;
        ``either``: other latches in an uncertain state, whose ratio is the larger of both directions; ``start``: the
        latch states the switch starts from ({latch: state}), where each draw's capsules are
        (acl.schedule.gains.state_positions of the draw: its own travel)."""
        from acl.schedule.bands import margin_band
        from acl.schedule.gains import latch_drive_forces, latch_forces, state_positions

        target = names[j]
        before = "a" if step.state == "b" else "b"

        def margin_for(d):
            F = latch_drive_forces(d, used, state_positions(d, start or {}))
            _, to_b, to_a = latch_forces(d, [])
            thr = to_b[j] if step.state == "b" else to_a[j]
            m = float((1.0 if step.state == "b" else -1.0) * F[j] / thr)
            others = {}
            for k, n in enumerate(names):
                if n != target:
                    own = 1.0 if states[n] == "a" else -1.0
                    others[n] = float(own * F[k] / (to_b[k] if own > 0 else to_a[k]))
                    if n in either:
                        others[n] = max(others[n], float(-own * F[k] / (to_a[k] if own > 0 else to_b[k])))
            return m, others

        band = margin_band(self.design, margin_for, samples=self.opts.band_samples, seed=self.opts.band_seed,
                           reload=self.opts.reload)
        self._margin_report(rep, band, f"the latch stays in state {before} (the drive does not switch it)",
                            others_what="switches")

    def _margin_report(self, rep: GoalReport, band, fails: str, others_what: str = ""):
        """Write a margin band into the goal's details and warn when the goal fails in the uncertainty."""
        if band is None:
            self.notes.append(f"{rep.name}: the design declares no uncertainty: no margin band "
                              "(declare `+- s` on parameters or `gain_uncertainty` on the transducer)")
            return
        rep.details["band"] = {"samples": band.samples, "failed": band.failed, "seed": self.opts.band_seed,
                               "quantile": 5, "margin_p05": band.p05, "draws_below_1": band.below_one,
                               "parameters": [p.name for p in self.design.uncertain_params()]
                               if self.opts.reload is not None else [],
                               "gain_uncertainty": self.design.transducer.gain_uncertainty
                               if self.design.transducer else None}
        if band.others_p95:
            rep.details["band"]["other_latch_ratios_p95"] = band.others_p95
        n = band.samples + band.failed
        if band.below_one:
            seen = band.below_one - band.failed
            more = (f"; {band.failed} more did not resolve or their model failed (a drawn value outside its "
                    "physical range, e.g. a negative coefficient), counted as failing") if band.failed else ""
            self.notes.append(f"warning: {rep.name}: in {seen} of {n} draws of the declared uncertainty {fails}"
                              f"{more} (5th percentile of the margin {band.p05:.3g}); narrow the uncertainty "
                              "(acl fit on data that identify it) or raise the margin")
        for other, r in band.others_p95.items():
            if r >= 1.0:
                self.notes.append(f"warning: {rep.name}: in the declared uncertainty the drive also {others_what} "
                                  f"latch `{other}` (95th percentile of its force over its switching force {r:.3g})")

    def _latch_candidates(self):
        from acl.schedule.gains import default_frequencies

        return default_frequencies(self.design, step_hz=2500.0)

    # -- hold ----------------------------------------------------------------------------------
    def _hold(self, i, step: HoldStep):
        from acl.schedule.gains import snap_in_voltages
        from acl.schedule.hold import HoldInfeasible, plan_hold

        name = f"step {i + 1}: hold gap {step.a}/{step.b} {step.mode}"
        vmax, _ = _limit(self.design, step.limits, self.opts)
        self.vmax_seen.append(vmax)
        if not step.tones:
            raise _diag("E-SCHED-TONES", f"{name}: a hold step needs its tones", step.span,
                        "write `, using [85 kHz, 125 kHz]` on the hold step")
        provider = self.opts.snap_provider or snap_in_voltages
        bound = step.bound if step.mode == "above" else None
        # above: a tone driven at vmax must still be `margin` from snap-in, so look up to margin x vmax
        v_snap = provider(self.design, step.a, step.b, step.tones,
                          vmax * step.margin if step.mode == "above" else vmax, bound)
        if v_snap is not None and np.any(np.asarray(v_snap) <= 0):
            raise _diag("E-SCHED-INFEASIBLE", f"{name}: the gap is already below its bound at rest",
                        step.span, "lower the bound or widen the rest gap")
        if v_snap is None:
            raise _diag("E-SCHED-MODEL", f"{name}: no snap-in model available (acl.analysis.mechanics."
                        "sweep_voltage)", step.span, "the mechanics analysis is needed for hold steps")
        try:
            plan = plan_hold(step.mode, DriveLimits(vmax), v_snap=v_snap, margin=step.margin)
        except HoldInfeasible as exc:
            raise DiagnosticError([Diagnostic(
                "E-SCHED-INFEASIBLE", Severity.ERROR, f"{name}: infeasible: binding "
                + "; ".join(exc.binding), step.span, "relax: " + "; or ".join(exc.relax),
                notes=(f"at t = {self.t:.4g} s",))])
        tones = [ScheduledTone(f, float(a)) for f, a, u in zip(step.tones, plan.amplitudes, plan.u)
                 if u > 1e-6 * max(plan.u.max(), 1e-300)]
        tones, ratio = self._hold_resimulate(name, step, tones, vmax, bound)
        self._add(step.duration, tones, i, name)
        details = {"snap_index": float(sum(t.amplitude_v ** 2 / v ** 2 for t in tones
                                           for f, v in zip(step.tones, v_snap) if f == t.frequency_hz)),
                   "critical_voltages_v": [float(v) for v in v_snap], "margin": step.margin, "mode": step.mode}
        if ratio is not None:
            details["resimulated_margin"] = ratio
        rep = GoalReport(name, "hold", i, self.t - step.duration, self.t,
                         tuple(t.frequency_hz for t in tones),
                         model=("snap-in of the whole drive re-simulated (acl.analysis.mechanics)"
                                if ratio is not None else
                                "snap index sum u/Vcrit^2 (forces add in V^2)"),
                         details=details)
        self.goals.append(rep)
        if ratio is not None and self.opts.band_samples > 0:
            self._hold_band(rep, step, tones, vmax, bound)

    def _hold_band(self, rep: GoalReport, step: HoldStep, tones, vmax, bound):
        """5th percentile of the re-simulated hold margin over draws of the declared uncertainty.

        ``above``: the factor by which the drive can grow before the pair snaps (or the gap reaches the
        bound) on the drawn design; ``cross``: the factor by which the drive exceeds snap-in.
        """
        from acl.schedule.bands import margin_band

        provider = self.opts.critical_provider
        if provider is None:
            from acl.schedule.gains import critical_scale as provider
        pairs = [(t.frequency_hz, t.amplitude_v) for t in tones]
        total = sum(a for _, a in pairs)
        if not pairs or total <= 0:
            return
        if step.mode == "above":
            def margin_for(d):
                s = provider(d, step.a, step.b, pairs, 1.5 * step.margin, bound)
                if s is None:
                    raise ValueError("no snap-in model")
                return min(float(s), 1.5 * step.margin)     # not searched beyond: a lower bound
            fails = "the drive snaps the pair in (or closes the gap below its bound)"
        else:
            def margin_for(d):
                s = provider(d, step.a, step.b, pairs, max(vmax / total, 1.0) * 1.5, None)
                if s is None:
                    raise ValueError("no snap-in model")
                return float(1.0 / s) if s > 0 else float("inf")
            fails = "the drive does not snap the pair in"
        band = margin_band(self.design, margin_for, samples=self.opts.band_samples, seed=self.opts.band_seed,
                           reload=self.opts.reload)
        self._margin_report(rep, band, fails)

    def _hold_resimulate(self, name, step: HoldStep, tones, vmax, bound):
        """Re-simulate the drive's snap-in and rescale it so the voltage margin holds; (tones, ratio).

        ratio is the scale of the drive at snap-in (or at the gap bound) over the drive itself:
        >= margin for `above`; for `cross` the drive is margin x a snapping drive, ratio <= 1/margin
        (reported as its inverse, the factor by which the drive exceeds snap-in).
        """
        provider = self.opts.critical_provider
        if provider is None:
            if self.opts.snap_provider is not None:
                return tones, None          # an injected snap model: nothing better to re-simulate
            from acl.schedule.gains import critical_scale as provider
        if not tones:
            return tones, None
        pairs = [(t.frequency_hz, t.amplitude_v) for t in tones]
        total = sum(a for _, a in pairs)
        margin = step.margin
        if step.mode == "above":
            s = provider(self.design, step.a, step.b, pairs, 1.5 * margin, bound)
            if s is None:
                return tones, None
            if s < margin:
                # the safe set is star-shaped about zero drive: scale the drive back onto the margin
                f = s / margin * (1 - 1e-6)
                tones = [ScheduledTone(t.frequency_hz, t.amplitude_v * f) for t in tones]
                self.notes.append(f"{name}: the whole drive snaps at {s:.4g} x itself (the per-tone "
                                  f"snap index promised {margin:g}); amplitudes scaled by {f:.4g}")
                s = provider(self.design, step.a, step.b,
                             [(t.frequency_hz, t.amplitude_v) for t in tones], 1.5 * margin, bound)
                if s is None or s < margin * (1 - 1e-4):
                    raise _diag("E-SCHED-MODEL", f"{name}: the re-simulated snap-in margin "
                                f"{s if s is not None else float('nan'):.4g} stays below {margin:g}",
                                step.span, "pin a single tone with `using`")
            return tones, float(s)
        s = provider(self.design, step.a, step.b, pairs, vmax / total, None)
        if s is None:
            return tones, None
        if not s * margin <= 1.0 + 1e-9:
            f = s * margin * (1 + 1e-6)
            if not np.isfinite(f) or total * f > vmax * (1 + 1e-9):
                raise _diag("E-SCHED-INFEASIBLE", f"{name}: infeasible: the whole drive snaps only at "
                            f"{s:.4g} x itself; {margin:g} x that exceeds the {vmax:g} V limit",
                            step.span, f"raise the max voltage above {vmax:g} V; or lower the margin")
            tones = [ScheduledTone(t.frequency_hz, t.amplitude_v * f) for t in tones]
            self.notes.append(f"{name}: the whole drive snaps only at {s:.4g} x itself; amplitudes "
                              f"scaled by {f:.4g} to cross by the margin {margin:g}")
            s = s / f
        return tones, float(1.0 / s)


@dataclass(frozen=True)
class _Push:
    """A step's push on a latch towards one state, over the force that switches it there (_Compiler._push_ratios)."""

    r: float          # nominal, at the most-switching waypoint (a drive, hold or sweep: its one drive)
    lo: float         # 5th percentile over the declared uncertainty (of each draw's largest waypoint push)
    hi: float         # 95th percentile (of each draw's largest push, crossfades included)
    band: str         # what the band was drawn from ("": no band)
    up: float         # nominal largest push, also while crossfading between waypoints (>= r, r0)
    where: str        # " at waypoint w of N (t = ...)" for a path, else ""; the equilibrium's note
    r0: float = float("nan")    # the same drive with the capsules undeflected on the branch (lo <= min(r, r0))
    lost: bool = False          # under the drive no equilibrium stays on the branch: never "left for sure"


def _is_fade(seg: Segment) -> bool:
    """Whether ``seg`` is a silent segment inserted between two steps (:meth:`_Compiler._crossfade`)."""
    return not seg.tones and (seg.goal or "").endswith(FADE_GOAL)


def _boundary_tones(before: Segment, after: Segment) -> tuple[list[float], np.ndarray, np.ndarray, np.ndarray]:
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


def _nominal_end(start: str, rb: np.ndarray, ra: np.ndarray) -> str:
    """The state a latch starting in ``start`` ends in under waypoint pushes ``rb``/``ra`` (ratios; >= 1 switches)."""
    state = start
    for b, a in zip(rb, ra):
        if state == "a" and b >= 1.0:
            state = "b"
        elif state == "b" and a >= 1.0:
            state = "a"
    return state


class _Snapped(Exception):
    """A sweep's frequency at which the mechanism snaps in (:meth:`_Compiler._static_reach` stops there)."""

    def __init__(self, frequency: float):
        super().__init__(frequency)
        self.frequency = float(frequency)


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


def _sampling_miss(spec, points: np.ndarray, sample_path) -> float:
    """Largest distance (m) between the path and the straight moves joining its waypoints: both are
    sampled evenly by arc length, so the path at each dense arc position is compared with the
    waypoints interpolated there (a circle on two waypoints misses by its diameter)."""
    n = len(points)
    dense = sample_path(spec, int(min(max(20 * n, 2000), 200_000))).points
    s_dense, s_way = np.linspace(0.0, 1.0, len(dense)), np.linspace(0.0, 1.0, n)
    between = np.column_stack([np.interp(s_dense, s_way, points[:, k]) for k in range(points.shape[1])])
    return float(np.max(np.linalg.norm(dense - between, axis=1)))


def _diag(code: str, message: str, span: Span | None, hint: str | None = None) -> DiagnosticError:
    return DiagnosticError([error(code, message, span, hint)])


def _choose_all_phases(sched: Schedule, fs: float) -> None:
    """Pick low-peak phases per group of consecutive segments sharing the same frequencies (phases
    the user gave are kept), and record each segment's analog peak bound."""
    from acl.schedule.phases import choose_phases, group_peaks

    segs = sched.segments
    i = 0
    while i < len(segs):
        key = tuple(t.frequency_hz for t in segs[i].tones)
        j = i
        while j + 1 < len(segs) and tuple(t.frequency_hz for t in segs[j + 1].tones) == key \
                and segs[j + 1].goal == segs[i].goal:
            j += 1
        group = segs[i:j + 1]
        amps = np.array([[t.amplitude_v for t in s.tones] for s in group]).reshape(len(group), -1)
        tones0 = group[0].tones
        phases = np.array([t.phase_rad for t in tones0])
        if any(t.sweep for t in tones0):
            peaks = np.abs(amps).sum(axis=1)
        else:
            if len(key) > 1:
                worst = amps[int(np.argmax(amps.sum(axis=1)))]
                phases, _ = choose_phases(key, worst, fs, fixed=[t.phase_fixed for t in tones0],
                                          start=phases)
            peaks = group_peaks(key, phases, amps, fs)
        for m in range(i, j + 1):
            s = segs[m]
            segs[m] = Segment(s.start_s, s.end_s, tuple(
                ScheduledTone(t.frequency_hz, t.amplitude_v, float(p), t.frequency_end_hz, t.sweep,
                              t.phase_fixed)
                for t, p in zip(s.tones, phases)), s.step, s.goal, float(peaks[m - i]))
        i = j + 1
