"""Paper Eq. (3), the declared reduced pair model (`acl fit --model eq3`): the stable gap of a facing pair.

P(d) = alpha a(f) V^2/d^2 - (thrust_a + thrust_b) with attraction positive (own thrust plus the partner's jet drag,
F_AS = F_d as the paper assumes), each beam deflecting by its law; the stable equilibrium d = d0 - delta_a - delta_b
reached from the rest gap, or contact (d = 0) past snap-in.  Solved by a vectorized bracket search from the rest gap
and the Illinois variant of regula falsi (acl.physics.roots), all rows at once.  The default pair model is the
analysis' own force model (acl.fit.group); this one is used only where a user asks for it.
"""
from __future__ import annotations

import numpy as np

from acl.fit import beam as B
from acl.physics.effects import drag_load, elastica_blend
from acl.physics.roots import illinois_step

N_GRID = 32
N_REFINE = 12
_GRID = np.linspace(0.0, 1.0, N_GRID + 1)     # the bracket grid from the rest gap (0) to the far end (1)


class _Flag:
    """A switch that ``with FLAG: ...`` turns on for the block (``active``)."""

    def __init__(self):
        self.active = False

    def __enter__(self):
        self.active = True
        return self

    def __exit__(self, *exc):
        self.active = False
        return False


def _spec(arrs, law, parent=None) -> tuple:
    """A law spec: per side the arrays (rigid length, c_D, c_T, L, EI, is a beam) and law codes of some rows, with
    (side 0 fixed, side 1 fixed, both sides alike).  ``parent``: the flags of a spec whose rows include these (a
    side fixed, or sides alike, on all of them is so on any of them: not checked again)."""
    pf = parent or (False, False, False)
    fixed = tuple(pf[c] or bool(np.all(law[c] == 2)) for c in range(2))
    return arrs, law, (*fixed, pf[2] or all(np.array_equal(a, b) for a, b in zip(arrs[0], arrs[1])))


def _make_laws(spec, lam):
    """(law of side 0, law of side 1, same) from a law spec (:func:`_spec`): paper Eq. (1), blended with the elastica
    by ``lam`` (large_deflection), zero for a side fixed to the substrate; one law when both sides are alike.  ``lam``
    a scalar or per row (rows of several predictions stacked, :func:`predict_many`)."""
    arrs, law, (fixed0, fixed1, same) = spec

    def make(l_, cd_, ct_, L_, EI_, beam_):
        if _on(lam) and np.any(beam_):
            wgt = np.where(beam_, lam, 0.0)
            return lambda load: elastica_blend(B.eq1_deflection(load, l_, cd_, ct_),
                                               np.where(beam_, B.elastica_deflection(load, L_, l_, EI_), 0.0), wgt)
        return lambda load: B.eq1_deflection(load, l_, cd_, ct_)

    def still(load):                                     # a side fixed to the substrate does not move
        return np.zeros(np.shape(load))

    first = still if fixed0 else make(*arrs[0])
    if fixed1 and not same:
        return first, still, False
    return first, (first if same else make(*arrs[1])), same


def _on(x) -> bool:
    """A scalar coefficient is non-zero (per-row coefficients: stacked only when all are, :func:`predict_many`)."""
    return bool(np.all(x != 0)) if np.ndim(x) else bool(x)


def _with_drag(law, c_p, steps=3):
    """Deflection law under a neighbour's jet drag, delta = law(P (1 - c_p |delta|)) (acl.physics.effects.drag_load),
    solved by Newton from the linear-law solution delta_lin / (1 + c_p |delta_lin|)."""
    def dragged(load):
        lin = law(load)
        lo, hi = np.minimum(lin, 0.0), np.maximum(lin, 0.0)
        d = lin / (1.0 + c_p * np.abs(lin))
        for _ in range(steps):
            ad = np.abs(d)
            x = drag_load(load, ad, c_p)
            h = 1e-6 * np.maximum(np.abs(x), 1e-30)
            lx, lxh = law(np.stack([x, x + h]))                     # (one call: the law is elementwise)
            r = lx - d
            slope = (lxh - lx) / h                                  # d law / d load
            dr = -slope * load * c_p * np.sign(d) * (1.0 - c_p * ad > 0) - 1.0   # d r / d delta
            d = np.clip(d - r / np.where(dr != 0, dr, -1.0), lo, hi)
        return d
    return dragged


def _pair_equilibrium(law0, law1, a_rad, push, d0, same=False, tol=None, info=None, guess=None, gather=None,
                      warm=False):
    """Stable gap of a facing pair under P(d) = a/d^2 - b, first root of d0 - d - delta_a - delta_b from d0.

    Bracketed on a grid from d0 (towards contact when the pair attracts at rest, outwards up to the
    largest repulsive opening otherwise; the whole grid in one vectorized evaluation), then refined by
    the Illinois variant of regula falsi (superlinear, always inside the bracket).
    Returns (delta_a, delta_b); past snap-in (no root before contact) the pair is in contact, d = 0.
    ``tol``: on |gap residual| (default 1e-12 of the largest d0); ``info``: a dict, filled with what
    :func:`_pair_warm` needs to reuse this solve (the bracket cell, its sign margin, the root).
    ``guess`` (with ``gather(rows) -> (law0, law1, same)`` of those rows, repeats allowed): each row's bracketing cell
    in an earlier solve; the grid is then read from d0 only up to the end of that cell (and on to the end where it has
    no crossing there), which gives the same first crossing, the same bracket and the same values bit for bit: the
    grid is elementwise.
    """
    both, g = _gap_residual(law0, law1, a_rad, push, d0, same)
    attract = a_rad / (d0 * d0) - push >= 0
    ra, rb = both(-push)
    far = np.where(attract, 0.02 * d0, d0 - ra - rb + 1e-12)
    m = d0.size
    cols = np.arange(m)
    if guess is None or gather is None or np.shape(guess) != (m,):
        guess, G = None, None
    else:
        G = np.full((N_GRID + 1, m), np.nan) if info is not None and warm else None
    found, k, a, fa, b, fb, G0, G = _bracket(g, a_rad, push, d0, far, guess, gather, G)
    exact = G0 == 0
    tol = 1e-12 * np.max(d0) if tol is None else tol
    for _ in range(N_REFINE):
        c, fc, flip = illinois_step(g, a, fa, b, fb)
        a, fa = np.where(flip, b, a), np.where(flip, fb, 0.5 * fa)
        b, fb = c, fc
        if np.all(np.abs(fc[found]) <= tol):
            break
    d = np.where(exact, d0, b)
    if info is not None and not warm:       # what a later solve's guess needs (the warm start's extras only with WARM)
        info.update(k=k, found=found)
        info = None
    if info is not None:
        # sign margin: the smallest |G| on the grid points before the bracketing cell (all of them when there is no
        # crossing), where a perturbation would have to flip a sign to make the search stop at another root
        j = np.arange(N_GRID + 1)[:, None]
        before = np.where(found, j < k, True)
        absg = np.where(before & np.isfinite(G), np.abs(G), np.inf)
        jmin = np.argmin(absg, axis=0)
        info.update(attract=attract, far=far, k=k, found=found, exact=exact, d=d, fb=fb,
                    conv=~found | exact | (np.abs(fb) <= tol), jmin=jmin, margin=absg[jmin, cols], Gj=G[jmin, cols],
                    tol=tol)
    found = found | exact
    if info is not None:       # the deflections at d and, 1e-8 d0 further, the slope of the gap residual there
        e = 1e-8 * d0
        dd = np.stack([d, d + e])
        da2, db2 = both(a_rad / (dd * dd) - push)
        da, db = da2[0], db2[0]
        info["slope"] = ((d0 - dd[1] - da2[1] - db2[1]) - (d0 - d - da - db)) / e
    else:
        load = a_rad / (d * d) - push
        da, db = both(load)
    return np.where(found, da, 0.5 * d0), np.where(found, db, 0.5 * d0)


def _gap_residual(law0, law1, a_rad, push, d0, same):
    """(both, g): the two deflections under a load, and the gap residual g(d) = d0 - d - delta_a - delta_b of a pair
    at gap d (paper Eq. 3: Bjerknes a_rad / d^2 against the push)."""
    def both(load):
        da = law0(load)
        return da, (da if same else law1(load))

    def g(d):
        da, db = both(a_rad / (d * d) - push)
        return d0 - d - da - db

    return both, g


def _bracket(g, a_rad, push, d0, far, guess, gather, G=None):
    """(found, k, a, fa, b, fb, g at d0, G) of the first sign change of ``g`` per row on the grid from d0 to ``far``:
    the whole grid at once (``guess`` None; G the grid's values), or read with :func:`_scan` from d0 up to each
    row's guessed cell and on to the end where it has no crossing there (``G``, if given, receives the values)."""
    m = d0.size
    cols = np.arange(m)
    if guess is None:
        D = d0 + _GRID[:, None] * (far - d0)                       # (N_GRID + 1, n)
        G = g(D)
        sg = np.sign(G)
        cross = sg[1:] != sg[:-1]
        k = np.argmax(cross, axis=0)
        return cross.any(axis=0), k, D[k, cols], G[k, cols], D[k + 1, cols], G[k + 1, cols], G[0], G
    npts = np.minimum(np.asarray(guess, int) + 2, N_GRID + 1)
    found, k, a, fa, b, fb, G0 = _scan(cols, npts, a_rad, push, d0, far, gather, G)
    more = ~found & (npts < N_GRID + 1)
    if np.any(more):                               # no crossing up to the guessed cell: read the rest of the grid
        r = np.flatnonzero(more)
        f2, k2, a2, fa2, b2, fb2, _ = _scan(r, np.full(r.size, N_GRID + 1), a_rad, push, d0, far, gather, G)
        found[r], k[r], a[r], fa[r], b[r], fb[r] = f2, k2, a2, fa2, b2, fb2
    return found, k, a, fa, b, fb, G0, G


def _scan(rows, npts, a_rad, push, d0, far, gather, G=None):
    """The grid of :func:`_pair_equilibrium` read on rows ``rows`` from d0 up to ``npts`` points each (one flat
    evaluation): (found, k, a, fa, b, fb, G at d0) of the first crossing per row; ``G`` (N_GRID + 1, n) receives
    the values read."""
    total = int(npts.sum())
    start = np.cumsum(npts) - npts
    r = np.repeat(rows, npts)
    j = np.arange(total) - np.repeat(start, npts)
    d0r, farr = d0[r], far[r]
    D = d0r + _GRID[j] * (farr - d0r)
    l0, l1, sm = gather(r)
    load = a_rad[r] / (D * D) - push[r]
    da = l0(load)
    Gv = d0r - D - da - (da if sm else l1(load))
    if G is not None:
        G[j, r] = Gv
    sg = np.sign(Gv)
    cross = np.zeros(total, bool)
    cross[1:] = (sg[1:] != sg[:-1]) & (j[1:] > 0)
    hits = np.flatnonzero(cross)
    first_row, first = np.unique(r[hits], return_index=True)      # r is sorted by row: the first crossing of each
    t = hits[first]
    pos = np.searchsorted(rows, first_row)
    n = rows.size
    found = np.zeros(n, bool)
    k = np.zeros(n, int)
    a, fa, b, fb = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    found[pos] = True
    k[pos] = j[t] - 1
    a[pos], fa[pos], b[pos], fb[pos] = D[t - 1], Gv[t - 1], D[t], Gv[t]
    # rows without a crossing: the full grid's argmax of no crossing is cell 0
    none = ~found
    if np.any(none):
        t0 = start[none]
        a[none], fa[none] = D[t0], Gv[t0]
        t1 = np.minimum(t0 + 1, start[none] + npts[none] - 1)
        b[none], fb[none] = D[t1], Gv[t1]
    return found, k, a, fa, b, fb, Gv[start]


WARM_SAFETY = 100.0     # a grid sign may move by at most this fraction of its margin (1/100) for the warm start
WARM_CHANGE = 1e-3      # largest relative change of a_rad, push and the rest opening for which a warm start is tried


class _FDColumns(_Flag):
    """``with FD_COLUMNS: predict(...)``: the predictions are finite-difference neighbours of the last one made outside
    (acl.fit.solve.fit's Jacobian), so a pair's equilibrium may start from that solve (:func:`_pair_solve`)."""


FD_COLUMNS = _FDColumns()


def _pair_solve(P, law0, law1, a_rad, push, d0, same, law_sig, laws):
    """:func:`_pair_equilibrium` of the pair rows, using the last full solve (kept on ``P``) where it can.

    Inputs (a_rad, push, deflection laws) bitwise those of the last full solve: its result (the solve is
    deterministic).  Otherwise the full solve reads the grid only up to each row's last bracketing cell (the same
    result bit for bit, :func:`_pair_equilibrium` ``guess``), except inside ``FD_COLUMNS`` (a Jacobian's
    finite-difference columns) with a_rad and push within WARM_CHANGE of the last full solve: :func:`_pair_warm`, a
    Newton step from the last root, kept for a row only if no grid sign before its cell can have flipped and it
    converges to the full solve's tolerance (else that row is solved in full), so a column agrees with the full
    solve's to the solver tolerance (tests/test_fit_pair_warm.py).  Full solves outside FD_COLUMNS refresh the cache."""
    cache = getattr(P, "_eq_cache", None)
    guess = None
    if cache is not None and (cache["d0"] is d0 or (cache["d0"].shape == d0.shape and np.array_equal(cache["d0"], d0))) \
            and cache["same"] == same:
        same_law = _same_law(law_sig, cache["law_sig"])
        if same_law and np.array_equal(a_rad, cache["a_rad"]) and np.array_equal(push, cache["push"]):
            return cache["da"], cache["db"]
        if law_sig[0] or law_sig[1]:     # an iterated law (elastica blend, drag): read the grid only up to the cell
            guess = np.where(cache["found"], cache["k"], N_GRID)
        if P.options.warm and FD_COLUMNS.active and "slope" in cache:
            with np.errstate(all="ignore"):
                ok = np.all(np.abs(a_rad - cache["a_rad"]) <= WARM_CHANGE * np.abs(cache["a_rad"])) and \
                    np.all(np.abs(push - cache["push"]) <= WARM_CHANGE * np.abs(cache["push"]))
            if ok:
                return _pair_warm(cache, law0, law1, a_rad, push, d0, same, laws)
            return _pair_equilibrium(law0, law1, a_rad, push, d0, same, guess=guess, gather=laws)
    if FD_COLUMNS.active:
        return _pair_equilibrium(law0, law1, a_rad, push, d0, same, guess=guess, gather=laws)
    info: dict = {}
    da, db = _pair_equilibrium(law0, law1, a_rad, push, d0, same, info=info, guess=guess, gather=laws,
                               warm=P.options.warm)
    info.update(d0=d0, same=same, law_sig=law_sig, a_rad=a_rad, push=push, da=da, db=db)
    P._eq_cache = info
    return da, db


def _same_law(sig, ref) -> bool:
    """Two law signatures (lam, c_p, law arrays) are equal (the same deflection laws)."""
    return (sig[0] == ref[0] and sig[1] == ref[1] and len(sig) == len(ref)
            and all(a is b or np.array_equal(a, b) for a, b in zip(sig[2:], ref[2:])))


def _pair_solve_many(P, reqs) -> list:
    """[:func:`_pair_solve` of each request] (the warm start off): the same numbers, with the solves of
    requests whose deflection laws have the same form (fixed sides, alike sides, elastica blend and drag on or off)
    made at once on their stacked rows (:func:`_pair_equilibrium_many`)."""
    cache = getattr(P, "_eq_cache", None)
    out: list = [None] * len(reqs)
    todo: dict = {}
    for j, q in enumerate(reqs):
        _, law0, law1, a_rad, push, d0, same, law_sig, laws, sp, lam, c_p = q
        guess = None
        if cache is not None and (cache["d0"] is d0 or (cache["d0"].shape == d0.shape
                                                        and np.array_equal(cache["d0"], d0))) and cache["same"] == same:
            if _same_law(law_sig, cache["law_sig"]) and np.array_equal(a_rad, cache["a_rad"]) \
                    and np.array_equal(push, cache["push"]):
                out[j] = (cache["da"], cache["db"])
                continue
            if law_sig[0] or law_sig[1]:
                guess = np.where(cache["found"], cache["k"], N_GRID)
        form = (sp[2], same, _on(lam), bool(c_p > 0))
        todo.setdefault(form, []).append((j, guess))
    for form, items in todo.items():
        if len(items) == 1:
            (j, guess), = items
            q = reqs[j]
            out[j] = _pair_equilibrium(q[1], q[2], q[3], q[4], q[5], q[6], guess=guess, gather=q[8])
            continue
        qs = [reqs[j] for j, _ in items]
        m = qs[0][5].size
        d0 = np.concatenate([q[5] for q in qs])
        arrs = tuple(tuple(np.concatenate([q[9][0][c][k] for q in qs]) for k in range(6)) for c in range(2))
        law = tuple(np.concatenate([q[9][1][c] for q in qs]) for c in range(2))

        def per_row(vals):
            """One coefficient of the stacked predictions: a scalar when they agree bitwise, else per row."""
            vals = [float(v) for v in vals]
            if all(v.hex() == vals[0].hex() for v in vals):
                return vals[0]
            return np.repeat(np.array(vals), m)

        lam = per_row([q[10] for q in qs])
        c_p = per_row([q[11] for q in qs])

        def gather(sub, arrs=arrs, law=law, lam=lam, c_p=c_p, parent=_spec(arrs, law)[2]):
            """(law0, law1, same) of the stacked rows ``sub``."""
            sl = lambda x: x[sub] if np.ndim(x) else x      # noqa: E731
            l0, l1, sm = _make_laws(_spec(tuple(tuple(a[sub] for a in side) for side in arrs),
                                          tuple(x[sub] for x in law), parent), sl(lam))
            if _on(c_p > 0):
                l0 = _with_drag(l0, sl(c_p))
                l1 = l0 if sm else _with_drag(l1, sl(c_p))
            return l0, l1, sm

        law0, law1, same = gather(np.arange(d0.size))
        guess = None if all(g is None for _, g in items) else \
            np.concatenate([np.full(m, N_GRID) if g is None else g for _, g in items])
        da, db = _pair_equilibrium_many(law0, law1, np.concatenate([q[3] for q in qs]),
                                        np.concatenate([q[4] for q in qs]), d0, same, len(qs), guess, gather)
        for b, (j, _) in enumerate(items):
            out[j] = (da[b * m:(b + 1) * m], db[b * m:(b + 1) * m])
    return out


def _pair_equilibrium_many(law0, law1, a_rad, push, d0, same, nblk, guess, gather):
    """:func:`_pair_equilibrium` of ``nblk`` pair solves at once, their rows stacked (blocks of equal size, equal rest
    gaps): the bracket grid read as with ``guess`` (None: the whole grid for every row; a row of a solve without one
    reads the whole grid, which gives the same bracket), and each block's refinement stopped where its own solve stops (all its rows converged), so that
    every block's numbers are its own solve's, bit for bit."""
    both, g = _gap_residual(law0, law1, a_rad, push, d0, same)
    attract = a_rad / (d0 * d0) - push >= 0
    ra, rb = both(-push)
    far = np.where(attract, 0.02 * d0, d0 - ra - rb + 1e-12)
    per = d0.size // nblk
    found, _, a, fa, b, fb, G0, _ = _bracket(g, a_rad, push, d0, far, guess, gather)
    exact = G0 == 0
    tol = 1e-12 * np.max(d0)
    live = np.ones(nblk, bool)
    for _ in range(N_REFINE):
        on = None if live.all() else np.repeat(live, per)
        c, fc, flip = illinois_step(g, a, fa, b, fb)
        if live.all():
            a, fa = np.where(flip, b, a), np.where(flip, fb, 0.5 * fa)
            b, fb = c, fc
        else:
            a, fa = np.where(on & flip, b, a), np.where(on, np.where(flip, fb, 0.5 * fa), fa)
            b, fb = np.where(on, c, b), np.where(on, fc, fb)
        live &= ~np.all(((np.abs(fc) <= tol) | ~found).reshape(nblk, per), axis=1)     # as each solve stops
        if not np.any(live):
            break
    d = np.where(exact, d0, b)
    found = found | exact
    load = a_rad / (d * d) - push
    da, db = both(load)
    return np.where(found, da, 0.5 * d0), np.where(found, db, 0.5 * d0)


def _pair_warm(c, law0, law1, a_rad, push, d0, same, laws):
    """Pair equilibrium from the cached full solve ``c`` (:func:`_pair_solve`): one Newton step from its root with its
    slope.  A row keeps it if the gap residual changed, at the root and at the grid point of smallest margin before
    the bracketing cell, by less than 1/WARM_SAFETY of that margin (no grid sign before the root can have flipped:
    the full solve would stop at the same root) and the step lands within the full solve's tolerance; any other row
    is solved by :func:`_pair_equilibrium` with that tolerance."""
    def g(d):
        load = a_rad / (d * d) - push
        da = law0(load)
        db = da if same else law1(load)
        return d0 - d - da - db, da, db

    root, tol = c["d"], c["tol"]
    dj = d0 + np.linspace(0.0, 1.0, N_GRID + 1)[c["jmin"]] * (c["far"] - d0)
    with np.errstate(all="ignore"):
        attract = a_rad / (d0 * d0) - push >= 0
        (g0, gj), DA, DB = g(np.stack([root, dj]))
        change = np.maximum(np.abs(g0 - c["fb"]), np.abs(gj - c["Gj"]))
        found = c["found"] & ~c["exact"]
        # a row at rest (G = 0 at d0: no load) stays there while it has no load
        good = (attract == c["attract"]) & np.where(
            c["exact"], g0 == 0, c["conv"] & (c["margin"] > WARM_SAFETY * change))
        da, db = DA[0], DB[0]
        step = found & good & ~(np.abs(g0) <= tol)
        if np.any(step):
            d1 = root - g0 / c["slope"]
            f1, da1, db1 = g(d1)
            good &= ~step | (np.abs(f1) <= tol)
            da, db = np.where(step, da1, da), np.where(step, db1, db)
    live = c["found"] | c["exact"]
    da, db = np.where(live, da, 0.5 * d0), np.where(live, db, 0.5 * d0)
    bad = ~good
    if np.any(bad):
        l0, l1, sm = laws(bad)
        ra, rb = _pair_equilibrium(l0, l1, a_rad[bad], push[bad], d0[bad], sm, tol=tol)
        da[bad], db[bad] = ra, rb
    return da, db
