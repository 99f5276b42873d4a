"""The rows of a group (acl.fit.group) with everything that does not change from one prediction to the next: the
nodes, their laws and directions, the capsules and orifices, the force engine of the rows' frequencies; and the
stacking of blocks of one topology into one batched solve."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.fit import beam as B

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
