"""ACL1xx: capsule resonances against the transducer, crosstalk between capsules, program tones."""
from __future__ import annotations

import numpy as np

from acl.diagnostics import Severity
from acl.lint.context import Context, khz
from acl.lint.registry import rule
from acl.physics.limits import modes_overlap
from acl.physics.ties import first_max, first_max_item


@rule("ACL101", "resonance-outside-band",
      "a capsule whose resonance lies outside the transducer band cannot be driven there",
      Severity.ERROR, "acoustics")
def resonance_outside_band(ctx: Context):
    t = ctx.design.transducer
    if t is None:
        ctx.note("ACL101", "no transducer declared: no band to check against")
        return
    lo, hi = t.band
    for cap in ctx.design.capsules:
        modes = ctx.modes(cap)
        outside = [m for m in modes if not lo <= m.frequency_hz <= hi]
        if not outside:
            continue
        if len(outside) == len(modes):
            msg = f"no resonance of capsule `{cap.name}` lies in the band of transducer `{t.name}`"
        else:
            names = ", ".join(f"{m.dominant_orifice} ({khz(m.frequency_hz)})" for m in outside)
            msg = f"capsule `{cap.name}`: mode(s) {names} outside the band of transducer `{t.name}`"
        yield ctx.finding("ACL101", msg, cap.span, notes=[
            f"band {khz(lo)} .. {khz(hi)}",
            *(f"mode of `{m.dominant_orifice}`: {khz(m.frequency_hz)}, Q = {m.q:.3g}" for m in modes)],
            hint="change the cavity volume or the orifice radius (Table S1), or use another transducer")


@rule("ACL102", "low-transducer-gain",
      "where the transducer's gain is low the capsule needs a higher voltage for the same thrust",
      Severity.WARNING, "acoustics", ("gain_ratio",))
def low_transducer_gain(ctx: Context):
    t = ctx.design.transducer
    if t is None:
        ctx.note("ACL102", "no transducer declared: gain assumed flat")
        return
    lo, hi = t.band
    grid = np.linspace(lo, hi, 400)
    best = float(ctx.gain(grid).max())
    if best <= 0:
        return
    ratio = ctx.threshold("gain_ratio")
    for cap in ctx.design.capsules:
        for m in ctx.modes(cap):
            if not lo <= m.frequency_hz <= hi:
                continue                      # ACL101's business
            g = float(ctx.gain([m.frequency_hz])[0])
            if g < ratio * best:
                yield ctx.finding("ACL102",
                    f"transducer `{t.name}` gives {g / best:.0%} of its best gain at the {khz(m.frequency_hz)} "
                    f"resonance of `{cap.name}.{m.dominant_orifice}`", cap.span, notes=[
                        f"gain {g:.4g} Pa/V at {khz(m.frequency_hz)}; best in band {best:.4g} Pa/V",
                        f"thrust scales with gain^2: {(g / best) ** 2:.2g} of the best",
                        f"threshold gain_ratio = {ratio:g}"],
                    hint="tune the capsule to a stronger part of the transducer response")


def separate_pairs(ctx: Context) -> dict[tuple[str, str], str]:
    """Pairs of capsules meant to be driven separately, with the reason.

    A pair is meant to be driven separately when a `require separation(a, b)` names it, or when
    either capsule is addressed on its own by a program (`follow`, or a `hold`/`switch` acting on
    it).  Capsules of a design that never addresses one of them alone are a group driven together.
    """
    d = ctx.design
    names = [c.name for c in d.capsules]
    out: dict[tuple[str, str], str] = {}
    for r in d.requires:
        if r.kind == "separation" and len(r.args) == 2 and r.args[0] != r.args[1]:
            out[tuple(sorted(r.args))] = f"`{r.text}`"
    alone: dict[str, str] = {}
    for p, st in ctx.steps():
        if st.kind == "follow":
            alone.setdefault(st.capsule, f"program `{p.name}` follows `{st.capsule}` alone")
    for a in alone:
        moving = set(ctx.tied([a]))              # a capsule trussed to the followed one moves with it
        for b in names:
            if b not in moving:
                out.setdefault(tuple(sorted((a, b))), alone[a])
    return out


@rule("ACL103", "mode-crosstalk",
      "capsules meant to be driven separately whose modes overlap within their bandwidths cannot be addressed alone",
      Severity.WARNING, "acoustics", ("bandwidth_overlap",))
def mode_crosstalk(ctx: Context):
    k = ctx.threshold("bandwidth_overlap")
    for (a, b), why in sorted(separate_pairs(ctx).items()):
        ca, cb = ctx.design.capsule(a), ctx.design.capsule(b)
        for ma in ctx.modes(ca):
            for mb in ctx.modes(cb):
                f1, f2 = ma.frequency_hz, mb.frequency_hz
                overlap, limit = modes_overlap(f1, ma.q, f2, mb.q, k)
                if overlap:
                    yield ctx.finding("ACL103",
                        f"modes of `{a}.{ma.dominant_orifice}` ({khz(f1)}) and `{b}.{mb.dominant_orifice}` "
                        f"({khz(f2)}) overlap within their bandwidths", cb.span, notes=[
                            f"|f1 - f2| = {khz(abs(f1 - f2))} < {k:g} x (f1/Q1 + f2/Q2)/2 = {khz(float(limit))}"
                            f" (Q1 = {ma.q:.3g}, Q2 = {mb.q:.3g})",
                            f"driven separately because {why}"],
                        hint="separate the resonances: change one capsule's volume or orifice radius")


def _intended(ctx: Context, step, rel: np.ndarray, freqs) -> list[set[str]]:
    """Capsules each tone of a step is meant to drive."""
    names = [c.name for c in ctx.design.capsules]
    if step.kind == "follow":                  # with the capsules trussed to it: they move together
        moving = set(ctx.tied([step.capsule]))
        return [moving for _ in freqs]
    if step.kind == "hold":
        held = set(ctx.tied([step.a.split(".")[0], step.b.split(".")[0]]))
        return [held for _ in freqs]
    if step.kind == "switch":
        on = set(ctx.carried(step.latch))
        return [on for _ in freqs]
    out = []
    for j, f in enumerate(freqs):
        inband = ctx.analysis.in_band(f)
        out.append(inband or {names[first_max(rel[:, j])]})
    return out


@rule("ACL104", "unintended-excitation",
      "a program tone that drives a capsule it is not meant for moves that capsule too",
      Severity.WARNING, "acoustics", ("crosstalk_ratio",))
def unintended_excitation(ctx: Context):
    if len(ctx.design.capsules) < 2:
        return
    ratio = ctx.threshold("crosstalk_ratio")
    names = [c.name for c in ctx.design.capsules]
    index = {n: i for i, n in enumerate(names)}
    for p, st in ctx.steps():
        if st.kind not in ("drive", "follow", "hold", "switch"):
            continue                              # a sweep excites everything on purpose
        freqs = ctx.step_frequencies(st)
        if not freqs:
            continue
        rel = ctx.relative_thrust(freqs)
        intended = _intended(ctx, st, rel, freqs)
        for j, f in enumerate(freqs):
            for i in np.flatnonzero(rel[:, j] > ratio).tolist():     # capsule order, as the message list
                name = names[i]
                if name in intended[j]:
                    continue
                shown = sorted(index[n] for n in intended[j] | {name} if n in index)
                yield ctx.finding("ACL104",
                    f"the {khz(f)} tone of program `{p.name}` drives `{name}` at {rel[i, j]:.0%} of its peak thrust "
                    f"(meant for {', '.join(f'`{n}`' for n in sorted(intended[j]))})", st.span, notes=[
                        f"threshold crosstalk_ratio = {ratio:g} (thrust relative to the capsule's own peak)",
                        *(_modes_note(ctx, names[c]) for c in shown)],
                    hint="move the tone or the capsule's resonance apart, or accept it with a justified suppression")


def _modes_note(ctx: Context, name: str) -> str:
    return ctx.cached(("modes_note", name), lambda: f"`{name}` modes: " + ", ".join(
        f"{khz(m.frequency_hz)} (Q {m.q:.3g})" for m in ctx.modes(name)))


@rule("ACL105", "bubble-beyond-linear",
      "a drive that moves an interface beyond the linear regime makes every predicted force untrustworthy",
      Severity.WARNING, "acoustics", ("linear_amplitude", "sweep_samples"))
def bubble_beyond_linear(ctx: Context):
    from acl.analysis.acoustics import interface_labels
    from acl.design.model import Drive, Tone

    limit = ctx.threshold("linear_amplitude")
    n = int(ctx.threshold("sweep_samples"))
    labels = interface_labels(ctx.design)
    for p, st in ctx.steps():
        if st.kind == "drive":
            amps = ctx.analysis.interface_amplitudes(st.drive)
            k, v = first_max_item(amps)                      # ties: the first declared (acl.physics.ties)
            worst, where, at = (v, k, st.drive) if v > 0.0 else (0.0, "", None)
        elif st.kind == "sweep":        # every sampled tone in one coupled solve
            freqs = np.linspace(st.f_start, st.f_stop, n)
            eps = ctx.analysis.sweep_interface_amplitudes(freqs, st.amplitude)    # (F, interfaces)
            worst, where, at = 0.0, "", None
            if eps.size:
                j, i = np.unravel_index(first_max(eps.reshape(-1)), eps.shape)   # the first largest (ties: acl.physics.ties)
                if eps[j, i] > 0.0:
                    worst, where = float(eps[j, i]), labels[i]
                    at = Drive(tones=(Tone(frequency=float(freqs[j]), amplitude=st.amplitude),))
        else:
            continue                      # the compiler decides those amplitudes and refuses them itself
        if worst > limit:
            f = at.tones[0].frequency if at and at.tones else 0.0
            yield ctx.finding("ACL105",
                f"program `{p.name}` drives interface `{where}` to eps/R = {worst:.6g} (at {khz(f)}), beyond the "
                f"linear bubble model", st.span, notes=[
                    f"threshold linear_amplitude = {limit:g} (centre amplitude / orifice radius; docs/physics.md)",
                    "amplitude per volt from the coupled bubble model and the transducer gain table"],
                hint="lower the voltage or move the tone off resonance (`acl compile` warns and widens its band; past the hemisphere, eps/R > 1, it refuses without --allow-nonlinear)")
