"""Latch-state tracking: the state each bistable latch is in when a step starts, and the pushes that move it."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from acl.diagnostics import Diagnostic, DiagnosticError, Severity
from acl.physics.ties import first_max_item
from acl.schedule.state import (
    DRIVEN_KINDS,
    FLIP_KINDS,
    LATCH_FLIP_CODE,
    LATCH_STATE_MARGIN,
    CompileState,
    is_fade,
    mode_frequencies,
)


def latch_track(comp: CompileState, i: int) -> dict:
    """{latch: (state, certain, why)} when step ``i`` starts.

    As the switch steps before it left them (:attr:`switch_outcome`), and every other step that plays a drive
    before it -- drive, sweep, follow (each waypoint) and hold (:func:`_switched_by`): a bistable latch stays
    switched when the drive stops.  ``why`` names the step that set the state (None: the declared state);
    ``certain`` is False where a drive pushed the latch near the force that switches it, or over it only in part
    of the declared uncertainty: then ``state`` is the likelier one (the nominal pushes in the played order).
    """
    memo = comp.states_memo
    if 0 not in memo:
        memo[0] = {l.name: (l.state, True, None) for l in comp.design.latches}
    k = max(j for j in memo if j <= i)
    cur = dict(memo[k])
    for j in range(k, i):
        st = comp.program.steps[j]
        if st.kind == "switch" and st.latch in cur:
            cur[st.latch] = comp.switch_outcome.get(j, (st.state, True, f"step {j + 1} (switch)"))
        elif st.kind in DRIVEN_KINDS:
            changed = _switched_by(comp, j, cur)
            if st.kind in FLIP_KINDS:
                _flip_warn(comp, j, cur, changed)
            cur.update(changed)
        memo[j + 1] = dict(cur)
    return cur


def _switched_by(comp: CompileState, j: int, cur: dict) -> dict:
    """{latch: (state, certain, why)} for the bistable latches whose state the drive of step ``j`` (a drive, sweep,
    follow or hold) changes or makes uncertain, from the states ``cur`` it starts in.

    The push is the switch planner's force model: the force of the drive along each latch's axis
    (acl.schedule.gains.latch_drive_forces, or the injected ``latch_provider``, at rest) over the force that
    switches it to the other state (a->b its switching force, b->a its release force), with the capsules at the
    drive's static equilibrium and undeflected (:func:`_branch_pushes`: both must be on the same side); a sweep's
    at its band's worst frequency (interfaces.band_maximum); a path's at its most-switching waypoint
    (:func:`_push_ratios`).  Switched for sure: push >= LATCH_STATE_MARGIN and, with a margin band
    (``band_samples``), its 5th percentile over the declared uncertainty >= 1, and never pushed back (below);
    left for sure: the largest push towards the other state (a path's between its waypoints too) <=
    1/LATCH_STATE_MARGIN and the band's 95th percentile < 1.  Anything between: uncertain, in the state the
    nominal pushes leave it in (a path: waypoint by waypoint; a push >= 1 x switches).
    """
    step = f"step {j + 1} ({comp.program.steps[j].kind})"
    try:
        pushes = _push_ratios(comp, j, cur)
    except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        try:
            bi = bistable(comp)
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


def _flip_warn(comp: CompileState, j: int, cur: dict, changed: dict) -> None:
    """W-SCHED-LATCH-FLIP at a follow or hold step whose drive switches a latch, or may (:func:`_switched_by`)."""
    step = comp.program.steps[j]
    for n, (state, certain, why) in changed.items():
        was, was_sure, _ = cur[n]
        if certain and was_sure and state == was:
            continue
        what = (f"switches latch `{n}` from state {was} to state {state}; later steps are planned from state "
                f"{state}" if certain and state != was else
                f"may switch latch `{n}`: it ends in state a or b (likelier {state}); a later `switch` is planned "
                "to work from both")
        goal = "path" if step.kind == "follow" else "hold"
        comp.step_warnings.append(Diagnostic(
            LATCH_FLIP_CODE, Severity.WARNING, f"step {j + 1}: {step.kind}: the {goal}'s drive {what}",
            step.span, "keep the step's drive away from the latch's switching and release forces (other tones, "
            "a lower limit), or switch the latch back afterwards with a `switch` step", notes=(why,)))


def bistable(comp: CompileState) -> dict:
    """{latch: index} of the latches that stay switched when the drive stops (a finite release force)."""
    _, to_b, to_a = _latch_thresholds(comp, comp.design)
    return {l.name: k for k, l in enumerate(comp.design.latches) if np.isfinite(to_a[k]) and np.isfinite(to_b[k])}


def _latch_thresholds(comp: CompileState, design):
    provider = comp.opts.latch_provider
    if provider is None:
        from acl.schedule.gains import latch_forces as provider
    return provider(design, [])


def _latch_push(comp: CompileState, design, tones) -> tuple:
    """((L,) force N of ``tones`` ((Hz, V)) along each latch axis, to_b, to_a): the switch planner's model."""
    provider = comp.opts.latch_provider
    if provider is not None:        # an injected model: force per V^2 of each tone (as the switch LP)
        forces, to_b, to_a = provider(design, tuple(f for f, _ in tones))
        return np.asarray(forces, float) @ np.array([a * a for _, a in tones], float), to_b, to_a
    from acl.schedule.gains import latch_drive_forces, latch_forces

    _, to_b, to_a = latch_forces(design, [])
    return latch_drive_forces(design, tones), to_b, to_a


def _waypoint_pushes(comp: CompileState, design, freqs, U) -> tuple:
    """((L, N) force N of each waypoint drive, (L, N-1, 2) upper bounds of the force towards b / towards a while
    crossfading from waypoint w to w + 1, to_b, to_a); ``U`` (K, N) amplitudes V of the tones ``freqs``.

    Tones add in power, each quadratic in its amplitude (force_model.quadratic_in_amplitude): the force is
    G @ U^2 with G the force per V^2 of each tone (acl.schedule.gains.latch_forces, the switch LP's), and while
    the renderer crossfades two waypoints each tone's power lies between its two ends, so the force towards a
    state is at most the sum over tones of the larger end.  A drive whose forces are not quadratic (declared
    drive saturation) is evaluated waypoint by waypoint, without the crossfade bound (its ends only).
    """
    U = np.asarray(U, float)
    provider = comp.opts.latch_provider
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
            seen[key], to_b, to_a = _latch_push(comp, design, [(float(f), float(a)) for f, a in zip(freqs, key)])
        cols.append(seen[key])
    _, to_b, to_a = _latch_thresholds(comp, design) if not seen else (None, to_b, to_a)
    F = np.array(cols, float).T.reshape(len(to_b), U.shape[1])
    up = np.stack([np.maximum(F[:, :-1], F[:, 1:]), np.maximum(-F[:, :-1], -F[:, 1:])], axis=-1)
    return F, up, np.asarray(to_b, float), np.asarray(to_a, float)


def _push_ratios(comp: CompileState, j: int, cur: dict | None = None) -> dict:
    """{bistable latch: {"b": _Push, "a": _Push, "seq": {start state: end state}}} for the drive of step ``j``,
    from the latch states ``cur`` it starts in ({latch: (state, certain, why)}; None: the declared ones).

    Its push towards each state over the force that switches the latch there (:func:`_switched_by`).  A drive or
    hold plays one drive; a sweep is taken at its band's worst frequency; a follow step plays one drive per
    waypoint: its most-switching waypoint's push (``where`` names it), ``up`` the largest push also between
    waypoints (:func:`_waypoint_pushes`), and ``seq`` the state the nominal pushes leave the latch in, waypoint by
    waypoint, from each state (a push >= 1 x switches).  The worst drive (waypoint, frequency) is found with the
    capsules at rest; its push is then taken with the capsules where they are (:func:`_branch_pushes`): at the
    static equilibrium under the drive on the branch the latch leaves (state a for the push towards b, b for the
    push back), ``r``, and undeflected on that branch, ``r0``; the other latches in their (likelier) states.
    ``lo`` .. ``hi``: the 5th percentile of the most-switching waypoint's push and the 95th of the largest one over
    the declared uncertainty (acl.schedule.bands.margin_band, at rest: the percentiles of each draw's extremes
    over the whole path, so every waypoint's band is inside), moved by the nominal change from rest to
    the worse of ``r`` and ``r0`` (lo = hi = the push without a band)."""
    if j in comp.push_memo:
        return comp.push_memo[j]
    bi = bistable(comp)
    segs = [s for s in comp.segments if s.step == j and not is_fade(s)]
    tones = [t for s in segs for t in s.tones if t.amplitude_v > 0]
    chirp = next((t for t in tones if t.frequency_end_hz), None)
    freqs = sorted({t.frequency_hz for t in tones})
    U = np.array([[sum(t.amplitude_v for t in s.tones if t.frequency_hz == f and t.amplitude_v > 0)
                   for s in segs] for f in freqs], float).reshape(len(freqs), len(segs))
    steps = comp.program.steps[j].kind == "follow" and len(segs) > 1

    def ratios(d):
        """{latch: {to: (push at the worst drive, its waypoint index or frequency, largest push incl. crossfades)}},
        the waypoint pushes (rb, ra) per latch for the nominal order (None: one drive)."""
        if not tones:
            return {n: {"b": (0.0, 0, 0.0), "a": (0.0, 0, 0.0)} for n in bi}, None
        if chirp is None:
            F, up, to_b, to_a = _waypoint_pushes(comp, d, freqs, U)
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
                seen[f] = _latch_push(comp, d, [(float(f), chirp.amplitude_v)])
            return seen[f]

        out = {}
        for n, k in bi.items():
            rb, fb = interfaces.band_maximum(lambda f: float(at(f)[0][k] / at(f)[1][k]), chirp.frequency_hz,
                                             chirp.frequency_end_hz, mode_frequencies(comp), rtol=1e-6)
            ra, fa = interfaces.band_maximum(lambda f: float(-at(f)[0][k] / at(f)[2][k]), chirp.frequency_hz,
                                             chirp.frequency_end_hz, mode_frequencies(comp), rtol=1e-6)
            out[n] = {"b": (rb, float(fb), rb), "a": (ra, float(fa), ra)}
        return out, None

    from acl.analysis import interfaces

    nominal, seq = ratios(comp.design)
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
            eq = _branch_pushes(comp, drive_of(w), states, n, to) if tones else None
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
    if comp.opts.band_samples > 0 and comp.opts.latch_provider is None and tones and bi:
        from acl.schedule.bands import margin_band

        def margin_for(d):
            r, _ = ratios(d)
            return 1.0, {k: x for n, v in r.items() for to, (x0, _, xu) in v.items()
                         for k, x in ((f"+{n}>{to}", xu), (f"-{n}>{to}", -x0))}

        band = margin_band(comp.design, margin_for, samples=comp.opts.band_samples, seed=comp.opts.band_seed,
                           reload=comp.opts.reload)
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
    comp.push_memo[j] = res
    return res


def _branch_pushes(comp: CompileState, tones, states: dict, latch: str, to: str):
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
    if comp.opts.latch_provider is not None or not comp.design.capsules or not tones:
        return None
    key = (tuple(tones), tuple(sorted(states.items())), latch, to)
    if key in comp.branch_memo:
        return comp.branch_memo[key]
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.physics.latch import latch_landscape
    from acl.schedule.gains import latch_drive_forces, latch_forces, state_positions

    try:
        k = next(i for i, l in enumerate(comp.design.latches) if l.name == latch)
        branch = dict(states)
        branch[latch] = "a" if to == "b" else "b"
        lands = {lt.name: latch_landscape(*mechanics.latch_geometry(lt, comp.design)) for lt in comp.design.latches}
        pos = state_positions(comp.design, branch)
        _, to_b, to_a = latch_forces(comp.design, [])
        thr = float(to_b[k]) if to == "b" else -float(to_a[k])
        r0 = float(latch_drive_forces(comp.design, tones, pos)[k] / thr)
        drive = Drive(tones=tuple(Tone(frequency=f, amplitude=a) for f, a in tones))
        st = mechanics.equilibrium(comp.design, drive, acoustics.force_model_for(comp.design), start=pos)
        on_branch = st.status in ("ok", "snap_in")
        for lt in comp.design.latches:
            land, u = lands[lt.name], st.deflections.get(lt.name)
            if land.unstable is None or u is None:
                continue
            if (u > land.unstable) != (branch.get(lt.name, lt.state) == "b"):
                on_branch = False
        if not on_branch:
            out = (r0, r0, " (undeflected)", True)
        else:
            r = float(latch_drive_forces(comp.design, tones, st.positions)[k] / thr)
            note = f" at its static equilibrium ({r0:.3g} x undeflected)" if f"{r:.3g}" != f"{r0:.3g}" else ""
            out = (r, r0, note, False)
    except (DiagnosticError, KeyError, StopIteration, ValueError, ArithmeticError, np.linalg.LinAlgError):
        out = None
    comp.branch_memo[key] = out
    return out


def settle(comp: CompileState, drive, force_model, states: dict):
    """(largest capsule displacement from rest, m, that capsule, status) at the equilibrium under ``drive``.

    A latch that rests in state a but is in state b when the step starts (an earlier switch), or that the
    drive itself switches (acl.analysis.mechanics.latch_margins: its push reaches the switching force), is
    solved from its state b (the shuttle's capsules moved by the travel there): the branch the device is on.
    ValueError when the mechanics does not converge.
    """
    key = (tuple((t.frequency, t.amplitude) for t in drive.tones), tuple(sorted(states.items())))
    if key in comp.settled:             # a ramp repeats its drives
        return comp.settled[key]
    from acl.analysis import mechanics
    from acl.schedule.gains import state_positions

    want, margins = {}, None
    for lt in comp.design.latches:
        if lt.state != "a":
            continue
        if states.get(lt.name, lt.state) == "a":
            margins = margins if margins is not None else mechanics.latch_margins(comp.design, drive, force_model)
            if not margins[lt.name].margin >= 1.0:
                continue
        want[lt.name] = "b"
    # the capsules each such latch carries (mounted and trussed to them) moved by its travel
    st = mechanics.equilibrium(comp.design, drive, force_model, start=state_positions(comp.design, want))
    if st.status not in ("ok", "snap_in"):
        raise ValueError(f"no equilibrium ({st.status})")
    who, best = first_max_item({c.name: float(np.linalg.norm(np.asarray(st.displacements[c.name], float)))
                                for c in comp.design.capsules})     # ties: the first capsule declared
    comp.settled[key] = (best, who, st.status)
    return comp.settled[key]


@dataclass(frozen=True)
class _Push:
    """A step's push on a latch towards one state, over the force that switches it there (:func:`_push_ratios`)."""

    r: float          # nominal, at the most-switching waypoint (a drive, hold or sweep: its one drive)
    lo: float         # 5th percentile over the declared uncertainty (of each draw's largest waypoint push)
    hi: float         # 95th percentile (of each draw's largest push, crossfades included)
    band: str         # what the band was drawn from ("": no band)
    up: float         # nominal largest push, also while crossfading between waypoints (>= r, r0)
    where: str        # " at waypoint w of N (t = ...)" for a path, else ""; the equilibrium's note
    r0: float = float("nan")    # the same drive with the capsules undeflected on the branch (lo <= min(r, r0))
    lost: bool = False          # under the drive no equilibrium stays on the branch: never "left for sure"


def _nominal_end(start: str, rb: np.ndarray, ra: np.ndarray) -> str:
    """The state a latch starting in ``start`` ends in under waypoint pushes ``rb``/``ra`` (ratios; >= 1 switches)."""
    state = start
    for b, a in zip(rb, ra):
        if state == "a" and b >= 1.0:
            state = "b"
        elif state == "b" and a >= 1.0:
            state = "a"
    return state
