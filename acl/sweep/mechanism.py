"""Batched equilibria, snap-in and deflections of a whole mechanism (springs, latches, trusses, any number of moving capsules).

The batched twin of :mod:`acl.analysis.mechanics` for mechanisms that :mod:`acl.sweep.evaluate`'s closed
forms for one capsule on a beam or a pair on two beams do not cover.  The degrees of freedom are
those of :func:`acl.analysis.mechanics.build_mechanism` for the nominal design (its groups, elements
and spring links); every number that depends on a swept parameter is taken per point:

* each group's basis of motion (the plane perpendicular to its beam's axis, the latch's or spring's
  axis; mechanics._perp_basis), the null space of the truss bars between supported capsules (the
  bar directions follow the capsule centres; mechanics.build_mechanism, SVD per point);
* restoring forces: paper Eq. (1) in the beam's plane (isotropic, smallest second moment), the von
  Mises truss latch law (acl.physics.latch; a latch held in state b from its second stable state), linear springs, spring links (mechanics._restoring);
* the acoustic forces of every capsule at displaced centres (the evaluator's force engine, the
  same model as acoustics.force_batch).

Equilibria: Newton on the generalized coordinates with a forward-difference Jacobian (one force
evaluation per coordinate), stable while the Jacobian's eigenvalues have positive real parts
(Bazant & Cedolin, Stability of Structures, Ch. 4).  Continuation in the drive scale V (natural
parameter) with a tangent predictor (Euler in V^2 along K_T^-1 G, Keller 1977) and an adaptive
step: a step is accepted only when Newton converges to a stable, admissible (no contact:
mechanics._admissible) equilibrium within ``STEP_REACH`` of the prediction (analyze's
pseudo-arclength steps move at most half its 5 um length scale), and no prediction moves more than
``STEP_MOVE``; the step grows while the corrections stay small.  A failed short step brackets the
fold (snap-in) from above and the bracket is bisected from below: the reported snap-in voltage is
the last stable voltage less the bracket's width, below the fold by at most 4 ``rtol`` x V_max, never
above it.  No Python loop over points: a loop over continuation steps and Newton iterations, each
vectorised over the points.
"""
from __future__ import annotations

import numpy as np

from acl.physics import batch as PB
from acl.physics.roots import golden_max, illinois_ascending
from acl.sweep.acoustic_state import beam_force, beam_k0

STEP_REACH = 2.5e-6       # m; largest accepted distance of a step's equilibrium from its tangent prediction
FOLD_STEP = 1e-4          # relative to v_max; a failed step this short brackets a fold (bisection below it)
STEP_MOVE = 50e-6         # m; largest predicted move of the coordinates in one continuation step
AXIS_TOL = 1e-12          # relative; a group with two elements needs their axes fixed to this


class MechanismError(ValueError):
    """The mechanism cannot be batched for these points (the message says why)."""


def not_batched(design) -> str | None:
    """Why the general batched mechanism does not cover ``design`` (None: it does)."""
    from acl.analysis import mechanics as ME
    from acl.diagnostics import DiagnosticError

    try:
        ME.build_mechanism(design)
    except DiagnosticError:
        return "the mechanism's joints do not resolve (acl check reports them)"
    return None


def _direction(J, G) -> np.ndarray:
    """Branch tangent dz/d(V^2) = K_T^-1 G at an equilibrium of R(z) = V^2 G(z) (Keller 1977); 0 where K_T is singular."""
    ok = np.isfinite(J).all(axis=(1, 2)) & np.isfinite(G).all(axis=1)
    ok &= np.abs(np.linalg.det(np.where(ok[:, None, None], J, 0.0))) > 0
    t = np.linalg.solve(np.where(ok[:, None, None], J, np.eye(J.shape[-1])), np.where(ok[:, None], G, 0.0)[..., None])
    return np.where(ok[:, None], t[..., 0], 0.0)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perp_basis(axis):
    """(N, 3, 2) orthonormal basis of the plane perpendicular to each axis (mechanics._perp_basis)."""
    a = _unit(axis)
    trial = np.where((np.abs(a[:, 0]) < 0.9)[:, None], np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    e1 = _unit(trial - a * np.einsum("bk,bk->b", trial, a)[:, None])
    return np.stack([e1, np.cross(a, e1)], axis=2)


class Mechanism:
    """The mechanism of ``ev.design`` over the evaluator's points (see the module docstring)."""

    def __init__(self, ev):
        from acl.analysis import mechanics as ME

        self.ev = ev
        d = ev.design
        self.n = ev.n
        mech = ME.build_mechanism(d)
        self.mech = mech
        names = [c.name for c in ev.caps]
        self.names = names
        ncap = len(names)
        n = ev.n
        # per-point basis of each group (N, 3, k)
        self.bases = []
        self.elements = []
        for gi, A in enumerate(mech.bases):
            els = [el for el in mech.elements if el.group == gi]
            k = A.shape[1]
            if k == 0:
                self.bases.append(np.zeros((n, 3, 0)))
                continue
            if len(els) == 1:
                el = els[0]
                B = self._element_basis(el)
                if B.shape[2] != k:
                    raise MechanismError(f"group {mech.groups[gi]}: its element's motion does not match the mechanism's")
                self.bases.append(B)
            else:
                for el in els:
                    B = self._element_basis(el)
                    if np.max(np.abs(B - B[:1])) > AXIS_TOL:
                        raise MechanismError(f"group {mech.groups[gi]} has several elements whose axes a swept parameter moves")
                self.bases.append(np.broadcast_to(A, (n, 3, k)))
        for el in mech.elements:
            self.elements.append(self._element_law(el))
        self.links = []
        for (_k, _nax, ga, gb, name) in mech.links:
            ks = ev.get(f"springs.{name}.stiffness")
            nax = _unit(ev.vec(f"springs.{name}.axis"))
            self.links.append((ks, nax, ga, gb, name))
        # q (N, nq) -> capsule displacements: place (N, nq, C, 3)
        nq = mech.n
        place = np.zeros((n, nq, ncap, 3))
        for c, name in enumerate(names):
            gi = mech.member_group[name]
            o, k = mech.offsets[gi], self.bases[gi].shape[2]
            place[:, o:o + k, c, :] = np.swapaxes(self.bases[gi], 1, 2)
        self.place_q = place
        self.Z = self._null_space(ME)
        self.m = self.Z.shape[2]
        self.place = np.einsum("nqm,nqck->nmck", self.Z, place)
        self.rest = ev.layout()["rest"]
        self._pairs = self._admissible_pairs()

    # -- construction -----------------------------------------------------------------------------
    def _element_basis(self, el):
        ev = self.ev
        if el.kind == "beam":
            return _perp_basis(ev.vec(f"beams.{el.name}.axis"))
        base = "latches" if el.kind == "latch" else "springs"
        return _unit(ev.vec(f"{base}.{el.name}.axis"))[:, :, None]

    def _element_law(self, el):
        ev = self.ev
        if el.kind == "beam":
            c = next(i for i, cap in enumerate(ev.caps)
                     if (j := ev.design.mount_of(cap.name)) is not None and j.kind == "mount"
                     and j.target_kind == "beam" and j.target == el.name)
            bm = ev.beam_of(c)
            basis = _perp_basis(bm["axis"])
            return {"kind": "beam", "name": el.name, "group": el.group, "basis": basis, "L": bm["L"], "l": bm["l"],
                    "EI": bm["EI"], "law": bm["law"], "k0": beam_k0(bm)}
        if el.kind == "latch":
            base = f"latches.{el.name}"
            geo = tuple(ev.get(f"{base}.{k}") for k in ("angle", "length", "width", "thickness"))
            geo += (ev.get(f"{base}.youngs_modulus") * ev.e_scale(),)     # stiffness_scale (mechanics.latch_geometry)
            # held in state b: travel measured from state a, the rest at the second stable state (mechanics._latch_law)
            u0 = PB.latch_state_b(*geo) if ev.design.latch(el.name).state == "b" else np.zeros(self.n)
            return {"kind": "latch", "name": el.name, "group": el.group, "axis": _unit(ev.vec(f"{base}.axis")),
                    "geo": geo, "u0": u0}
        return {"kind": "spring", "name": el.name, "group": el.group, "axis": _unit(ev.vec(f"springs.{el.name}.axis")),
                "k": ev.get(f"springs.{el.name}.stiffness")}

    def _null_space(self, ME) -> np.ndarray:
        """Z (N, nq, m): q = Z z, the null space of the (linearised) truss bars between supported capsules, per point."""
        d, mech, ev = self.ev.design, self.mech, self.ev
        nq = mech.n
        names = self.names
        supported = {nm for nm in names if d.mount_of(nm) is not None}
        anchors = {a.name for a in d.anchors}
        centre = {nm: ev.capsule(i)["center"] for i, nm in enumerate(names)}
        rows = []
        for j in d.joints:
            if j.kind != "link" or j.element_kind != "truss":
                continue
            ends = [e for e in (j.a, j.b) if e in names]
            other = j.b if j.a in names else j.a
            if len(ends) == 2 and ends[0] in supported and ends[1] in supported:
                a, pb = ends[0], centre[ends[1]]
                bend = ends[1]
            elif len(ends) == 1 and ends[0] in supported and other in anchors:
                a, pb, bend = ends[0], ev.vec(f"anchors.{other}.position"), None
            else:
                continue
            nb = _unit(pb - centre[a])
            row = np.zeros((self.n, nq))
            for end, sgn in ((a, 1.0), (bend, -1.0)):
                if end is None:
                    continue
                gi = mech.member_group[end]
                o, k = mech.offsets[gi], self.bases[gi].shape[2]
                row[:, o:o + k] += sgn * np.einsum("nik,ni->nk", self.bases[gi], nb)
            rows.append(row)
        if not rows or nq == 0:
            return np.broadcast_to(np.eye(nq), (self.n, nq, nq)).copy()
        C = np.stack(rows, axis=1)                                           # (N, r, nq)
        _, s, vt = np.linalg.svd(C)
        rank = int(np.sum(s[0] > 1e-9 * max(s[0].max(), 1e-300)))
        ranks = (s > 1e-9 * np.maximum(s.max(axis=1, keepdims=True), 1e-300)).sum(axis=1)
        if np.any(ranks != rank):
            raise MechanismError("the truss bars' constraints change rank over the points")
        return np.swapaxes(vt[:, rank:, :], 1, 2).copy()

    def _admissible_pairs(self):
        """Closest orifices (nominal choice, mechanics._closest_orifices) of capsules in different groups, their rest direction per point."""
        mech, ev = self.mech, self.ev
        lay = ev.layout()
        out = []
        for i, ca in enumerate(ev.caps):
            for j in range(i + 1, len(ev.caps)):
                cb = ev.caps[j]
                if mech.member_group[ca.name] == mech.member_group[cb.name] or not ca.orifices or not cb.orifices:
                    continue
                best = min(((np.linalg.norm(np.subtract(ob.center, oa.center)), ia, ib)
                            for ia, oa in enumerate(ca.orifices) for ib, ob in enumerate(cb.orifices)))
                ka = int(np.flatnonzero(lay["body"] == i)[best[1]])
                kb = int(np.flatnonzero(lay["body"] == j)[best[2]])
                pa = lay["rest"][:, i] + lay["offsets"][:, ka]
                pb = lay["rest"][:, j] + lay["offsets"][:, kb]
                out.append((i, j, np.einsum("nk,nk->n", pb - pa, _unit(pb - pa)), _unit(pb - pa)))
        return out

    # -- forces ------------------------------------------------------------------------------------
    def displacements(self, z) -> np.ndarray:
        """(N, C, 3) capsule displacements at coordinates z (N, m)."""
        return np.einsum("nmck,nm->nck", self.place, z)

    def group_x(self, q, gi) -> np.ndarray:
        if gi is None:
            return np.zeros((self.n, 3))
        o, k = self.mech.offsets[gi], self.bases[gi].shape[2]
        return np.einsum("nik,nk->ni", self.bases[gi], q[:, o:o + k])

    def restoring(self, z) -> np.ndarray:
        """Generalized restoring force (N, m) at z (mechanics._restoring)."""
        q = np.einsum("nqm,nm->nq", self.Z, z)
        f = np.zeros_like(q)
        for el in self.elements:
            gi = el["group"]
            o, k = self.mech.offsets[gi], self.bases[gi].shape[2]
            if k == 0:
                continue
            x = self.group_x(q, gi)
            if el["kind"] == "beam":
                B = el["basis"]
                u = np.einsum("nij,nj->ni", B, np.einsum("nij,ni->nj", B, x))
                delta = np.linalg.norm(u, axis=-1)
                P = beam_force(delta, el)
                ratio = np.where(delta < 1e-15 * el["L"], el["k0"], P / np.where(delta > 0, delta, 1.0))
                fe = ratio[:, None] * u
            elif el["kind"] == "latch":
                a = el["axis"]
                s = el["u0"] + np.einsum("ni,ni->n", a, x)
                fe = PB.latch_force(s, *el["geo"])[:, None] * a
            else:
                a = el["axis"]
                fe = (el["k"] * np.einsum("ni,ni->n", a, x))[:, None] * a
            f[:, o:o + k] += np.einsum("nik,ni->nk", self.bases[gi], fe)
        for ks, nax, ga, gb, _name in self.links:
            ext = np.einsum("ni,ni->n", nax, self.group_x(q, ga) - self.group_x(q, gb))
            for g, sgn in ((ga, 1.0), (gb, -1.0)):
                if g is None or self.bases[g].shape[2] == 0:
                    continue
                o, k = self.mech.offsets[g], self.bases[g].shape[2]
                f[:, o:o + k] += (sgn * ks * ext)[:, None] * np.einsum("nik,ni->nk", self.bases[g], nax)
        return np.einsum("nqm,nq->nm", self.Z, f)

    def external(self, z, freqs, volts) -> np.ndarray:
        """Generalized acoustic force (N, m) at z for the drive (freqs, volts)."""
        F = self.ev.forces(self.rest + self.displacements(z), freqs, volts)
        return np.einsum("nmck,nck->nm", self.place, F)

    def residual(self, z, lam, freqs, volts) -> np.ndarray:
        return self.restoring(z) - lam[:, None] * self.external(z, freqs, volts)

    def admissible(self, z) -> np.ndarray:
        """No contact: every pair's gap along its rest direction stays positive (mechanics._admissible)."""
        ok = np.ones(self.n, bool)
        if not self._pairs:
            return ok
        disp = self.displacements(z)
        for i, j, g0, nrm in self._pairs:
            ok &= g0 + np.einsum("nk,nk->n", nrm, disp[:, j] - disp[:, i]) > 0.0
        return ok

    def deflections(self, z) -> dict:
        """{element: (N,)} as mechanics._deflections: beam load-point deflection, latch travel, spring extension."""
        q = np.einsum("nqm,nm->nq", self.Z, z)
        out = {}
        for el in self.elements:
            x = self.group_x(q, el["group"])
            if el["kind"] == "beam":
                B = el["basis"]
                out[el["name"]] = np.linalg.norm(np.einsum("nij,ni->nj", B, x), axis=-1)
            elif el["kind"] == "latch":
                out[el["name"]] = el["u0"] + np.einsum("ni,ni->n", el["axis"], x)
            else:
                out[el["name"]] = np.einsum("ni,ni->n", el["axis"], x)
        for _ks, nax, ga, gb, name in self.links:
            out[name] = np.einsum("ni,ni->n", nax, self.group_x(q, ga) - self.group_x(q, gb))
        return out

    # -- solvers -------------------------------------------------------------------------------------
    def solve(self, z, lam, freqs, volts, live, iterations: int = 12, h: float = 1e-12, patient: bool = False,
              jacobian=None):
        """Newton from z at drive scale lam (rows ``live``): (z, converged to a stable admissible equilibrium, tangent
        stiffness there, generalized acoustic force there).

        ``jacobian`` (the tangent stiffness at the last equilibrium) starts chord iterations (Keller
        1977), refreshed by a forward-difference Jacobian when they stop contracting.  Converged when
        |R| <= 1e-10 x the force scale (solve_equilibrium's test) or the step is below 1e-10 of |z|.
        A row whose Newton steps stop contracting (by half after the third) is given up, unless
        ``patient`` (the probe just above a kink of the force law).
        """
        m = self.m
        conv = np.zeros(self.n, bool)
        lost = ~live.copy()
        prev = np.full(self.n, np.inf)

        def tangent(z, r):
            J = np.empty((self.n, m, m))
            for k in range(m):
                dz = z.copy()
                dz[:, k] += h
                J[:, :, k] = (self.residual(dz, lam, freqs, volts) - r) / h
            return np.where(np.isfinite(J), J, 0.0)

        J = None if jacobian is None else jacobian.copy()
        chord = J is not None
        newton_its = 0
        for it in range(4 * iterations + 1):
            R, G = self.restoring(z), self.external(z, freqs, volts)
            r = R - lam[:, None] * G
            scale = np.maximum(np.abs(R).max(axis=1), np.abs(lam[:, None] * G).max(axis=1))
            active = ~(conv | lost)
            conv |= active & (np.abs(r).max(axis=1) <= 1e-10 * scale + 1e-30)
            active = ~(conv | lost)
            if not active.any() or newton_its >= iterations:
                break
            if not chord:
                J = tangent(z, r)
                newton_its += 1
            ok_j = np.abs(np.linalg.det(J)) > 0
            step = np.linalg.solve(np.where(ok_j[:, None, None], J, np.eye(m)),
                                   -np.where(np.isfinite(r), r, 0.0)[..., None])[..., 0]
            step = np.where((ok_j & np.isfinite(r).all(axis=1))[:, None], step, np.nan)
            fine = np.isfinite(step).all(axis=1)
            size = np.linalg.norm(step, axis=-1)
            if chord and (it >= 4 or np.any(active & ~(size < 0.5 * prev) & np.isfinite(prev))):
                chord = False                           # the chord stalls: Newton from here on
                prev = np.full(self.n, np.inf)
                continue
            z = np.where((active & fine)[:, None], z + step, z)
            conv |= active & fine & (size <= 1e-10 * np.linalg.norm(z, axis=-1) + 1e-18)
            if not chord:
                lost |= active & ~fine
            if not chord and newton_its >= 4 and not patient:
                lost |= active & ~conv & ~(size < 0.5 * prev)
            prev = np.where(active, size, prev)
        # stability at the converged point
        G = self.external(z, freqs, volts)
        r = self.restoring(z) - lam[:, None] * G
        J = tangent(z, r)
        mev = np.linalg.eigvals(J).real.min(axis=1)
        good = conv & ~lost & (mev > 0) & np.isfinite(z).all(axis=1) & self.admissible(z)
        return z, good, J, G

    def continuation(self, freqs, volts, v_max, steps: int = 12, rtol: float = 1e-9, budget: int = 300):
        """Stable branch from rest as the drive is scaled by V from 0 to v_max: (V reached, z there, reached v_max).

        Rows whose branch is still moving after ``budget`` x ``steps`` steps stop there, not reached: their
        snap-in is the last stable voltage, a lower bound.
        """
        v_max = np.broadcast_to(np.asarray(v_max, float), (self.n,)).copy()
        z = np.zeros((self.n, self.m))
        if self.m == 0:
            return v_max, z, np.ones(self.n, bool)
        _, _, J, G = self.solve(z, np.zeros(self.n), freqs, volts, np.zeros(self.n, bool))     # tangent at rest
        st = {"z": z, "J": J, "t": _direction(J, G), "v": np.zeros(self.n), "dv": v_max / steps, "v_max": v_max,
              "done": np.zeros(self.n, bool), "reached": np.zeros(self.n, bool), "failed": np.zeros(self.n, bool),
              "pending": np.zeros(self.n, bool), "v_fail": np.full(self.n, np.inf)}
        self._march(st, freqs, volts, steps, rtol, budget * steps)
        return st["v"], st["z"], st["reached"]

    def _march(self, st: dict, freqs, volts, steps: int, rtol: float, left: int) -> None:
        """Continuation steps on the state ``st`` (arrays over the points, updated in place); when fewer than half
        the points are still going, the rest continue on a mechanism of those points only.

        Each step predicts along the branch's tangent (Euler in V^2, exact where the response is linear in
        the drive's power), shortened so that the prediction moves at most ``STEP_MOVE``, and corrects by
        Newton; it is accepted when the corrected equilibrium is stable, admissible and within
        ``STEP_REACH`` of the prediction.  The step grows while the corrections stay small (by up to 2x,
        sqrt of STEP_REACH / 4 over the correction: the predictor's error is quadratic in the step) and
        is halved after a failure, so a fold is bracketed from below by bisection.
        """
        z, J, t, v, dv, v_max = st["z"], st["J"], st["t"], st["v"], st["dv"], st["v_max"]
        done, reached, failed, pending, v_fail = st["done"], st["reached"], st["failed"], st["pending"], st["v_fail"]
        while left > 0:
            going = ~done
            if not going.any():
                break
            if self.n >= 16 and going.sum() <= self.n // 2:
                rows = np.flatnonzero(going)
                sub = {k: a[rows].copy() for k, a in st.items()}
                self.sub(rows)._march(sub, freqs, volts, steps, rtol, left)
                for k, a in st.items():
                    a[rows] = sub[k]
                return
            live = going & ~pending
            if not live.any():
                self._over_the_fold(st, freqs, volts, rtol)
                continue
            left -= 1
            v_try = np.minimum(np.minimum(v + dv, v_max), np.where(np.isfinite(v_fail), 0.5 * (v + v_fail), np.inf))
            dlam = v_try * v_try - v * v
            move = np.linalg.norm(t, axis=-1) * dlam
            big = live & (move > STEP_MOVE)
            if big.any():           # shorten the step to a predicted move of STEP_MOVE
                v_try = np.where(big, np.sqrt(v * v + dlam * STEP_MOVE / np.where(big, move, 1.0)), v_try)
                dv[...] = np.where(big, v_try - v, dv)
                dlam = v_try * v_try - v * v
            pred = z + t * dlam[:, None]
            zn, conv, Jn, Gn = self.solve(pred, v_try * v_try, freqs, volts, live, jacobian=J)
            off = np.linalg.norm(zn - pred, axis=-1)
            good = conv & (off <= STEP_REACH) & live
            z[...] = np.where(good[:, None], zn, z)
            J[...] = np.where(good[:, None, None], Jn, J)
            t[...] = np.where(good[:, None], _direction(Jn, Gn), t)
            v[...] = np.where(good, v_try, v)
            # grow after two successes in a row, halve after a failure: near the fold, a bisection from below
            with np.errstate(divide="ignore"):
                grow = np.clip(np.sqrt(0.25 * STEP_REACH / off), 0.5, 2.0)
            dv[...] = np.where(good, np.where(failed, dv, np.minimum(dv * grow, v_max / steps)),
                               np.where(live, dv / 2, dv))
            # a step of at most FOLD_STEP x v_max that fails brackets the fold from above: bisection from there
            small = live & ~good & (v_try - v <= FOLD_STEP * v_max)
            v_fail[...] = np.where(small, np.minimum(v_fail, v_try), v_fail)
            failed[...] = live & ~good
            hit = good & (v >= v_max)
            reached |= hit
            done |= hit
            # bracketed to rtol: probed just above, together with the other rows that fold (one batch)
            pending |= live & ~hit & ((~good & (dv < rtol * v_max)) | (v_fail - v < rtol * v_max))
        if pending.any():
            self._over_the_fold(st, freqs, volts, rtol)
            done |= pending

    def _over_the_fold(self, st: dict, freqs, volts, rtol: float) -> None:
        """The rows ``pending`` at a limit point, or at a kink of the force law (a latch buckling) that Newton's
        steps cannot cross: a patient solve just above it, kept only when it stays next to the branch
        (acl.physics.equilibrium._equilibrium_just_above); those continue, the others are done (snapped).

        A snapped row reports its last stable voltage less the width of its bracket (at most 2 rtol x v_max):
        Newton's residual test (1e-10 of the force scale) accepts a point up to that far past a kink, and
        the bracket's width is larger, so the reported snap-in stays below the fold.
        """
        z, J, t, v, dv, v_max = st["z"], st["J"], st["t"], st["v"], st["dv"], st["v_max"]
        folded = st["pending"].copy()
        margin = np.minimum(st["v_fail"] - v, 2 * dv)
        for rel in (1e-6, 1e-4):
            v_up = np.minimum(v * (1 + rel) + rel, v_max)
            zn, conv, Jn, Gn = self.solve(z, v_up * v_up, freqs, volts, folded, iterations=30, patient=True)
            near = np.linalg.norm(zn - z, axis=-1) <= 1e-2 * np.maximum(np.linalg.norm(z, axis=-1), 1e-300)
            over = folded & conv & near
            z[...] = np.where(over[:, None], zn, z)
            J[...] = np.where(over[:, None, None], Jn, J)
            t[...] = np.where(over[:, None], _direction(Jn, Gn), t)
            v[...] = np.where(over, v_up, v)
            dv[...] = np.where(over, 4 * rtol * v_max, dv)
            st["failed"][...] = np.where(over, False, st["failed"])
            st["v_fail"][...] = np.where(over, np.inf, st["v_fail"])
            hit = over & (v >= v_max)
            st["reached"][...] |= hit
            st["done"][...] |= hit
            folded &= ~over
        v[...] = np.where(folded, np.maximum(v - margin, 0.0), v)
        st["done"][...] |= folded
        st["pending"][...] = False

    def smooth_one(self) -> bool:
        """One coordinate and smooth restoring laws (no latch): the branch is the curve V^2(z) = R(z)/G(z)."""
        return self.m == 1 and not any(el["kind"] == "latch" for el in self.elements)

    def snap_in(self, freqs, volts, v_max) -> np.ndarray:
        """Snap-in voltage of the drive shape (NaN: a stable branch up to v_max)."""
        v_max = np.broadcast_to(np.asarray(v_max, float), (self.n,))
        if self.smooth_one():
            cur = self.curve(freqs, volts)
            v = np.sqrt(cur["v2_fold"])
            out = np.where(cur["has_fold"] & (v <= v_max), v, np.nan)
            rows = np.flatnonzero(cur["open"])          # no contact bound: the continuation decides
            if rows.size:      # (not the subset's snap_in: its curve is open again, and it recursed without end)
                v, _, reached = self.sub(rows).continuation(freqs, volts, v_max[rows])
                out[rows] = np.where(reached, np.nan, v)
            return out
        v, _, reached = self.continuation(freqs, volts, v_max)
        return np.where(reached, np.nan, v)

    def equilibrium(self, freqs, volts):
        """(z, ok) at the drive itself (scale 1), by continuation from rest; not ok after snap-in."""
        if self.smooth_one():
            return self.curve_equilibrium(freqs, volts)
        _, z, reached = self.continuation(freqs, volts, 1.0)
        return z, reached

    def sub(self, rows) -> "Mechanism":
        return Mechanism(self.ev.subset(rows))

    # -- one smooth coordinate: the branch as a curve ------------------------------------------------
    def _v2(self, s, d, freqs, volts):
        """Drive scale V^2 holding the mechanism at z = d s (N,): R/G, +inf where the force no longer pushes along d."""
        z = (d * s)[:, None]
        g = self.external(z, freqs, volts)[:, 0] * d
        r = self.restoring(z)[:, 0] * d
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(g > 0, r / np.where(g > 0, g, 1.0), np.inf)

    def curve(self, freqs, volts, grid: int = 24, golden: int = 30) -> dict:
        """First maximum of V^2 along the coordinate from rest towards the force at rest, up to contact (grid, then golden section; Kiefer 1953)."""
        key = ("curve", freqs, volts)
        if key in self.ev.cache:
            return self.ev.cache[key]
        zero = np.zeros((self.n, 1))
        g0 = self.external(zero, freqs, volts)[:, 0]
        d = np.sign(g0)
        # contact: a pair's gap along its rest direction reaches 0 (mechanics._admissible)
        s_max = np.full(self.n, np.inf)
        unit = self.displacements(np.ones((self.n, 1)))
        for i, j, gap0, nrm in self._pairs:
            closing = -np.einsum("nk,nk->n", nrm, unit[:, j] - unit[:, i]) * d
            s_max = np.where(closing > 0, np.minimum(s_max, gap0 / np.where(closing > 0, closing, 1.0)), s_max)
        still = d == 0
        open_ = ~np.isfinite(s_max) & ~still
        span = np.where(np.isfinite(s_max), s_max, 0.0) * 0.999
        fr = np.linspace(0.0, 1.0, grid + 1)[1:]
        v2 = np.stack([self._v2(f * span, d, freqs, volts) for f in fr], axis=1)
        pos = np.where(np.isfinite(v2) & (v2 > 0), v2, np.inf)
        falls = pos[:, :-1] > pos[:, 1:]
        has = falls.any(axis=1) & ~still & ~open_
        k = np.where(has, np.argmax(falls, axis=1), grid - 1)
        rows = np.arange(self.n)
        lo = np.where(k > 0, fr[np.maximum(k - 1, 0)], 0.0) * span
        hi = fr[np.minimum(k + 1, grid - 1)] * span
        fbest, xbest = golden_max(lambda x: self._v2(x, d, freqs, volts), lo, hi, golden)
        best = np.maximum(fbest, pos[rows, k])
        s_best = np.where(pos[rows, k] >= fbest, fr[k] * span, xbest)
        out = {"v2_fold": np.where(has, best, np.nan), "s_fold": s_best, "has_fold": has, "dir": d,
               "s_max": span, "open": open_, "still": still}
        self.ev.cache[key] = out
        return out

    def curve_equilibrium(self, freqs, volts):
        """(z, ok): V^2(s) = 1 on the ascending branch below the fold (regula falsi, Illinois); not ok after snap-in or at contact."""
        cur = self.curve(freqs, volts)
        d = cur["dir"]
        z = np.zeros((self.n, 1))
        ok = cur["still"].copy()
        rows = np.flatnonzero(~cur["still"] & ~cur["open"] & ~(cur["v2_fold"] < 1.0))
        if rows.size:
            m = self if rows.size == self.n else self.sub(rows)
            dd = d[rows]
            hi = np.where(cur["has_fold"][rows], cur["s_fold"][rows], cur["s_max"][rows])
            s, fs, _ = illinois_ascending(lambda x, _st: (m._v2(x, dd, freqs, volts) - 1.0, None),
                                             np.zeros(rows.size), hi, -np.ones(rows.size),
                                             m._v2(hi, dd, freqs, volts) - 1.0, 60, 1e-13, 1e-15)
            good = np.abs(fs) <= 1e-9
            z[rows, 0] = np.where(good, dd * s, 0.0)
            ok[rows] = good
        rows = np.flatnonzero(cur["open"])
        if rows.size:
            m = self.sub(rows)
            _, zz, reached = m.continuation(freqs, volts, 1.0)
            z[rows], ok[rows] = zz, reached
        return z, ok
