"""Forward model of a group (acl.fit.mechanism ``Unit("group")``): interacting capsules on their own supports, bodies
of several orifices or of several capsules tied by trusses, latches among them; and a body moving alone.

Each **node** is a rigid body on one support (acl.fit.mechanism.rigid_body, the rules of acl.analysis.mechanics): a
cantilever moves across its axis by paper Eq. (1) (isotropic in that plane, less the directions trusses to fixed
points hold), a spring along its axis by P/k, a latch along its axis by its rising branches from state a
(acl.physics.latch), a fixed node not at all.  Every **orifice** is its own bubble.  Per row, with tones adding in
power, the force terms of acl.analysis.acoustics.force_model, with each orifice's volume response held at its value
at rest (coupled through the liquid, transducer table, declared thrust):

* own thrust gamma tau_o(f) V^2 of orifice o along -n_o (tau_o its share per V^2 relative to the reference capsule);
* secondary Bjerknes force between every two orifices of different capsules, alpha a_ij(f) V^2 / d_ij^2 along the
  line of their current centres (paper Eq. (3); a_ij = the analysis' attraction x d^2 at rest, relative to the
  reference pair);
* the laminar round jet of every orifice dragging every other capsule (acl.physics.forces.jet_drag, Schlichting),
  at the current distance and angle, as the analysis does.

Each capsule's load is the sum over its orifices and the terms it feels; a node's load is the sum over its capsules,
projected on the directions it can move along.  The equilibrium z = D(z) (z the nodes' coordinates, D their
deflection laws at the loads of z) is solved by Newton with a finite-difference Jacobian, all rows at once, first at
full load from the last solution found for the row, and where that fails by continuation from rest in ``N_STEPS``
load steps; a step without a stable equilibrium (no convergence, the Jacobian of z - D(z) loses its positive
determinant, two orifices of different nodes within 2 % of their rest distance) is a snap-in: the two orifices
closest to touching meet halfway (all the way when one node is fixed) and the rest of the group is solved around
them.  A node alone (a body) feels loads that do not depend on where it is: one evaluation, no Newton.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.fit import beam as B
from acl.fit.effects import GAP_REF
from acl.physics.effects import drag_load, elastica_blend, mode_response_ratio, substrate_factor
from acl.physics.forces import capsule_forces

N_STEPS = 8
N_NEWTON = 12
N_CHORD = 6           # chord steps at most (each must halve the residual) before Newton takes over
STALL = 3          # Newton iterations without halving a row's residual after which it has no equilibrium near its start
LAW = {"beam": 0, "spring": 1, "fixed": 2, "latch": 3}


@dataclass
class GroupBlock:
    """The rows of one group (or body) in one override set, with everything row-independent precomputed."""

    rows: np.ndarray          # (r,) row indices into the data set
    caps: tuple               # C capsule names
    law: np.ndarray           # (N,) node law: 0 beam, 1 spring, 2 fixed, 3 latch
    L: np.ndarray             # (N,)
    l: np.ndarray
    EI: np.ndarray
    cd: np.ndarray            # spring: compliance
    basis: np.ndarray         # (N, 3, 2) directions each node allows (zero-padded)
    k: np.ndarray             # (N,) how many
    latch: list               # (N,) latch table of each latch node (acl.fit.latch.latch_table), else None
    latch_geo: list           # (N,) its geometry (angle, length, width, thickness, E), else None
    cap_node: np.ndarray      # (C,) node of each capsule
    rest: np.ndarray          # (C, 3) capsule centres at rest
    outer: np.ndarray         # (C,) radius a jet drags
    cap_height: np.ndarray    # (C,) first orifice's height (substrate_proximity, as the analysis)
    orif_cap: np.ndarray      # (n,) capsule of each orifice
    offsets: np.ndarray       # (n, 3)
    normals: np.ndarray       # (n, 3) outward normals (the jets)
    labels: tuple             # n "capsule.orifice"
    tau: np.ndarray           # (r, T, n) thrust per V^2 of each orifice relative to gamma0
    arel: np.ndarray          # (r, T, n, n) Bjerknes coefficient per V^2 relative to the reference pair at f_ref
    fn: np.ndarray            # (n,) natural frequency of the mode each orifice dominates (Hz)
    q: np.ndarray             # (n,)
    tables: list              # per orifice (ln V/V0, ln f/f0) of its mode (bubble shrinkage)
    kind: np.ndarray          # (r,) observable kind: 0 gap, 1 displacement, 2 position, 3 latch state
    oi: np.ndarray            # (r,) gap: orifice a; else the capsule observed
    oj: np.ndarray            # (r,) gap: orifice b
    axis: np.ndarray          # (r, 3) displacement axis / position unit vector
    obase: np.ndarray         # (r,) position: rest coordinate
    neighboured: np.ndarray = None  # (N,) bool: neighbour_drag acts on the node (acl.fit.mechanism.Network)
    springs: list = None      # (N,) per node: ((stiffness, unit axis), ...) of springs tying it to fixed points
    engines: list = None      # [acl.analysis.acoustics force engine of every drive frequency of the rows at 1 V]
    fidx: np.ndarray = None   # (r, T) index of each tone's frequency in that engine (-1: no tone)
    orif_ix: np.ndarray = None    # (n,) each orifice's interface index in the design (acl.analysis.acoustics layout)
    cap_ix: np.ndarray = None     # (C,) each capsule's index in the design
    all_rest: np.ndarray = None   # (C_all, 3) every capsule centre of the design at rest
    gamma0: float = 1.0
    alpha_ref: float = 0.0
    gmask: np.ndarray = None  # (n,) bool: gamma scales this orifice's thrust (acl.fit.forward.Prepared.gamma_caps)
    cache: np.ndarray = None  # (r, m) last equilibrium found per row (warm start of the next evaluation)
    closing: np.ndarray = None    # (r, 2) the orifice pair in contact of each row past snap-in at the last evaluation
    fold: tuple = None            # ((r,) last stable continuation step of the rows that snapped, (r, m) configuration)
    member: np.ndarray = None     # (r,) stacked blocks (:func:`stack`): the override set of each row, indexing the
    eoff: np.ndarray = None       # leading axis of rest, offsets, all_rest and eoff (M, ., 3); None: one set

    def contact_rows(self):
        return self.closing[:, 0] >= 0 if self.closing is not None else np.zeros(self.rows.size, bool)

    @property
    def points(self) -> np.ndarray:
        """(n, 3) orifice centres at rest ((M, n, 3) of a stack)."""
        return self.rest[..., self.orif_cap, :] + self.offsets

    @property
    def orif_node(self) -> np.ndarray:
        return self.cap_node[self.orif_cap]


def block(inst, unit, name, rows, f, v, gamma0, alpha_ref, ftable) -> GroupBlock:
    """Precompute a group's rows (``name`` the observable; ``ftable(volume, radii, mode, medium)`` the table of the
    natural frequency of a capsule's mode against its gas volume, for bubble shrinkage)."""
    from acl.fit.latch import latch_table
    from acl.fit.mechanism import _target_capsule, orifice_forces_per_v2

    net = unit.net
    sides = unit.sides
    N = len(sides)
    r, T = len(rows), f.shape[1]
    basis = np.zeros((N, 3, 2))
    k = np.zeros(N, int)
    law = np.array([LAW[s.law] for s in sides])
    for i, s in enumerate(sides):
        k[i] = s.basis.shape[1] if s.law != "fixed" else 0
        basis[i, :, :k[i]] = s.basis[:, :k[i]]
    cd = np.zeros(N)
    for i, s in enumerate(sides):
        if s.law == "beam":
            cd[i] = B.stiffness_integrals(np.array([s.L]), np.array([s.l]), np.array([s.EI]))[0][0]
        elif s.law == "spring":
            cd[i] = s.compliance
    latch = [latch_table(s.latch) if s.law == "latch" else None for s in sides]
    latch_geo = [s.latch if s.law == "latch" else None for s in sides]
    n = len(net.labels)
    tau = np.zeros((r, T, n))
    arel = np.zeros((r, T, n, n))
    fr, vr = f[rows], v[rows]
    for fk in np.unique(fr[vr > 0]):
        m = (fr == fk) & (vr > 0)
        labels, thr, att = orifice_forces_per_v2(inst, fk)
        ix = np.array([labels.index(lab) for lab in net.labels])
        tau += m[:, :, None] * (thr[ix] / gamma0)[None, None, :]
        if alpha_ref:
            arel += m[:, :, None, None] * (att[np.ix_(ix, ix)] / alpha_ref)[None, None]
    obs = inst.design.observe(name)
    kind = np.zeros(r, int)
    oi = np.zeros(r, int)
    oj = np.zeros(r, int)
    axis = np.zeros((r, 3))
    obase = np.zeros(r)
    if obs.kind == "gap":
        oi[:], oj[:] = net.labels.index(obs.a), net.labels.index(obs.b)
    else:
        cap = _target_capsule(inst.design, obs)
        oi[:] = net.caps.index(cap)
        if obs.kind == "state":
            kind[:] = 3
        elif obs.kind == "displacement":
            kind[:] = 1
            axis[:] = np.asarray(obs.axis, float) / np.linalg.norm(obs.axis)
        else:
            kind[:] = 2
            c = "xyz".index(obs.component)
            axis[:, c] = 1.0
            obase[:] = float(net.rest[oi[0], c])
    med = inst.medium
    tables = []
    for o in range(n):
        volume, radii, modes = net.bubbles[net.orif_cap[o]]
        first = int(np.flatnonzero(net.orif_cap == net.orif_cap[o])[0])
        tables.append(ftable(volume, radii, modes[o - first], med))
    height = np.array([net.offsets[np.flatnonzero(net.orif_cap == c)[0], 2] + net.rest[c, 2]
                       if np.any(net.orif_cap == c) else net.rest[c, 2] for c in range(len(net.caps))])
    from acl.analysis.rows import force_engine, layout
    from acl.design.model import Drive, Tone

    freqs = np.unique(fr[vr > 0])
    fidx = np.full((r, T), -1)
    for i, fk in enumerate(freqs):
        fidx[(fr == fk) & (vr > 0)] = i
    engines = []
    if freqs.size:                # one force engine of every drive frequency of the rows at 1 V (per-tone responses)
        key = ("eng", tuple(float(x) for x in freqs))
        if key not in inst._tau:
            inst._tau[key] = force_engine(inst.design, Drive(tones=tuple(Tone(frequency=float(x), amplitude=1.0)
                                                                           for x in freqs)), cached=False)
        engines.append(inst._tau[key])
    lay = layout(inst.design)
    names = [c.name for c in lay.caps]
    extra = dict(engines=engines, fidx=fidx, orif_ix=np.array([lay.labels.index(lab) for lab in net.labels]),
                 cap_ix=np.array([names.index(c) for c in net.caps]), all_rest=np.asarray(lay.rest, float),
                 gamma0=float(gamma0), alpha_ref=float(alpha_ref), springs=[tuple(s.springs) for s in sides],
                 neighboured=None if net.neighboured is None else np.asarray(net.neighboured, bool))
    return GroupBlock(np.asarray(rows), net.caps, law, np.array([s.L for s in sides]), np.array([s.l for s in sides]),
                      np.array([s.EI for s in sides]), cd, basis, k, latch, latch_geo, np.asarray(net.cap_node, int),
                      np.asarray(net.rest, float), np.asarray(net.outer, float), height,
                      np.asarray(net.orif_cap, int), np.asarray(net.offsets, float), np.asarray(net.normals, float),
                      tuple(net.labels), tau, arel, net.modes[:, 0].copy(), net.modes[:, 1].copy(), tables,
                      kind, oi, oj, axis, obase, **extra)


# what must be equal for two blocks to share one batched solve (the rest geometry may differ)
_SHARED = ("caps", "law", "L", "l", "EI", "cd", "basis", "k", "cap_node", "outer", "cap_height", "orif_cap", "normals",
           "labels", "fn", "q", "neighboured", "orif_ix", "cap_ix", "gamma0", "alpha_ref", "gmask")


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is b
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    return a == b


def _shares_engine(a: GroupBlock, b: GroupBlock) -> bool:
    """The two blocks' force engines give the same forces at the same positions (same capsules, tones, constants)."""
    if len(a.engines) != len(b.engines):
        return False
    for ea, eb in zip(a.engines, b.engines):
        if ea is eb:
            continue
        if not (_same(ea.f, eb.f) and _same(ea.lay.body, eb.lay.body) and _same(ea.lay.radii, eb.lay.radii)
                and _same(ea.h0, eb.h0) and _same(ea.pressure, eb.pressure) and ea.rho == eb.rho and ea.c == eb.c
                and ea.consts.keys() == eb.consts.keys()
                and all(_same(np.asarray(ea.consts[k]), np.asarray(eb.consts[k])) for k in ea.consts)
                and _same(np.asarray(ea.system.radii), np.asarray(eb.system.radii))):
            return False
    return True


def _stackable(a: GroupBlock, b: GroupBlock) -> bool:
    if a.member is not None or b.member is not None or np.any(a.law == LAW["latch"]) or np.any(b.law == LAW["latch"]):
        return False
    if a.rest.shape != b.rest.shape or a.offsets.shape != b.offsets.shape or a.all_rest.shape != b.all_rest.shape:
        return False
    if not all(_same(getattr(a, f), getattr(b, f)) for f in _SHARED):
        return False
    if tuple(map(tuple, a.springs or ())) != tuple(map(tuple, b.springs or ())) or len(a.tables) != len(b.tables):
        return False
    if any(not (_same(ta[0], tb[0]) and _same(ta[1], tb[1])) for ta, tb in zip(a.tables, b.tables)):
        return False
    return a.tau.shape[1:] == b.tau.shape[1:] and _shares_engine(a, b)


def stack(blocks: list) -> list:
    """The blocks with one topology (same capsules, supports, laws, tones and force engine; rest geometry free: the
    gaps of a pair, the sets of an experiment) joined into one block whose rows are solved in one batched Newton
    solve; each row keeps its override set's rest geometry (``member``).  Latches are not stacked."""
    import dataclasses

    out: list = []
    runs: list = []
    for blk in blocks:
        for run in runs:
            if _stackable(run[0], blk):
                run.append(blk)
                break
        else:
            runs.append([blk])
    for run in runs:
        if len(run) == 1:
            out.append(run[0])
            continue
        per_row = {k: np.concatenate([getattr(b, k) for b in run]) for k in
                   ("rows", "tau", "arel", "kind", "oi", "oj", "axis", "obase", "fidx")}
        member = np.concatenate([np.full(b.rows.size, i) for i, b in enumerate(run)])
        eoff = np.stack([np.asarray(b.engines[0].lay.offsets, float) if b.engines else np.zeros((0, 3)) for b in run])
        out.append(dataclasses.replace(run[0], rest=np.stack([b.rest for b in run]),
                                       offsets=np.stack([b.offsets for b in run]),
                                       all_rest=np.stack([b.all_rest for b in run]), member=member, eoff=eoff,
                                       cache=None, closing=None, fold=None, **per_row))
    return out


SNAP_KEEP = 0.04      # relative change of a snapped row's loads at rest (and of its laws) that keeps it snapped


def _still_snapped(blk: GroupBlock, was, sig) -> np.ndarray:
    """(r,) bool: rows in contact at the last evaluation whose branch folded at a continuation step below the last
    (the fold at most (N_STEPS - 1)/N_STEPS of the full load) and whose thrust and Bjerknes sums at rest changed by at
    most SNAP_KEEP relative since they were last followed, the stiffness, elastica weight, gradient, gap exponent and
    neighbour drag by at most SNAP_KEEP: the fold cannot have moved past full load (it would take a change of
    1/N_STEPS = 12.5 %), so the row is still in contact without being followed again."""
    prev = blk.__dict__.get("verified")
    if prev is None or prev.shape != sig.shape or blk.fold is None or blk.fold[0].shape != was.shape:
        return np.zeros(was.shape, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(sig[:, :2] / prev[:, :2] - 1.0)
    near = (rel <= SNAP_KEEP).all(axis=1) & (np.abs(sig[:, 2:] - prev[:, 2:]) <= SNAP_KEEP).all(axis=1)
    return was & near & (blk.fold[0] <= N_STEPS - 2)


def _mode_factors(P, blk, coeffs, effects, t):
    """(r, T, n) factor on each orifice's squared volume amplitude from free f0 / Q and bubble shrinkage: the one-mode
    ratio |H(f; f_n', Q')|^2 / |H(f; f_n, Q)|^2 of the mode the orifice dominates (acl.physics.effects), normalised so
    that the reference capsule's thrust at f_ref keeps gamma.  ``f0`` / ``q`` scale every mode alike, ``f0@CAP`` every
    mode of one capsule (by its first mode's ratio), ``f0@CAP.ORIFICE`` one orifice's mode."""
    keys = [k for k in coeffs if k.split("@")[0] in ("f0", "q")]
    rate = effects.get("bubble_shrinkage", {}).get("shrink_rate", 0.0)
    if not keys and not rate:
        return None
    fn, q = blk.fn.copy(), blk.q.copy()
    ref = P.ref_capsule
    fr, qr = P.modes0[ref]
    fr1, qr1 = fr, qr
    caps = np.array([blk.caps[c] for c in blk.orif_cap], dtype=object)
    for key in keys:
        what, _, who = key.partition("@")
        j = 0 if what == "f0" else 1
        scale = coeffs[key] / P.modes0[who or ref][j]
        hit = (np.array([lab == who for lab in blk.labels]) if "." in who else caps == who) if who \
            else np.ones(len(blk.labels), bool)
        if j == 0:
            fn = np.where(hit, fn * scale, fn)
        else:
            q = np.where(hit, q * scale, q)
        if not who or who == ref or who == P.ref_orifice:
            fr1, qr1 = (fr1 * scale, qr1) if j == 0 else (fr1, qr1 * scale)
    norm = float(mode_response_ratio(P.f_ref, fr, qr, fr1, qr1)) if keys else 1.0
    fc = np.broadcast_to(fn, (blk.rows.size, fn.size)).copy()
    if rate:
        for o, (lx, lf) in enumerate(blk.tables):
            fc[:, o] = fn[o] * np.exp(np.interp(-rate * t, lx, lf))
    f = P.f[blk.rows][:, :, None]
    out = mode_response_ratio(f, blk.fn[None, None, :], blk.q[None, None, :], fc[:, None, :], q[None, None, :]) / norm
    return np.where(np.isfinite(out), out, 0.0)


def _distinct_rows(P, blk: GroupBlock, timed: bool = True):
    """(block of the distinct rows, index of each row's) when rows repeat (repeated ramps: every input of a row's
    prediction, its tones, observable and, when ``timed`` (bubble shrinkage acts: the only input of a group's
    prediction that reads the time), its time, bitwise the same), else None; made once per block and ``timed``."""
    tag = ("distinct", bool(timed))
    if tag not in blk.__dict__:
        import dataclasses

        r = blk.rows
        mem = blk.member if blk.member is not None else np.zeros(r.size)
        key = np.column_stack([P.f[r], P.v[r]] + ([P.t[r]] if timed else [])
                              + [blk.kind, blk.oi, blk.oj, blk.axis, blk.obase, blk.fidx, mem.astype(float)])
        _, first, inv = np.unique(np.ascontiguousarray(key).view(np.uint64), axis=0, return_index=True,
                                  return_inverse=True)
        red = None
        if first.size < r.size:
            order = np.argsort(first)
            rank = np.empty_like(order)
            rank[order] = np.arange(order.size)
            keep = first[order]
            per_row = {k: getattr(blk, k)[keep] for k in ("rows", "tau", "arel", "kind", "oi", "oj", "axis", "obase",
                                                         "fidx", "member") if getattr(blk, k) is not None}
            red = (dataclasses.replace(blk, cache=None, closing=None, fold=None, **per_row), keep, rank[inv.ravel()])
        blk.__dict__[tag] = red
    return blk.__dict__[tag]


def predict(P, blk: GroupBlock, coeffs, effects, w, gamma, alpha, es, lam, grad, c_p) -> tuple:
    """(predicted observable change (m, relative to the row's ``base``), snapped (r,) bool, latch push / switching
    force (r,)) of the block's rows; ``w`` (r, T) the squared drive pressure per V^2 of each tone (gain, its effects),
    the rest as in acl.fit.forward._predict.  Repeated rows are solved once (:func:`_distinct_rows`; each row's
    inputs are the same, so is its number), unless a coefficient is given per row."""
    timed = "bubble_shrinkage" in effects        # the only input of a group row that reads its time (_mode_factors)
    red = None if "tone_weight" in coeffs else _distinct_rows(P, blk, timed)
    if red is not None:
        sub, keep, inv = red
        ch, sn, ra = _predict_block(P, sub, coeffs, effects, w[keep], gamma, alpha, es, lam, grad, c_p)
        return ch[inv], sn[inv], ra[inv]
    return _predict_block(P, blk, coeffs, effects, w, gamma, alpha, es, lam, grad, c_p)


def _predict_block(P, blk: GroupBlock, coeffs, effects, w, gamma, alpha, es, lam, grad, c_p) -> tuple:
    """:func:`predict` of every row of ``blk``."""
    from acl.fit.latch import latch_travel_exact

    r, N, C, n = blk.rows.size, blk.law.size, len(blk.caps), blk.orif_cap.size
    t = P.t[blk.rows]
    # rest geometry of each row's override set (a stack of blocks, :func:`stack`, holds several; else one)
    mem = blk.member if blk.member is not None else np.zeros(r, int)
    REST = blk.rest if blk.rest.ndim == 3 else blk.rest[None]                     # (M, C, 3)
    OFFS = blk.offsets if blk.offsets.ndim == 3 else blk.offsets[None]            # (M, n, 3)
    ALL_REST = blk.all_rest if blk.all_rest.ndim == 3 else blk.all_rest[None]     # (M, C_all, 3)
    res = _mode_factors(P, blk, coeffs, effects, t)
    sub_c = np.ones(C)
    if "substrate_proximity" in effects:
        sub_c = substrate_factor(blk.cap_height, effects["substrate_proximity"]["h_substrate"])
    sub = sub_c[blk.orif_cap]
    wt = w[:, :, None] if res is None else w[:, :, None] * res
    # gamma scales the thrust of the orifices whose capsules declare it (every orifice when gmask is None)
    g_o = np.full(n, gamma) if blk.gmask is None else np.where(blk.gmask, gamma, blk.gamma0)
    thrust = (blk.tau * wt).sum(axis=1) * (g_o * sub)[None, :]                       # (r, n)
    wab = w[:, :, None, None] if res is None else w[:, :, None, None] * np.sqrt(res[:, :, :, None] * res[:, :, None, :])
    A = alpha * (blk.arel * wab).sum(axis=1) * np.sqrt(np.outer(sub, sub))[None]    # (r, n, n)
    beam = blk.law == 0
    cd, ct = B.stiffness_integrals(blk.L, blk.l, blk.EI * es, grad)
    cd = np.where(beam, cd, blk.cd)
    ct = np.where(beam, ct, 0.0)
    l_ = np.where(beam, blk.l, 0.0)
    moving = np.flatnonzero(blk.k > 0)
    m = int(blk.k.sum())
    offs = np.concatenate([[0], np.cumsum(blk.k)])
    slots = [(i, c) for i in range(N) for c in range(blk.k[i])]
    if N == 1:
        c_p = 0.0                        # a body alone has no neighbour: neighbour_drag does not act
    tied = [(i, blk.springs[i]) for i in range(N) if blk.springs and blk.springs[i] and blk.k[i]]

    def law(i, load):
        d = B.eq1_deflection(load, l_[i], cd[i], ct[i])
        if lam and beam[i]:
            d = elastica_blend(d, B.elastica_deflection(load, blk.L[i], blk.l[i], blk.EI[i] * es), lam)
        return d

    SLOT = np.zeros((len(slots), N * 3))                                           # coordinate -> node displacement
    for s_, (i_, c_) in enumerate(slots):
        SLOT[s_, 3 * i_:3 * i_ + 3] = blk.basis[i_, :, c_]

    def disp(z):                                                                   # (r, m) -> (r, N, 3)
        return (z @ SLOT).reshape(z.shape[0], N, 3)

    moves = N > 1 and bool(blk.engines)
    n_gap = effects["bjerknes_shape"]["gap_exponent"] if "bjerknes_shape" in effects else 0.0
    if blk.engines:
        # the analysis' force engine of the rows' frequencies (at 1 V): its constants restricted to the group's
        # orifices, with what the fit adds (gamma on the orifices it scales, alpha relative to the reference pair,
        # the substrate factor, a Bjerknes gap shape); each row's drive (tones, gain effects, mode factors) weights
        # its volumes per frequency and orifice, so that acl.physics.forces.capsule_forces gives the row's forces
        eng = blk.engines[0]
        ix = blk.orif_ix
        a_scale = alpha / blk.alpha_ref if blk.alpha_ref else 1.0
        consts = {"thrust": eng.consts["thrust"][:, ix] * (g_o / blk.gamma0 * sub)[None],
                  "w2p2": eng.consts["w2p2"], "other": eng.consts["other"][np.ix_(ix, ix)],
                  "bjerknes": eng.consts["bjerknes"][np.ix_(ix, ix)] * a_scale * np.sqrt(np.outer(sub, sub)),
                  "drag_mask": blk.orif_cap[:, None] != np.arange(C)[None, :],
                  "gap_exponent": float(n_gap), "gap_ref": GAP_REF}
        wt_all = np.broadcast_to(wt, w.shape + (n,))
        Wf = np.zeros((r, eng.f.size, n))
        for k_t in range(blk.fidx.shape[1]):
            on = blk.fidx[:, k_t] >= 0
            np.add.at(Wf, (np.flatnonzero(on), blk.fidx[on, k_t]), wt_all[on, k_t])
        Wf = np.sqrt(Wf)
        EOFF = blk.eoff if blk.eoff is not None else np.asarray(eng.lay.offsets, float)[None]   # (M, n_all, 3)
        if "u_rest" not in blk.__dict__:      # the coupled volumes with every capsule at rest (per pascal, (M, F, n))
            blk.__dict__["u_rest"] = eng.response(ALL_REST[:, eng.lay.body] + EOFF)[:, :, ix]
        u_rest = blk.__dict__["u_rest"]
        # rows of one tone need the coupled response at their frequency only: one response per frequency, each over
        # its rows (the same equations at fewer frequencies, acl.physics.coupling.prepared_response)
        single = moves and eng.f.size > 1 and bool(np.all(blk.fidx[:, 1:] < 0)) and bool(np.all(blk.fidx[:, 0] >= 0))
        if single and "per_f" not in blk.__dict__:
            from acl.physics import constants as PC
            from acl.physics.coupling import prepared_response

            blk.__dict__["per_f"] = [prepared_response(eng.system, eng.f[k:k + 1], eng.rho, eng.c,
                                                       PC.SUBSTRATE_REFLECTION,
                                                       h0=None if eng.h0 is None else eng.h0[k:k + 1])
                                     for k in range(eng.f.size)]

        def response(pos, rows_):
            if not single:
                return eng.response(pos)
            fk = blk.fidx[rows_, 0]
            u = np.zeros((pos.shape[0], eng.f.size, pos.shape[1]), complex)
            for k in np.unique(fk):
                sel = fk == k
                u[sel, k] = blk.__dict__["per_f"][k](pos[sel])[:, 0]
            return u
    onehot = np.zeros((n, C))
    onehot[np.arange(n), blk.orif_cap] = 1.0
    to_node = np.zeros((C, N))
    to_node[np.arange(C), blk.cap_node] = 1.0

    def geometry(z, rows_=slice(None)):
        """(node displacements (r, N, 3), capsule centres (r, C, 3), orifice centres (r, n, 3), their distances
        (r, n, n)) at coordinates z of the rows ``rows_``."""
        x = disp(z)
        xc = x[:, blk.cap_node]                                                    # (r, C, 3)
        mr = mem[rows_]
        centres = REST[mr] + xc
        p = centres[:, blk.orif_cap] + OFFS[mr]                                    # (r, n, 3)
        d = np.linalg.norm(p[:, None, :, :] - p[:, :, None, :], axis=-1)
        return x, centres, p, d

    def loads(z, scale, rows_=slice(None)):
        """(node loads (r, N, 3), orifice distances (r, n, n), node displacements (r, N, 3)) at coordinates z: the
        analysis' force model (acl.physics.forces.capsule_forces) of the group's capsules at their positions, the
        coupled volumes where the capsules are (a body alone: at rest, nothing moves relative to it)."""
        x, centres, p, d = geometry(z, rows_)
        if blk.engines:
            mr = mem[rows_]
            if moves:
                allc = ALL_REST[mr]
                allc[:, blk.cap_ix] = centres
                u = response(allc[:, eng.lay.body] + EOFF[mr], rows_)[:, :, blk.orif_ix]  # (B, F, n) per Pa
                # orifices in contact (past snap-in) make the coupled response singular: there, the volumes at rest
                bad = ~np.isfinite(u).all(axis=(1, 2))
                if bad.any():
                    u[bad] = u_rest[mr[bad]]
            else:
                u = u_rest[mr]
            F = capsule_forces(centres, blk.orif_cap, OFFS[0], blk.normals, onehot, blk.outer,
                               u * Wf[rows_], consts, points=p)[0]
        else:                                                                      # no tone: no acoustic force
            F = np.zeros((z.shape[0], C, 3))
        Fn = scale[:, None, None] * np.einsum("rck,cn->rnk", F, to_node)
        if c_p > 0:
            dragged_n = drag_load(Fn, np.linalg.norm(x, axis=-1)[..., None], c_p)
            Fn = dragged_n if blk.neighboured is None else np.where(blk.neighboured[None, :, None], dragged_n, Fn)
        for i, ties in tied:             # springs to fixed points pull back along their axes (elastic, not scaled)
            for ks, ax in ties:
                Fn[:, i] -= ks * (x[:, i] @ ax)[:, None] * ax[None]
        return Fn, d, x

    def D(z, scale, rows_=slice(None)):
        Fn, d, _ = loads(z, scale, rows_)
        out = np.zeros_like(z)
        for i in moving:
            Pi = np.einsum("rk,kc->rc", Fn[:, i], blk.basis[i, :, :blk.k[i]])
            o = offs[i]
            if blk.law[i] == 3:                   # latch: along its axis from state a (a pull stretches its beams)
                out[:, o] = latch_travel_exact(Pi[:, 0], blk.latch_geo[i], blk.latch[i], es)
                continue
            mag = np.linalg.norm(Pi, axis=1)
            dl = law(i, mag)
            out[:, o:o + blk.k[i]] = np.divide(Pi * dl[:, None], mag[:, None], out=np.zeros_like(Pi),
                                               where=mag[:, None] > 0)
        return out, d

    PTS0 = REST[:, blk.orif_cap] + OFFS                                           # (M, n, 3) orifices at rest
    across = blk.orif_node[:, None] != blk.orif_node[None, :]                     # orifices of different nodes
    REST_D = np.where(across[None], np.linalg.norm(PTS0[:, None, :, :] - PTS0[:, :, None, :], axis=-1), np.inf)
    # per override set: the length scale of the finite-difference step and the tolerance (its smallest rest distance)
    SCALE = np.array([float(np.min(rd)) if np.isfinite(rd).any() else float(np.max(blk.L)) for rd in REST_D])
    H = (1e-9 * SCALE)[mem]                                                       # (r,)
    TOL = (1e-6 * SCALE)[mem]
    DEN = np.where(across[None], REST_D, 1.0)[mem]                                # (r, n, n) rest distances
    scale_len = float(SCALE.min())

    def DJ(zl, sl, live, at=None):
        """(D(z), orifice distances, finite-difference Jacobian of z - D(z)) of every row: the row and its m perturbed
        copies in one evaluation of D (per-call overhead dominates, so each Newton iteration is one call); ``at``:
        (D(z), distances) already evaluated at zl (only the m copies are)."""
        nl = live.size
        h = H[live]
        zp = np.concatenate([zl[None], zl[None] + h[None, :, None] * np.eye(m)[:, None, :]])    # (m + 1, nl, m)
        if at is None:
            Dp, dd = D(zp.reshape((m + 1) * nl, m), np.tile(sl, m + 1), np.tile(live, m + 1))
            Dp = Dp.reshape(m + 1, nl, m)
        else:
            Dq, _ = D(zp[1:].reshape(m * nl, m), np.tile(sl, m), np.tile(live, m))
            Dp, dd = np.concatenate([at[0][None], Dq.reshape(m, nl, m)]), at[1]
        Fz = zl - Dp[0]
        J = np.transpose(((zp[1:] - Dp[1:]) - Fz[None]) / h[None, :, None], (1, 2, 0))   # (nl, m rows, m cols)
        return Dp[0], dd[:nl], J

    def chord(zl, sl, live, J0, Fz_all, d_all, J_all, fresh):
        """Chord steps with each row's Jacobian of the last evaluation ``J0`` (warm start: the optimizer's previous
        iterate), one evaluation of D per step; a row stops when converged (then its Jacobian is taken afresh at the
        z it stopped at: stability is judged exactly as Newton judges it), when its residual fails to halve (it goes
        on by Newton), or when it leaves the branch (Newton finds that too).  Fills the rows converged; returns the
        indices of the rest."""
        act = np.flatnonzero(np.isfinite(J0).all(axis=(1, 2)))
        rest = np.setdiff1d(np.arange(live.size), act)
        done = []
        prev = np.full(act.size, np.inf)
        for _ in range(N_CHORD):
            if act.size == 0:
                break
            Dz, dd = D(zl[act], sl[act], live[act])
            Fz = zl[act] - Dz
            res = np.abs(Fz).max(axis=1)
            near = np.where(across[None], dd / DEN[live[act]], np.inf).reshape(act.size, -1).min(axis=1)
            conv = res <= 1e-3 * TOL[live[act]]
            off = ~np.isfinite(Fz).all(axis=1) | (near <= 0.02) | (res > 0.5 * prev)
            if conv.any():
                # chord converges linearly: the row is within the tolerance, not at machine precision as Newton's
                # quadratic steps leave it (a Jacobian column of the fit, a 1e-6 step, reads differences far below
                # the tolerance); one Newton step with the Jacobian taken afresh there polishes it, and its residual
                # and distances are those at the polished z (the Jacobian, one tolerance away, judges stability)
                c = act[conv]
                _, _, Jc = DJ(zl[c], sl[c], live[c], at=(Dz[conv], dd[conv]))
                try:
                    dz = np.linalg.solve(Jc, -Fz[conv][:, :, None])[:, :, 0]
                except np.linalg.LinAlgError:
                    dz = np.zeros_like(Fz[conv])
                zl[c] = zl[c] + np.where(np.isfinite(dz), dz, 0.0)
                Dc, dc = D(zl[c], sl[c], live[c])
                Fz_all[c], d_all[c], J_all[c], fresh[c] = zl[c] - Dc, dc, Jc, True
                done.append(c)
            rest = np.concatenate([rest, act[off & ~conv]])
            go = ~conv & ~off
            act, Fz, prev = act[go], Fz[go], res[go]
            if act.size:
                try:
                    dz = np.linalg.solve(J0[act], -Fz[:, :, None])[:, :, 0]
                except np.linalg.LinAlgError:
                    break
                zl[act] = zl[act] + np.where(np.isfinite(dz), dz, 0.0)
        return np.sort(np.concatenate([rest, act]).astype(int))

    last: dict = {}

    def solve(z0, sl, live, iters=N_NEWTON, J0=None):
        """Newton on z - D(z) = 0 from z0; (z, stable equilibrium found, relative gaps (rows, n, n)).  A row's residual,
        Jacobian and distances at the z it stops at are those of its last iteration (no second evaluation).  ``J0``
        (rows, m, m; NaN: none): the rows' Jacobians of the last evaluation, for :func:`chord` steps first.  The
        Jacobian of every row at the z it stops at is left in ``last["J"]``."""
        zl = z0.copy()
        nl = live.size
        Fz_all = np.zeros_like(zl)
        d_all = np.zeros((nl, n, n))
        J_all = np.zeros((nl, m, m))
        fresh = np.zeros(nl, bool)          # rows whose stored evaluation is at their current zl
        act = np.arange(nl)                 # rows still iterating: a row stops once converged, or once it has left
        if J0 is not None:
            act = chord(zl, sl, live, J0, Fz_all, d_all, J_all, fresh)
        best = np.full(nl, np.inf)          # the branch (non-finite, or two orifices within 2 % of contact), or once
        stalled = np.zeros(nl, int)         # STALL iterations in a row did not halve its smallest residual so far
        for _ in range(iters):
            if act.size == 0:
                break
            Dz, dd, J = DJ(zl[act], sl[act], live[act])
            Fz = zl[act] - Dz
            Fz_all[act], d_all[act], J_all[act] = Fz, dd, J
            fresh[act] = True
            near = np.where(across[None], dd / DEN[live[act]], np.inf)
            res = np.abs(Fz).max(axis=1)
            stalled[act] = np.where(res <= 0.5 * best[act], 0, stalled[act] + 1)
            best[act] = np.minimum(best[act], res)
            stop = (res <= 1e-3 * TOL[live[act]]) | ~np.isfinite(Fz).all(axis=1) \
                | (near.reshape(act.size, -1).min(axis=1) <= 0.02) | (stalled[act] >= STALL)
            act, Fz, J = act[~stop], Fz[~stop], J[~stop]
            if act.size == 0:
                break
            try:
                dz = np.linalg.solve(J, -Fz[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            zl[act] = zl[act] + np.where(np.isfinite(dz), dz, 0.0)
            fresh[act] = False
        stale = np.flatnonzero(~fresh)
        if stale.size:
            Dz, dd, J = DJ(zl[stale], sl[stale], live[stale])
            Fz_all[stale], d_all[stale], J_all[stale] = zl[stale] - Dz, dd, J
        det = np.linalg.det(J_all)
        last["J"] = J_all
        rel = np.where(across[None], d_all / DEN[live], np.inf)
        good = (np.abs(Fz_all).max(axis=1) <= TOL[live]) & (det > 0) & (rel.reshape(nl, -1).min(axis=1) > 0.02)
        return zl, good, rel

    def solve_pinned(z0, rows, pinned, iters=N_NEWTON):
        """Newton on the coordinates not in ``pinned`` (the two nodes in contact stay where they are)."""
        free = np.setdiff1d(np.arange(m), pinned)
        zl = z0.copy()
        sl = np.ones(rows.size)
        for _ in range(iters):
            if free.size == 0:
                break
            Dz, _, J = DJ(zl, sl, rows)
            Fz = zl - Dz
            if np.all(np.abs(Fz[:, free]).max(axis=1) <= 1e-3 * TOL[rows]):
                break
            J = J[:, free][:, :, free]
            try:
                dz = np.linalg.solve(J, -Fz[:, free, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            zl[:, free] += np.where(np.isfinite(dz), dz, 0.0)
        return zl

    def _contact(z, rows, i, j, warm):
        """Orifices i and j in contact (paper Eq. (3) past snap-in): they meet halfway (all the way when one node is
        fixed), projected on what their nodes allow; the rest of the group in equilibrium around them."""
        zc = warm.copy()
        ni, nj = blk.orif_node[i], blk.orif_node[j]
        line = PTS0[mem[rows], j] - PTS0[mem[rows], i]                            # (rows, 3)
        share = (0.5, 0.5) if blk.k[ni] and blk.k[nj] else ((1.0, 0.0) if blk.k[ni] else (0.0, 1.0))
        pinned = []
        for node, sgn, sh in ((ni, 1.0, share[0]), (nj, -1.0, share[1])):
            o, k = offs[node], blk.k[node]
            if k:
                zc[:, o:o + k] = (sgn * sh * line) @ blk.basis[node, :, :k]
                pinned.extend(range(o, o + k))
        return solve_pinned(zc, rows, np.array(pinned, int))

    snapped = np.zeros(r, bool)
    closing = np.zeros((r, 2), int)
    everyone = np.arange(r)
    if m == 0:
        z = np.zeros((r, 0))
    elif N == 1 and not tied:
        z = D(np.zeros((r, m)), np.ones(r), everyone)[0]           # a body alone: its load does not depend on z
    else:
        # most rows: Newton at full load from the last solution found for them (warm start across the optimizer's
        # evaluations) or from rest; the rows where that fails are followed from rest by continuation
        start = blk.cache if blk.cache is not None and blk.cache.shape == (r, m) else np.zeros((r, m))
        was = blk.contact_rows() if blk.cache is not None and blk.cache.shape == (r, m) else np.zeros(r, bool)
        z = np.zeros((r, m))
        good = np.zeros(r, bool)
        jnew = np.full((r, m, m), np.nan)             # Jacobian at each row's equilibrium at full load (next warm start)
        # rows that snapped last time with their fold at least one continuation step (1/N_STEPS of the load) below full
        # load, whose loads at rest and laws have changed since by far less than that step: still past their fold
        sig = np.column_stack([thrust.sum(axis=1), np.abs(A).sum(axis=(1, 2)),
                               np.broadcast_to([np.log(es), lam, grad or 0.0, n_gap, c_p * scale_len], (r, 5))])
        kept = _still_snapped(blk, was, sig)
        if kept.any():
            snapped[kept] = True
            closing[kept] = blk.closing[kept]
            was = was & ~kept
        tried = everyone[~was & ~kept]               # rows in contact last time go straight to their continuation
        J0 = None
        if tried.size:
            jc = blk.__dict__.get("jcache")
            J0 = jc[tried] if jc is not None and jc.shape == (r, m, m) and blk.cache is not None else None
            z[tried], good[tried], _ = solve(start[tried], np.ones(tried.size), tried, 8, J0=J0)
            jnew[tried[good[tried]]] = last["J"][good[tried]]
        todo = everyone[~good & ~kept]
        first = np.ones(r, int)                       # first continuation step of each row
        if todo.size:
            z[todo] = 0.0
            if blk.fold is not None and blk.fold[0].shape == (r,):
                # rows that folded at the last evaluation: restart from their last stable step (not from rest); rows
                # in equilibrium at full load at the last evaluation (a Jacobian kept) that are no longer: from that
                # equilibrium at the step below full load.  One solve; a row that fails there starts from rest.
                k_prev, z_prev = blk.fold
                had = np.isfinite(J0).all(axis=(1, 2)) if J0 is not None else np.zeros(tried.size, bool)
                held = np.zeros(r, bool)
                held[tried[had]] = True
                again = todo[(k_prev[todo] > 0) | held[todo]]
                if again.size:
                    k0 = np.where(held[again], N_STEPS - 1, k_prev[again])
                    zl, ok, _ = solve(np.where(held[again][:, None], start[again], z_prev[again]), k0 / N_STEPS, again)
                    z[again[ok]] = zl[ok]
                    first[again[ok]] = k0[ok] + 1
        last_good = np.where(kept, blk.fold[0] if kept.any() else 0, 0)
        for step in range(1, N_STEPS + 1):
            rows_ = todo[first[todo] <= step]
            if todo.size == 0:
                break
            if rows_.size == 0:
                continue
            zl, ok, rel = solve(z[rows_], np.full(rows_.size, step / N_STEPS), rows_)
            z[rows_[ok]] = zl[ok]
            if step == N_STEPS:
                jnew[rows_[ok]] = last["J"][ok]
            last_good[rows_[ok]] = step
            bad = rows_[~ok]
            if bad.size:
                # no stable equilibrium next to the last one: the branch folded (snap-in); the orifices closest to
                # touching at the last stable configuration close
                d_bad = geometry(z[bad], bad)[3]       # distances only (no loads): as solve(..., iters=0) gives them
                rel = np.where(across[None], d_bad / DEN[bad], np.inf)
                flat = rel.reshape(bad.size, -1).argmin(axis=1)
                closing[bad] = np.column_stack(np.unravel_index(flat, (n, n)))
                snapped[bad] = True
                last_good[bad] = step - 1
            todo = np.setdiff1d(todo, bad)
        blk.fold = (np.where(snapped, last_good, 0), np.where(kept[:, None], blk.fold[1], z) if kept.any() else z.copy())
        prev = blk.__dict__.get("verified")
        blk.__dict__["verified"] = np.where(kept[:, None], prev, sig) if kept.any() else sig
        for i, j in {(int(a), int(b)) for a, b in closing[snapped]}:
            sel = np.flatnonzero(snapped & (closing[:, 0] == i) & (closing[:, 1] == j))
            warm = start[sel] if blk.cache is not None else z[sel]
            z[sel] = _contact(z, sel, i, j, warm)
        blk.cache = z.copy()
        blk.__dict__["jcache"] = jnew
        blk.closing = np.where(snapped[:, None], closing, -1)
    if np.any(blk.kind == 3):             # a latch state reads the loads; every other observable the geometry
        Fn, _, x = loads(z, np.ones(r), everyone)
    else:
        x = disp(z)
    xc = x[:, blk.cap_node]
    p = PTS0[mem] + xc[:, blk.orif_cap]
    rr = np.arange(r)
    gap = np.linalg.norm(p[rr, blk.oj] - p[rr, blk.oi], axis=1)
    rest_gap = np.linalg.norm(PTS0[mem, blk.oj] - PTS0[mem, blk.oi], axis=1)
    contact = snapped & (((closing[:, 0] == blk.oi) & (closing[:, 1] == blk.oj))
                         | ((closing[:, 0] == blk.oj) & (closing[:, 1] == blk.oi)))
    gap = np.where(contact, 0.0, gap)
    oc = np.where(blk.kind == 0, 0, blk.oi)
    moved = np.einsum("rk,rk->r", xc[rr, oc], blk.axis)
    ratio = np.zeros(r)
    node = blk.cap_node[oc]
    for i in np.unique(node[blk.kind == 3]):
        if blk.law[i] == 3:
            sel = (blk.kind == 3) & (node == i)
            push = np.einsum("rk,k->r", Fn[sel, i], blk.basis[i, :, 0])
            ratio[sel] = np.maximum(push, 0.0) / (blk.latch[i][2] * es)
    return np.where(blk.kind == 0, gap - rest_gap, moved), snapped, ratio
