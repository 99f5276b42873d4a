"""Adapters from a resolved Design to the plain arrays the convex programs take.

This is the only module of acl.schedule that calls the analysis stage:

* :func:`model_gain_table` -- displacement per V^2 of a capsule vs frequency: the acoustic force per V^2
  on the body it belongs to (:func:`acl.analysis.acoustics.force_model`: thrust, the neighbours' Bjerknes
  force and jet drag, transducer transfer function included) where the capsules are when the drive
  starts, times the small-force compliance of what carries the capsule (beam: paper Eq. 1 as P -> 0;
  spring).  This is the exact linearisation of the static equilibrium at zero drive: every force is
  quadratic in the tone amplitudes, so a displacement changes the forces only at second order in V^2.
* :func:`model_forward` -- the nonlinear forward model used to re-simulate a schedule:
  :func:`acl.analysis.mechanics.equilibrium` (warm-started along the path) when that module
  exists, otherwise the thrust through the nonlinear beam law of paper Eq. (1);
  :func:`model_forward_many` -- the same for many designs at once (the nominal design and its band's draws: one
  batched solve per waypoint, :mod:`acl.analysis.equilibria`).
* :func:`latch_forces` -- force per V^2 of each tone along each latch's axis (the full
  :func:`acl.analysis.acoustics.force_model` at rest), and the latches' switching / release forces
  (``acl.physics.latch.latch_landscape``).
* :func:`state_positions` -- where the capsules are with the latches in given states (a latch's shuttle
  moved by its travel);
* :func:`latch_drive_forces` -- the force of a whole multi-tone drive along each latch's axis (the
  full force model: not quadratic in the amplitude when the design declares drive saturation).
* :func:`snap_in_voltages` -- per-tone snap-in (or gap-bound) voltage from
  ``acl.analysis.mechanics.sweep_voltage``.

Each returns numbers only; errors are ValueError with a message the caller turns into a diagnostic.
"""
from __future__ import annotations

import importlib
from typing import Callable

import numpy as np

from acl.design.model import Design, Drive, Tone
from acl.schedule.tones import GainTable

Forward = Callable[[np.ndarray], np.ndarray]      # u (N, K) V^2 -> displacement (N, 2) m


def _optional(module: str):
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError:
        return None


def default_frequencies(design: Design, step_hz: float = 500.0) -> np.ndarray:
    """Candidate tones: the transducer band (or 40-160 kHz as the paper's sweep) on a grid."""
    lo, hi = design.transducer.band if design.transducer else (40e3, 160e3)
    lo = max(lo, step_hz)
    return np.arange(np.ceil(lo / step_hz) * step_hz, hi + step_hz / 2, step_hz)


def _force_per_v2(design: Design, capsule: str, frequencies, positions=None) -> np.ndarray:
    """Acoustic force (N per V^2, 3-vector) on the body of ``capsule`` (it and the capsules trussed to it) for each
    tone alone at 1 V: thrust + Bjerknes + jet drag (paper Eqs. 2-3 via acl.analysis.acoustics.force_model), the
    capsules at rest or at ``positions`` (name -> centre, m; missing names at rest).  The Bjerknes forces inside the
    body cancel (equal and opposite); a neighbour's do not."""
    from acl.analysis import tones

    body = _rigidly_linked(design, [capsule])
    names = [c.name for c in design.capsules]
    per_tone = tones.tone_forces(design, np.asarray(frequencies, float), positions)      # (F, C, 3), one batch
    return np.sum([per_tone[:, names.index(c)] for c in body], axis=0).reshape(len(frequencies), 3)


def _carrier(design: Design, capsule: str):
    """(kind, element) of what carries ``capsule``: ("beam", Beam) | ("spring", Spring) | ..."""
    joint = design.mount_of(capsule)
    if joint is None or joint.kind == "fix":
        raise ValueError(f"capsule `{capsule}` is {'fixed' if joint else 'not mounted'}: it cannot follow a path")
    if joint.target_kind == "beam":
        return "beam", design.beam(joint.target)
    if joint.target_kind == "spring":
        return "spring", design.spring(joint.target)
    return "latch", design.latch(joint.target)


def _plane_projector(axis) -> np.ndarray:
    """(2, 3) projection onto the design x-y plane of the directions a carrier lets the capsule move."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    lateral = np.eye(3) - np.outer(a, a)          # a beam bends perpendicular to its axis
    return lateral[:2]


def compliance_matrix(design: Design, capsule: str) -> np.ndarray:
    """(2, 3) small-force compliance (m/N): planar displacement of the capsule per 3-D force."""
    kind, el = _carrier(design, capsule)
    if kind == "beam":
        from acl.physics.beams import eq1_small_force_stiffness

        k = eq1_small_force_stiffness(el.length, el.rigid_length, el.bending_stiffness)
        return _plane_projector(el.axis) / k
    a = np.asarray(el.axis, float)
    a = a / np.linalg.norm(a)
    k = el.stiffness if kind == "spring" else None
    if k is None:
        raise ValueError(f"capsule `{capsule}` rides a latch: use a switch step, not a path")
    return np.outer(a, a)[:2] / k


def model_gain_table(design: Design, capsule: str, frequencies=None, positions=None) -> GainTable:
    """Planar displacement per V^2 (m/V^2) of ``capsule`` vs frequency: the linearised static equilibrium at zero
    drive (acoustic force on its body x small-force compliance of its carrier, paper Eq. 1 as P -> 0), with the
    capsules at rest or at ``positions`` (e.g. :func:`state_positions` after a latch switch)."""
    f = default_frequencies(design) if frequencies is None else np.asarray(frequencies, float)
    force = _force_per_v2(design, capsule, f, positions)                  # (F, 3)
    gains = force @ compliance_matrix(design, capsule).T              # (F, 2)
    where = "at rest" if not positions else "where the latch states put the capsules"
    return GainTable(frequencies=f, gains=gains,
                     source=f"model (thrust + Bjerknes + jet drag {where}, x small-force compliance)")


def model_forward(design: Design, capsule: str, frequencies, start=None) -> tuple[Forward, str]:
    """The nonlinear forward model for ``capsule`` under tones at ``frequencies`` and its name.

    ``start``: capsule centres (name -> m) where the mechanism is when the drive begins (:func:`state_positions`: a
    latch switched earlier carries its capsules moved by its travel); None: at rest in the declared states.  Each
    waypoint's equilibrium is continued from the previous one, the first from ``start``; the displacement is the
    capsule's from its declared centre.  A bistable latch pushed over its switching force goes on from its other
    state; an equilibrium lost otherwise (a pair's snap-in) is NaN, and so is every later waypoint until one with no
    drive (the contact holds while a drive plays: no release model; silence releases it).
    """
    freqs = [float(f) for f in frequencies]
    mech = _optional("acl.analysis.mechanics")
    if mech is not None and hasattr(mech, "equilibrium"):
        def forward(u: np.ndarray) -> np.ndarray:
            got = model_forward_many([design], capsule, freqs, u, [start])[0]
            if isinstance(got, Exception):
                raise got
            return got

        return forward, "nonlinear equilibrium (acl.analysis.mechanics)"
    kind, el = _carrier(design, capsule)
    per_tone = _force_per_v2(design, capsule, freqs, start)           # (K, 3) N/V^2
    if kind == "beam":
        from acl.physics.beams import eq1_deflection

        proj = _plane_projector(el.axis)

        def forward(u: np.ndarray) -> np.ndarray:
            F = u @ per_tone                                          # (N, 3)
            Fp = F @ proj.T                                           # planar, perpendicular part
            mag = np.linalg.norm(Fp, axis=1)
            d = eq1_deflection(mag, el.length, el.rigid_length, el.bending_stiffness)
            unit = np.divide(Fp, mag[:, None], out=np.zeros_like(Fp), where=mag[:, None] > 0)
            return unit * np.asarray(d)[:, None]

        return forward, "nonlinear beam law, paper Eq. (1) (mechanics module absent)"
    C = compliance_matrix(design, capsule)
    return (lambda u: (u @ per_tone) @ C.T), "linear spring (mechanics module absent)"


def _waypoint(design: Design, drive: Drive, prev, start):
    """One waypoint of :func:`model_forward` solved alone: the equilibrium under ``drive`` warm-started from ``prev``
    (continued from rest when it is None or fails), else from ``start``, else on a bistable latch's switched branch."""
    from acl.analysis import acoustics, mechanics

    fm = acoustics.force_model_for(design)
    eq = mechanics.equilibrium(design, drive, fm, start=prev)
    if eq.status != "ok" and prev is not start:
        eq = mechanics.equilibrium(design, drive, fm, start=start)
    for flipped in (_flipped_latches(design, prev, drive) if eq.status != "ok" else ()):
        # the branch was lost because a bistable latch snapped through: the device goes on from its
        # other state (it stays there when the drive falls: hysteresis)
        again = settle_from(design, drive, flipped)
        if again is not None:
            return again
    return eq


def _gain_variant(base: Design, d: Design) -> bool:
    """Whether ``d`` is ``base`` with only its transducer gain table changed (a draw of bands.sample_designs without
    uncertain parameters): every other field the very same object, so the force engine of ``base`` with ``d``'s gains
    and thrust scales (tones.drive_factors) is ``d``'s."""
    if d is base:
        return True
    if type(d) is not type(base):
        return False
    for name in type(base).model_fields:
        if name != "transducer" and getattr(d, name) is not getattr(base, name):
            return False
    ta, tb = base.transducer, d.transducer
    if ta is None or tb is None:
        return ta is tb
    return all(getattr(ta, n) is getattr(tb, n) or getattr(ta, n) == getattr(tb, n)
               for n in type(ta).model_fields if n not in ("gain_frequencies", "gain_pa_per_v"))


def model_forward_many(designs, capsule: str, frequencies, u: np.ndarray, starts=None) -> list:
    """``model_forward(d, capsule, frequencies, start)(u)`` for every design ``d`` (with its ``start``) at once: the
    designs that differ only in their gain table (draws of a band) are one batch, solved waypoint by waypoint, each row
    warm-started from its own previous waypoint (acl.analysis.mechanics.equilibria); a row the batch does not settle is
    solved alone (:func:`_waypoint`), so every row follows the scalar model's branch.  Entries are (N, 2) arrays, or
    the exception (ValueError, KeyError, FloatingPointError) a design's model raised."""
    designs = list(designs)
    starts = [None] * len(designs) if starts is None else list(starts)
    u = np.asarray(u, float)
    freqs = [float(f) for f in frequencies]
    families: list = []
    for i, d in enumerate(designs):
        for base, idx in families:
            if _gain_variant(base, d):
                idx.append(i)
                break
        else:
            families.append((d, [i]))
    out: list = [None] * len(designs)
    for base, idx in families:
        try:
            preds = _forward_rows(base, [designs[i] for i in idx], capsule, freqs, u, [starts[i] for i in idx])
        except (ValueError, KeyError, FloatingPointError) as exc:
            if len(idx) == 1:
                preds = [exc]
            else:         # which design's model fails: each on its own (a failing draw fails alone, as in a loop)
                preds = [model_forward_many([designs[i]], capsule, freqs, u, [starts[i]])[0] for i in idx]
        for i, p in zip(idx, preds):
            out[i] = p
    return out


def model_forward_tones(designs, capsule: str, frequencies, u: np.ndarray, starts=None) -> list:
    """:func:`model_forward_many` of each tone alone, as one batch: ``u`` (K, N) V^2 of tone k at its N waypoints ->
    [[entry per design] per tone], entry k, i ``model_forward_many(designs, capsule, [frequencies[k]], u[k][:, None],
    starts)[i]``.  Every (tone, design) a row of one batched solve per waypoint (each row the same computation as in
    its tone's own batch: the single-tone engine, acl.analysis.tones.force_rows_one_tone); designs that are not all
    gain-table variants of the first are solved tone by tone."""
    designs = list(designs)
    starts = [None] * len(designs) if starts is None else list(starts)
    freqs = [float(f) for f in frequencies]
    u = np.asarray(u, float).reshape(len(freqs), -1)
    if not designs or not freqs or not all(_gain_variant(designs[0], d) for d in designs):
        return [model_forward_many(designs, capsule, [f], u[k][:, None], starts) for k, f in enumerate(freqs)]
    nd = len(designs)
    try:
        preds = _forward_rows(designs[0], designs * len(freqs), capsule, freqs, u, starts * len(freqs),
                              tone=np.repeat(np.arange(len(freqs)), nd))
    except (ValueError, KeyError, FloatingPointError):          # which rows fail: tone by tone, as a loop would
        return [model_forward_many(designs, capsule, [f], u[k][:, None], starts) for k, f in enumerate(freqs)]
    return [preds[k * nd:(k + 1) * nd] for k in range(len(freqs))]


def _forward_rows(base: Design, members: list, capsule: str, freqs: list, u: np.ndarray, starts: list,
                  tone=None) -> list:
    """:func:`model_forward_many` of one family of gain-table variants of ``base`` (rows: ``members``).  ``tone``
    (rows,): each row plays tone ``freqs[tone[j]]`` alone, at ``u[tone[j]]`` V^2 per waypoint (``u`` (K, N))
    (:func:`model_forward_tones`); else every row plays all tones at ``u`` (N, K)."""
    from acl.analysis import equilibria, tones

    names = [c.name for c in base.capsules]
    ci = names.index(capsule)
    nrow = len(members)
    one = tone is not None
    n = u.shape[1] if one else u.shape[0]
    factors = [tones.drive_factors(d, freqs) for d in members]
    gains = np.array([g for g, _ in factors], float).reshape(nrow, len(freqs))
    if one:
        gains = gains[np.arange(nrow), tone][:, None]            # each row's gain at its own tone
    scales = np.array([s for _, s in factors], float).reshape(nrow, len(names))
    # rows with the same drive factors and the same start are the same computation (a gain-table point that no tone
    # interpolates from moves nothing): each solved once
    owner = {}
    first = [owner.setdefault((gains[j].tobytes(), scales[j].tobytes(), id(starts[j]))
                              + ((int(tone[j]),) if one else ()), j) for j in range(nrow)]
    if len(owner) < nrow:
        uniq = sorted(owner.values())
        sub = dict(zip(uniq, _forward_rows(base, [members[j] for j in uniq], capsule, freqs, u,
                                           [starts[j] for j in uniq], None if not one else tone[uniq])))
        return [sub[first[j]].copy() for j in range(nrow)]
    if one:
        amps = np.sqrt(np.maximum(u[tone], 0.0))                 # (rows, N): each row's amplitude at its tone
        row_freq = [[freqs[t]] for t in tone]
    else:
        amps = np.sqrt(np.maximum(u, 0.0))
    out = np.full((nrow, n, 2), np.nan)
    prev = list(starts)                      # where each row's last waypoint left the capsules (dict), or its start
    from_start = [True] * nrow               # prev is the row's start (the scalar model's ``prev is start``)
    contact = np.zeros(nrow, bool)

    def as_dict(centres):
        return {nm: centres[k] for k, nm in enumerate(names)}

    rest = {c.name: np.asarray(c.center, float) for c in base.capsules}

    def as_array(pos):
        return np.array([np.asarray(pos.get(nm, rest[nm]), float) for nm in names])

    for i in range(n):
        driven = amps[:, i] > 0 if one else np.full(nrow, bool(np.any(u[i] > 0)))
        active = [j for j in range(nrow) if not (contact[j] and driven[j])]
        contact[active] = False          # silence releases a contact (no acoustic force: the beams pull apart)
        if not active:
            continue

        def rows_force(sel, a=None if one else amps[i], i=i):
            sel = np.asarray(sel)
            if one:
                return lambda c, r, s: tones.force_rows_one_tone(base, c, freqs, tone[sel[r]], amps[sel[r], i] * s,
                                                                 gains[sel[r], 0], scales[sel[r]])
            return lambda c, r, s: tones.force_batch_tones(base, c, freqs, np.broadcast_to(a * s, (r.size, a.size)),
                                                               gains[sel[r]], scales[sel[r]])

        settled = {}
        warm = [j for j in active if prev[j] is not None]
        cold = [j for j in active if prev[j] is None]
        if warm:
            res = equilibria.equilibria(base, rows_force(warm), np.array([as_array(prev[j]) for j in warm]))
            settled.update({j: (res.positions[k], res.displacements[k, ci, :2]) for k, j in enumerate(warm)
                            if res.found[k]})
        if cold:
            res = equilibria.equilibria_from_rest(base, rows_force(cold), len(cold))
            settled.update({j: (res.positions[k], res.displacements[k, ci, :2]) for k, j in enumerate(cold)
                            if res.found[k]})
        for j in active:
            if j in settled:
                pos, disp = settled[j]
                out[j, i] = disp
                prev[j], from_start[j] = as_dict(pos), False
                continue
            fj, aj = (row_freq[j], [amps[j, i]]) if one else (freqs, amps[i])
            drive = Drive(tones=tuple(Tone(frequency=f, amplitude=float(a)) for f, a in zip(fj, aj)))
            eq = _waypoint(members[j], drive, starts[j] if from_start[j] else prev[j], starts[j])
            if eq.status == "ok":
                out[j, i] = np.asarray(eq.displacements[capsule], float)[:2]
                prev[j], from_start[j] = eq.positions, False
            else:    # snapped in or lost: NaN, reported as such, until silence (the contact holds while a drive plays)
                prev[j], from_start[j], contact[j] = starts[j], True, True
    return [out[j] for j in range(nrow)]


def settle_from(design: Design, drive: Drive, start: dict, steps: int = 6):
    """The stable equilibrium under ``drive`` continued from the configuration ``start`` (capsule -> centre, m): the
    drive's power ramped in ``steps`` equal steps, each solve warm-started from the last (acl.analysis.mechanics
    .equilibrium).  None when the branch is lost on the way (a fold: a pair snaps in), or when a solve falls back to
    another branch (a bistable latch back in the state ``start`` does not put it in) -- the mechanism has no stable
    equilibrium near ``start`` under that drive."""
    from acl.analysis import acoustics, mechanics

    fm = acoustics.force_model_for(design)
    pos, eq = start, None
    for k in range(1, steps + 1):
        s = np.sqrt(k / steps)
        part = Drive(tones=tuple(t.model_copy(update={"amplitude": t.amplitude * s}) for t in drive.tones))
        eq = mechanics.equilibrium(design, part, fm, start=pos)
        if eq.status != "ok" or not eq.stable or not _latch_moved(design, start, eq.positions):
            return None
        pos = eq.positions
    return eq


def _latch_travels(design: Design):
    """[(latch, unit axis, carried capsules, travel a -> b m)] of the bistable latches (a finite release force)."""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    out = []
    for lt in design.latches:
        land = latch_landscape(*latch_geometry(lt, design))
        if land.state_b is None or land.release_force is None:
            continue
        axis, carried = latch_axis_carried(design, lt)
        if carried:
            out.append((lt, axis, carried, float(land.state_b)))
    return out


def _flipped_latches(design: Design, positions, drive: Drive) -> list[dict]:
    """Capsule centres with one bistable latch in its other state each (from ``positions``, or rest), for the latches
    that ``drive`` pushes over the force that switches them there (latch_landscape's switching / release force, the
    force model at ``positions``): the starts from which an equilibrium lost at a latch's snap-through is found again
    on its switched branch (a pair's snap-in, with no latch pushed over, gets none)."""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    base = {c.name: np.asarray(c.center, float) for c in design.capsules}
    if positions:
        base.update({k: np.asarray(v, float) for k, v in positions.items()})
    declared = {c.name: np.asarray(c.center, float) for c in design.capsules}
    push = latch_drive_forces(design, [(t.frequency, t.amplitude) for t in drive.tones], base)
    index = {lt.name: k for k, lt in enumerate(design.latches)}
    out = []
    for lt, axis, carried, travel in _latch_travels(design):
        off = float((base[carried[0]] - declared[carried[0]]) @ axis)
        in_b = (off > travel / 2) if lt.state == "a" else (off > -travel / 2)
        land = latch_landscape(*latch_geometry(lt, design))
        f = float(push[index[lt.name]])
        if not ((-f >= land.release_force) if in_b else (f >= land.switching_force)):
            continue
        move = -travel if in_b else travel
        pos = dict(base)
        for c in carried:
            pos[c] = base[c] + move * axis
        out.append(pos)
    return out


def _latch_moved(design: Design, start: dict, positions: dict) -> bool:
    """Whether the equilibrium ``positions`` found from ``start`` kept every bistable latch on the side ``start`` put it
    (within half its travel), i.e. the solve found the switched branch rather than falling back to rest."""
    for lt, axis, carried, travel in _latch_travels(design):
        c = carried[0]
        if abs(float((np.asarray(positions[c], float) - np.asarray(start[c], float)) @ axis)) > travel / 2:
            return False
    return True


def latch_forces(design: Design, frequencies, positions=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forces (L, K) N/V^2 along each latch axis, to_b (L,) N, to_a (L,) N) for the design's latches.

    The force on a latch is that on the capsules mounted on its shuttle and those trussed to them, with the capsules at
    rest or at ``positions`` (name -> centre, m; missing names at rest; e.g. :func:`state_positions`).  Thresholds come
    from the latch landscape (switching force a->b, release force b->a; a monostable latch gets inf).
    """
    from acl.analysis import tones
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    freqs = [float(f) for f in frequencies]
    L = len(design.latches)
    forces = np.zeros((L, len(freqs)))
    to_b, to_a = np.full(L, np.inf), np.full(L, np.inf)
    rest = {c.name: np.asarray(c.center, float) for c in design.capsules}
    if positions:
        rest.update({k: np.asarray(v, float) for k, v in positions.items()})
    names = [c.name for c in design.capsules]
    per_tone = tones.tone_forces(design, freqs, rest)                  # (K, C, 3), one batch
    for i, latch in enumerate(design.latches):
        axis, carried = latch_axis_carried(design, latch)
        for k in range(len(freqs)):
            forces[i, k] = sum(float(per_tone[k, names.index(c)] @ axis) for c in carried)
        land = latch_landscape(*latch_geometry(latch, design))
        to_b[i] = land.switching_force
        if land.release_force is not None:
            to_a[i] = land.release_force
    return forces, to_b, to_a


def state_positions(design: Design, states: dict) -> dict | None:
    """Capsule centres (name -> m) with each latch in the state ``states`` gives it ({latch: "a" | "b"}; missing
    latches in their declared state): the capsules a latch carries (:func:`latch_axis_carried`) moved along its axis by
    the travel between its states (acl.physics.latch.latch_landscape ``state_b``) where the state is not the declared
    one.  None when every latch is in its declared state (the capsules at rest)."""
    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    pos = None
    for lt in design.latches:
        want = states.get(lt.name, lt.state)
        if want == lt.state:
            continue
        land = latch_landscape(*latch_geometry(lt, design))
        if land.state_b is None:
            continue
        pos = pos or {c.name: np.asarray(c.center, float) for c in design.capsules}
        travel = float(land.state_b) * (1.0 if want == "b" else -1.0)
        axis, carried = latch_axis_carried(design, lt)
        for c in carried:
            pos[c] = pos[c] + travel * axis
    return pos


def latch_axis_carried(design: Design, latch):
    """(unit axis, capsules whose force moves the latch's shuttle: those mounted on it and those trussed to them)."""
    axis = np.asarray(latch.axis, float)
    carried = _rigidly_linked(design, [j.capsule for j in design.joints if j.kind == "mount"
                                        and j.target_kind == "latch" and j.target == latch.name])
    return axis / np.linalg.norm(axis), carried


def latch_drive_forces(design: Design, tones, positions=None) -> np.ndarray:
    """(L,) N: force of the whole drive ``tones`` ((Hz, V) pairs) along each latch's axis, at rest or with the
    capsules at ``positions`` (name -> centre, m; missing names at rest).

    The full force model (:func:`acl.analysis.acoustics.force_model`, tones adding in power, the
    design's declared effects, drive saturation included: then the force is not V^2 x the force at 1 V).
    """
    from acl.analysis import acoustics

    drive = Drive(tones=tuple(Tone(frequency=float(f), amplitude=float(v)) for f, v in tones if v > 0))
    out = np.zeros(len(design.latches))
    if not drive.tones:
        return out
    rest = {c.name: np.asarray(c.center, float) for c in design.capsules}
    if positions:
        rest.update({k: np.asarray(v, float) for k, v in positions.items()})
    fm = acoustics.force_model(design, rest, drive)
    for i, latch in enumerate(design.latches):
        axis, carried = latch_axis_carried(design, latch)
        out[i] = sum(float(np.asarray(fm.get(c, np.zeros(3)), float) @ axis) for c in carried)
    return out


def _rigidly_linked(design: Design, capsules: list[str]) -> list[str]:
    """The capsules plus every capsule joined to them through truss links (they move as one)."""
    group, frontier = set(capsules), list(capsules)
    while frontier:
        c = frontier.pop()
        for j in design.joints:
            if j.kind == "link" and j.element_kind == "truss" and c in (j.a, j.b):
                other = j.b if j.a == c else j.a
                if other not in group and other != "ground" and other in {x.name for x in design.capsules}:
                    group.add(other)
                    frontier.append(other)
    return sorted(group)


def snap_in_voltages(design: Design, a: str, b: str, frequencies, v_max: float,
                     bound: float | None = None) -> np.ndarray | None:
    """Per-tone critical voltage (V; inf if none up to ``v_max``), or None without a mechanics model.

    The critical voltage of a tone alone is its snap-in voltage (``mechanics.sweep_voltage``) or,
    when ``bound`` (m) is given, the voltage at which the gap between the capsules of orifices
    ``a`` and ``b`` (``capsule.orifice``) first falls to ``bound`` on the stable branch, if lower.
    Forces add in V^2, but their shapes along the gap differ per tone, so the snap index
    ``sum_k u_k / Vcrit_k^2`` of :mod:`acl.schedule.hold` is exact for one tone only: a multi-tone
    drive is re-simulated with :func:`critical_scale`.
    """
    mech = _optional("acl.analysis.mechanics")
    if mech is None or not hasattr(mech, "sweep_voltage"):
        return None
    return np.asarray([_critical_scale(mech, design, a, b, Drive(tones=(Tone(frequency=float(f), amplitude=1.0),)),
                                       v_max, bound) for f in frequencies])


def critical_scale(design: Design, a: str, b: str, tones, s_max: float,
                   bound: float | None = None) -> float | None:
    """Factor by which the drive ``tones`` ((frequency Hz, amplitude V) pairs) can be scaled before
    the pair snaps in (or the gap falls to ``bound``): inf if not up to ``s_max``; None without a
    mechanics model.  Re-simulates the whole multi-tone drive (``mechanics.sweep_voltage``), so it
    checks the margin of a hold/cross step without the superposition assumption of the snap index.
    """
    mech = _optional("acl.analysis.mechanics")
    if mech is None or not hasattr(mech, "sweep_voltage"):
        return None
    shape = Drive(tones=tuple(Tone(frequency=float(f), amplitude=float(v)) for f, v in tones if v > 0))
    if not shape.tones:
        return float("inf")
    return _critical_scale(mech, design, a, b, shape, s_max, bound)


def _critical_scale(mech, design: Design, a: str, b: str, shape: Drive, v_max: float,
                    bound: float | None) -> float:
    """Scale of ``shape`` at snap-in or where gap(a, b) first reaches ``bound``; inf if neither up to v_max."""
    from acl.analysis import acoustics

    ca, cb = a.split(".")[0], b.split(".")[0]
    sw = mech.sweep_voltage(design, shape, v_max, acoustics.force_model_for(design))
    v = np.inf if sw.snap_voltage is None else float(sw.snap_voltage)
    if sw.status not in ("ok", "snap_in"):
        # the branch was lost before v_max: nothing is known beyond its last stable point
        v = min(v, float(sw.voltage[-1]) if sw.voltage.size else 0.0)
    if bound is not None and sw.voltage.size > 1:
        gap = sw.gap(design, ca, cb)
        below = np.flatnonzero(gap <= bound)
        if below.size:
            i = int(below[0])
            if i == 0:
                v = 0.0
            else:     # interpolate the crossing between branch points i-1 and i
                g0, g1 = gap[i - 1], gap[i]
                w = (g0 - bound) / (g0 - g1) if g0 != g1 else 1.0
                v = min(v, float(sw.voltage[i - 1] + w * (sw.voltage[i] - sw.voltage[i - 1])))
    return v
