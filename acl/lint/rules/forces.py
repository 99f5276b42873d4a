"""ACL2xx: secondary Bjerknes forces between bubble pairs (snap-in, sign changes over frequency)."""
from __future__ import annotations

import numpy as np

from acl.design.model import Drive, Tone
from acl.diagnostics import Severity
from acl.lint.context import Context, khz, um
from acl.lint.registry import rule


#: Net critical distances computed for a lint run's messages at most (each moves one capsule over a grid of gaps
#: through the whole force model); beyond, a finding names Eq. 3's d_c and says the net one was not computed.
NET_DC_MESSAGES = 20


def _closing_at_rest(ctx: Context, drive, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Net closing force (N, attraction positive) of pairs of capsule indices at rest from the total forces (thrust,
    Bjerknes, jet drag): acl.analysis.pairs.closing_component, as analyze's d_c uses it."""
    from acl.analysis.pairs import closing_component

    centres = np.array([c.center for c in ctx.design.capsules], float).reshape(-1, 3)
    return closing_component(ctx.net_force_array(drive), centres, a, b)


def _pushed_apart(ctx: Context, drive, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Eq. 3's premise, for pairs of capsule indices: each capsule's own thrust pushes it away from the other."""
    thrust = ctx.thrust_array(drive)
    centres = np.array([c.center for c in ctx.design.capsules], float).reshape(-1, 3)
    line = centres[b] - centres[a]
    u = line / np.maximum(np.linalg.norm(line, axis=1), 1e-300)[:, None]
    return (np.einsum("pk,pk->p", thrust[a], -u) > 0) & (np.einsum("pk,pk->p", thrust[b], u) > 0)


def managed_pairs(program) -> set[tuple[str, str]]:
    """Pairs whose gap a program governs itself: `hold gap(a, b) above ...` or `cross gap(a, b)`."""
    return {tuple(sorted((st.a.split(".")[0], st.b.split(".")[0])))
            for st in program.steps if st.kind == "hold"}


@rule("ACL201", "snap-in",
      "a bubble pair closer than its critical distance is pulled together by Bjerknes attraction (paper Eq. 3; "
      "the net force model)",
      Severity.ERROR, "forces", ("snap_margin", "sweep_samples"))
def snap_in(ctx: Context):
    if len(ctx.design.capsules) < 2:
        return
    margin = ctx.threshold("snap_margin")
    for p in ctx.design.programs:
        crossing = managed_pairs(p)
        flagged: dict[tuple[str, str], tuple] = {}      # pair -> (amplitude, step, drive, pair force)
        for st in p.steps:
            for drive in ctx.step_drives(st):
                amp = sum(t.amplitude for t in drive.tones)
                for key, row in _snap_candidates(ctx, drive, margin):
                    if key in crossing:
                        continue
                    if key not in flagged or amp > flagged[key][0]:
                        flagged[key] = (amp, st, drive, row)
        for key, (amp, st, drive, pf) in sorted(flagged.items()):
            verdict = _mechanics_verdict(ctx, drive, pf)
            if verdict is False:
                ctx.note("ACL201", f"`{pf.a}`/`{pf.b}` in `{p.name}`: below d_c, but the structure holds them "
                                   f"at the strongest drive ({amp:.3g} V)")
                continue
            tones = " + ".join(f"{khz(t.frequency)} @ {t.amplitude:.3g} V" for t in drive.tones)
            net = _net_critical_distance(ctx, drive, pf)
            eq3 = "none (Eq. 3's premise fails)" if pf.critical_distance is None else um(pf.critical_distance)
            shown = net if net is not None else pf.critical_distance
            yield ctx.finding("ACL201",
                f"`{pf.a}` and `{pf.b}` are {um(pf.distance)} apart, closer than their critical distance"
                + (f" {um(shown)}" if shown is not None else "") + f": program `{p.name}` snaps them together",
                st.span, notes=[
                    f"strongest drive {tones}",
                    f"Bjerknes attraction {pf.attraction * 1e9:.3g} nN at rest, phase difference "
                    f"{round(float(np.degrees(pf.phase_difference)))} deg",   # round(): never "-0"
                    ("d_c = " + (um(net) if net is not None else "not computed (more than "
                                 f"{NET_DC_MESSAGES} pairs flagged)")
                     + " where the net force (thrust, Bjerknes, jet drag) changes sign, as acl analyze's "
                     f"critical_distance_m; paper Eq. 3's sqrt(alpha / 2 gamma) = {eq3}; threshold snap_margin = "
                     f"{margin:g} (on Eq. 3's d_c; the net force is checked at rest)"),
                    "quasi-static equilibrium at this drive: " + (
                        "snaps in (acl.analysis.mechanics)" if verdict else
                        "not computed (set `mechanics = true` in the configuration or pass --mechanics)")],
                hint="increase the gap, or use `cross gap(a, b)` if the program means to bring them together")


def _net_critical_distance(ctx: Context, drive, pf) -> float | None:
    """acl analyze's d_c of the pair (acl.analysis.pairs.net_critical_distance), for the first NET_DC_MESSAGES
    findings of a run; None beyond, or where the net force never changes sign."""
    count = ctx.cached(("net_dc_count",), lambda: [0])
    key = ("net_dc", pf.a, pf.b, tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones))
    def compute():
        if count[0] >= NET_DC_MESSAGES:
            return None
        count[0] += 1
        from acl.analysis.pairs import net_critical_distance
        try:
            return net_critical_distance(ctx.design, drive, pf.a, pf.b)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
    return ctx.cached(key, compute)


def _snap_candidates(ctx: Context, drive, margin: float):
    """[(sorted pair names, :class:`PairForce`)] of the pairs under ``drive`` closer than ``margin`` x d_c
    (NaN compares False: no d_c, no snap-in), not both fixed, each pushed away from the other by its own
    thrust (Eq. 3's premise); cached per drive (the rows only: a design's pair tables are not kept)."""
    def compute():
        tab = ctx.pair_table(drive)
        # closer than Eq. 3's d_c (x margin), or already pulled together at rest by the net force: the pair is inside
        # the d_c acl analyze reports (where the net force changes sign), which can lie beyond Eq. 3's
        live = ~ctx.fixed_pairs(tab)
        close = np.flatnonzero(live & ((tab.distance < margin * tab.critical_distance) | (tab.attraction > 0)))
        if close.size:
            close = close[_pushed_apart(ctx, drive, tab.a[close], tab.b[close])]
        if close.size:
            eq3 = tab.distance[close] < margin * tab.critical_distance[close]
            close = close[eq3 | (_closing_at_rest(ctx, drive, tab.a[close], tab.b[close]) > 0)]
        return [(tuple(sorted((tab.names[tab.a[k]], tab.names[tab.b[k]]))), tab.row(k)) for k in close.tolist()]
    key = ("snap", tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones), margin)
    return ctx.cached(key, compute)


def _mechanics_verdict(ctx: Context, drive, pf) -> bool | None:
    """True if the equilibrium under ``drive`` snaps in, False if it holds, None if unknown (or not asked)."""
    if not ctx.config.mechanics:
        return None
    try:
        from acl.analysis.acoustics import force_model_for
        from acl.analysis.mechanics import equilibrium
    except ImportError:
        ctx.note("ACL201", "mechanics analysis unavailable: Eq. 3 criterion only")
        return None
    from acl.diagnostics import DiagnosticError

    key = ("equilibrium", tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones))
    try:
        state = ctx.cached(key, lambda: equilibrium(ctx.design, drive, force_model_for(ctx.design)))
    except DiagnosticError as exc:
        ctx.note("ACL201", f"mechanism not analysable ({exc}): Eq. 3 criterion only")
        return None
    if state.status == "ok":
        return False
    return True if state.status == "snap_in" else None


def _sign_changes(ctx: Context, freqs: np.ndarray, significance: float) -> list:
    """[(a, b, peak |force| per V^2, attracting frequencies, repelling frequencies)] of the pairs whose
    Bjerknes force under 1 V single tones at ``freqs`` changes sign where it matters next to the pair's own
    thrust (|Bjerknes| >= significance x the larger thrust); pairs of fixed capsules left out.  Cached per
    frequency set; one frequency's pair table at a time (a design's (F, pairs) masks are not built)."""
    def compute():
        names = [c.name for c in ctx.design.capsules]
        thrust = ctx.analysis.thrust_per_v2(freqs)                     # (capsules, F), N at 1 V
        ia, ib = np.triu_indices(len(names), 1)                        # acl.analysis.acoustics.pair_table's rows
        vals_all = np.empty((freqs.size, ia.size))
        pos_any = np.zeros(ia.size, bool)
        neg_any = np.zeros(ia.size, bool)
        for j, f in enumerate(freqs.tolist()):
            vals = vals_all[j] = ctx.pair_attraction(Drive(tones=(Tone(frequency=f, amplitude=1.0),)))
            strong = np.abs(vals) >= significance * np.maximum(thrust[ia, j], thrust[ib, j])
            pos_any |= strong & (vals > 0)
            neg_any |= strong & (vals < 0)
        fixed = ctx.analysis.fixed()
        cand = np.flatnonzero(pos_any & neg_any & ~(fixed[ia] & fixed[ib]))
        vals_c = vals_all[:, cand]                                      # (F, K)
        strong_c = np.abs(vals_c) >= significance * np.maximum(thrust[ia[cand], :], thrust[ib[cand], :]).T
        pos_c, neg_c = strong_c & (vals_c > 0), strong_c & (vals_c < 0)
        return [(names[ia[k]], names[ib[k]], np.abs(vals_c[:, i]).max(),
                 [float(f) for f in freqs[pos_c[:, i]]], [float(f) for f in freqs[neg_c[:, i]]])
                for i, k in enumerate(cand.tolist())]
    return ctx.cached(("sign_changes", tuple(freqs.tolist()), significance), compute)


def program_range(ctx: Context, program) -> tuple[float, float] | None:
    fs = [f for st in program.steps for f in ctx.step_frequencies(st)]
    if not fs or max(fs) <= min(fs) * (1 + 1e-9):
        return None
    return min(fs), max(fs)


@rule("ACL202", "force-sign-change",
      "a pair that attracts at some program frequencies and repels at others reverses its motion "
      "inside the program; say so with a justified suppression if that is the intent",
      Severity.WARNING, "forces", ("sweep_samples", "force_significance"))
def force_sign_change(ctx: Context):
    if len(ctx.design.capsules) < 2:
        return
    significance = ctx.threshold("force_significance")
    for p in ctx.design.programs:
        rng = program_range(ctx, p)
        if rng is None:
            continue
        freqs = ctx.sweep_frequencies(*rng)
        if not freqs.size:
            continue
        for a, b, scale, pos, neg in _sign_changes(ctx, freqs, significance):
            if pos and neg:
                yield ctx.finding("ACL202",
                    f"`{a}` and `{b}` attract and repel within the {khz(rng[0])} .. {khz(rng[1])} range of program `{p.name}`",
                    p.span, notes=[
                        f"attract at {khz(min(pos))} .. {khz(max(pos))}; repel at {khz(min(neg))} .. {khz(max(neg))}",
                        f"{len(freqs)} frequencies sampled, 1 V single tones; peak |force| {scale * 1e9:.3g} nN/V^2",
                        f"counted where |Bjerknes| >= force_significance = {significance:g} x the larger thrust"],
                    hint="if the reversal is intended, write `# acl: ignore[ACL202] <why>` on the program's line")
