"""ACL2xx: secondary Bjerknes forces between bubble pairs (snap-in, sign changes over frequency)."""
from __future__ import annotations

import numpy as np

from acl.design.model import Drive, Tone
from acl.diagnostics import Severity
from acl.lint.context import Context, khz, um
from acl.lint.registry import rule


def _both_fixed(ctx: Context, a: str, b: str) -> bool:
    fixed = {j.capsule for j in ctx.design.joints if j.kind == "fix"}
    return a in fixed and b in fixed


def _pushed_apart(ctx: Context, drive, a: str, b: str) -> bool:
    """Eq. 3's premise: each capsule's own thrust pushes it away from the other."""
    from acl.analysis.acoustics import thrust_vectors

    thrust = ctx.cached(("thrust", tuple((t.frequency, t.amplitude) for t in drive.tones)),
                        lambda: thrust_vectors(ctx.design, drive))
    ca, cb = np.asarray(ctx.design.capsule(a).center), np.asarray(ctx.design.capsule(b).center)
    u = (cb - ca) / max(float(np.linalg.norm(cb - ca)), 1e-300)
    return float(thrust[a] @ -u) > 0 and float(thrust[b] @ u) > 0


def _managed(program) -> set[tuple[str, str]]:
    """Pairs whose gap a program governs itself: `hold gap(a, b) above ...` or `cross gap(a, b)`."""
    return {tuple(sorted((st.a.split(".")[0], st.b.split(".")[0])))
            for st in program.steps if st.kind == "hold"}


@rule("ACL201", "snap-in",
      "a bubble pair closer than its critical distance is pulled together by Bjerknes attraction (paper Eq. 3)",
      Severity.ERROR, "forces", ("snap_margin", "sweep_samples"))
def snap_in(ctx: Context):
    if len(ctx.design.capsules) < 2:
        return
    margin = ctx.threshold("snap_margin")
    for p in ctx.design.programs:
        crossing = _managed(p)
        flagged: dict[tuple[str, str], tuple] = {}      # pair -> (amplitude, step, drive, pair force)
        for st in p.steps:
            for drive in ctx.step_drives(st):
                amp = sum(t.amplitude for t in drive.tones)
                for pf in ctx.pair_forces(drive):
                    key = tuple(sorted((pf.a, pf.b)))
                    if key in crossing or _both_fixed(ctx, pf.a, pf.b):
                        continue
                    dc = pf.critical_distance
                    if dc is None or pf.distance >= margin * dc or not _pushed_apart(ctx, drive, pf.a, pf.b):
                        continue
                    if key not in flagged or amp > flagged[key][0]:
                        flagged[key] = (amp, st, drive, pf)
        for key, (amp, st, drive, pf) in sorted(flagged.items()):
            verdict = _mechanics_verdict(ctx, drive, pf)
            if verdict is False:
                ctx.note("ACL201", f"`{pf.a}`/`{pf.b}` in `{p.name}`: below d_c, but the structure holds them "
                                   f"at the strongest drive ({amp:.3g} V)")
                continue
            tones = " + ".join(f"{khz(t.frequency)} @ {t.amplitude:.3g} V" for t in drive.tones)
            yield ctx.finding("ACL201",
                f"`{pf.a}` and `{pf.b}` are {um(pf.distance)} apart, closer than their critical distance "
                f"{um(pf.critical_distance)}: program `{p.name}` snaps them together", st.span, notes=[
                    f"strongest drive {tones}",
                    f"Bjerknes attraction {pf.attraction * 1e9:.3g} nN at rest, phase difference "
                    f"{np.degrees(pf.phase_difference):.0f} deg",
                    f"d_c = sqrt(alpha / 2 gamma) (paper Eq. 3); threshold snap_margin = {margin:g}",
                    "quasi-static equilibrium at this drive: " + (
                        "snaps in (acl.analysis.mechanics)" if verdict else
                        "not computed (set `mechanics = true` in the configuration or pass --mechanics)")],
                hint="increase the gap, or use `cross gap(a, b)` if the program means to bring them together")


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
    from acl.analysis.acoustics import selectivity

    significance = ctx.threshold("force_significance")
    names = [c.name for c in ctx.design.capsules]
    for p in ctx.design.programs:
        rng = program_range(ctx, p)
        if rng is None:
            continue
        freqs = ctx.sweep_frequencies(*rng)
        thrust = selectivity(ctx.design, freqs).thrust_per_v2          # (capsules, F), N at 1 V
        att: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
        for k, f in enumerate(freqs):
            for pf in ctx.pair_forces(Drive(tones=(Tone(frequency=float(f), amplitude=1.0),))):
                push = max(thrust[names.index(pf.a), k], thrust[names.index(pf.b), k])
                att.setdefault((pf.a, pf.b), []).append((float(f), pf.attraction, push))
        for (a, b), rows in att.items():
            if _both_fixed(ctx, a, b):
                continue
            vals = np.array([v for _, v, _ in rows])
            scale = np.abs(vals).max()
            if scale == 0:
                continue
            # a sign only counts where the Bjerknes force matters next to the pair's own thrust
            strong = np.abs(vals) >= significance * np.array([t for _, _, t in rows])
            rows = [(f, v) for f, v, _ in rows]
            pos = [f for (f, v), s in zip(rows, strong) if s and v > 0]
            neg = [f for (f, v), s in zip(rows, strong) if s and v < 0]
            if pos and neg:
                yield ctx.finding("ACL202",
                    f"`{a}` and `{b}` attract and repel within the {khz(rng[0])} .. {khz(rng[1])} range of program `{p.name}`",
                    p.span, notes=[
                        f"attract at {khz(min(pos))} .. {khz(max(pos))}; repel at {khz(min(neg))} .. {khz(max(neg))}",
                        f"{len(freqs)} frequencies sampled, 1 V single tones; peak |force| {scale * 1e9:.3g} nN/V^2",
                        f"counted where |Bjerknes| >= force_significance = {significance:g} x the larger thrust"],
                    hint="if the reversal is intended, write `# acl: ignore[ACL202] <why>` on the program's line")
