"""ACL3xx: bistable latches (paper Fig. 6) against the forces of each program step.

Forces are the acoustic forces on the capsule carried by the latch shuttle, at rest, projected on
the latch's actuation axis (quasi-static: the capsule moves little before the latch snaps).  The
switching and release forces are those of :func:`acl.physics.latch.latch_landscape`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from acl.design.model import Drive, Tone
from acl.diagnostics import Severity
from acl.lint.context import Context, Unavailable, khz
from acl.lint.registry import rule


def landscape(ctx: Context, latch):
    """The latch's energy landscape, shared by every design with the same latch geometry."""
    return _landscape(latch.angle, latch.length, latch.width, latch.thickness, latch.youngs_modulus)


@lru_cache(maxsize=256)
def _landscape(angle: float, length: float, width: float, thickness: float, youngs: float):
    try:
        from acl.physics.latch import latch_landscape
    except ImportError as exc:  # pragma: no cover - physics module missing
        raise Unavailable(f"latch physics unavailable ({exc})") from None
    return latch_landscape(angle, length, width, thickness, youngs)


def _carried(ctx: Context, latch) -> list[str]:
    return ctx.carried(latch.name)


def _push(ctx: Context, latch, drive: Drive, state: str) -> float:
    """Force (N) pushing the shuttle out of ``state`` (towards the other one)."""
    axis = np.asarray(latch.axis, float)
    total = sum(float(np.asarray(ctx.forces(drive)[c]) @ axis) for c in _carried(ctx, latch))
    return total if state == "a" else -total


def _needed(land, state: str) -> float | None:
    return land.switching_force if state == "a" else land.release_force


@rule("ACL301", "latch-unintended-switch",
      "a program step whose force on a latch approaches its switching force may flip it when it should hold",
      Severity.ERROR, "latches", ("latch_hold_factor", "sweep_samples"))
def latch_unintended_switch(ctx: Context):
    factor = ctx.threshold("latch_hold_factor")
    for latch in ctx.design.latches:
        if not _carried(ctx, latch):
            continue
        land = landscape(ctx, latch)
        for p in ctx.design.programs:
            state = latch.state
            for st in p.steps:
                if st.kind == "switch" and st.latch == latch.name:
                    state = st.state
                    continue
                needed = _needed(land, state)
                if needed is None or needed <= 0:
                    continue
                worst, worst_drive = 0.0, None
                for drive in ctx.step_drives(st):
                    push = _push(ctx, latch, drive, state)
                    if push > worst:
                        worst, worst_drive = push, drive
                if worst_drive is None or worst * factor < needed:
                    continue
                tones = " + ".join(f"{khz(t.frequency)} @ {t.amplitude:.3g} V" for t in worst_drive.tones)
                verdict = "switches" if worst >= needed else "nearly switches"
                yield ctx.finding("ACL301",
                    f"a step of program `{p.name}` {verdict} latch `{latch.name}` out of state {state} "
                    f"({worst * 1e9:.3g} nN of the {needed * 1e9:.3g} nN needed)", st.span, notes=[
                        f"drive {tones}",
                        f"threshold latch_hold_factor = {factor:g}: push x factor >= needed",
                        "quasi-static force on the carried capsule at rest, along the latch axis"],
                    hint="lower this step's voltage or move its tones off the latch capsule's resonance")
                break


@rule("ACL302", "latch-switch-margin",
      "an intended latch switch whose available force is below the required margin may fail in the device",
      Severity.ERROR, "latches", ("sweep_samples",))
def latch_switch_margin(ctx: Context):
    for p in ctx.design.programs:
        states = {l.name: l.state for l in ctx.design.latches}
        for st in p.steps:
            if st.kind != "switch":
                continue
            latch = ctx.design.latch(st.latch)
            state = states[latch.name]
            states[latch.name] = st.state
            if state == st.state:
                continue
            caps = _carried(ctx, latch)
            if not caps:
                yield ctx.finding("ACL302", f"latch `{latch.name}` carries no capsule: nothing can switch it", st.span,
                                  hint=f"mount a capsule on `{latch.name}.shuttle`")
                continue
            land = landscape(ctx, latch)
            needed = _needed(land, state)
            if not land.bistable or needed is None:
                yield ctx.finding("ACL302", f"latch `{latch.name}` is not bistable: it cannot hold state {st.state}",
                                  latch.span, notes=[f"angle {np.degrees(latch.angle):.3g} deg, L/w = "
                                                     f"{latch.length / latch.width:.3g}"],
                                  hint="increase the beam angle or slenderness (Jiang et al. 2019)")
                continue
            avail, how = available_force(ctx, latch, st, state)
            if avail is None:
                ctx.note("ACL302", f"switch of `{latch.name}` in `{p.name}`: no voltage limit known")
                continue
            margin = avail / needed if needed > 0 else float("inf")
            if margin < st.margin:
                yield ctx.finding("ACL302",
                    f"switching latch `{latch.name}` to state {st.state} has margin {margin:.2f}, under the "
                    f"required {st.margin:g}", st.span, notes=[
                        f"needed {needed * 1e9:.3g} nN; best available {avail * 1e9:.3g} nN ({how})"],
                    hint="raise the limit, tune the carried capsule, or make the latch easier to switch")


def available_force(ctx: Context, latch, step, state: str) -> tuple[float | None, str]:
    """Largest push out of ``state`` a switch step can apply: pinned tones, else each carried mode, at the limit."""
    v = ctx.max_voltage(step)
    if v is None:
        return None, ""
    if step.tones:
        freqs = list(step.tones)
    else:
        freqs = [m.frequency_hz for c in _carried(ctx, latch) for m in ctx.modes(ctx.design.capsule(c))]
    best, best_f = 0.0, None
    for f in freqs:
        push = _push(ctx, latch, Drive(tones=(Tone(frequency=f, amplitude=v),)), state)
        if push > best:
            best, best_f = push, f
    how = f"{khz(best_f)} @ {v:.3g} V" if best_f else f"no tone pushes the right way at {v:.3g} V"
    return best, how
