"""Forward model of a group of three or more interacting capsules (acl.fit.mechanism ``Unit("group")``).

Each capsule sits on its own support (a cantilever moves across its axis by paper Eq. (1), isotropic in that
plane as in :mod:`acl.analysis.mechanics`; a spring along its axis by P/k; a fixed capsule not at all).  Per
row, with tones adding in power:

* own thrust gamma tau_i(f) V^2 along -n_i (the orifice's outward normal n_i), as for a lone actuator;
* every two capsules attract by alpha a_ij(f) V^2 / d_ij^2 along the line of their orifices (paper Eq. (3),
  a_ij from :func:`acl.analysis.acoustics.pair_forces` relative to the reference pair at f_ref);
* the jet of capsule i drags the first capsule it points at (within 30 deg of its axis) with a force equal to
  i's thrust, along n_i: the paper's F_AS = F_d assumption of Eq. (3), which for two facing capsules is the
  pair model of :mod:`acl.fit.forward` exactly.

The equilibrium z = D(z) (z the supports' coordinates, D the deflection laws applied to the loads at z) is
followed by continuation in the load from rest (``N_STEPS`` steps, Newton with a finite-difference Jacobian
at each, vectorized over rows).  A row whose branch folds (Newton fails, the Jacobian of z - D(z) loses its
positive determinant, or two orifices meet) has snapped in: the pair that closed is in contact (gap 0), the
rest of the group is taken where it was at the fold.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.fit import beam as B
from acl.physics.effects import drag_load, elastica_blend, mode_response_ratio, substrate_factor

N_STEPS = 8
N_NEWTON = 12


@dataclass
class GroupBlock:
    """The rows of one group in one override set, with everything row-independent precomputed."""

    rows: np.ndarray          # (r,) row indices into the data set
    caps: tuple               # N capsule names
    law: np.ndarray           # (N,) 0 beam, 1 spring, 2 fixed
    L: np.ndarray             # (N,)
    l: np.ndarray
    EI: np.ndarray
    cd: np.ndarray            # spring: compliance
    basis: np.ndarray         # (N, 3, 2) directions each support allows (zero-padded)
    k: np.ndarray             # (N,) how many
    points: np.ndarray        # (N, 3) orifice centres at rest
    normals: np.ndarray       # (N, 3) outward normals
    jets: np.ndarray          # (N,) capsule dragged by each jet (-1 none)
    tau: np.ndarray           # (r, T, N) thrust per V^2 relative to gamma0
    arel: np.ndarray          # (r, T, N, N) Bjerknes coefficient per V^2 relative to the reference pair at f_ref
    height: np.ndarray        # (N,)
    fn: np.ndarray            # (N,) first natural frequency (Hz)
    q: np.ndarray             # (N,)
    tables: list              # per capsule (ln V/V0, ln f/f0) (bubble shrinkage)
    kind: np.ndarray          # (r,) observable kind: 0 gap, 1 displacement, 2 position
    oi: np.ndarray            # (r,) capsule index of the observable (gap: a)
    oj: np.ndarray            # (r,) gap: b
    axis: np.ndarray          # (r, 3) displacement axis / position unit vector
    obase: np.ndarray         # (r,) position: rest coordinate
    cache: np.ndarray = None  # (r, m) last equilibrium found per row (warm start of the next evaluation)
    closing: np.ndarray = None    # (r, 2) the pair in contact of each row past snap-in at the last evaluation (-1)
    fold: tuple = None            # ((r,) last stable continuation step of the rows that snapped, (r, m) configuration)

    def contact_rows(self):
        return self.closing[:, 0] >= 0 if self.closing is not None else np.zeros(self.rows.size, bool)


def block(inst, unit, name, rows, f, v, gamma0, alpha_ref, ftable) -> GroupBlock:
    """Precompute a group's rows (``name`` the observable, ``ftable(volume, radius, medium)`` the shrinkage table)."""
    from acl.fit.mechanism import pair_alpha_per_v2, thrust_per_v2

    sides = unit.sides
    N = len(sides)
    r, T = len(rows), f.shape[1]
    basis = np.zeros((N, 3, 2))
    k = np.zeros(N, int)
    law = np.array([{"beam": 0, "spring": 1, "fixed": 2}[s.law] for s in sides])
    for i, s in enumerate(sides):
        k[i] = s.basis.shape[1]
        basis[i, :, :k[i]] = s.basis
    cd = np.zeros(N)
    for i, s in enumerate(sides):
        if s.law == "beam":
            cd[i] = B.stiffness_integrals(np.array([s.L]), np.array([s.l]), np.array([s.EI]))[0][0]
        elif s.law == "spring":
            cd[i] = s.compliance
    tau = np.zeros((r, T, N))
    arel = np.zeros((r, T, N, N))
    fr, vr = f[rows], v[rows]
    for fk in np.unique(fr[vr > 0]):
        m = (fr == fk) & (vr > 0)
        tp = thrust_per_v2(inst, fk)
        for i, s in enumerate(sides):
            tau[:, :, i] += m * (tp[s.capsule] / gamma0)
        if alpha_ref:
            for i in range(N):
                for j in range(i + 1, N):
                    a = pair_alpha_per_v2(inst, sides[i].capsule, sides[j].capsule, fk) / alpha_ref
                    arel[:, :, i, j] += m * a
                    arel[:, :, j, i] += m * a
    obs = inst.design.observe(name)
    idx = {s.capsule: i for i, s in enumerate(sides)}
    kind = np.zeros(r, int)
    oi = np.zeros(r, int)
    oj = np.zeros(r, int)
    axis = np.zeros((r, 3))
    obase = np.zeros(r)
    if obs.kind == "gap":
        oi[:], oj[:] = idx[obs.a.split(".")[0]], idx[obs.b.split(".")[0]]
    else:
        from acl.fit.mechanism import _target_capsule

        oi[:] = idx[_target_capsule(inst.design, obs)]
        if obs.kind == "displacement":
            kind[:] = 1
            axis[:] = np.asarray(obs.axis, float) / np.linalg.norm(obs.axis)
        else:
            kind[:] = 2
            c = "xyz".index(obs.component)
            axis[:, c] = 1.0
            obase[:] = float(inst.design.capsule(sides[oi[0]].capsule).center[c])
    med = inst.medium
    return GroupBlock(np.asarray(rows), tuple(s.capsule for s in sides), law,
                      np.array([s.L for s in sides]), np.array([s.l for s in sides]), np.array([s.EI for s in sides]),
                      cd, basis, k, np.asarray(unit.points, float), np.asarray(unit.normals, float),
                      np.asarray(unit.jets, int), tau, arel, np.array([s.height for s in sides]),
                      np.array([s.mode[0] for s in sides]), np.array([s.mode[1] for s in sides]),
                      [ftable(s.bubble[0], s.bubble[1], med) for s in sides], kind, oi, oj, axis, obase)


def _mode_factors(P, blk, coeffs, effects, t):
    """(r, T, N) factor on each capsule's squared volume amplitude from free f0 / Q and bubble shrinkage (the same
    one-mode ratio as acl.fit.forward._resonance_factors; the reference capsule's thrust at f_ref keeps gamma)."""
    keys = [k for k in coeffs if k.split("@")[0] in ("f0", "q")]
    rate = effects.get("bubble_shrinkage", {}).get("shrink_rate", 0.0)
    if not keys and not rate:
        return None
    fn, q = blk.fn.copy(), blk.q.copy()
    ref = P.ref_capsule
    fr, qr = P.modes0[ref]
    fr1, qr1 = fr, qr
    for key in keys:
        what, _, cap = key.partition("@")
        j = 0 if what == "f0" else 1
        scale = coeffs[key] / P.modes0[cap or ref][j]
        hit = np.array([c == cap for c in blk.caps]) if cap else np.ones(len(blk.caps), bool)
        if j == 0:
            fn = np.where(hit, fn * scale, fn)
        else:
            q = np.where(hit, q * scale, q)
        if not cap or cap == ref:
            fr1, qr1 = (fr1 * scale, qr1) if j == 0 else (fr1, qr1 * scale)
    norm = float(mode_response_ratio(P.f_ref, fr, qr, fr1, qr1)) if keys else 1.0
    f = P.f[blk.rows][:, :, None]
    fc = np.broadcast_to(fn, (blk.rows.size, len(blk.caps))).copy()
    if rate:
        for i, (lx, lf) in enumerate(blk.tables):
            fc[:, i] = fn[i] * np.exp(np.interp(-rate * t, lx, lf))
    out = mode_response_ratio(f, blk.fn[None, None, :], blk.q[None, None, :], fc[:, None, :], q[None, None, :]) / norm
    return np.where(np.isfinite(out), out, 0.0)


def predict(P, blk: GroupBlock, coeffs, effects, w, gamma, alpha, es, lam, grad, c_p) -> np.ndarray:
    """Predicted observable change (m, relative to the row's ``base``) of the group's rows; ``w`` (r, T) the
    squared drive pressure per V^2 of each tone (gain, its effects), the rest as in acl.fit.forward._predict."""
    r, N = blk.rows.size, len(blk.caps)
    t = P.t[blk.rows]
    res = _mode_factors(P, blk, coeffs, effects, t)
    sub = np.ones(N)
    if "substrate_proximity" in effects:
        sub = substrate_factor(blk.height, effects["substrate_proximity"]["h_substrate"])
    wt = w[:, :, None] if res is None else w[:, :, None] * res
    thrust = gamma * (blk.tau * wt).sum(axis=1) * sub[None, :]                      # (r, N)
    wab = w[:, :, None, None] if res is None else w[:, :, None, None] * np.sqrt(res[:, :, :, None] * res[:, :, None, :])
    A = alpha * (blk.arel * wab).sum(axis=1) * np.sqrt(np.outer(sub, sub))[None]   # (r, N, N)
    const = thrust[:, :, None] * -blk.normals[None]                                # own thrust (r, N, 3)
    for i, j in enumerate(blk.jets):
        if j >= 0:
            const[:, j] += thrust[:, i, None] * blk.normals[i][None]             # i's jet drags j (F_AS = F_d)
    beam = blk.law == 0
    cd, ct = B.stiffness_integrals(blk.L, blk.l, blk.EI * es, grad)
    cd = np.where(beam, cd, blk.cd)
    ct = np.where(beam, ct, 0.0)
    l_ = np.where(beam, blk.l, 0.0)
    moving = blk.k > 0
    m = int(blk.k.sum())
    slots = [(i, c) for i in range(N) for c in range(blk.k[i])]

    def law(i, load):
        d = B.eq1_deflection(load, l_[i], cd[i], ct[i])
        if lam and beam[i]:
            d = elastica_blend(d, B.elastica_deflection(load, blk.L[i], blk.l[i], blk.EI[i] * es), lam)
        return d

    def disp(z):                                                                   # (r, m) -> (r, N, 3)
        x = np.zeros((z.shape[0], N, 3))
        for s, (i, c) in enumerate(slots):
            x[:, i] += z[:, s, None] * blk.basis[i, :, c][None]
        return x

    def D(z, scale, rows_=slice(None)):
        x = disp(z)
        p = blk.points[None] + x
        sep = p[:, None, :, :] - p[:, :, None, :]                                 # p_j - p_i (r, i, j, 3)
        d = np.linalg.norm(sep, axis=-1)
        np.einsum("rii->ri", d)[:] = 1.0
        fb = np.einsum("rij,rijk->rik", A[rows_] / d**3, sep)                     # attraction towards each j
        F = scale[:, None, None] * (const[rows_] + fb)
        if c_p > 0:
            F = drag_load(F, np.linalg.norm(x, axis=-1)[..., None], c_p)
        out = np.zeros_like(z)
        for i in np.flatnonzero(moving):
            Pi = np.einsum("rk,kc->rc", F[:, i], blk.basis[i, :, :blk.k[i]])
            mag = np.linalg.norm(Pi, axis=1)
            dl = law(i, mag)
            o = sum(blk.k[:i])
            out[:, o:o + blk.k[i]] = np.divide(Pi * dl[:, None], mag[:, None], out=np.zeros_like(Pi),
                                               where=mag[:, None] > 0)
        return out, d

    rest_d = np.linalg.norm(blk.points[None, :, :] - blk.points[:, None, :], axis=-1)
    np.fill_diagonal(rest_d, np.inf)
    h = 1e-9 * float(np.min(rest_d))
    tol = 1e-6 * float(np.min(rest_d))

    def jac(zl, sl, live, Fz):
        """Finite-difference Jacobian of z - D(z): the m perturbed copies of every row in one evaluation of D."""
        nl = live.size
        zp = np.repeat(zl[None], m, axis=0) + h * np.eye(m)[:, None, :]          # (m, nl, m)
        Dp = D(zp.reshape(m * nl, m), np.tile(sl, m), np.tile(live, m))[0].reshape(m, nl, m)
        return np.transpose(((zp - Dp) - Fz[None]) / h, (1, 2, 0))               # (nl, m rows, m cols)

    def solve(z0, sl, live, iters=N_NEWTON):
        """Newton on z - D(z) = 0 from z0; (z, stable equilibrium found, relative gaps (rows, N, N))."""
        zl = z0.copy()
        for _ in range(iters):
            Dz, _ = D(zl, sl, live)
            Fz = zl - Dz
            if np.abs(Fz).max() <= 1e-3 * tol:
                break
            try:
                dz = np.linalg.solve(jac(zl, sl, live, Fz), -Fz[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            zl = zl + np.where(np.isfinite(dz), dz, 0.0)
        Dz, d = D(zl, sl, live)
        Fz = zl - Dz
        det = np.linalg.det(jac(zl, sl, live, Fz))
        rel = d / rest_d[None]
        np.einsum("rii->ri", rel)[:] = np.inf
        good = (np.abs(Fz).max(axis=1) <= tol) & (det > 0) & (rel.reshape(live.size, -1).min(axis=1) > 0.02)
        return zl, good, rel

    offs = np.concatenate([[0], np.cumsum(blk.k)])

    def solve_pinned(z0, rows, pinned, iters=N_NEWTON):
        """Newton on the coordinates not in ``pinned`` (the two capsules in contact stay where they are)."""
        free = np.setdiff1d(np.arange(m), pinned)
        zl = z0.copy()
        sl = np.ones(rows.size)
        for _ in range(iters):
            Fz = zl - D(zl, sl, rows)[0]
            if free.size == 0 or np.abs(Fz[:, free]).max() <= 1e-3 * tol:
                break
            J = jac(zl, sl, rows, Fz)[:, free][:, :, free]
            try:
                dz = np.linalg.solve(J, -Fz[:, free, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            zl[:, free] += np.where(np.isfinite(dz), dz, 0.0)
        return zl

    def _contact(solver, z, rows, i, j, warm):
        """Capsules i and j in contact (paper Eq. (3) past snap-in): their orifices meet halfway (all the way when
        one is fixed), projected on what their supports allow; the rest of the group in equilibrium around them."""
        zc = warm.copy()
        line = blk.points[j] - blk.points[i]
        share = (0.5, 0.5) if blk.k[i] and blk.k[j] else ((1.0, 0.0) if blk.k[i] else (0.0, 1.0))
        pinned = []
        for cap, sgn, sh in ((i, 1.0, share[0]), (j, -1.0, share[1])):
            o, k = offs[cap], blk.k[cap]
            if k:
                zc[:, o:o + k] = (sgn * sh * line) @ blk.basis[cap, :, :k]
                pinned.extend(range(o, o + k))
        return solver(zc, rows, np.array(pinned, int))

    snapped = np.zeros(r, bool)
    closing = np.zeros((r, 2), int)
    if m == 0:
        z = np.zeros((r, 0))
    else:
        # most rows: Newton at full load from the last solution found for them (warm start across the optimizer's
        # evaluations) or from rest; the rows where that fails are followed from rest by continuation
        start = blk.cache if blk.cache is not None and blk.cache.shape == (r, m) else np.zeros((r, m))
        everyone = np.arange(r)
        was = blk.contact_rows() if blk.cache is not None and blk.cache.shape == (r, m) else np.zeros(r, bool)
        z = np.zeros((r, m))
        good = np.zeros(r, bool)
        tried = everyone[~was]                      # rows in contact last time go straight to their continuation
        if tried.size:
            z[tried], good[tried], _ = solve(start[tried], np.ones(tried.size), tried, 8)
        todo = everyone[~good]
        first = np.ones(r, int)                       # first continuation step of each row
        if todo.size:
            z[todo] = 0.0
            if blk.fold is not None and blk.fold[0].shape == (r,):
                # rows that folded at the last evaluation: restart from their last stable step (not from rest)
                k_prev, z_prev = blk.fold
                again = todo[k_prev[todo] > 0]
                if again.size:
                    zl, ok, _ = solve(z_prev[again], k_prev[again] / N_STEPS, again)
                    z[again[ok]] = zl[ok]
                    first[again[ok]] = k_prev[again[ok]] + 1
        last_good = np.zeros(r, int)
        for step in range(1, N_STEPS + 1):
            rows_ = todo[first[todo] <= step]
            if todo.size == 0:
                break
            if rows_.size == 0:
                continue
            zl, ok, rel = solve(z[rows_], np.full(rows_.size, step / N_STEPS), rows_)
            z[rows_[ok]] = zl[ok]
            last_good[rows_[ok]] = step
            bad = rows_[~ok]
            if bad.size:
                # no stable equilibrium next to the last one: the branch folded (snap-in); the pair closest to
                # touching at the last stable configuration closes
                _, _, rel = solve(z[bad], np.full(bad.size, (step - 1) / N_STEPS), bad, 0)
                flat = rel.reshape(bad.size, -1).argmin(axis=1)
                closing[bad] = np.column_stack(np.unravel_index(flat, (N, N)))
                snapped[bad] = True
                last_good[bad] = step - 1
            todo = np.setdiff1d(todo, bad)
        blk.fold = (np.where(snapped, last_good, 0), z.copy())
        for i, j in {(int(a), int(b)) for a, b in closing[snapped]}:
            sel = np.flatnonzero(snapped & (closing[:, 0] == i) & (closing[:, 1] == j))
            warm = start[sel] if blk.cache is not None else z[sel]
            z[sel] = _contact(solve_pinned, z, sel, i, j, warm)
        blk.cache = z.copy()
        blk.closing = np.where(snapped[:, None], closing, -1)
    x = disp(z)
    p = blk.points[None] + x
    rr = np.arange(r)
    gap = np.linalg.norm(p[rr, blk.oj] - p[rr, blk.oi], axis=1)
    rest_gap = np.linalg.norm(blk.points[blk.oj] - blk.points[blk.oi], axis=1)
    contact = snapped & (((closing[:, 0] == blk.oi) & (closing[:, 1] == blk.oj))
                         | ((closing[:, 0] == blk.oj) & (closing[:, 1] == blk.oi)))
    gap = np.where(contact, 0.0, gap)
    moved = np.einsum("rk,rk->r", x[rr, blk.oi], blk.axis)
    return np.where(blk.kind == 0, gap - rest_gap, moved), snapped
