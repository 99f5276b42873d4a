"""Verification: re-simulation of each planned goal through the forward model, and its 95 % error band."""
from __future__ import annotations

import math

import numpy as np

from acl.design.model import HoldStep, SwitchStep
from acl.diagnostics import DiagnosticError
from acl.schedule.model import GoalReport, ScheduledTone
from acl.schedule.state import MAX_ROBUST_SPREAD, CompileState, diag


def band_planned(comp: CompileState) -> bool:
    """Whether follow goals get an error band from draws of the declared uncertainty (:func:`_band`)."""
    return comp.opts.band_samples > 0 and not (comp.opts.forward_provider is None and comp.opts.calibration is not None)


def robust_q(comp: CompileState, name, capsule, freqs, span, band: bool = False):
    """Q of the declared uncertainty at the chosen tones (None, with a note, when there is none).

    A 1-sigma spread beyond MAX_ROBUST_SPREAD x the gains is E-SCHED-UNCERTAINTY, for --robust and
    (``band``) for the error band of --band-samples, whose draws would all lose the path, each after
    seconds of re-simulation (a finite but absurd `+- s` made every draw cost ~20 s).
    """
    from acl.schedule.robust import robust_q

    if comp.opts.calibration is not None:
        if not band:
            comp.notes.append(f"{name}: --robust ignored: a measured calibration table declares no uncertainty")
        return None
    provider = comp.gains_now
    with np.errstate(all="ignore"):      # overflow is checked below, as a located error
        try:
            q = robust_q(comp.design, lambda d: provider(d, capsule, freqs).gains.T, comp.opts.reload)
        except (ValueError, KeyError, DiagnosticError):
            if not band:
                raise
            return None           # a 1-sigma design that does not resolve: the draws count it as failed
        if q is None:
            if not band:
                comp.notes.append(f"{name}: --robust: the design declares no uncertainty; the plan is the nominal one")
            return q
        g0 = np.linalg.norm(np.asarray(provider(comp.design, capsule, freqs).gains, float), 2)
        spread = float(np.sqrt(np.max(np.abs(np.linalg.eigvalsh(q))))) if np.all(np.isfinite(q)) else float("inf")
    if not (math.isfinite(spread) and spread <= MAX_ROBUST_SPREAD * g0):
        what = [f"`{p.name} +- {p.stddev:g} {p.unit}`".replace(" `", "`") for p in comp.design.uncertain_params()]
        t = comp.design.transducer
        if t is not None and t.gain_uncertainty:
            what.append(f"`{t.name}.gain_uncertainty = {t.gain_uncertainty:g}`")
        option, outcome = (("--band-samples", "an error band over such draws is not computed")
                           if band else ("--robust", "no plan can be robust to it"))
        raise diag("E-SCHED-UNCERTAINTY", f"{name}: {option}: at 1 sigma the declared uncertainty moves the "
                    f"gains by {'more than' if not math.isfinite(spread) else ''} "
                    f"{spread / g0 if math.isfinite(spread) and g0 > 0 else float('inf'):.3g} times their size "
                    f"(at most {MAX_ROBUST_SPREAD:g}): {outcome}".replace("by  ", "by "),
                    span, "check the declared uncertainty: " + (", ".join(what) or "none found")
                    + ("; or compile without an error band: --band-samples 0" if band else ""))
    return q


def gain_table(comp: CompileState, capsule):
    if comp.opts.calibration is not None:
        return comp.opts.calibration
    try:
        return comp.gains_now(comp.design, capsule)
    except (KeyError, ValueError) as exc:
        raise ValueError(f"no gain model for `{capsule}`: {exc}") from None


def resimulate(comp: CompileState, rep: GoalReport, capsule, u, targets, linear_pred):
    provider = comp.forward_now
    if comp.opts.forward_provider is None and comp.opts.calibration is not None:
        # a calibrated device has no better model than its calibration: report the linear plan
        err = np.linalg.norm(linear_pred - targets, axis=1)
        rep.model = "linear calibration gains"
        rep.predicted_m = linear_pred
        rep.rms_error_m, rep.max_error_m = float(np.sqrt(np.mean(err ** 2))), float(err.max())
        return
    if provider is None:
        from acl.schedule.gains import model_forward as provider
    try:
        forward, model = provider(comp.design, capsule, rep.frequencies_hz)
    except (KeyError, ValueError, ImportError) as exc:
        rep.model = f"unavailable: {exc}"
        return
    n = u.shape[1]
    idx = np.unique(np.linspace(0, n - 1, min(n, comp.opts.resim_points)).astype(int))
    band, nominal, solved = None, [], {}
    if comp.opts.band_samples > 0 and comp.opts.forward_provider is None and comp.many_now is not None:
        # the nominal design and the band's draws re-simulated as one batch (gains.model_forward_many)
        many = comp.many_now

        def forward_many(ds):
            # the designs of the band's cause (experiment.explain: the path's sensitivity) join the same batch
            from acl.schedule import experiment

            try:
                extra = [m for m in experiment.prepared(comp.design, comp.opts.reload)[2] if m is not None]
            except (ValueError, KeyError):      # explain meets the same failure later, where it always did
                extra = []
            uu = u[:, idx].T
            got = many([comp.design, *ds, *extra], capsule, rep.frequencies_hz, uu)
            nominal.append(got[0])
            solved[_memo_key(rep.frequencies_hz, uu)] = [(d, g) for d, g in zip([comp.design, *extra],
                                                                                  [got[0], *got[1 + len(ds):]])]
            return got[1:1 + len(ds)]

        band = _error_band(comp, provider, capsule, rep, u[:, idx], targets[idx], forward_many)
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
        comp.notes.append(f"{rep.name}: the forward model found no stable equilibrium at "
                          f"{int((~ok).sum())} of {ok.size} re-simulated waypoints (snap-in?); "
                          "the RMS error leaves them out and the maximum error is unbounded (null)")
    full = np.full_like(targets, np.nan)
    full[idx] = pred
    rep.predicted_m = full
    rep.details["resimulated_waypoints"] = int(idx.size)
    if comp.opts.band_samples > 0:
        _band(comp, rep, provider, capsule, u[:, idx], targets[idx], band if nominal else None, solved)


def _memo_key(freqs, uu) -> tuple:
    uu = np.ascontiguousarray(uu, float)
    return tuple(float(f) for f in freqs), uu.shape, uu.tobytes()


def _reusing(many, solved: dict):
    """``many`` answering from ``solved`` ({key: [(design, prediction)]}, by design identity) when every design asked
    was re-simulated already with the same tones and drive (the band's batch)."""
    def call(ds, f, uu):
        hit = solved.get(_memo_key(f, uu))
        if hit is not None:
            out = []
            for d in ds:
                got = next((g for e, g in hit if e is d), None)
                if got is None:
                    break
                out.append(got)
            else:
                return out
        return many(ds, f, uu)
    return call


def _error_band(comp: CompileState, provider, capsule, rep: GoalReport, u, targets, forward_many=None):
    from acl.schedule.bands import error_band

    return error_band(comp.design, lambda d: provider(d, capsule, rep.frequencies_hz)[0], u, targets,
                      samples=comp.opts.band_samples, seed=comp.opts.band_seed, reload=comp.opts.reload,
                      forward_many=forward_many)


def _band(comp: CompileState, rep: GoalReport, provider, capsule, u, targets, band=None, solved=None):
    """95th percentile of the re-simulated error over draws of the declared uncertainty (``band``: computed with
    the nominal re-simulation, :func:`resimulate`; ``solved``: the predictions that batch made, reused)."""
    from acl.schedule.bands import level, pinned, unmeasured_tones

    if band is None:
        band = _error_band(comp, provider, capsule, rep, u, targets)
    if band is None:
        comp.notes.append(f"{rep.name}: the design declares no uncertainty: no error band "
                          "(declare `+- s` on parameters or `gain_uncertainty` on the transducer)")
        return
    rep.rms_error_p95_m, rep.max_error_p95_m = band.rms_p95_m, band.max_p95_m
    rep.details["band"] = {"samples": band.samples, "failed": band.failed, "seed": comp.opts.band_seed,
                           "quantile": 95, "level": round(level(band.samples), 4), "parameters": [p.name for p in comp.design.uncertain_params()]
                           if comp.opts.reload is not None else [],
                           "gain_uncertainty": comp.design.transducer.gain_uncertainty
                           if comp.design.transducer else None}
    if band.pair:                            # a first-principles pair force drawn (acl.schedule.bands.pair_details)
        rep.details["band"]["pair_scale"] = band.pair
    if 0 < band.samples and level(band.samples) < 0.95:
        comp.notes.append(f"{rep.name}: the error band is the largest of {band.samples} draws, which bounds the "
                          f"95th percentile only with probability {level(band.samples):.0%}: give --band-samples "
                          "19 or more")
    pin = pinned(comp.design)
    if pin:
        rep.details["band"]["measured_gain"] = [{"frequency_hz": f, "stddev": sd} for f, sd in pin]
        off = unmeasured_tones(comp.design, rep.frequencies_hz)
        rep.details["band"]["unmeasured_tones_hz"] = off
        if off:
            comp.notes.append(f"{rep.name}: the calibration did not measure the transducer gain at "
                              f"{', '.join(f'{f / 1e3:g}' for f in off)} kHz (measured: "
                              f"{', '.join(f'{f / 1e3:g}' for f, _ in pin)} kHz): the band keeps the table's "
                              f"{comp.design.transducer.gain_uncertainty:.0%} prior there")
    from acl.schedule import experiment     # the band's cause and the reading that narrows it
    many = _reusing(lambda ds, f, uu: comp.many_now(ds, capsule, f, uu) if comp.many_now else
                    [provider(d, capsule, f)[0](uu) for d in ds], solved or {})
    ex = experiment.explain(comp.design, many, capsule, rep.frequencies_hz, u, targets,
                            reload=comp.opts.reload, band=band, seed=comp.opts.band_seed,
                            noise=comp.opts.reading_noise_m or experiment.READING_NOISE_M, name=rep.name,
                            earlier=comp.cure_readings,
                            many_tones=None if comp.many_now is None or comp.many_tones_now is None else
                            (lambda ds, f, uu: comp.many_tones_now(ds, capsule, f, uu)))
    if ex is not None:
        rep.band_plot = ex.pop("plot", None)
        rep.details["band"]["cause"] = ex
        m = ex.get("measurement")
        if m and comp.cure_readings is None:
            comp.cure_readings = (rep.name, [(r["frequency_hz"], r["voltage_v"]) for r in m["readings"]])
        comp.notes.append(experiment.summary(rep.name, ex))
    if band.failed:
        comp.notes.append(f"{rep.name}: {band.failed} of {comp.opts.band_samples} uncertainty draws lost the "
                          "equilibrium (snap-in) or did not resolve; they count as missing the path")


def switch_band(comp: CompileState, rep: GoalReport, used, step: SwitchStep, j, names, states: dict, either=(), start=None):
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

    band = margin_band(comp.design, margin_for, samples=comp.opts.band_samples, seed=comp.opts.band_seed,
                       reload=comp.opts.reload)
    _margin_report(comp, rep, band, f"the latch stays in state {before} (the drive does not switch it)",
                        others_what="switches")


def _margin_report(comp: CompileState, rep: GoalReport, band, fails: str, others_what: str = ""):
    """Write a margin band into the goal's details and warn when the goal fails in the uncertainty."""
    if band is None:
        comp.notes.append(f"{rep.name}: the design declares no uncertainty: no margin band "
                          "(declare `+- s` on parameters or `gain_uncertainty` on the transducer)")
        return
    rep.details["band"] = {"samples": band.samples, "failed": band.failed, "seed": comp.opts.band_seed,
                           "quantile": 5, "margin_p05": band.p05, "draws_below_1": band.below_one,
                           "parameters": [p.name for p in comp.design.uncertain_params()]
                           if comp.opts.reload is not None else [],
                           "gain_uncertainty": comp.design.transducer.gain_uncertainty
                           if comp.design.transducer else None}
    if band.others_p95:
        rep.details["band"]["other_latch_ratios_p95"] = band.others_p95
    if band.pair:
        rep.details["band"]["pair_scale"] = band.pair
    n = band.samples + band.failed
    if band.below_one:
        seen = band.below_one - band.failed
        more = (f"; {band.failed} more did not resolve or their model failed (a drawn value outside its "
                "physical range, e.g. a negative coefficient), counted as failing") if band.failed else ""
        comp.notes.append(f"warning: {rep.name}: in {seen} of {n} draws of the declared uncertainty {fails}"
                          f"{more} (5th percentile of the margin {band.p05:.3g}); narrow the uncertainty "
                          "(acl fit on data that identify it) or raise the margin")
    for other, r in band.others_p95.items():
        if r >= 1.0:
            comp.notes.append(f"warning: {rep.name}: in the declared uncertainty the drive also {others_what} "
                              f"latch `{other}` (95th percentile of its force over its switching force {r:.3g})")


def hold_band(comp: CompileState, rep: GoalReport, step: HoldStep, tones, vmax, bound):
    """5th percentile of the re-simulated hold margin over draws of the declared uncertainty.

    ``above``: the factor by which the drive can grow before the pair snaps (or the gap reaches the
    bound) on the drawn design; ``cross``: the factor by which the drive exceeds snap-in.
    """
    from acl.schedule.bands import margin_band

    provider = comp.opts.critical_provider
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
    band = margin_band(comp.design, margin_for, samples=comp.opts.band_samples, seed=comp.opts.band_seed,
                       reload=comp.opts.reload)
    _margin_report(comp, rep, band, fails)


def hold_resimulate(comp: CompileState, name, step: HoldStep, tones, vmax, bound):
    """Re-simulate the drive's snap-in and rescale it so the voltage margin holds; (tones, ratio).

    ratio is the scale of the drive at snap-in (or at the gap bound) over the drive itself:
    >= margin for `above`; for `cross` the drive is margin x a snapping drive, ratio <= 1/margin
    (reported as its inverse, the factor by which the drive exceeds snap-in).
    """
    provider = comp.opts.critical_provider
    if provider is None:
        if comp.opts.snap_provider is not None:
            return tones, None          # an injected snap model: nothing better to re-simulate
        from acl.schedule.gains import critical_scale as provider
    if not tones:
        return tones, None
    pairs = [(t.frequency_hz, t.amplitude_v) for t in tones]
    total = sum(a for _, a in pairs)
    margin = step.margin
    if step.mode == "above":
        s = provider(comp.design, step.a, step.b, pairs, 1.5 * margin, bound)
        if s is None:
            return tones, None
        if s < margin:
            # the safe set is star-shaped about zero drive: scale the drive back onto the margin
            f = s / margin * (1 - 1e-6)
            tones = [ScheduledTone(t.frequency_hz, t.amplitude_v * f) for t in tones]
            comp.notes.append(f"{name}: the whole drive snaps at {s:.4g} x itself (the per-tone "
                              f"snap index promised {margin:g}); amplitudes scaled by {f:.4g}")
            s = provider(comp.design, step.a, step.b,
                         [(t.frequency_hz, t.amplitude_v) for t in tones], 1.5 * margin, bound)
            if s is None or s < margin * (1 - 1e-4):
                raise diag("E-SCHED-MODEL", f"{name}: the re-simulated snap-in margin "
                            f"{s if s is not None else float('nan'):.4g} stays below {margin:g}",
                            step.span, "pin a single tone with `using`")
        return tones, float(s)
    s = provider(comp.design, step.a, step.b, pairs, vmax / total, None)
    if s is None:
        return tones, None
    if not s * margin <= 1.0 + 1e-9:
        f = s * margin * (1 + 1e-6)
        if not np.isfinite(f) or total * f > vmax * (1 + 1e-9):
            raise diag("E-SCHED-INFEASIBLE", f"{name}: infeasible: the whole drive snaps only at "
                        f"{s:.4g} x itself; {margin:g} x that exceeds the {vmax:g} V limit",
                        step.span, f"raise the max voltage above {vmax:g} V; or lower the margin")
        tones = [ScheduledTone(t.frequency_hz, t.amplitude_v * f) for t in tones]
        comp.notes.append(f"{name}: the whole drive snaps only at {s:.4g} x itself; amplitudes "
                          f"scaled by {f:.4g} to cross by the margin {margin:g}")
        s = s / f
    return tones, float(1.0 / s)
