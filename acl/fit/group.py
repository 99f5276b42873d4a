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

import numpy as np

from acl.fit import beam as B
from acl.fit.effects import GAP_REF
from acl.fit.group_block import LAW, GroupBlock, block, stack  # noqa: F401  (re-exported)
from acl.physics.effects import drag_load, elastica_blend, mode_response_ratio, substrate_factor
from acl.physics.forces import capsule_forces

N_STEPS = 8
N_NEWTON = 12
N_CHORD = 6           # chord steps at most (each must halve the residual) before Newton takes over
STALL = 3          # Newton iterations without halving a row's residual after which it has no equilibrium near its start

SNAP_KEEP = 0.04      # relative change of a snapped row's loads at rest (and of its laws) that keeps it snapped


def _still_snapped(blk: GroupBlock, was, sig) -> np.ndarray:
    """(r,) bool: rows in contact at the last evaluation whose branch folded at a continuation step below the last
    (the fold at most (N_STEPS - 1)/N_STEPS of the full load) and whose thrust and Bjerknes sums at rest changed by at
    most SNAP_KEEP relative since they were last followed, the stiffness, elastica weight, gradient, gap exponent and
    neighbour drag by at most SNAP_KEEP: the fold cannot have moved past full load (it would take a change of
    1/N_STEPS = 12.5 %), so the row is still in contact without being followed again."""
    if blk.fold is None or blk.fold[0].shape != was.shape:
        return np.zeros(was.shape, bool)
    return was & _unchanged(blk, sig) & (blk.fold[0] <= N_STEPS - 2)


def _unchanged(blk: GroupBlock, sig) -> np.ndarray:
    """(r,) bool: rows whose loads at rest and laws (``sig``) changed by at most SNAP_KEEP since they were last
    followed (:func:`_still_snapped`)."""
    prev = blk.__dict__.get("verified")
    if prev is None or prev.shape != sig.shape:
        return np.zeros(sig.shape[0], bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(sig[:, :2] / prev[:, :2] - 1.0)
    return (rel <= SNAP_KEEP).all(axis=1) & (np.abs(sig[:, 2:] - prev[:, 2:]) <= SNAP_KEEP).all(axis=1)


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


class Request:
    """What a prediction (acl.fit.forward._predict_steps) asks of its groups: the arguments of :func:`predict` of each
    block of P.groups; answered by [(change, snapped, ratio) of each block]."""

    def __init__(self, P, args: list):
        self.P, self.args = P, args

    def answer(self) -> list:
        return [predict(self.P, blk, *a) for blk, a in zip(self.P.groups, self.args)]

    @staticmethod
    def answer_many(requests: list) -> list:
        """[r.answer() for r in requests] (requests of one data set), each block's rows of every request in one
        :func:`predict_many`."""
        if not requests:
            return []
        P = requests[0].P
        out: list = [[] for _ in requests]
        for b, blk in enumerate(P.groups):
            for t, ans in enumerate(predict_many(P, blk, [q.args[b] for q in requests])):
                out[t].append(ans)
        return out


def predict(P, blk: GroupBlock, coeffs, effects, w, gamma, alpha, es, lam, grad, c_p) -> tuple:
    """(predicted observable change (m, relative to the row's ``base``), snapped (r,) bool, latch push / switching
    force (r,)) of the block's rows; ``w`` (r, T) the squared drive pressure per V^2 of each tone (gain, its effects),
    the rest as in acl.fit.forward._predict.  Repeated rows are solved once (:func:`_distinct_rows`; each row's
    inputs are the same, so is its number), unless a coefficient is given per row."""
    return predict_many(P, blk, [(coeffs, effects, w, gamma, alpha, es, lam, grad, c_p)])[0]


def predict_many(P, blk: GroupBlock, items) -> list:
    """[:func:`predict` (P, blk, *item) for item in ``items``] with the rows of every item stacked into one batched
    solve (a Jacobian's columns, a grid's points: the fixed cost of each call of the force model is paid once per
    Newton iteration, not once per item).  Every item starts from the block's state of the last evaluation (warm
    start, snapped rows, Jacobians), which is read, not replaced: the numbers agree with one prediction after the
    other to the solver's tolerance (each row converges to 1e-9 of the group's smallest rest distance), not bit for
    bit.  Latch blocks, per-row coefficients (``tone_weight``) or items that reduce their rows differently: one after
    the other."""
    K = len(items)
    timed = ["bubble_shrinkage" in it[1] for it in items]
    per_row = any("tone_weight" in it[0] for it in items)
    if K > 1 and (per_row or len(set(timed)) > 1 or np.any(blk.law == LAW["latch"]) or np.any(blk.kind == 3)):
        return [predict_many(P, blk, [it])[0] for it in items]
    red = None if per_row else _distinct_rows(P, blk, timed[0])
    if red is not None:
        sub, keep, inv = red
        outs = _predict_block(P, sub, [it[:2] + (it[2][keep],) + it[3:] for it in items])
        return [(ch[inv], sn[inv], ra[inv]) for ch, sn, ra in outs]
    return _predict_block(P, blk, items)


_ROW_STATE = ("rows", "tau", "arel", "kind", "oi", "oj", "axis", "obase", "fidx", "member", "cache", "closing")


def _tiled(blk: GroupBlock, K: int) -> GroupBlock:
    """``blk`` with its rows and its state of the last evaluation repeated K times (one copy per stacked item), the
    row-independent caches (coupled volumes at rest, per-frequency responses) shared."""
    import dataclasses

    def rep(a):
        return None if a is None else np.concatenate([a] * K)

    fields = {k: rep(getattr(blk, k)) for k in _ROW_STATE}      # (member None: one override set, as before)
    fold = None if blk.fold is None else (rep(blk.fold[0]), rep(blk.fold[1]))
    out = dataclasses.replace(blk, fold=fold, **fields)
    for k in ("jcache", "verified"):
        if blk.__dict__.get(k) is not None:
            out.__dict__[k] = rep(blk.__dict__[k])
    for k in ("u_rest", "per_f"):
        if k in blk.__dict__:
            out.__dict__[k] = blk.__dict__[k]
    return out


def _collinear_columns(points, normals, bases, law, axes, tol: float = 1e-12):
    """(coordinates across, along) the line of a collinear group, or (None, None): every point (orifices and capsule
    centres at rest, (p, 3)) and every normal on one line, beams and springs only, each coordinate (``bases``: per node
    (3, k)) and spring axis along the line or across it.  Then no force acts across the line while the coordinates
    across it are 0: the Jacobian's block across it is decoupled (block triangular)."""
    d = points - points[0]
    size = np.linalg.norm(d, axis=1)
    if size.max(initial=0.0) == 0.0 or np.any(law == LAW["latch"]):
        return None, None
    u = d[np.argmax(size)] / size.max()
    if np.any(np.linalg.norm(np.cross(d, u), axis=1) > tol * size.max()) or \
            np.any(np.linalg.norm(np.cross(normals, u), axis=1) > tol):
        return None, None
    along = np.abs(np.concatenate([b.T for b in bases]) @ u) if bases else np.zeros(0)
    if any(abs(abs(float(ax @ u) / np.linalg.norm(ax)) - 0.5) < 0.5 - tol for ax in axes) or \
            np.any((along > tol) & (np.abs(along - 1.0) > tol)):
        return None, None
    side = np.flatnonzero(along <= tol)
    return (side, np.flatnonzero(along > tol)) if side.size else (None, None)


def _predict_block(P, blk: GroupBlock, items) -> list:
    """:func:`predict_many` of every row of ``blk``: K items (coeffs, effects, w (r, T), gamma, alpha, es, lam, grad,
    c_p), their rows stacked item after item; each coefficient enters as its item's value on its rows."""
    from acl.fit.latch import latch_travel_exact

    K = len(items)
    r0 = blk.rows.size
    base = blk
    if K > 1:
        blk = _tiled(blk, K)
    r, N, C, n = blk.rows.size, blk.law.size, len(blk.caps), blk.orif_cap.size
    kid = np.repeat(np.arange(K), r0)                                              # (r,) item of each row
    # rest geometry of each row's override set (a stack of blocks, :func:`stack`, holds several; else one)
    mem = blk.member if blk.member is not None else np.zeros(r, int)
    REST = blk.rest if blk.rest.ndim == 3 else blk.rest[None]                     # (M, C, 3)
    OFFS = blk.offsets if blk.offsets.ndim == 3 else blk.offsets[None]            # (M, n, 3)
    ALL_REST = blk.all_rest if blk.all_rest.ndim == 3 else blk.all_rest[None]     # (M, C_all, 3)
    t0 = P.t[base.rows]
    res_k = [_mode_factors(P, base, it[0], it[1], t0) for it in items]
    res = None if all(x is None for x in res_k) else \
        np.concatenate([np.ones(base.tau.shape) if x is None else x for x in res_k])
    w = np.concatenate([it[2] for it in items])
    gamma = np.array([it[3] for it in items], float)
    alpha = np.array([it[4] for it in items], float)
    es = np.array([it[5] for it in items], float)
    lam = np.array([it[6] for it in items], float)
    grad_k = [it[7] for it in items]
    c_p = np.array([it[8] for it in items], float)
    sub_c = np.ones((K, C))
    for k_, it in enumerate(items):
        if "substrate_proximity" in it[1]:
            sub_c[k_] = substrate_factor(blk.cap_height, it[1]["substrate_proximity"]["h_substrate"])
    sub = sub_c[:, blk.orif_cap]                                                   # (K, n)
    wt = w[:, :, None] if res is None else w[:, :, None] * res
    # gamma scales the thrust of the orifices whose capsules declare it (every orifice when gmask is None)
    g_o = np.repeat(gamma[:, None], n, axis=1) if blk.gmask is None else np.where(blk.gmask[None], gamma[:, None],
                                                                                   blk.gamma0)
    thrust = (blk.tau * wt).sum(axis=1) * (g_o * sub)[kid]                         # (r, n)
    wab = w[:, :, None, None] if res is None else w[:, :, None, None] * np.sqrt(res[:, :, :, None] * res[:, :, None, :])
    root_sub = np.sqrt(sub[:, :, None] * sub[:, None, :])                         # (K, n, n)
    A = alpha[kid][:, None, None] * (blk.arel * wab).sum(axis=1) * root_sub[kid]  # (r, n, n)
    beam = blk.law == 0
    cd = np.zeros((K, N))
    ct = np.zeros((K, N))
    for k_ in range(K):
        cd[k_], ct[k_] = B.stiffness_integrals(blk.L, blk.l, blk.EI * es[k_], grad_k[k_])
    cd = np.where(beam, cd, blk.cd)
    ct = np.where(beam, ct, 0.0)
    l_ = np.where(beam, blk.l, 0.0)
    moving = np.flatnonzero(blk.k > 0)
    m = int(blk.k.sum())
    offs = np.concatenate([[0], np.cumsum(blk.k)])
    slots = [(i, c) for i in range(N) for c in range(blk.k[i])]
    if N == 1:
        c_p = np.zeros(K)                # a body alone has no neighbour: neighbour_drag does not act
    tied = [(i, blk.springs[i]) for i in range(N) if blk.springs and blk.springs[i] and blk.k[i]]
    n_gap = np.array([it[1]["bjerknes_shape"]["gap_exponent"] if "bjerknes_shape" in it[1] else 0.0 for it in items])

    def item(a, rows_):
        """Per-item values (K, ...) on the rows ``rows_`` (one item: its value, broadcast)."""
        return a[0] if K == 1 else a[kid[rows_]]

    def law(i, load, rows_):
        d = B.eq1_deflection(load, l_[i], item(cd[:, i], rows_), item(ct[:, i], rows_))
        if lam.any() and beam[i]:
            d = elastica_blend(d, B.elastica_deflection(load, blk.L[i], blk.l[i], blk.EI[i] * item(es, rows_)),
                               item(lam, rows_))
        return d

    SLOT = np.zeros((len(slots), N * 3))                                           # coordinate -> node displacement
    for s_, (i_, c_) in enumerate(slots):
        SLOT[s_, 3 * i_:3 * i_ + 3] = blk.basis[i_, :, c_]

    def disp(z):                                                                   # (r, m) -> (r, N, 3)
        return (z @ SLOT).reshape(z.shape[0], N, 3)

    moves = N > 1 and bool(blk.engines)
    if blk.engines:
        # the analysis' force engine of the rows' frequencies (at 1 V): its constants restricted to the group's
        # orifices, with what the fit adds (gamma on the orifices it scales, alpha relative to the reference pair,
        # the substrate factor, a Bjerknes gap shape); each row's drive (tones, gain effects, mode factors) weights
        # its volumes per frequency and orifice, so that acl.physics.forces.capsule_forces gives the row's forces
        eng = blk.engines[0]
        ix = blk.orif_ix
        a_scale = alpha / blk.alpha_ref if blk.alpha_ref else np.ones(K)
        c_thrust = eng.consts["thrust"][:, ix][None] * (g_o / blk.gamma0 * sub)[:, None, :]           # (K, F, n)
        c_bjerknes = eng.consts["bjerknes"][np.ix_(ix, ix)][None] * a_scale[:, None, None] * root_sub   # (K, n, n)
        consts = {"w2p2": eng.consts["w2p2"], "other": eng.consts["other"][np.ix_(ix, ix)],
                  "drag_mask": blk.orif_cap[:, None] != np.arange(C)[None, :], "gap_ref": GAP_REF}

        def consts_of(rows_):
            """The force constants of the rows ``rows_`` (one item: its own, broadcast over the rows)."""
            gap = float(n_gap[0]) if K == 1 else n_gap[kid[rows_]][:, None, None]
            return {**consts, "thrust": item(c_thrust, rows_), "bjerknes": item(c_bjerknes, rows_),
                    "gap_exponent": gap}
        wt_all = np.broadcast_to(wt, w.shape + (n,))
        Wf = np.zeros((r, eng.f.size, n))
        for k_t in range(blk.fidx.shape[1]):
            on = blk.fidx[:, k_t] >= 0
            np.add.at(Wf, (np.flatnonzero(on), blk.fidx[on, k_t]), wt_all[on, k_t])
        Wf = np.sqrt(Wf)
        EOFF = blk.eoff if blk.eoff is not None else np.asarray(eng.lay.offsets, float)[None]   # (M, n_all, 3)
        if "u_rest" not in blk.__dict__:      # the coupled volumes with every capsule at rest (per pascal, (M, F, n))
            blk.__dict__["u_rest"] = eng.response(ALL_REST[:, eng.lay.body] + EOFF)[:, :, ix]
        u_rest = base.__dict__["u_rest"] = blk.__dict__["u_rest"]
        # rows of one tone need the coupled response at their frequency only: one solve over the rows, each at its
        # own frequency and uncoupled blocks (acl.physics.coupling.coupled_volumes broadcasts them as batch axes); a
        # row with no tone (0 V) feels no force whatever its volumes per pascal: none computed
        single = moves and eng.f.size > 1 and bool(np.all(blk.fidx[:, 1:] < 0))
        if single:
            from acl.physics import constants as PC
            from acl.physics.coupling import coupled_volumes

        def response(pos, rows_):
            if not single:
                return eng.response(pos)
            fk = blk.fidx[rows_, 0]
            u = np.zeros((pos.shape[0], eng.f.size, pos.shape[1]), complex)
            on = np.flatnonzero(fk >= 0)
            if on.size:
                k = fk[on]
                u[on, k] = coupled_volumes(eng.h0[k][:, None], eng.system.slot, pos[on], eng.system.radii,
                                           eng.f[k][:, None], eng.rho, eng.c, PC.SUBSTRATE_REFLECTION)[:, 0]
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
                               u * Wf[rows_], consts_of(rows_), points=p)[0]
        else:                                                                      # no tone: no acoustic force
            F = np.zeros((z.shape[0], C, 3))
        Fn = scale[:, None, None] * np.einsum("rck,cn->rnk", F, to_node)
        if c_p.any():
            cp = item(c_p, rows_)
            dragged_n = drag_load(Fn, np.linalg.norm(x, axis=-1)[..., None], cp if K == 1 else cp[:, None, None])
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
                out[:, o] = latch_travel_exact(Pi[:, 0], blk.latch_geo[i], blk.latch[i], item(es, rows_))
                continue
            mag = np.linalg.norm(Pi, axis=1)
            dl = law(i, mag, rows_)
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

    SIDE, AXIAL = _collinear_columns(np.concatenate([PTS0.reshape(-1, 3), REST.reshape(-1, 3)]), blk.normals,
                                     [blk.basis[i, :, :blk.k[i]] for i in range(N)], blk.law,
                                     [ax for _, ties in tied for _, ax in ties])
    ALL_COLS = np.arange(m)

    def sideways(zl, sl, live, Fz):
        """The Jacobian columns (nl, m, len(SIDE)) of z - D(z) across the line of a collinear group, at zl."""
        ns, nl = SIDE.size, live.size
        h = H[live]
        zp = zl[None] + h[None, :, None] * np.eye(m)[SIDE][:, None, :]                            # (ns, nl, m)
        Dq, _ = D(zp.reshape(ns * nl, m), np.tile(sl, ns), np.tile(live, ns))
        return np.transpose(((zp - Dq.reshape(ns, nl, m)) - Fz[None]) / h[None, :, None], (1, 2, 0))

    def DJ(zl, sl, live, at=None):
        """(D(z), orifice distances, finite-difference Jacobian of z - D(z)) of every row: the row and its m perturbed
        copies in one evaluation of D (per-call overhead dominates, so each Newton iteration is one call); ``at``:
        (D(z), distances) already evaluated at zl (only the m copies are).  A collinear group with every row on its
        line (:func:`_collinear_columns`): the copies along the line only, the columns across it are the identity
        (their block is decoupled: no force across the line, checked exactly) until :func:`solve` evaluates them once
        at the solution (:func:`sideways`)."""
        nl = live.size
        h = H[live]
        cols = AXIAL if SIDE is not None and not np.any(zl[:, SIDE]) else ALL_COLS
        q = cols.size
        zp = np.concatenate([zl[None], zl[None] + h[None, :, None] * np.eye(m)[cols][:, None, :]])    # (q + 1, nl, m)
        if at is None:
            Dp, dd = D(zp.reshape((q + 1) * nl, m), np.tile(sl, q + 1), np.tile(live, q + 1))
            Dp = Dp.reshape(q + 1, nl, m)
        else:
            Dq, _ = D(zp[1:].reshape(q * nl, m), np.tile(sl, q), np.tile(live, q))
            Dp, dd = np.concatenate([at[0][None], Dq.reshape(q, nl, m)]), at[1]
        Fz = zl - Dp[0]
        Jq = np.transpose(((zp[1:] - Dp[1:]) - Fz[None]) / h[None, :, None], (1, 2, 0))   # (nl, m rows, q cols)
        if q == m:
            return Dp[0], dd[:nl], Jq
        J = np.zeros((nl, m, m))
        J[:, :, cols] = Jq
        J[:, SIDE, SIDE] = 1.0
        off = np.flatnonzero(np.any(Fz[:, SIDE] != 0, axis=1))
        if off.size:                    # a force across the line after all: those rows' columns across it now
            J[np.ix_(off, ALL_COLS, SIDE)] = sideways(zl[off], sl[off], live[off], Fz[off])
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
        rel = np.where(across[None], d_all / DEN[live], np.inf)
        near_ok = rel.reshape(nl, -1).min(axis=1) > 0.02
        if SIDE is not None:            # a collinear group: the columns across its line once, at each row's solution
            on = np.flatnonzero(~np.any(zl[:, SIDE], axis=1) & (np.abs(Fz_all).max(axis=1) <= TOL[live]) & near_ok)
            if on.size:
                J_all[np.ix_(on, ALL_COLS, SIDE)] = sideways(zl[on], sl[on], live[on], Fz_all[on])
        det = np.linalg.det(J_all)
        last["J"] = J_all
        good = (np.abs(Fz_all).max(axis=1) <= TOL[live]) & (det > 0) & near_ok
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

    def fold_rows(bad, step, closing, snapped, last_good, z):
        """No stable equilibrium at load ``step`` next to the last one (z): the branch folded (snap-in); the orifices
        closest to touching at that last stable configuration close."""
        d_bad = geometry(z[bad], bad)[3]       # distances only (no loads): as solve(..., iters=0) gives them
        rel = np.where(across[None], d_bad / DEN[bad], np.inf)
        flat = rel.reshape(bad.size, -1).argmin(axis=1)
        closing[bad] = np.column_stack(np.unravel_index(flat, (n, n)))
        snapped[bad] = True
        last_good[bad] = step - 1

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
                               np.column_stack([np.log(es), lam, [g or 0.0 for g in grad_k], n_gap,
                                                c_p * scale_len])[kid]])
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
        fold_at = np.zeros(r, int)                    # rows whose restart failed: the step it failed at
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
                    z0 = np.where(held[again][:, None], start[again], z_prev[again])
                    zl, ok, _ = solve(z0, k0 / N_STEPS, again)
                    z[again[ok]] = zl[ok]
                    first[again[ok]] = k0[ok] + 1
                    # no stable equilibrium at step k0 next to the last one found there, the loads at rest and the
                    # laws within SNAP_KEEP of those it was found at (a start closer than a continuation step's, of
                    # 1/N_STEPS): the fold is below k0, as a continuation from rest would find it; else from rest
                    lost = ~ok & _unchanged(blk, sig)[again]
                    z[again[lost]] = z0[lost]
                    fold_at[again[lost]] = k0[lost]
        last_good = np.where(kept, blk.fold[0] if kept.any() else 0, 0)
        lost = np.flatnonzero(fold_at)
        if lost.size:
            fold_rows(lost, fold_at[lost], closing, snapped, last_good, z)
            todo = np.setdiff1d(todo, lost)
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
                fold_rows(bad, np.full(bad.size, step), closing, snapped, last_good, z)
            todo = np.setdiff1d(todo, bad)
        blk.fold = (np.where(snapped, last_good, 0), np.where(kept[:, None], blk.fold[1], z) if kept.any() else z.copy())
        prev = blk.__dict__.get("verified")
        blk.__dict__["verified"] = np.where(kept[:, None], prev, sig) if kept.any() else sig
        for i, j in (np.unique(closing[snapped], axis=0) if snapped.any() else ()):
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
            ratio[sel] = np.maximum(push, 0.0) / (blk.latch[i][2] * item(es, np.flatnonzero(sel)))
    change = np.where(blk.kind == 0, gap - rest_gap, moved)
    return [(change[k_ * r0:(k_ + 1) * r0], snapped[k_ * r0:(k_ + 1) * r0], ratio[k_ * r0:(k_ + 1) * r0])
            for k_ in range(K)]
