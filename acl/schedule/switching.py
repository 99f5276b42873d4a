"""Switch pass: a latch switch step, planned by the latch LP and checked against the full model."""
from __future__ import annotations

import dataclasses

import numpy as np

from acl.design.model import SwitchStep
from acl.diagnostics import Diagnostic, DiagnosticError, Severity
from acl.schedule import latch_state as LS
from acl.schedule import verify as VF
from acl.schedule.model import GoalReport, ScheduledTone
from acl.schedule.path import DriveLimits
from acl.schedule.state import CONTACT_CODE, LATCH_STATE_CODE, CompileState, add, diag, drive_limit


def switch(comp: CompileState, i, step: SwitchStep):
    """Plan a switch from the state the latch is in when the step starts (:func:`latch_state.latch_track`: earlier switches,
    drives, sweeps, paths and holds).  Already there: nothing played.  Uncertain (a drive pushed it near its
    switching force): planned from the other state, which also leaves it in the wanted state if it is there
    already (the drive pushes it further in); when no drive does that within the limits, W-SCHED-LATCH-STATE at
    the step.  Another latch in an uncertain state is kept put in both directions, or, when no drive does that,
    in its likelier state with W-SCHED-LATCH-STATE."""
    from acl.schedule.latch import SwitchInfeasible, plan_switch

    name = f"step {i + 1}: switch {step.latch} -> {step.state}"
    vmax, _ = drive_limit(comp.design, step.limits, comp.opts)
    comp.vmax_seen.append(vmax)
    names = [l.name for l in comp.design.latches]
    if step.latch not in names:
        raise diag("E-SCHED-MODEL", f"{name}: no latch named `{step.latch}`", step.span)
    track = LS.latch_track(comp, i)
    state, certain, why = track[step.latch]
    source = why or "its declared state"
    before = state if certain else "a or b"
    if certain and state == step.state:
        comp.notes.append(f"{name}: latch already in state {step.state} ({source}); nothing to do")
        add(comp, step.duration, [], i, name)
        comp.goals.append(GoalReport(name, "switch", i, comp.t - step.duration, comp.t, (),
                                     model="nothing played: the latch is already in that state",
                                     details={"state_before": state, "state_from": source, "already": True}))
        comp.switch_outcome[i] = (state, True, why)
        return
    other = "a" if step.state == "b" else "b"
    doubt = [k for k, n in enumerate(names) if n != step.latch and not track[n][1]]
    freqs = tuple(step.tones) or tuple(_latch_candidates(comp))
    j = names.index(step.latch)
    states = [track[n][0] for n in names]
    states[j] = other                # certain: it is there; uncertain: a drive from there works from both
    positions = None
    if comp.opts.latch_provider is None:
        # the forces where the capsules are: a latch in a state other than its declared one carries its capsules
        # moved by the travel (Fig. 6f: in state b `partner` faces `arm_cap` 40 um away, whose attraction at
        # 125 kHz pushes the shuttle further into b, where at rest 125 kHz pushed it back towards a)
        from acl.schedule.gains import latch_forces, state_positions

        positions = state_positions(comp.design, dict(zip(names, states)))
        forces, to_b, to_a = latch_forces(comp.design, freqs, positions)
    else:
        forces, to_b, to_a = comp.opts.latch_provider(comp.design, freqs)

    def infeasible(exc):
        return DiagnosticError([Diagnostic(
            "E-SCHED-INFEASIBLE", Severity.ERROR, f"{name}: infeasible: binding "
            + "; ".join(exc.binding), step.span, "relax: " + "; or ".join(exc.relax),
            notes=(f"at t = {comp.t:.4g} s, {len(freqs)} candidate tones",)
            + ((f"latch `{step.latch}` is in state {other}: {why}",) if why else ()))])

    kept_both = bool(doubt)
    plan = None
    if not certain and comp.opts.latch_provider is None:
        # planned from the other state, the drive must also leave the latch where it is if it is in the wanted
        # state already: its push back from there, with the capsules where that state puts them, kept below
        # 1/margin of the force that switches it back (when no drive does that, planned without it and warned)
        where = dict(zip(names, states))
        where[step.latch] = step.state
        Fw, _, _ = latch_forces(comp.design, freqs, state_positions(comp.design, where))
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
    except SwitchInfeasible as exc:  # noqa: F841  (raised below, inside this handler)
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
            _latch_warn(comp, i, step, f"{name}: latch `{step.latch}` may be in state {other} and no drive within "
                             f"the limits switches it from there: the step plays nothing, and the latch may stay "
                             f"in state {other}",
                             f"make the earlier drive decisive (well above or below the latch's switching force), "
                             f"or give the switch tones that push the latch to state {step.state}",
                             (why, "planned from state " + other + ": binding " + "; ".join(exc.binding)))
            add(comp, step.duration, [], i, name)
            comp.goals.append(GoalReport(name, "switch", i, comp.t - step.duration, comp.t, (),
                                         model="nothing played: no drive switches the latch from its other state",
                                         details={"state_before": before, "state_from": source, "already": False,
                                                  "state_certain": False}))
            comp.switch_outcome[i] = (state, False, why)
            return
    if doubt and not kept_both:
        _latch_warn(comp, i, step, f"{name}: " + ", ".join(f"latch `{names[k]}`" for k in doubt)
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
    if comp.opts.latch_provider is None:
        used, F_full = _switch_full_model(comp, name, step, used, j, sig, thr_t, vmax, positions)
        if F_full is not None:
            F, model = F_full, "force of the whole drive (declared drive saturation)"
            plan = dataclasses.replace(plan, required_force=step.margin * thr_t)
    add(comp, step.duration, [ScheduledTone(f, float(a)) for f, a in used], i, name)
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
        raise diag("E-SCHED-SOLVER", f"{name}: the emitted tones miss the switching margins "
                    "the latch program promised", step.span, "report this design")
    details = {"force_n": force, "required_n": plan.required_force,
               "margin": force / plan.required_force * step.margin, "other_latch_ratios": others,
               "state_before": before, "state_from": source, "planned_from": other,
               "forces_at": "the declared positions" if positions is None else
               "the latch states' positions (" + ", ".join(f"`{n}` in state {s}" for n, s, lt in
                                                         zip(names, states, comp.design.latches)
                                                         if s != lt.state) + ")"}
    if not certain:
        back = _push_back(comp, used, names, states, j, step.state) if comp.opts.latch_provider is None else None
        if back is not None and back > 1.0 / step.margin:
            # where the capsules are in the wanted state the drive may push the other way (a neighbour's attraction
            # that only acts there): "it pushes it further in" is not so
            details["push_back_ratio"] = back
            _latch_warn(comp, i, step, f"{name}: latch `{step.latch}` may be in state a or b; planned from "
                             f"state {other}, but if it is in state {step.state} already the drive pushes it back "
                             f"towards state {other} at {back:.3g} x the force that switches it there",
                             "make the earlier drive decisive (well above or below the latch's switching force), "
                             "or switch the latch to a known state first", (why,))
        else:
            comp.notes.append(f"{name}: latch `{step.latch}` may be in state a or b ({why}): planned from state "
                              f"{other}, which also leaves it in state {step.state} if it is there already (the "
                              "drive pushes it further in)")
    _switch_aftermath(comp, i, step, name, used, after, details)
    rep = GoalReport(name, "switch", i, comp.t - step.duration, comp.t,
                     tuple(f for f, _ in used), model=model, details=details)
    comp.goals.append(rep)
    comp.switch_outcome[i] = (step.state, True, f"step {i + 1} (switch)")
    if comp.opts.band_samples > 0 and comp.opts.latch_provider is None:
        VF.switch_band(comp, rep, used, step, j, names, after, [names[k] for k in doubt] if kept_both else [],
                          dict(zip(names, states)))


def _switch_aftermath(comp: CompileState, i, step, name, used, after: dict, details: dict) -> None:
    """W-SCHED-CONTACT at a switch whose drive, once the latch is in its new state, leaves the mechanism no stable
    equilibrium there (gains.settle_from the new states' positions, the drive's power ramped up): the moved
    capsules now face a neighbour inside its critical distance and the switch's own drive snaps them in (Fig. 6f:
    after `switch ctl to b` partner faces arm_cap 40 um away, and 85 kHz, below both bubbles' resonance, drives
    them in phase: they attract).  ``details["aftermath"]`` says what was found."""
    if comp.opts.latch_provider is not None or not used:
        return
    from acl.design.model import Drive, Tone
    from acl.schedule.gains import settle_from, state_positions

    start = state_positions(comp.design, after) or {c.name: np.asarray(c.center, float)
                                                    for c in comp.design.capsules}
    drive = Drive(tones=tuple(Tone(frequency=float(f), amplitude=float(a)) for f, a in used if a > 0))
    try:
        eq = settle_from(comp.design, drive, start)
    except (ValueError, KeyError, ArithmeticError, np.linalg.LinAlgError, DiagnosticError) as exc:
        details["aftermath"] = f"not checked ({exc})"
        return
    if eq is not None:
        details["aftermath"] = "stable in the new state under the switch's drive"
        return
    details["aftermath"] = "no stable equilibrium in the new state under the switch's drive (snap-in)"
    comp.step_warnings.append(Diagnostic(
        CONTACT_CODE, Severity.WARNING,
        f"{name}: once latch `{step.latch}` is in state {step.state}, the switch's own drive leaves the mechanism no "
        "stable equilibrium there (acl.analysis.mechanics, the drive ramped up from the new state): capsules the "
        "latch moved snap in to a neighbour, and stay in contact while a drive plays", step.span,
        "switch with tones that do not attract the moved capsules to their neighbours, or with a lower limit if "
        "the latch still switches below the snap-in; a `pause` after the switch releases the contact"))


def _push_back(comp: CompileState, used, names, states, j, to) -> float | None:
    """The push of the drive ``used`` on latch ``j`` back from state ``to`` (the other latches in ``states``), with
    the capsules where that state puts them, over the force that switches it back; None when not computable."""
    from acl.schedule.gains import latch_drive_forces, latch_forces, state_positions

    where = dict(zip(names, states))
    where[names[j]] = to
    try:
        F = latch_drive_forces(comp.design, used, state_positions(comp.design, where))
        _, to_b, to_a = latch_forces(comp.design, [])
    except (DiagnosticError, KeyError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    return float(-F[j] / to_a[j]) if to == "b" else float(F[j] / to_b[j])


def _latch_warn(comp: CompileState, i, step, message: str, hint: str, notes=()) -> None:
    comp.step_warnings.append(Diagnostic(LATCH_STATE_CODE, Severity.WARNING, message, step.span, hint,
                                          notes=tuple(notes)))


def _switch_full_model(comp: CompileState, name, step: SwitchStep, used, j, sig, thr_t, vmax, positions=None):
    """Re-check a switch with the full force model when forces are not ~V^2 (drive saturation).

    The LP plans with the force per V^2 at 1 V; a declared saturation makes the real force of the
    planned drive smaller.  The drive is scaled up (bisection: the force grows with the scale)
    until the latch gets ``margin`` x its switching force, within the limit; (tones, forces (L,)), the capsules at
    ``positions`` (the latch states', :func:`gains.state_positions`; None: at rest).
    """
    from acl.analysis.acoustics import force_model_for

    if force_model_for(comp.design).quadratic_in_amplitude or not used:
        return used, None
    from acl.schedule.gains import latch_drive_forces

    def at(scale):
        F = latch_drive_forces(comp.design, [(f, a * scale) for f, a in used], positions)
        return float(sig * F[j] / thr_t), F

    r, F = at(1.0)
    if r >= step.margin * (1 - 1e-6):
        return used, F
    top = vmax / sum(a for _, a in used)
    r_top, F_top = at(top)
    if r_top < step.margin:
        raise diag("E-SCHED-INFEASIBLE", f"{name}: infeasible: with the declared drive saturation the "
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
    comp.notes.append(f"{name}: the declared drive saturation leaves the planned drive at {r:.3g} x the "
                      f"switching force; amplitudes scaled by {hi:.4g} to reach the margin {step.margin:g}")
    return [(f, a * hi) for f, a in used], F


def _latch_candidates(comp: CompileState):
    from acl.schedule.gains import default_frequencies

    return default_frequencies(comp.design, step_hz=2500.0)
