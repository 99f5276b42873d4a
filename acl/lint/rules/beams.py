"""ACL4xx: cantilevers under the program's loads: elastic strain and the small-deflection model.

The load is the acoustic force on the carried capsule at rest, perpendicular to the beam (paper
Eq. 1 with the rigid actuator length); a `follow` step instead prescribes the tip's path, so its
largest excursion is the deflection.  Strain is the bending strain at the clamp,
P (L + l) c / (E I), with c the half-thickness in the bending plane (its largest value).
"""
from __future__ import annotations

import numpy as np

from acl.diagnostics import Severity
from acl.lint.context import Context, khz, um
from acl.lint.registry import rule
from acl.physics.limits import clamp_strain, eq1_limit_ratio  # the laws, shared with the sweep (acl.sweep.checks)


def _carried(ctx: Context, beam) -> str | None:
    return next((j.capsule for j in ctx.design.joints if j.kind == "mount" and j.target == beam.name), None)


def _half_depth(beam) -> float:
    s = beam.section
    return s.diameter / 2 if s.shape == "circle" else min(s.width, s.thickness) / 2


def capsule_linked(ctx: Context, capsule: str) -> bool:
    """Whether a link (truss, spring) joins ``capsule``; a lint context keeps the set of linked capsules."""
    if not isinstance(ctx, Context):              # acl.sweep.checks asks with its own object
        return any(j.kind == "link" and capsule in (j.a, j.b) for j in ctx.design.joints)
    return capsule in ctx.cached("linked_capsules", lambda: {
        x for j in ctx.design.joints if j.kind == "link" for x in (j.a, j.b)})


def _equilibrium_load(ctx: Context, beam, cap: str, drive):
    """Tip deflection and load from the whole mechanism's equilibrium (links carry part of the load)."""
    from acl.analysis import acoustics, mechanics
    from acl.physics.beams import eq1_force

    state = mechanics.equilibrium(ctx.design, drive, acoustics.force_model)
    axis = np.asarray(beam.axis, float)
    d = np.asarray(state.displacements[cap], float)
    defl = float(np.linalg.norm(d - (d @ axis) * axis))
    return defl, float(eq1_force(defl, beam.length, beam.rigid_length, beam.bending_stiffness))


def beam_loads(ctx: Context, beam):
    """Worst load of each program on ``beam``: {program: (deflection m, strain, step, how)}; cached."""
    def compute():
        from acl.physics.beams import eq1_deflection, eq1_force

        cap = _carried(ctx, beam)
        out = {}
        if cap is None:
            return out
        linked = capsule_linked(ctx, cap)
        if linked and not ctx.config.mechanics:
            ctx.note("ACL401", f"beam `{beam.name}`: capsule `{cap}` is linked by a truss or spring, so the "
                     "free-cantilever load does not apply; not checked without --mechanics")
            return out
        L, l, EI = beam.length, beam.rigid_length, beam.bending_stiffness
        for p in ctx.design.programs:
            worst = None
            if linked:
                steps = list(enumerate(p.steps))
            else:         # the strongest drive step, over every free beam at once; then the `follow` paths
                steps = _program_follows(ctx, p).get(cap, [])
                top = _program_loads(ctx, p)
                bi = _free_beams(ctx)[0].index(beam.name)
                if top is not None and top[0][bi] > -np.inf:
                    P, i, k = float(top[0][bi]), int(top[1][bi]), int(top[2][bi])
                    st = p.steps[i]
                    worst = (float(eq1_deflection(P, L, l, EI)), P, st, f"drive {_tones(ctx.step_drives(st)[k])}", i)
            for i, st in steps:
                if st.kind == "follow":
                    if st.capsule != cap:
                        continue
                    ext = path_extent(st)
                    if ext is None:
                        continue
                    P = float(eq1_force(ext, L, l, EI))
                    cand = (ext, P, st, f"path of `follow` reaches {um(ext)} from rest", i)
                elif st.kind == "hold" and st.mode == "cross" and cap in (st.a.split(".")[0], st.b.split(".")[0]):
                    continue          # the pair ends in contact: the load at rest geometry does not apply
                else:          # linked: the mechanism's equilibrium (mechanics enabled)
                    cand = None
                    for drive in ctx.step_drives(st):
                        defl, P = _equilibrium_load(ctx, beam, cap, drive)
                        if cand is None or P > cand[1]:
                            cand = (defl, P, st, f"drive {_tones(drive)} (equilibrium of the linked mechanism)", i)
                    if cand is None:
                        continue
                # the first strongest step (in program order)
                if worst is None or cand[1] > worst[1] or (cand[1] == worst[1] and cand[4] < worst[4]):
                    worst = cand
            if worst is not None:
                defl, P, st, how, _ = worst
                strain = clamp_strain(P, L, l, _half_depth(beam), EI)
                out[p.name] = (defl, strain, P, st, how)
        return out
    return ctx.cached(("beam", beam.name), compute)


def _free_beams(ctx: Context):
    """(beam names, carried capsule index (B,), unit axes (B, 3)) of every beam that carries a capsule."""
    def compute():
        index = {c.name: i for i, c in enumerate(ctx.design.capsules)}
        rows = [(b.name, index[cap], np.asarray(b.axis, float)) for b in ctx.design.beams
                if (cap := _carried(ctx, b)) is not None]
        return ([r[0] for r in rows], np.array([r[1] for r in rows], int),
                np.array([r[2] for r in rows], float).reshape(-1, 3))
    return ctx.cached("free_beams", compute)


def _program_follows(ctx: Context, program) -> dict[str, list]:
    """{capsule: [(step index, step)]} of the `follow` steps of ``program``."""
    def compute():
        out: dict[str, list] = {}
        for i, st in enumerate(program.steps):
            if st.kind == "follow":
                out.setdefault(st.capsule, []).append((i, st))
        return out
    return ctx.cached(("follows", id(program)), compute)


def _program_loads(ctx: Context, program):
    """For every beam of :func:`_free_beams`, its strongest load at rest over the drive steps of ``program``
    (the first strongest step, and in it the first strongest drive): (load (B,) N or -inf, step index (B,),
    drive index (B,)); None when the program applies no drive.  A `cross` of a pair does not load its
    capsules' beams (the pair ends in contact)."""
    def compute():
        names, ci, _ = _free_beams(ctx)
        caps = [ctx.design.capsules[i].name for i in ci.tolist()]
        rows, where, ks = [], [], []
        for i, st in enumerate(program.steps):
            if st.kind == "follow":
                continue
            loads = _step_loads(ctx, st)
            if loads is None:
                continue
            P = np.array(loads[1], float)          # a copy: the cross mask below
            if st.kind == "hold" and st.mode == "cross":
                ends = (st.a.split(".")[0], st.b.split(".")[0])
                P[[c in ends for c in caps]] = -np.inf
            rows.append(P)
            where.append(i)
            ks.append(loads[0])
        if not rows:
            return None
        M = np.array(rows).reshape(len(rows), len(names))
        best = np.argmax(M, axis=0)                       # the first strongest step
        cols = np.arange(len(names))
        return M[best, cols], np.array(where)[best], np.array(ks).reshape(M.shape)[best, cols]
    return ctx.cached(("program_loads", id(program)), compute)


def _step_loads(ctx: Context, step):
    """For every beam of :func:`_free_beams`: (index of the first strongest drive (B,), its load
    perpendicular to the beam (B,) N, the drives), over the drives of ``step`` at rest; None without drives."""
    drives = ctx.step_drives(step)
    if not drives:
        return None

    def compute():          # per set of drives (steps with the same tones share it); forces not kept
        _, ci, axes = _free_beams(ctx)
        F = np.array([ctx.analysis.force_array(d)[ci] for d in drives]).reshape(len(drives), ci.size, 3)
        along = np.einsum("dbk,bk->db", F, axes)
        loads = np.linalg.norm(F - along[..., None] * axes, axis=-1)
        k = np.argmax(loads, axis=0)                      # the first strongest drive
        return k, loads[k, np.arange(k.size)]
    key = tuple(tuple((t.frequency, t.amplitude, t.phase) for t in d.tones) for d in drives)
    k, loads = ctx.cached(("step_loads", key), compute)
    return k, loads, drives


def _tones(drive) -> str:
    return " + ".join(f"{khz(t.frequency)} @ {t.amplitude:.3g} V" for t in drive.tones)


def path_extent(step) -> float | None:
    try:
        from acl.design.paths import sample_path

        pts = sample_path(step.path, 400).points
    except Exception:
        return None
    return float(np.max(np.linalg.norm(pts, axis=1))) if len(pts) else None


@rule("ACL401", "beam-strain",
      "bending strain beyond the material's elastic range deforms the beam for good",
      Severity.ERROR, "beams", ("strain_limit", "sweep_samples"))
def beam_strain(ctx: Context):
    limit = ctx.threshold("strain_limit")
    for beam in ctx.design.beams:
        for prog, (defl, strain, P, st, how) in beam_loads(ctx, beam).items():
            if strain > limit:
                yield ctx.finding("ACL401",
                    f"program `{prog}` strains beam `{beam.name}` to {strain:.1%} at the clamp, beyond the "
                    f"{limit:.0%} elastic limit", st.span, notes=[
                        f"{how}: tip load {P * 1e9:.3g} nN, tip deflection {um(defl)}",
                        f"strain = P (L + l) c / (E I), L = {um(beam.length)}, l = {um(beam.rigid_length)}, "
                        f"c = {um(_half_depth(beam))}, E = {beam.youngs_modulus / 1e6:.3g} MPa",
                        f"threshold strain_limit = {limit:g}"] + ([
                        f"the deflection is {defl / beam.length:.2g} L, far beyond the range of Eq. (1) (see ACL402): "
                        "the numbers are an extrapolation of the small-deflection model, not a prediction"]
                        if defl > 0.5 * beam.length else []),
                    hint="lower the drive, or use a longer or thinner beam")




# Eq. (1) holds to 5 % up to 0.21 L without a rigid part and further with one (acl.physics.beams):
# below this fraction of L no beam can be flagged at the default tolerance, so the elastica is skipped.
SAFE_RATIO = 0.2


@rule("ACL402", "beam-large-deflection",
      "beyond about 0.3 L (0.21-0.5 L with the actuator's rigid length) paper Eq. (1) no longer predicts the tip",
      Severity.WARNING, "beams", ("eq1_tolerance", "sweep_samples"))
def beam_large_deflection(ctx: Context):
    tol = ctx.threshold("eq1_tolerance")
    for beam in ctx.design.beams:
        for prog, (defl, strain, P, st, how) in beam_loads(ctx, beam).items():
            L = beam.length
            if tol >= 0.05 and defl < SAFE_RATIO * L:
                continue
            ratio = eq1_limit_ratio(round(beam.rigid_length / L, 2), tol)
            if defl > ratio * L:
                yield ctx.finding("ACL402",
                    f"program `{prog}` deflects beam `{beam.name}` by {um(defl)} = {defl / L:.2f} L, beyond the "
                    f"{ratio:.2f} L where paper Eq. (1) holds", st.span, notes=[
                        f"{how}: tip load {P * 1e9:.3g} nN",
                        f"Eq. (1) departs from the elastica by more than {tol:.0%} beyond {ratio:.2f} L "
                        f"(rigid length l = {beam.rigid_length / L:.2f} L; acl.physics.beams.eq1_validity_limit)"],
                    hint="keep deflections smaller, or analyse with the elastica (mode='large')")
