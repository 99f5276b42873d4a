"""Step passes: drive, sweep and pause segments; follow goals (path programs); hold goals (snap-in LPs)."""
from __future__ import annotations

import numpy as np

from acl.design.model import FollowStep, HoldStep
from acl.diagnostics import Diagnostic, DiagnosticError, Severity
from acl.schedule import latch_state as LS
from acl.schedule import safety as SF
from acl.schedule import verify as VF
from acl.schedule.model import GoalReport, ScheduledTone
from acl.schedule.path import DriveLimits
from acl.schedule.state import MAX_PROGRAM_S, MAX_WAYPOINTS, TRACKING_CODE, CompileState, add, diag, drive_limit


def drive(comp: CompileState, i, step):
    vmax, _ = drive_limit(comp.design, None, comp.opts)
    comp.vmax_seen.append(vmax)
    tones = [ScheduledTone(t.frequency, t.amplitude, t.phase, phase_fixed=t.phase_given)
             for t in step.drive.tones]
    add(comp, step.duration, tones, i, f"step {i + 1}: drive")
    comp.goals.append(GoalReport(f"step {i + 1}: drive", "drive", i, comp.t - step.duration, comp.t,
                                 tuple(t.frequency_hz for t in tones), details={"limit_v": vmax}))


def sweep(comp: CompileState, i, step):
    comp.vmax_seen.append(drive_limit(comp.design, None, comp.opts)[0])
    tone = ScheduledTone(step.f_start, step.amplitude, 0.0, step.f_stop, "log" if step.log else "linear")
    name = f"step {i + 1}: sweep"
    add(comp, step.duration, [tone], i, name)
    # checked against the covered range like every goal, but not a goal of schedule.json (it promises nothing)
    comp.inner_goals.append(GoalReport(name, "sweep", i, comp.t - step.duration, comp.t,
                                       (step.f_start, step.f_stop)))


def pause(comp: CompileState, i, step):
    add(comp, step.duration, [], i, f"step {i + 1}: pause")


def follow(comp: CompileState, i, step: FollowStep):
    from acl.design.paths import PathError, path_length, sample_path
    from acl.schedule.bands import pinned
    from acl.schedule.path import PathInfeasible, plan_path
    from acl.schedule.solve import SolverFailure
    from acl.schedule.tones import choose_tones, measured_choice, measured_count

    name = f"step {i + 1}: follow {step.capsule}"
    vmax, slew = drive_limit(comp.design, step.limits, comp.opts)
    comp.vmax_seen.append(vmax)
    try:
        duration = step.duration or path_length(step.path) / step.speed
        if not (np.isfinite(duration) and 0 < duration <= MAX_PROGRAM_S):
            raise diag("E-SCHED-DURATION", f"{name}: the path takes {duration:.4g} s, not a positive "
                        f"time up to {MAX_PROGRAM_S:g} s", step.span, "give a duration or a sensible speed")
        n = duration / comp.opts.waypoint_dt_s
        if not n <= MAX_WAYPOINTS:
            raise diag("E-SCHED-PATH", f"{name}: {n:.4g} waypoints, more than {MAX_WAYPOINTS}",
                        step.span, f"raise --waypoint-dt above {duration / MAX_WAYPOINTS:.3g} s")
        n = max(2, int(round(n)))
        path = sample_path(step.path, n)
        miss = _sampling_miss(step.path, path.points, sample_path)
        if miss > comp.opts.tolerance_m:
            raise diag("E-SCHED-PATH", f"{name}: {n} waypoints {duration / n:.3g} s apart cut corners: the "
                        f"device, moving from waypoint to waypoint, misses the path by up to {miss * 1e6:.3g} um "
                        f"(tolerance {comp.opts.tolerance_m * 1e6:g} um)", step.span,
                        f"give the path more time, or lower --waypoint-dt below {comp.opts.waypoint_dt_s:g} s")
    except (PathError, TypeError, ZeroDivisionError) as exc:
        raise diag("E-SCHED-PATH", f"{name}: {exc}", step.span,
                    "give a duration or a positive speed, and a well-formed path")
    dt = duration / n
    try:
        comp.forward_now, comp.gains_now = _models_for(comp, i, name)
        table = VF.gain_table(comp, step.capsule)
        measured = tuple(f for f, _ in pinned(comp.design))
        choice = choose_tones(table, path.points, vmax, comp.opts.tones_per_path, step.tones, measured)
        # more measured tones than the conservative reach allows may still be feasible: planned first, the choice
        # above if not (a recompile on a calibration plays the tones the readings measured wherever it can)
        more = None if step.tones or not measured else measured_choice(
            table, path.points, vmax, comp.opts.tones_per_path, measured, measured_count(choice, measured) + 1)
    except ValueError as exc:
        raise diag("E-SCHED-TONES", f"{name}: {exc}", step.span, getattr(exc, "help", None) or
                   "pin the tones with `, using [85 kHz, 125 kHz]` on the follow step, or give a calibration sweep (--calibration)")
    if comp.opts.calibration is not None and comp.design.latches:
        SF.calibration_state_check(comp, i, name, step, choice.frequencies)
    # the renderer crossfades consecutive waypoints with a raised cosine over min(ramp, dt), whose
    # steepest slope is pi/2 x the mean: the plan's step per waypoint must leave room for it
    fade = min(comp.opts.ramp_s, dt)
    plan_slew = None if slew is None else slew * 2.0 * fade / (np.pi * dt) * (1 - 1e-4)
    limits = DriveLimits(max_voltage=vmax, slew_rate=plan_slew)
    try:
        for attempt in ([more] if more is not None else []) + [choice]:
            rq = VF.robust_q(comp, name, step.capsule, attempt.frequencies, step.span) if comp.opts.robust else None
            if not comp.opts.robust and VF.band_planned(comp):     # refuse an absurd spread before planning (each
                VF.robust_q(comp, name, step.capsule, attempt.frequencies, step.span, band=True)   # draw: seconds)
            u_start = None
            if slew is not None:        # slew from what is playing before the goal (silence at the start)
                before = {t.frequency_hz: t.amplitude_v for t in comp.segments[-1].tones} if comp.segments else {}
                u_start = np.array([before.get(f, 0.0) ** 2 for f in attempt.frequencies])
            try:
                plan = plan_path(attempt.gains, path.points, dt, limits, tolerance=comp.opts.tolerance_m,
                                 u_start=u_start, lam=comp.opts.lam, slew_model=comp.opts.slew_model,
                                 refine=comp.opts.refine, robust_q=rq, robust_mode=comp.opts.robust_mode)
            except PathInfeasible:
                if attempt is choice:
                    raise
                continue                # more measured tones cannot follow it: the conservative choice
            choice = attempt
            break
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
        raise diag("E-SCHED-SOLVER", f"{name}: {exc}", step.span, "report this design")
    history = []                    # RMS error (m) before and after each nonlinear pass
    if comp.opts.nonlinear_passes > 0:
        plan, history = _correct(comp, name, step.capsule, choice, plan, path.points, dt, limits, rq, u_start)
    amps = plan.amplitudes                                      # (K, N)
    start = comp.t
    for w in range(n):
        tones = [ScheduledTone(f, float(amps[k, w])) for k, f in enumerate(choice.frequencies)]
        add(comp, dt, tones, i, name)
    rep = GoalReport(name, "follow", i, start, comp.t, choice.frequencies,
                     times_s=start + dt * np.arange(n), target_m=path.points,
                     amplitudes_v=amps.T.copy(), capsule=step.capsule)
    rep.linear_rms_error_m = float(np.sqrt(np.mean(plan.error ** 2)))
    VF.resimulate(comp, rep, step.capsule, plan.u, path.points, plan.predicted)
    if rep.max_error_m is not None and not rep.max_error_m <= comp.opts.tolerance_m * (1 + 1e-6) \
            and rep.model.startswith("nonlinear"):
        worst = ("has waypoints without a stable equilibrium (its error is unbounded)"
                 if not np.isfinite(rep.max_error_m) else
                 f"is missed by up to {rep.max_error_m * 1e6:.3g} um (RMS {rep.rms_error_m * 1e6:.3g} um)")
        passes = comp.opts.nonlinear_passes
        # every pass ran and the last one still lowered the error: more passes are the cure before a new path
        falling = passes > 0 and len(history) == passes + 1 and history[-1] < history[-2]
        comp.step_warnings.append(Diagnostic(
            TRACKING_CODE, Severity.WARNING, f"{name}: re-simulated through the nonlinear model the path {worst}, "
            f"beyond the {comp.opts.tolerance_m * 1e6:g} um tolerance the plan meets on its linear gains",
            step.span,
            (f"re-plan against the nonlinear model (--nonlinear-passes {max(3, 2 * passes)}); or "
             if passes < 3 else
             f"the error was still falling after {passes} nonlinear passes (RMS {history[-2] * 1e6:.3g} -> "
             f"{history[-1] * 1e6:.3g} um at the last): re-plan with more (--nonlinear-passes {2 * passes}); or "
             if falling else
             f"{passes} nonlinear passes were not enough (the error stopped falling): ")
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
    if comp.opts.robust:
        rep.details["robust"] = rq is not None
        rep.details["robust_mode"] = comp.opts.robust_mode
    comp.goals.append(rep)


def _correct(comp: CompileState, name, capsule, choice, plan, points, dt, limits, rq, u_start=None):
    """(plan, RMS error per pass) re-planned against the nonlinear forward model (acl.schedule.correct); the first
    plan and no history if unavailable."""
    from acl.schedule.correct import correct_plan
    from acl.schedule.path import PathInfeasible, plan_path
    from acl.schedule.solve import SolverFailure

    provider = comp.forward_now
    try:
        forward, _ = provider(comp.design, capsule, choice.frequencies)
    except (KeyError, ValueError, ImportError) as exc:
        comp.notes.append(f"{name}: no nonlinear correction ({exc})")
        return plan, []

    def plan_for(p):
        return plan_path(choice.gains, p, dt, limits, tolerance=comp.opts.tolerance_m, u_start=u_start,
                         lam=comp.opts.lam, slew_model=comp.opts.slew_model, refine=comp.opts.refine,
                         robust_q=rq, robust_mode=comp.opts.robust_mode)

    try:
        best, history = correct_plan(plan_for, forward, points, plan, comp.opts.nonlinear_passes)
    except (PathInfeasible, SolverFailure):
        comp.notes.append(f"{name}: a nonlinear correction pass was infeasible; kept the linear plan")
        return plan, []
    best.notes.append("nonlinear correction: RMS error " + " -> ".join(f"{h * 1e6:.3g}" for h in history)
                      + " um over the passes (the best plan kept)")
    best.targets = np.asarray(points, float)
    return best, history


def _models_for(comp: CompileState, i: int, name: str):
    """(forward provider (design, capsule, freqs) -> (forward, name), gain provider (design, capsule, freqs=None) ->
    GainTable) of the follow goal of step ``i``: the injected ones, or acl.schedule.gains.model_forward and
    model_gain_table from where the latch states put the capsules when the step starts (:func:`latch_state.latch_track`;
    each draw of a band or of --robust at its own travel).  Fig. 6f: after `switch ctl to b` partner faces arm_cap
    inside d_c and their attraction bends the beam the other way; planned and re-simulated from the declared
    state a, a path of arm_cap after the switch was predicted as if partner were 110 um away."""
    from acl.schedule.gains import (model_forward, model_forward_many, model_forward_tones, model_gain_table,
                                    state_positions)

    forward = comp.opts.forward_provider or model_forward
    # the re-simulation and its band's draws as one batch (gains.model_forward_many) when the model is the default
    comp.many_now = None if comp.opts.forward_provider is not None else \
        (lambda ds, capsule, freqs, u: model_forward_many(ds, capsule, freqs, u))
    comp.many_tones_now = None if comp.opts.forward_provider is not None else model_forward_tones
    given = comp.opts.gain_provider
    gains = (lambda d, capsule, freqs=None: given(d, capsule) if freqs is None else given(d, capsule, freqs)) \
        if given is not None else model_gain_table
    if not comp.design.latches:
        return forward, gains
    track = LS.latch_track(comp, i)
    states = {n: s for n, (s, _, _) in track.items()}
    moved = [l.name for l in comp.design.latches if states.get(l.name, l.state) != l.state]
    doubt = [n for n, (_, sure, _) in track.items() if not sure]
    if doubt:
        comp.notes.append(f"{name}: planned and re-simulated with " + ", ".join(
            f"latch `{n}` in state {states[n]}" for n in doubt)
            + " (its likelier state: an earlier drive left it uncertain)")
    if not moved:
        return forward, gains
    comp.notes.append(f"{name}: planned and re-simulated with " + ", ".join(
        f"latch `{n}` in state {states[n]}" for n in moved) + " (its capsules moved by the latch's travel)")
    if comp.opts.forward_provider is None:
        forward = lambda d, capsule, freqs: model_forward(d, capsule, freqs, start=state_positions(d, states))  # noqa: E731
        comp.many_now = lambda ds, capsule, freqs, u: model_forward_many(  # noqa: E731
            ds, capsule, freqs, u, [state_positions(d, states) for d in ds])
        comp.many_tones_now = lambda ds, capsule, freqs, u: model_forward_tones(  # noqa: E731
            ds, capsule, freqs, u, [state_positions(d, states) for d in ds])
    if given is None:
        gains = lambda d, capsule, freqs=None: model_gain_table(d, capsule, freqs,  # noqa: E731
                                                                positions=state_positions(d, states))
    return forward, gains


def hold(comp: CompileState, i, step: HoldStep):
    from acl.schedule.gains import snap_in_voltages
    from acl.schedule.hold import HoldInfeasible, plan_hold

    name = f"step {i + 1}: hold gap {step.a}/{step.b} {step.mode}"
    vmax, _ = drive_limit(comp.design, step.limits, comp.opts)
    comp.vmax_seen.append(vmax)
    if not step.tones:
        raise diag("E-SCHED-TONES", f"{name}: a hold step needs its tones", step.span,
                    "write `, using [85 kHz, 125 kHz]` on the hold step")
    provider = comp.opts.snap_provider or snap_in_voltages
    bound = step.bound if step.mode == "above" else None
    # above: a tone driven at vmax must still be `margin` from snap-in, so look up to margin x vmax
    v_snap = provider(comp.design, step.a, step.b, step.tones,
                      vmax * step.margin if step.mode == "above" else vmax, bound)
    if v_snap is not None and np.any(np.asarray(v_snap) <= 0):
        raise diag("E-SCHED-INFEASIBLE", f"{name}: the gap is already below its bound at rest",
                    step.span, "lower the bound or widen the rest gap")
    if v_snap is None:
        raise diag("E-SCHED-MODEL", f"{name}: no snap-in model available (acl.analysis.mechanics."
                    "sweep_voltage)", step.span, "the mechanics analysis is needed for hold steps")
    try:
        plan = plan_hold(step.mode, DriveLimits(vmax), v_snap=v_snap, margin=step.margin)
    except HoldInfeasible as exc:
        raise DiagnosticError([Diagnostic(
            "E-SCHED-INFEASIBLE", Severity.ERROR, f"{name}: infeasible: binding "
            + "; ".join(exc.binding), step.span, "relax: " + "; or ".join(exc.relax),
            notes=(f"at t = {comp.t:.4g} s",))])
    tones = [ScheduledTone(f, float(a)) for f, a, u in zip(step.tones, plan.amplitudes, plan.u)
             if u > 1e-6 * max(plan.u.max(), 1e-300)]
    tones, ratio = VF.hold_resimulate(comp, name, step, tones, vmax, bound)
    add(comp, step.duration, tones, i, name)
    details = {"snap_index": float(sum(t.amplitude_v ** 2 / v ** 2 for t in tones
                                       for f, v in zip(step.tones, v_snap) if f == t.frequency_hz)),
               "critical_voltages_v": [float(v) for v in v_snap], "margin": step.margin, "mode": step.mode}
    if ratio is not None:
        details["resimulated_margin"] = ratio
    rep = GoalReport(name, "hold", i, comp.t - step.duration, comp.t,
                     tuple(t.frequency_hz for t in tones),
                     model=("snap-in of the whole drive re-simulated (acl.analysis.mechanics)"
                            if ratio is not None else
                            "snap index sum u/Vcrit^2 (forces add in V^2)"),
                     details=details)
    comp.goals.append(rep)
    if ratio is not None and comp.opts.band_samples > 0:
        VF.hold_band(comp, rep, step, tones, vmax, bound)


def _sampling_miss(spec, points: np.ndarray, sample_path) -> float:
    """Largest distance (m) between the path and the straight moves joining its waypoints: both are
    sampled evenly by arc length, so the path at each dense arc position is compared with the
    waypoints interpolated there (a circle on two waypoints misses by its diameter)."""
    n = len(points)
    dense = sample_path(spec, int(min(max(20 * n, 2000), 200_000))).points
    s_dense, s_way = np.linspace(0.0, 1.0, len(dense)), np.linspace(0.0, 1.0, n)
    between = np.column_stack([np.interp(s_dense, s_way, points[:, k]) for k in range(points.shape[1])])
    return float(np.max(np.linalg.norm(dense - between, axis=1)))
